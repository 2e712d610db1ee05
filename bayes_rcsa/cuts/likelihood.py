"""The stability likelihood of cutting-test outcomes.

For a cut at spindle speed n and axial depth a, a draw of the tool-point
dynamics θ and cutting coefficients (K_t, K_r) predicts the limit depth
a_lim(n; θ, K_t, K_r) (a registered stability method on the draw's RCSA
tool-point FRFs in X and Y; ZOA by default).  The probability that the cut
chatters is a probit in the log depth ratio,

    P(chatter | θ, K_t, K_r) = ε + (1 - 2ε) Φ( ln(a / a_lim) / w ),

with the boundary width ``w`` (default :data:`DEFAULT_BOUNDARY_WIDTH` = 0.1:
a cut 10 % below the predicted limit chatters with probability 16 %, 25 %
below with 0.6 %) and a label error ``ε`` (default
:data:`DEFAULT_LABEL_ERROR` = 0.01: a cut far from the boundary is still
reported the other way once in a hundred, so that one mislabelled cut cannot
veto a draw).  ``w`` → 0 and ε = 0 give the step of the deterministic lobes.
The width may also be sampled (a log-uniform prior, :class:`BoundaryWidth`).
A draw with no limit in the band (a_lim = inf) predicts "stable".  The idea
of a smooth Gaussian-CDF boundary on the ZOA limit follows Cornelius,
Karandikar & Schmitz (npj Adv. Manuf. 2024).

Cost: each draw's FRFs are computed once per (clamping length, tool), and
the method is evaluated only at the cut speeds, once per ratio node of the
coefficient prior (:mod:`.coefficients`); the level of the coefficients
enters by exact scaling (a_lim ∝ 1/K_t at a fixed K_r/K_t), so any number
of coefficient draws per dynamics draw costs nothing more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import SetupError
from .coefficients import CoefficientPrior

__all__ = ["DEFAULT_BOUNDARY_WIDTH", "DEFAULT_LABEL_ERROR", "BoundaryWidth", "chatter_probability",
           "outcome_log_likelihood", "CutGroup", "CutLikelihood", "inverse_limits_at_cuts"]

#: Width of the probit boundary in ln(depth / limit): 0.1 = the limit is known to about ±10 %.
DEFAULT_BOUNDARY_WIDTH = 0.1
#: Probability that a cut far from the boundary is reported the other way (mislabel, unmodelled effect).
DEFAULT_LABEL_ERROR = 0.01


@dataclass(frozen=True)
class BoundaryWidth:
    """Boundary width ``w``: fixed (``lo == hi``) or log-uniform on [lo, hi] and sampled.

    Attributes
    ----------
    lo, hi : float, > 0, in ln(depth ratio)
    """

    lo: float = DEFAULT_BOUNDARY_WIDTH
    hi: float = DEFAULT_BOUNDARY_WIDTH

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and 0 < self.lo <= self.hi <= 2.0):
            raise SetupError(f"boundary width {self.lo!r}..{self.hi!r}: expected 0 < lo <= hi <= 2 "
                             "(a width in ln(depth / limit), e.g. 0.1)")

    @property
    def sampled(self) -> bool:
        return self.hi > self.lo

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n,) widths."""
        if not self.sampled:
            return np.full(n, self.lo)
        return np.exp(rng.uniform(math.log(self.lo), math.log(self.hi), n))

    def ln_prob(self, w) -> np.ndarray:
        """Log density of ln w (uniform), -inf outside; 0 for a fixed width at its value."""
        w = np.asarray(w, dtype=float)
        if not self.sampled:
            return np.where(np.isclose(w, self.lo, rtol=1e-12, atol=0), 0.0, -np.inf)
        ok = (w >= self.lo) & (w <= self.hi)
        return np.where(ok, -math.log(math.log(self.hi / self.lo)), -np.inf)

    def describe(self) -> dict:
        return {"width": self.lo} if not self.sampled else {"log_uniform": [self.lo, self.hi]}


