"""Update a posterior with cut outcomes without redoing the hammer-test fit: importance re-weighting.

The hammer posterior's draws θ_d (equally weighted) are the proposal.  Every
draw is paired with ``M`` draws of the cutting coefficients from their prior
(:class:`~.coefficients.CoefficientPrior`) and, when it is sampled, of the
boundary width; each such *particle* p = (d, u, j, w) gets the weight

    W_p ∝ Π_c P(outcome_c | θ_d, K_t(u), K_r(u, j), w)

(:class:`~.likelihood.CutLikelihood`).  This is exact importance sampling of
p(θ, K_t, K_r | hammer, cuts) ∝ p(θ | hammer) p(K_t, K_r) p(cuts | θ, K_t, K_r):
the hammer posterior is the proposal and cancels.  Since the coefficients'
level enters the limits by exact scaling, M costs nothing but memory.

ESS check.  Two effective sample sizes are reported: of the particles, and
of the *draws* (weights summed per draw), 1 / Σ_d W_d².  The second measures
how many distinct hammer draws carry the update; below ``min_ess`` the cuts
contradict (or sharpen far beyond) the hammer posterior and re-weighting
cannot represent the result.  The update is then refused with the reason
(:class:`~bayes_rcsa.errors.ConvergenceError`) rather than returning a
posterior of a few repeated draws.

The output is ``n_out`` particles drawn by systematic resampling (equal
weights), ready to be written as an ordinary posterior with K_t/K_r draws.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConvergenceError, SetupError
from ..stats import weights as _weights
from ..stats.weights import MIN_ESS_UPDATE, effective_sample_size
from .coefficients import CoefficientPrior
from .likelihood import BoundaryWidth, CutLikelihood, chatter_probability

__all__ = ["UpdateSettings", "UpdateResult", "importance_update", "systematic_resample", "weighted_quantile",
           "effective_sample_size", "per_cut_summary", "normalise_log_weights", "DEFAULT_MIN_ESS",
           "DEFAULT_PARTICLES_PER_DRAW"]

#: Coefficient (and width) draws per hammer draw: the level scales exactly, so many are cheap.
DEFAULT_PARTICLES_PER_DRAW = 32
#: Fewer effective hammer draws than this and the update is refused (default of ``--min-ess``; why 50:
#: :data:`bayes_rcsa.stats.weights.MIN_ESS_UPDATE`).
DEFAULT_MIN_ESS = MIN_ESS_UPDATE


@dataclass(frozen=True)
class UpdateSettings:
    """Settings of :func:`importance_update`.

    Attributes
    ----------
    particles_per_draw : int >= 1, coefficient/width draws per hammer draw (M)
    min_ess : float, the least ESS of the draws accepted
    n_out : int or None, draws of the updated posterior (None: as many as hammer draws)
    """

    particles_per_draw: int = DEFAULT_PARTICLES_PER_DRAW
    min_ess: float = DEFAULT_MIN_ESS
    n_out: int | None = None

    def __post_init__(self) -> None:
        if int(self.particles_per_draw) != self.particles_per_draw or self.particles_per_draw < 1:
            raise SetupError(f"particles_per_draw={self.particles_per_draw!r}: expected an integer >= 1")
        if not (self.min_ess >= 1):
            raise SetupError(f"min_ess={self.min_ess!r}: expected >= 1")


@dataclass(frozen=True)
class UpdateResult:
    """The re-weighted and resampled particles.

    Attributes
    ----------
    draw : (n_out,) int, hammer draw of each output draw
    u, node, width : (n_out,), log level, ratio node, boundary width
    kt, kr : (n_out,) Pa
    ess_particles, ess_draws : float
    n_particles, n_draws : int
    log_evidence : float, ln of the mean likelihood of the prior particles (ln p(cuts | hammer))
    per_cut : list of dict, one per cut (see :func:`importance_update`)
    prior_kt, prior_kr : (n_particles,) Pa, the coefficients before the cuts (for comparisons)
    weights : (n_particles,) normalised weights
    particle_draw : (n_particles,) int
    limits : (n_particles, n_cuts) m, every particle's limit at every cut
    particle_u, particle_node : (n_particles,) the particles' log level and ratio node
    loo_weights : (n_cuts, n_particles) normalised weights without each cut
    particle_width : (n_particles,) the particles' boundary widths
    """

    draw: np.ndarray
    u: np.ndarray
    node: np.ndarray
    width: np.ndarray
    kt: np.ndarray
    kr: np.ndarray
    ess_particles: float
    ess_draws: float
    n_particles: int
    n_draws: int
    log_evidence: float
    per_cut: list = field(default_factory=list)
    prior_kt: np.ndarray | None = None
    prior_kr: np.ndarray | None = None
    weights: np.ndarray | None = None
    particle_draw: np.ndarray | None = None
    limits: np.ndarray | None = None
    particle_u: np.ndarray | None = None
    particle_node: np.ndarray | None = None
    loo_weights: np.ndarray | None = None
    particle_width: np.ndarray | None = None


def systematic_resample(weights, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` indices drawn by systematic resampling (one uniform; low variance), sorted."""
    w = np.asarray(weights, dtype=float)
    c = np.cumsum(w / w.sum())
    c[-1] = 1.0
    pos = (rng.uniform() + np.arange(n)) / n
    return np.searchsorted(c, pos, side="left")


def weighted_quantile(values, weights, q) -> np.ndarray:
    """Quantiles ``q`` of ``values`` (n,) under ``weights`` (n,) (inverse CDF; inf allowed), (len(q),)."""
    v = np.asarray(values, dtype=float)
    w = np.asarray(weights, dtype=float)
    order = np.argsort(v, kind="stable")
    c = np.cumsum(w[order])
    c /= c[-1]
    i = np.searchsorted(c, np.atleast_1d(q), side="left")
    return v[order][np.minimum(i, v.size - 1)]


