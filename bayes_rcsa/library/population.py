"""The population model of a tool library's contact laws (docs/library.md, docs/theory.md).

Per holder type ``t`` and combination ``s`` (a tool in a holder of that
type), the contact law's parameters in their *population coordinates*
``z`` are

    z_s ~ Normal(a_t + b_t x_s, diag(sigma_t^2)),   x_s = ln(d_s / 10 mm)

with ``d_s`` the tool's shank diameter.  The coordinates are those in which
the stage-1 prior of ``identify`` is flat:

===========  ==================  ===========================
parameter    coordinate z        unit of z
===========  ==================  ===========================
k_xf         log10 k(l_a)        log10(N/m)
k_thetaM     log10 k(l_a)        log10(N m/rad)
g_xf         g                   1
g_thetaM     g                   1
c_xf         log10 c             log10(N s/m)
c_thetaM     log10 c             log10(N m s/rad)
===========  ==================  ===========================

Only the parameters sampled in every stage-1 fit enter (a damping held fixed
in the setups is not pooled).  The stiffness refers to the library's common
reference length ``l_a`` (the short end of the clamping range shared by all
setups).

Hyperparameters per type and coordinate ``j`` (units of ``z_j``; ``x`` is
dimensionless), weakly informative and set from the stage-1 prior box
``[lo_j, hi_j]`` so that they carry the units of the setups:

* ``a_tj ~ Normal((lo_j + hi_j) / 2, (hi_j - lo_j) / 2)``
* ``b_tj ~ Normal(0, B_j)``, ``B_j = 2`` decades per e-fold of diameter for
  log10 coordinates (a stiffness ~ d^4 has b = 1.7), ``Q`` for growth
* ``sigma_tj ~ HalfNormal(S_j)``, ``S_j = 0.5`` decades (a factor ~3 between
  combinations) for log10 coordinates, ``Q / 2`` for growth

The sampler moves in ``(a, b, sigma)`` with ``sigma >= 0``.  (In ``ln sigma`` the
posterior has a long exponential tail towards small spreads that emcee
explores poorly; in ``sigma`` the same region is a bounded interval.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError

__all__ = ["COORDINATES", "SCALES", "D_REF", "MODEL_VERSION", "Hyperprior", "covariate", "coordinate_units",
           "to_coordinates", "from_coordinates"]

#: Version of the population model and of population.nc; a file of another version is refused.
MODEL_VERSION = "bayes_rcsa.library/1"
#: m, reference shank diameter of the covariate ``x = ln(d / D_REF)``.
D_REF = 0.010
#: Contact parameters a population can pool, in vector order.
COORDINATES = ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "c_thetaM")
#: Coordinate of each parameter: log10 of the value or the value itself.
SCALES = {"k_xf": "log10", "k_thetaM": "log10", "g_xf": "linear", "g_thetaM": "linear", "c_xf": "log10",
          "c_thetaM": "log10"}
_UNITS = {"k_xf": "N/m", "k_thetaM": "N m/rad", "g_xf": "1", "g_thetaM": "1", "c_xf": "N s/m",
          "c_thetaM": "N m s/rad"}
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


@dataclass(frozen=True)
class Hyperprior:
    """The weakly-informative hyperprior of one holder type (the same for every type).

    Attributes
    ----------
    names : tuple of str, (d,) pooled coordinates
    a_mean, a_sd : (d,) prior of the mean at 10 mm (units of z)
    b_sd : (d,) prior sd of the diameter slope (units of z per unit of x)
    s_scale : (d,) half-normal scale of the spread (units of z)
    """

    names: tuple
    a_mean: np.ndarray
    a_sd: np.ndarray
    b_sd: np.ndarray
    s_scale: np.ndarray

    @classmethod
    def from_box(cls, names, box: np.ndarray, growth_bound: float) -> "Hyperprior":
        """The documented defaults for the stage-1 prior box (d, 2) in population coordinates."""
        box = np.asarray(box, dtype=float)
        if box.shape != (len(names), 2) or not np.all(np.isfinite(box)) or np.any(box[:, 1] <= box[:, 0]):
            raise SetupError(f"stage-1 prior box {box.tolist()} of {list(names)}: expected finite lo < hi")
        growth = np.array([SCALES[n] == "linear" for n in names])
        q = float(growth_bound) if growth_bound > 0 else 1.0
        return cls(tuple(names), box.mean(axis=1), 0.5 * (box[:, 1] - box[:, 0]),
                   np.where(growth, q, 2.0), np.where(growth, 0.5 * q, 0.5))

    @property
    def ndim(self) -> int:
        return len(self.names)

    def ln_prob(self, a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Log density of (a, b, sigma); ``-inf`` where a spread is negative.

        Parameters
        ----------
        a, b, s : (..., d)

        Returns
        -------
        (...,)
        """
        za = (a - self.a_mean) / self.a_sd
        zb = b / self.b_sd
        zs = s / self.s_scale
        const = float(np.sum(-np.log(self.a_sd) - np.log(self.b_sd) - np.log(self.s_scale))
                      - self.ndim * (1.5 * math.log(2 * math.pi) - math.log(2.0)))
        lp = const - 0.5 * np.sum(za * za + zb * zb + zs * zs, axis=-1)
        return np.where(np.all(s >= 0, axis=-1), lp, -np.inf)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, 3d) draws of (a, b, sigma)."""
        d = self.ndim
        a = self.a_mean + self.a_sd * rng.standard_normal((n, d))
        b = self.b_sd * rng.standard_normal((n, d))
        s = np.abs(self.s_scale * rng.standard_normal((n, d)))
        return np.concatenate([a, b, s], axis=1)

    def describe(self) -> dict:
        return {n: {"a": {"distribution": "normal", "mu": float(self.a_mean[j]), "sigma": float(self.a_sd[j])},
                    "b": {"distribution": "normal", "mu": 0.0, "sigma": float(self.b_sd[j])},
                    "sigma": {"distribution": "half-normal", "scale": float(self.s_scale[j])},
                    "unit": coordinate_units(n)}
                for j, n in enumerate(self.names)}
