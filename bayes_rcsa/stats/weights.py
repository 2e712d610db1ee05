"""Importance weights: normalisation from log weights, effective sample size, Pareto smoothing, thresholds.

Every importance re-weighting of the package (the design's nested Monte Carlo, the library's pooled and
two-stage weights, identify's tail check, the cuts update and next-cut ranking) goes through these functions,
and judges its weights with the constants below -- one constant per meaning, each with the reason for its value.

Effective sample size: Kish's ``(sum w)^2 / sum w^2`` (Kish 1965), computed as ``1 / sum w^2`` of the weights
normalised to sum to one.  Equal weights give ``n``, one non-zero weight gives 1.

Pareto shape ``k``: PSIS (Vehtari, Simpson, Gelman, Yao & Gabry 2024, "Pareto smoothed importance sampling",
JMLR 25(72)) fits a generalised Pareto distribution to the largest weights; its shape ``k`` estimates how heavy
the weights' tail is.  Computed here (:func:`pareto_smoothed_log_weights`), not by ArviZ's ``psislw``: the same
published algorithm, but importing ArviZ costs 2-4 s of start-up (it loads matplotlib, xarray, pandas and
scipy.stats), more than an importance-sampled identification itself; tests/test_stats.py checks the two agree.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConvergenceError

__all__ = ["normalise_log_weights", "effective_sample_size", "pareto_smoothed_log_weights", "pareto_k",
           "importance_reliable", "PARETO_K_MAX", "MIN_ESS", "MIN_ESS_INTERVAL_END", "MIN_ESS_UPDATE",
           "MIN_ESS_COVARIANCE", "MIN_ESS_PER_DIMENSION"]

#: Largest Pareto shape ``k`` of reliable importance weights.  Vehtari et al. (2024, JMLR 25(72)) show
#: the PSIS estimate's error converging at a practically useful rate for ``k < min(1 - 1/log10(S), 0.7)``; with
#: S >= 2,200 draws (the tail check uses 25,000 and 100,000) the sample-size term is above 0.7, so 0.7 is the bound.
PARETO_K_MAX = 0.7

#: Fewest effective draws behind a weighted Monte Carlo estimate (a quantile, a width, a kernel average) for it to
#: be used at all; below it the weights have collapsed onto a handful of draws.  The same meaning and value in the
#: design's nested re-weighting (median over the simulated measurements: ESS 30-300 on the design bench,
#: docs/design.md), the library's pooled estimate of a setup and its two-stage site averages (docs/library.md),
#: and the next-cut ranking's warning.  30 is the usual count for a sample mean's normal approximation: its
#: Monte Carlo standard error is then 1/sqrt(30) = 0.18 posterior standard deviations.
MIN_ESS = 30.0

#: Fewest effective importance draws for a verdict on a posterior's 5 % and 95 % points (identify's tail check,
#: the library's tail correction).  A 5 % point from an ESS of 1,000 has a Monte Carlo standard error of
#: sqrt(0.05 * 0.95 / 1000) / phi(1.645) = 0.07 posterior sd for a normal posterior, a sixth of the check's
#: 0.4-sd tolerance (:data:`bayes_rcsa.inference.tail_check.TOLERANCE_SD`), so a disagreement is not Monte Carlo
#: noise.
MIN_ESS_INTERVAL_END = 1000

#: Default of the fewest effective hammer draws (``bayes-rcsa update --min-ess``) below which the cuts update by
#: re-weighting is refused (a user setting, hence its own constant).  Larger than :data:`MIN_ESS` because the
#: updated posterior is resampled to as many draws as the hammer posterior and used as a posterior in its own
#: right (lobes, next cuts), not as one estimate; on the cuts bench the ESS of the draws had medians of 871-984 and
#: minima of 850-925 of 1,000, and no update came near 50 (docs/stability.md).
MIN_ESS_UPDATE = 50.0

#: Fewest effective draws, at least (:data:`MIN_ESS_COVARIANCE`) and per dimension (:data:`MIN_ESS_PER_DIMENSION`),
#: of a weighted pilot whose mean and covariance refit an importance proposal (identify's tail check).  Ten draws
#: per dimension is the common rule for a sample covariance: the smallest eigenvalue of one from n draws in d
#: dimensions shrinks like (1 - sqrt(d / n))^2 (Marchenko-Pastur), to 0.47 of the truth at n = 10 d, and fewer
#: leave it near-singular; the floor of 100 keeps the one- to three-dimensional fits from refitting to a few heavy
#: draws.
MIN_ESS_COVARIANCE = 100
MIN_ESS_PER_DIMENSION = 10


def normalise_log_weights(log_weights, axis: int | None = None, refuse: bool = True,
                          reason: str = "no importance weight: the largest log weight is not finite") -> np.ndarray:
    """Weights ``exp(log_w) / sum exp(log_w)``, computed stably (the largest log weight subtracted first).

    Parameters
    ----------
    log_weights : (n,) or (..., n, ...) float, unnormalised log weights (``-inf``: weight zero)
    axis : int or None, the axis over which the weights sum to one (None: all of them)
    refuse : bool
        What a set without any finite log weight gives: ``True`` a :class:`ConvergenceError` with ``reason``,
        ``False`` NaN weights for that set (the caller tests for them).
    reason : str, the error's message

    Returns
    -------
    weights : same shape as ``log_weights``, non-negative, summing to one along ``axis``

    Raises
    ------
    ConvergenceError
        ``refuse`` and some set's largest log weight is not finite.
    """
    lw = np.asarray(log_weights, dtype=float)
    top = np.max(lw, axis=axis, keepdims=axis is not None)
    if refuse and not np.all(np.isfinite(top)):
        raise ConvergenceError(reason)
    with np.errstate(invalid="ignore"):  # -inf - -inf of a set without weight: NaN, as documented
        w = np.exp(lw - top)
    return w / np.sum(w, axis=axis, keepdims=axis is not None)


def effective_sample_size(weights, axis: int = -1, normalised: bool = False):
    """Kish's effective sample size ``1 / sum w^2`` of the weights normalised to sum to one.

    Parameters
    ----------
    weights : (..., n) non-negative weights (any scale)
    axis : int, the axis of the draws
    normalised : bool
        The weights already sum to one (e.g. from :func:`normalise_log_weights`): use them as given, so that the
        result is exactly ``1 / sum w^2`` of the caller's weights.

    Returns
    -------
    float for 1-D weights, else an array without ``axis``: between 1 (one draw carries everything) and ``n``
    (equal weights)
    """
    w = np.asarray(weights, dtype=float)
    if not normalised:
        w = w / np.sum(w, axis=axis, keepdims=True)
    ess = 1.0 / np.sum(w * w, axis=axis)
    return float(ess) if np.ndim(ess) == 0 else ess


def _gpd_fit(tail: np.ndarray) -> tuple[float, float]:
    """Shape ``k`` and scale ``sigma`` of a generalised Pareto distribution fitted to ``tail`` (sorted, > 0).

    Zhang & Stephens (2009, Technometrics 51(3)): the posterior mean of ``theta = -k / sigma`` over a grid of
    ``30 + floor(sqrt(n))`` quantile-based values, each weighted by its profile likelihood; then ``k`` shrunk
    towards 0.5 by a prior worth 10 observations (Vehtari et al. 2024, appendix).
    """
    n = tail.size
    m = 30 + int(math.sqrt(n))
    theta = 1.0 - np.sqrt(m / (np.arange(1, m + 1, dtype=float) - 0.5))
    theta = theta / (3.0 * tail[int(n / 4 + 0.5) - 1]) + 1.0 / tail[-1]
    k = np.mean(np.log1p(-theta[:, None] * tail), axis=1)
    profile = n * (np.log(-theta / k) - k - 1.0)
    # normalised likelihood weights without overflow: w_i = 1 / sum_j exp(l_j - l_i)
    w = 1.0 / np.sum(np.exp(profile[None, :] - profile[:, None]), axis=1)
    keep = w >= 10 * np.finfo(float).eps
    w, theta = w[keep], theta[keep]
    theta_hat = float(np.sum(theta * w / np.sum(w)))
    k_hat = float(np.mean(np.log1p(-theta_hat * tail)))
    sigma = -k_hat / theta_hat
    return (n * k_hat + 10 * 0.5) / (n + 10), sigma


def _gpd_quantile(p: np.ndarray, k: float, sigma: float) -> np.ndarray:
    """Quantiles of the generalised Pareto distribution at ``p`` in (0, 1)."""
    if sigma <= 0:
        return np.full_like(p, np.nan)
    if abs(k) < np.finfo(float).eps:
        return -sigma * np.log1p(-p)
    return sigma * np.expm1(-k * np.log1p(-p)) / k


def pareto_smoothed_log_weights(log_weights) -> tuple[np.ndarray, float]:
    """Pareto-smoothed importance-sampling log weights and the shape ``k`` of the fitted tail (PSIS).

    Vehtari et al. (2024): the ``M = ceil(min(n / 5, 3 sqrt(n)))`` largest weights are replaced by the
    expected order statistics of a generalised Pareto distribution fitted to their excess over the
    ``(M + 1)``-th largest (:func:`_gpd_fit`), capped at the largest raw weight; with fewer than five tail
    weights above the smallest positive double no fit is made and ``k`` is infinite.

    Parameters
    ----------
    log_weights : (n,) unnormalised log importance weights (finite)

    Returns
    -------
    (n,) smoothed log weights normalised to sum to one, and ``k`` (above :data:`PARETO_K_MAX` the estimate is
    unreliable)
    """
    x = np.array(log_weights, dtype=float)
    n = x.size
    x -= np.max(x)
    order = np.argsort(x)
    m = int(math.ceil(min(n / 5.0, 3.0 * math.sqrt(n))))
    cut = max(float(x[order[-m - 1]]), float(np.log(np.finfo(float).tiny)))
    tail_idx = np.flatnonzero(x > cut)
    k = math.inf
    if tail_idx.size > 4:
        tail_order = np.argsort(x[tail_idx])
        exp_cut = math.exp(cut)
        excess = np.exp(x[tail_idx][tail_order]) - exp_cut
        # the profile likelihood's differences overflow exp() for grid points far from the best (weight 0, as
        # intended), and a grid point at 1 / max log1p(-1)s to -inf
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            k, sigma = _gpd_fit(excess)
        if math.isfinite(k):
            p = np.arange(0.5, tail_idx.size) / tail_idx.size
            # a very heavy fitted tail (large k) overflows the top quantiles to inf: capped just below, as any
            # smoothed weight above the largest raw one
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                x[tail_idx[tail_order]] = np.log(_gpd_quantile(p, k, sigma) + exp_cut)
            x[x > 0] = 0.0  # no smoothed weight above the largest raw one
    top = np.max(x)
    x -= top + math.log(np.sum(np.exp(x - top)))
    return x, float(k)


def pareto_k(log_weights) -> float:
    """PSIS Pareto shape ``k`` of log importance weights (n,) (:func:`pareto_smoothed_log_weights`)."""
    return pareto_smoothed_log_weights(log_weights)[1]


def importance_reliable(k: float, ess: float, min_ess: float = MIN_ESS_INTERVAL_END) -> bool:
    """Whether importance weights with Pareto shape ``k`` and effective sample size ``ess`` can be trusted:
    ``k <= PARETO_K_MAX`` and ``ess >= min_ess`` (a NaN ``k`` is not)."""
    return bool(k <= PARETO_K_MAX and ess >= min_ess)