def normalise_log_weights(logw: np.ndarray) -> np.ndarray:
    """exp(logw) / sum (n,), computed stably (:func:`bayes_rcsa.stats.weights.normalise_log_weights`);
    ConvergenceError when every particle's weight is zero."""
    return _weights.normalise_log_weights(logw, reason="every particle has zero likelihood under the cut outcomes; "
                                          "the cuts contradict the posterior entirely")


def importance_update(likelihood: CutLikelihood, prior: CoefficientPrior, width: BoundaryWidth,
                      rng: np.random.Generator, settings: UpdateSettings | None = None,
                      refuse: bool = True) -> UpdateResult:
    """Re-weight the draws of ``likelihood`` (its inverse limits) with the cut outcomes and resample.

    Parameters
    ----------
    likelihood : CutLikelihood of the hammer draws
    prior : CoefficientPrior
    width : BoundaryWidth
    rng : numpy.random.Generator
    settings : UpdateSettings
    refuse : bool, raise when the ESS of the draws is below ``settings.min_ess`` (False: return the result,
        e.g. to start the MCMC fallback of :mod:`.mcmc` from it)

    Returns
    -------
    UpdateResult.  ``per_cut[c]`` holds the cut's speed, depth and outcome, the median limit at it
    before and after (m), the median after without this cut (leave-one-cut-out) and ``moved``, the
    relative change of the median limit at its speed that this cut makes (after / without - 1),
    P(chatter) predicted before and after, and the K_t median without the cut.

    Raises
    ------
    ConvergenceError
        The ESS of the draws is below ``settings.min_ess`` (message gives the ESS and what to do).
    """
    s = settings or UpdateSettings()
    n_draws = likelihood.n_draws
    m = int(s.particles_per_draw)
    draw = np.repeat(np.arange(n_draws), m)
    u, node = prior.sample(rng, draw.size)
    w = width.sample(rng, draw.size)
    pw = likelihood.pointwise(draw, u, node, w)  # (P, C)
    logl = pw.sum(axis=1)
    weights = normalise_log_weights(logl)
    ess_p = effective_sample_size(weights)
    ess_d = effective_sample_size(np.bincount(draw, weights, n_draws))
    top = float(np.max(logl))
    log_evidence = top + float(np.log(np.mean(np.exp(logl - top))))
    if refuse and ess_d < s.min_ess:
        raise ConvergenceError(
            f"importance re-weighting collapsed: the {likelihood.n_cuts} cut(s) leave an effective sample size of "
            f"{ess_d:.1f} hammer draws (of {n_draws}; {ess_p:.1f} of {draw.size} particles), below {s.min_ess:g}: the "
            "cuts contradict or sharpen the hammer posterior far beyond what its draws can represent; use more "
            "draws (--draws), a wider coefficient prior (--kt V±T) or a wider boundary (--boundary-width), or check "
            "the cuts' clamping length, immersion and feed")
    n_out = s.n_out or n_draws
    pick = systematic_resample(weights, n_out, rng)
    kt_all, kr_all = prior.coefficients(u, node)
    limits = likelihood.limits(draw, u, node)
    loo = np.array([normalise_log_weights(logl - pw[:, c]) for c in range(pw.shape[1])])  # a few tens of cuts
    per_cut = per_cut_summary(likelihood, limits, w, limits, weights, loo, w, kt_all)
    return UpdateResult(draw[pick], u[pick], node[pick], w[pick], kt_all[pick], kr_all[pick], ess_p, ess_d,
                        int(draw.size), n_draws, log_evidence, per_cut, kt_all, kr_all, weights, draw, limits,
                        u, node, loo, w)


def per_cut_summary(likelihood, before_limits, before_width, limits, weights, loo_weights, width, kt) -> list[dict]:
    """What each cut did: median limit at it before/after/without it, P(chatter), K_t without it.

    Parameters
    ----------
    likelihood : CutLikelihood (depths, outcomes, label error)
    before_limits : (n_before, n_cuts) m, limits of the hammer-only particles (equal weights)
    before_width : (n_before,) their boundary widths
    limits : (n, n_cuts) m, of the updated particles; weights (n,); loo_weights (n_cuts, n) without each cut
    width, kt : (n,) of the updated particles
    """
    flat = np.full(before_limits.shape[0], 1.0 / before_limits.shape[0])
    out = []
    for c in range(limits.shape[1]):  # a few tens of cuts, each vectorised over particles
        loo = loo_weights[c]
        before = float(weighted_quantile(before_limits[:, c], flat, 0.5)[0])
        after = float(weighted_quantile(limits[:, c], weights, 0.5)[0])
        without = float(weighted_quantile(limits[:, c], loo, 0.5)[0])
        p_after = chatter_probability(likelihood.depth_m[c], limits[:, c], width, likelihood.label_error)
        p_before = chatter_probability(likelihood.depth_m[c], before_limits[:, c], before_width, likelihood.label_error)
        out.append({
            "depth_m": float(likelihood.depth_m[c]), "outcome": "chatter" if likelihood.chatter[c] else "stable",
            "median_limit_before_m": before, "median_limit_after_m": after, "median_limit_without_m": without,
            "moved": (after / without - 1.0) if np.isfinite(after) and np.isfinite(without) and without > 0 else None,
            "p_chatter_before": float(np.mean(p_before)), "p_chatter_after": float(np.sum(weights * p_after)),
            "kt_median_without_pa": float(weighted_quantile(kt, loo, 0.5)[0]),
        })
    return out