def _z(depth_m, limit_m, width):
    depth = np.asarray(depth_m, dtype=float)
    limit = np.asarray(limit_m, dtype=float)
    w = np.asarray(width, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.log(depth) - np.log(limit)  # -inf where the limit is inf: surely stable
        z = np.where(w > 0, x / np.where(w > 0, w, 1.0), np.sign(x) * np.inf)
    return np.where(np.isnan(z), 0.0, z)  # w -> 0 at depth == limit: the midpoint of the step


def chatter_probability(depth_m, limit_m, width=DEFAULT_BOUNDARY_WIDTH, label_error: float = 0.0) -> np.ndarray:
    """P(chatter) = ε + (1 - 2ε) Φ(ln(depth / limit) / width), broadcast over the inputs.

    Parameters
    ----------
    depth_m : (...) m, axial depth of the cut
    limit_m : (...) m, predicted limit (inf: no chatter predicted)
    width : (...) >= 0, boundary width in ln(depth ratio); 0 gives the step (0.5 at the limit)
    label_error : float ε in [0, 0.5)
    """
    from scipy.special import ndtr

    return label_error + (1 - 2 * label_error) * ndtr(_z(depth_m, limit_m, width))


def outcome_log_likelihood(depth_m, limit_m, chatter, width=DEFAULT_BOUNDARY_WIDTH,
                           label_error: float = DEFAULT_LABEL_ERROR) -> np.ndarray:
    """Pointwise log P(outcome) of cuts, broadcast over the inputs (e.g. (n_particles, n_cuts)).

    Uses ``log_ndtr`` so that outcomes far on the wrong side stay finite (no underflow to -inf) when ε = 0.

    Parameters
    ----------
    depth_m, limit_m, width : as :func:`chatter_probability`
    chatter : (...) bool, True where the cut chattered
    label_error : float ε in [0, 0.5)
    """
    from scipy.special import log_ndtr

    if not (0.0 <= label_error < 0.5):
        raise SetupError(f"label_error={label_error!r}: expected a probability in [0, 0.5)")
    z = _z(depth_m, limit_m, width)
    s = np.where(np.asarray(chatter, dtype=bool), z, -z)
    lp = log_ndtr(s)
    if label_error == 0:
        return lp
    # log(ε + (1 - 2ε) Φ(s)) without underflow: logaddexp(log ε, log(1 - 2ε) + log Φ(s))
    return np.logaddexp(math.log(label_error), math.log1p(-2 * label_error) + lp)


@dataclass(frozen=True)
class CutGroup:
    """Cuts that share one tool-point FRF and one cutting geometry.

    Attributes
    ----------
    frf_x, frf_y : (n_draws, n_freq) complex, m/N, the draws' tool-point FRFs
    frequency_hz : (n_freq,) Hz
    cutting : CuttingConditions (its K_t, K_r are ignored: the prior's are used)
    index : (k,) int, positions of the group's cuts in the cut list
    speed_rpm : (k,) rpm of those cuts
    """

    frf_x: np.ndarray
    frf_y: np.ndarray
    frequency_hz: np.ndarray
    cutting: object
    index: np.ndarray
    speed_rpm: np.ndarray


def inverse_limits_at_cuts(groups, n_cuts: int, prior: CoefficientPrior, method: str = "zoa",
                           options=None) -> np.ndarray:
    """1 / a_lim of every draw at every cut at the prior's reference level, per ratio node.

    Parameters
    ----------
    groups : sequence of CutGroup (their draws in the same order)
    n_cuts : int
    prior : CoefficientPrior (reference K_t = ``prior.kt``; one evaluation per ratio node)
    method : name in :data:`~bayes_rcsa.stability.methods.STABILITY_METHODS`
    options : MethodOptions or None

    Returns
    -------
    (n_nodes, n_draws, n_cuts) 1/m; 0 where the method finds no limit (inf).
    """
    from ..stability.methods import STABILITY_METHODS, MethodOptions, method_names

    if method not in method_names():
        raise SetupError(f"method={method!r}: expected one of {', '.join(method_names())}")
    impl = STABILITY_METHODS.get(method)
    options = MethodOptions() if options is None else options
    impl.check(options)
    ratios = prior.ratios
    n_draws = groups[0].frf_x.shape[0]
    out = np.zeros((ratios.size, n_draws, n_cuts))
    for g in groups:  # a few (clamping length, tool, immersion, feed) groups; each vectorised over draws
        speeds, where = np.unique(g.speed_rpm, return_inverse=True)
        for j, rho in enumerate(ratios):
            c = replace(g.cutting, kt=prior.kt, kr=float(prior.kt * rho))
            lim = np.atleast_2d(impl.depth_limits(g.frf_x, g.frf_y, g.frequency_hz, c, speeds, options).depth_limit_m)
            with np.errstate(divide="ignore"):
                out[j][:, g.index] = 1.0 / lim[:, where]
    return out


class CutLikelihood:
    """log P(outcomes | draw, coefficients, width) of a set of cuts, vectorised over particles.

    A *particle* is (draw index d, log level u, ratio node j, width w): the
    limit of cut c is ``exp(-u) / inv[j, d, c]``.

    Parameters
    ----------
    inverse_limits : (n_nodes, n_draws, n_cuts) 1/m, from :func:`inverse_limits_at_cuts`
    depth_m : (n_cuts,) m
    chatter : (n_cuts,) bool
    label_error : float ε
    """

    def __init__(self, inverse_limits, depth_m, chatter, label_error: float = DEFAULT_LABEL_ERROR):
        self.inverse_limits = np.asarray(inverse_limits, dtype=float)
        self.depth_m = np.asarray(depth_m, dtype=float)
        self.chatter = np.asarray(chatter, dtype=bool)
        if self.inverse_limits.ndim != 3 or self.inverse_limits.shape[2] != self.depth_m.size \
                or self.chatter.shape != self.depth_m.shape:
            raise SetupError("CutLikelihood: inverse_limits must be (n_nodes, n_draws, n_cuts) with n_cuts = "
                             f"{self.depth_m.size}; got {self.inverse_limits.shape}")
        self.label_error = float(label_error)

    @property
    def n_cuts(self) -> int:
        return int(self.depth_m.size)

    @property
    def n_draws(self) -> int:
        return int(self.inverse_limits.shape[1])

    def limits(self, draw, u, node) -> np.ndarray:
        """(n_particles, n_cuts) m, the limit of every particle at every cut (inf: none)."""
        inv = self.inverse_limits[np.asarray(node), np.asarray(draw)] * np.exp(np.asarray(u, dtype=float))[:, None]
        with np.errstate(divide="ignore"):
            return 1.0 / inv

    def pointwise(self, draw, u, node, width) -> np.ndarray:
        """(n_particles, n_cuts) log P(outcome of cut c | particle)."""
        w = np.asarray(width, dtype=float)
        return outcome_log_likelihood(self.depth_m[None, :], self.limits(draw, u, node), self.chatter[None, :],
                                      w[:, None] if w.ndim else w, self.label_error)

    def __call__(self, draw, u, node, width) -> np.ndarray:
        """(n_particles,) log likelihood of all cuts."""
        return self.pointwise(draw, u, node, width).sum(axis=1)
