"""The population model of a tool library's contact laws (docs/library.md, docs/theory.md).

Per holder type ``t`` and combination ``s`` (a tool in a holder of that
type), the contact law's parameters in their *population coordinates*
``z`` are

    z_s ~ Normal(a_t + b_t x_s, diag(sigma_t^2)),   x_s = ln(d_s / 10 mm)

with ``d_s`` the tool's shank diameter.  The coordinates are those in which
the stage-1 prior of ``identify`` is flat:

==============  ==================  ===========================
parameter       coordinate z        unit of z
==============  ==================  ===========================
k_xf            log10 k(l_a)        log10(N/m)
k_thetaM        log10 k(l_a)        log10(N m/rad)
g_xf            g                   1
g_thetaM        g                   1
c_xf            log10 c             log10(N s/m)
c_thetaM        log10 c             log10(N m s/rad)
law_shape_bend  u                   1
==============  ==================  ===========================

Only the parameters sampled in every stage-1 fit enter (a damping held fixed
in the setups is not pooled).  ``law_shape_bend`` (the term
``law_shape_uncertainty``: where the contact law lies between the parallel,
``u = 0``, and the series two-spring law, ``u = 1``) enters only when every
setup has the term in its ``[model]`` and was fitted at three or more
clamping lengths: with two lengths ``u`` is not identified (its stage-1
posterior is its prior), and pooling it would only return the prior;
otherwise it is left out with a warning (stage1.py).  The stiffness refers
to the library's common reference length ``l_a`` (the short end of the
clamping range shared by all setups).

Across holder types (one more level, model version 2) the diameter slope and
the spread are partially pooled, per coordinate ``j``:

    b_tj = b0_j + tau_b,j * delta_tj,          delta_tj ~ N(0, 1)
    ln sigma_tj ~ N(ln sigma0_j, tau_s,j^2)

Hyperpriors (units of ``z_j``; ``x`` is dimensionless), weakly informative
and set from the stage-1 prior box ``[lo_j, hi_j]`` so that they carry the
units of the setups:

* ``a_tj ~ Normal((lo_j + hi_j) / 2, (hi_j - lo_j) / 2)`` per type
* ``b0_j ~ Normal(0, B_j)``, ``B_j = 2`` decades per e-fold of diameter for
  log10 coordinates (a stiffness ~ d^4 has b = 1.7), ``Q`` for growth,
  the box width ``W`` for the law's bend (``W = 1`` for ``u`` in [0, 1]: the
  bend may move through its whole range per e-fold of diameter; the growth
  formula with ``Q = 1``)
* ``tau_b,j ~ HalfNormal(B_j / 8)``: 0.25 decades per e-fold (exponents of
  the stiffness-diameter law differing by ~0.6 between types), ``Q / 8``,
  ``W / 8``
* ``ln sigma0_j ~ Normal(ln(S_j / 5), 1)``, ``S_j = 0.5`` decades for log10
  coordinates (median 0.1 decade = 26 % between combinations, 95 % within
  0.014-0.7 decades), ``Q / 2`` for growth, ``W / 2`` for the law's bend
  (median 0.1 of ``u`` between combinations)
* ``tau_s,j ~ HalfNormal(0.5)`` (e-folds: types' spreads differing by a
  factor ~1.6 per sd)

Stage 2 integrates ``a``, ``delta`` and ``b0`` out in closed form (they
enter linearly), ``ln sigma0`` in closed form and ``tau_s`` by quadrature;
emcee samples ``(ln sigma_tj, tau_b,j)``: ``d (T + 1)`` dimensions for ``T``
types.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError

__all__ = ["COORDINATES", "SHAPE_COORDINATES", "SCALES", "D_REF", "MODEL_VERSION", "Hyperprior", "covariate",
           "coordinate_units", "to_coordinates", "from_coordinates"]

#: Version of the population model and of population.nc; a file of another version is refused.
MODEL_VERSION = "bayes_rcsa.library/2"
#: m, reference shank diameter of the covariate ``x = ln(d / D_REF)``.
D_REF = 0.010
#: Parameters a population can pool, in vector order: the contact's, then the law's bend (term
#: ``law_shape_uncertainty``), last so that the contact coordinates keep their order.
COORDINATES = ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "c_thetaM", "law_shape_bend")
#: Pooled coordinates that are not contact parameters (not part of a new setup's joint contact prior).
SHAPE_COORDINATES = ("law_shape_bend",)
#: Coordinate of each parameter: log10 of the value or the value itself.
SCALES = {"k_xf": "log10", "k_thetaM": "log10", "g_xf": "linear", "g_thetaM": "linear", "c_xf": "log10",
          "c_thetaM": "log10", "law_shape_bend": "linear"}
_UNITS = {"k_xf": "N/m", "k_thetaM": "N m/rad", "g_xf": "1", "g_thetaM": "1", "c_xf": "N s/m",
          "c_thetaM": "N m s/rad", "law_shape_bend": "1"}
#: Plausible shank diameters (m); outside, the setup's units are wrong (e.g. mm written as m).
DIAMETER_RANGE = (0.5e-3, 0.2)


def coordinate_units(name: str) -> str:
    """Unit of the population coordinate of ``name`` (e.g. ``"log10(N/m)"``)."""
    return f"log10({_UNITS[name]})" if SCALES[name] == "log10" else _UNITS[name]


def covariate(diameter_m, where: str = "shank diameter") -> np.ndarray:
    """``x = ln(d / 10 mm)`` of shank diameters in m.

    Raises
    ------
    SetupError
        A diameter outside 0.5 mm - 200 mm (mixed units, e.g. mm given as m).
    """
    d = np.asarray(diameter_m, dtype=float)
    lo, hi = DIAMETER_RANGE
    bad = ~(np.isfinite(d) & (d >= lo) & (d <= hi))
    if np.any(bad):
        v = float(np.atleast_1d(d)[np.argmax(np.atleast_1d(bad))])
        raise SetupError(f"{where} {v!r} m: expected {lo * 1e3:g} mm - {hi * 1e3:g} mm in metres (mixed units?)")
    return np.log(d / D_REF)


def to_coordinates(names, values) -> np.ndarray:
    """Population coordinates (n, d) of physical values ``{name: (n,)}``."""
    cols = []
    for n in names:
        v = np.asarray(values[n], dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            cols.append(np.log10(v) if SCALES[n] == "log10" else v)
    return np.column_stack(cols)


def from_coordinates(names, z) -> dict[str, np.ndarray]:
    """Physical values ``{name: (n,)}`` of population coordinates (n, d)."""
    z = np.atleast_2d(z)
    return {n: (10.0 ** z[:, j] if SCALES[n] == "log10" else z[:, j]) for j, n in enumerate(names)}


#: tau_s grid (e-folds) of the quadrature over the spreads' pooling scale: geometric, fine near 0 where the
#: half-normal prior has its mode and the integrand its (integrable) peak when the types' spreads agree.
_TAU_S_GRID = np.geomspace(1e-3, 3.0, 96)


@dataclass(frozen=True)
class Hyperprior:
    """The weakly-informative hyperprior of a library's population (docs/theory.md, "Tool-library population").

    Attributes
    ----------
    names : tuple of str, (d,) pooled coordinates
    a_mean, a_sd : (d,) prior of each type's mean at 10 mm (units of z)
    b_sd : (d,) prior sd of the common diameter slope b0 (units of z per unit of x)
    tb_scale : (d,) half-normal scale of the slopes' spread between types tau_b (units of b)
    ls_mean : (d,) prior mean of ln sigma0 (sigma0 in units of z)
    ls_sd : float, prior sd of ln sigma0 (e-folds)
    ts_scale : float, half-normal scale of the spreads' spread between types tau_s (e-folds)
    """

    names: tuple
    a_mean: np.ndarray
    a_sd: np.ndarray
    b_sd: np.ndarray
    tb_scale: np.ndarray
    ls_mean: np.ndarray
    ls_sd: float = 1.0
    ts_scale: float = 0.5

    @classmethod
    def from_box(cls, names, box: np.ndarray, growth_bound: float) -> "Hyperprior":
        """The documented defaults for the stage-1 prior box (d, 2) in population coordinates.

        Parameters
        ----------
        names : sequence of str, (d,) pooled coordinates
        box : (d, 2) stage-1 prior box in population coordinates
        growth_bound : float, the growth law's bound Q (1): the scale of the growth factors' slope and spread
        """
        box = np.asarray(box, dtype=float)
        if box.shape != (len(names), 2) or not np.all(np.isfinite(box)) or np.any(box[:, 1] <= box[:, 0]):
            raise SetupError(f"stage-1 prior box {box.tolist()} of {list(names)}: expected finite lo < hi")
        shape = np.array([n in SHAPE_COORDINATES for n in names])
        growth = np.array([SCALES[n] == "linear" for n in names]) & ~shape
        q = float(growth_bound) if growth_bound > 0 else 1.0
        # the law's bend has no growth bound: its own range (the box width, 1 for u in [0, 1]) plays Q's part
        width = box[:, 1] - box[:, 0]
        b_sd = np.where(growth, q, np.where(shape, width, 2.0))
        s_scale = np.where(growth, 0.5 * q, np.where(shape, 0.5 * width, 0.5))
        return cls(tuple(names), box.mean(axis=1), 0.5 * (box[:, 1] - box[:, 0]), b_sd, b_sd / 8.0,
                   np.log(s_scale / 5.0))

    @property
    def ndim(self) -> int:
        return len(self.names)

    def ln_prob_tau_b(self, tau_b: np.ndarray) -> np.ndarray:
        """Log half-normal density of the slopes' spread ``tau_b`` (..., d); ``-inf`` where negative."""
        z = tau_b / self.tb_scale
        lp = np.sum(-0.5 * z * z - np.log(self.tb_scale) + 0.5 * math.log(2.0 / math.pi), axis=-1)
        return np.where(np.all(tau_b >= 0, axis=-1), lp, -np.inf)

    def ln_prob_log_sigma(self, u: np.ndarray) -> np.ndarray:
        """Log density of the types' log spreads with ``ln sigma0`` and ``tau_s`` integrated out.

        Per coordinate ``j`` the ``T`` values ``u_tj = ln sigma_tj`` are, given ``tau_s``, jointly normal
        with mean ``ls_mean_j`` and covariance ``tau_s^2 I + ls_sd^2 1 1^T`` (``ln sigma0`` integrated out in
        closed form, Sherman-Morrison); ``tau_s`` is integrated numerically against its half-normal prior
        on a geometric grid (trapezoid weights).

        Parameters
        ----------
        u : (..., T, d) ln sigma (sigma in units of z)

        Returns
        -------
        (...,)
        """
        T = u.shape[-2]
        c = self.ls_sd ** 2
        r = u - self.ls_mean  # (..., T, d)
        rr = np.sum(r * r, axis=-2)[..., None]  # (..., d, 1)
        rs = np.sum(r, axis=-2)[..., None]
        t2, t2c, logdet, ln_w = _quadrature(T, c, self.ts_scale)
        # one (..., d, G) buffer updated in place, operation for operation:
        # ln_n + ln_w with q = (rr - c rs^2 / t2c) / t2 and ln_n = -0.5 (q + logdet + T ln 2 pi)
        x = c * rs * rs / t2c
        np.subtract(rr, x, out=x)
        x /= t2
        x += logdet
        x += T * math.log(2 * math.pi)
        x *= -0.5
        x += ln_w
        top = np.max(x, axis=-1, keepdims=True)
        x -= top
        lse = top[..., 0] + np.log(np.sum(np.exp(x, out=x), axis=-1))
        return np.sum(lse, axis=-1)

    def sample_log_sigma(self, rng: np.random.Generator, n: int, n_types: int) -> np.ndarray:
        """(n, T, d) prior draws of ln sigma."""
        d = self.ndim
        ls0 = self.ls_mean + self.ls_sd * rng.standard_normal((n, 1, d))
        tau = np.abs(self.ts_scale * rng.standard_normal((n, 1, d)))
        return ls0 + tau * rng.standard_normal((n, n_types, d))

    def describe(self) -> dict:
        return {n: {"a": {"distribution": "normal", "mu": float(self.a_mean[j]), "sigma": float(self.a_sd[j]),
                          "per": "holder type"},
                    "b0": {"distribution": "normal", "mu": 0.0, "sigma": float(self.b_sd[j])},
                    "tau_b": {"distribution": "half-normal", "scale": float(self.tb_scale[j])},
                    "b": "b_t = b0 + tau_b * delta_t, delta_t ~ normal(0, 1) per holder type",
                    "ln_sigma0": {"distribution": "normal", "mu": float(self.ls_mean[j]), "sigma": self.ls_sd},
                    "tau_s": {"distribution": "half-normal", "scale": self.ts_scale, "unit": "e-folds"},
                    "sigma": "ln sigma_t ~ normal(ln sigma0, tau_s) per holder type",
                    "unit": coordinate_units(n)}
                for j, n in enumerate(self.names)}


@functools.lru_cache(maxsize=64)
def _quadrature(n_types: int, c: float, ts_scale: float) -> tuple:
    """The parts of :meth:`Hyperprior.ln_prob_log_sigma`'s quadrature over ``tau_s`` that do not depend on the
    log spreads, for ``n_types`` types, ``c = ls_sd^2`` and the half-normal scale ``ts_scale`` (e-folds).

    Returns
    -------
    t2 : (G,) squared grid of :data:`_TAU_S_GRID`; t2c : (G,) ``t2 + n_types c``
    logdet : (G,) ``(n_types - 1) ln t2 + ln t2c``; ln_w : (G,) :func:`_tau_weights`
        Read-only: the cache (keyed by all three arguments, 64 entries) hands out the same arrays.
    """
    t2 = _TAU_S_GRID ** 2
    t2c = t2 + n_types * c
    logdet = (n_types - 1) * np.log(t2) + np.log(t2c)
    out = (t2, t2c, logdet, _tau_weights(ts_scale))
    for a in out:
        a.setflags(write=False)
    return out


def _tau_weights(scale: float) -> np.ndarray:
    """Log trapezoid weights of the half-normal(scale) prior on :data:`_TAU_S_GRID` (normalised to 1)."""
    g = _TAU_S_GRID
    dens = np.exp(-0.5 * (g / scale) ** 2)
    w = np.empty_like(g)
    w[1:-1] = 0.5 * (g[2:] - g[:-2])
    w[0] = 0.5 * (g[1] - g[0]) + g[0]  # the interval [0, g0] joins the first node
    w[-1] = 0.5 * (g[-1] - g[-2])
    w = dens * w
    return np.log(w / np.sum(w))
