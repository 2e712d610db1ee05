"""Simulation-based calibration (SBC): ranks of truths among posterior draws and their uniformity.

If a parameter vector ``theta*`` is drawn from the prior, data ``y`` from the
model given ``theta*``, and ``L`` draws from the exact posterior ``p(theta | y)``,
then the rank of each coordinate of ``theta*`` among its ``L`` draws is uniform
on ``{0, ..., L}`` (Talts et al. 2018).  A sampler, a likelihood or a prior
implementation that is wrong shows up as non-uniform ranks: too narrow a
posterior piles the ranks at both ends (a U shape), too wide a posterior in the
middle, a biased one to one side (Modrák et al. 2023).

Uniformity is judged on the rank ECDF.  With ``N`` ranks and ``K`` evaluation
points ``z_i = i / K`` (``i = 1, ..., K - 1``, ``K`` dividing ``L + 1`` so that
``z_i`` falls on the rank grid), ``N F(z_i)`` is Binomial(``N``, ``z_i``) under
uniformity.  The *simultaneous* band of Säilynoja, Bürkner & Vehtari (2022,
"Graphical test for discrete uniformity and its applications in goodness-of-fit
evaluation and multiple sample comparison", Statistics and Computing 32:32) is
the set of pointwise central Binomial intervals at one adjusted level
``gamma``, chosen (here by simulation, their "simulation" method) so that the
whole ECDF lies inside all of them with probability ``1 - alpha``.  The test
statistic is the smallest pointwise two-sided tail probability of the ECDF;
its null distribution gives both the band (its ``alpha`` quantile is
``gamma``) and a p-value.  A chi-square test on binned ranks is also offered
(less powerful against the U and hump shapes of a wrong width).

Several parameters are judged together at a family-wise level by Holm's
step-down procedure (:func:`holm`).

Layer 0: numpy and scipy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import SetupError

__all__ = [
    "sbc_ranks",
    "rank_among_draws",
    "ecdf_difference",
    "null_statistics",
    "ecdf_statistic",
    "EcdfBand",
    "simultaneous_band",
    "ecdf_pvalue",
    "chi_square_pvalue",
    "holm",
    "SbcCheck",
    "sbc_check",
    "N_SIMULATIONS",
]

N_SIMULATIONS = 20000  # null ECDFs simulated for the band and the p-values (alpha quantile error ~0.1 alpha)


def sbc_ranks(truth: np.ndarray, draws: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Rank of each truth among its posterior draws, ties broken at random.

    Parameters
    ----------
    truth : (..., n_params)
        The prior draws the data were simulated from (any monotone coordinate).
    draws : (..., n_draws, n_params)
        Posterior draws of the same replicate(s), thinned to be nearly independent.
    rng : numpy.random.Generator
        Breaks ties: a truth equal to ``t`` draws gets a uniform rank among the ``t + 1`` places.

    Returns
    -------
    (..., n_params) int in ``[0, n_draws]``
    """
    truth = np.asarray(truth, dtype=float)
    draws = np.asarray(draws, dtype=float)
    if draws.shape[:-2] != truth.shape[:-1] or draws.shape[-1] != truth.shape[-1]:
        raise SetupError(f"sbc_ranks: draws of shape {draws.shape} do not match truths of shape {truth.shape} "
                         "(expected (..., n_draws, n_params) and (..., n_params))")
    t = truth[..., None, :]
    below = np.count_nonzero(draws < t, axis=-2)
    ties = np.count_nonzero(draws == t, axis=-2)
    return below + rng.integers(0, ties + 1)


def rank_among_draws(truth: np.ndarray, draws: np.ndarray, n_ranked: int, rng: np.random.Generator) -> np.ndarray:
    """Rank of ``truth`` (n_params,) among ``n_ranked`` rows of ``draws`` (n, n_params) chosen at random.

    For posteriors given as many equally weighted draws (resampled particles, the kept draws of a converged
    ensemble): a random subset is as good as thinning, and rows are reused only when there are fewer than
    ``n_ranked``.  Ties are broken by :func:`sbc_ranks`.
    """
    draws = np.asarray(draws, dtype=float)
    pick = rng.choice(draws.shape[0], size=n_ranked, replace=draws.shape[0] < n_ranked)
    return sbc_ranks(np.asarray(truth, dtype=float), draws[pick], rng)


def _points(n_draws: int, n_points: int | None) -> int:
    k = n_draws + 1 if n_points is None else int(n_points)
    if k < 2 or (n_draws + 1) % k:
        raise SetupError(f"n_points = {n_points}: expected a divisor >= 2 of n_draws + 1 = {n_draws + 1}")
    return k


def _ecdf_counts(ranks: np.ndarray, n_draws: int, k: int) -> np.ndarray:
    """``N F(z_i)`` at ``z_i = i / k``, ``i = 1..k-1``: (k - 1, ...) counts of ranks below ``i (L + 1) / k``."""
    ranks = np.asarray(ranks)
    if np.any(ranks < 0) or np.any(ranks > n_draws):
        raise SetupError(f"ranks outside [0, {n_draws}] for n_draws = {n_draws}")
    return np.cumsum(_bin_counts(ranks, n_draws, k), axis=0)[:-1]


def _bin_counts(ranks: np.ndarray, n_draws: int, k: int) -> np.ndarray:
    """Ranks (n_ranks, ...) per interval ``[b (L + 1) / k, (b + 1) (L + 1) / k)``: (k, ...) counts."""
    bins = np.asarray(ranks) * k // (n_draws + 1)
    flat = bins.reshape(bins.shape[0], -1)
    m = flat.shape[1]
    counts = np.bincount((flat * m + np.arange(m)).ravel(), minlength=k * m).reshape(k, m)
    return counts.reshape((k,) + bins.shape[1:])


def ecdf_difference(ranks: np.ndarray, n_draws: int, n_points: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """ECDF of the scaled ranks minus the uniform CDF at the evaluation points.

    Parameters
    ----------
    ranks : (n_ranks,) or (n_ranks, n_params) int in ``[0, n_draws]``
    n_draws : int
        Posterior draws per replicate ``L``.
    n_points : int, optional
        ``K`` (a divisor of ``L + 1``); default ``L + 1`` (every rank).

    Returns
    -------
    z : (K - 1,) evaluation points ``i / K``
    diff : (K - 1,) or (K - 1, n_params)  ``F(z) - z``
    """
    k = _points(n_draws, n_points)
    ranks = np.asarray(ranks)
    z = np.arange(1, k) / k
    counts = _ecdf_counts(ranks, n_draws, k)
    zz = z if ranks.ndim == 1 else z[:, None]
    return z, counts / ranks.shape[0] - zz


def _tail_table(n: int, z: np.ndarray) -> np.ndarray:
    """Two-sided pointwise tail probability ``2 min(P(X <= x), P(X >= x))``, X ~ Binomial(n, z_i), capped at 1,
    for every count ``x = 0..n``: (n + 1, K - 1)."""
    from scipy.stats import binom

    x = np.arange(n + 1)[:, None]
    return np.minimum(1.0, 2.0 * np.minimum(binom.cdf(x, n, z), binom.sf(x - 1, n, z)))


def _tail_probability(counts: np.ndarray, n: int, z: np.ndarray) -> np.ndarray:
    """:func:`_tail_table` at ``counts`` (..., K - 1) of ECDFs at ``z`` (K - 1,)."""
    return _tail_table(n, z)[counts, np.arange(z.size)]


def null_statistics(n_ranks: int, n_points: int, n_sim: int, rng: np.random.Generator) -> np.ndarray:
    """Null distribution of the ECDF statistic (:func:`ecdf_statistic`) for ``n_ranks`` uniform ranks.

    Under uniformity the counts in the ``K`` evaluation intervals are
    Multinomial(``n_ranks``, ``1/K``), whatever ``L`` is (``K`` divides ``L + 1``).

    Returns
    -------
    (n_sim,) smallest pointwise tail probability of each simulated ECDF
    """
    k = int(n_points)
    z = np.arange(1, k) / k
    counts = np.cumsum(rng.multinomial(n_ranks, np.full(k, 1.0 / k), size=n_sim), axis=1)[:, :-1]
    return _tail_probability(counts, n_ranks, z).min(axis=1)


def ecdf_statistic(ranks: np.ndarray, n_draws: int, n_points: int | None = None) -> np.ndarray:
    """Smallest pointwise two-sided Binomial tail probability of the rank ECDF (small = non-uniform).

    Parameters
    ----------
    ranks : (n_ranks,) or (n_ranks, n_params)

    Returns
    -------
    float or (n_params,)
    """
    k = _points(n_draws, n_points)
    ranks = np.asarray(ranks)
    counts = _ecdf_counts(ranks, n_draws, k)
    z = np.arange(1, k) / k
    p = _tail_probability(np.moveaxis(counts, 0, -1), ranks.shape[0], z)
    return p.min(axis=-1)


@dataclass(frozen=True)
class EcdfBand:
    """Simultaneous ``1 - alpha`` band of the rank ECDF difference (Säilynoja et al. 2022).

    Attributes
    ----------
    z : (K - 1,) evaluation points
    lower, upper : (K - 1,) bounds of ``F(z) - z``
    alpha : float
    gamma : float
        The adjusted pointwise level: the band is the central Binomial interval of tail ``gamma / 2`` at each point.
    n_ranks : int
    """

    z: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    alpha: float
    gamma: float
    n_ranks: int

    def contains(self, diff: np.ndarray) -> np.ndarray:
        """Whether each ECDF difference (K - 1,) or (K - 1, n) lies wholly inside the band: bool or (n,)."""
        d = np.asarray(diff)
        lo, hi = (self.lower, self.upper) if d.ndim == 1 else (self.lower[:, None], self.upper[:, None])
        eps = 0.5 / self.n_ranks  # counts are integers: compare on the count grid
        return np.all((d >= lo - eps) & (d <= hi + eps), axis=0)


def simultaneous_band(n_ranks: int, n_points: int, alpha: float, rng: np.random.Generator,
                      n_sim: int = N_SIMULATIONS) -> EcdfBand:
    """The simultaneous ``1 - alpha`` band of the ECDF difference of ``n_ranks`` uniform ranks.

    ``gamma`` is the ``alpha`` quantile of :func:`null_statistics` (the largest
    value with at most ``alpha n_sim`` simulated statistics below it); the band
    at ``z_i`` holds the counts ``x`` with ``P(X <= x) >= gamma / 2`` and
    ``P(X >= x) >= gamma / 2`` (X ~ Binomial(n_ranks, z_i)).  An ECDF is inside
    iff its statistic is at least ``gamma``, so the coverage is ``1 - alpha`` up to
    the simulation error and the discreteness of the statistic (which only makes
    it larger).

    Parameters
    ----------
    n_ranks : int, replicates N
    n_points : int, evaluation points K
    alpha : float in (0, 1)
    rng : numpy.random.Generator
    n_sim : int, simulated null ECDFs
    """
    from scipy.stats import binom

    if not 0 < alpha < 1:
        raise SetupError(f"alpha = {alpha!r}: expected a number in (0, 1)")
    stats = np.sort(null_statistics(n_ranks, n_points, n_sim, rng))
    gamma = float(stats[int(np.floor(alpha * n_sim))])
    z = np.arange(1, n_points) / n_points
    x = np.arange(n_ranks + 1)[:, None]
    inside = (binom.cdf(x, n_ranks, z) >= gamma / 2) & (binom.sf(x - 1, n_ranks, z) >= gamma / 2)
    lo = np.argmax(inside, axis=0)
    hi = n_ranks - np.argmax(inside[::-1], axis=0)
    return EcdfBand(z, lo / n_ranks - z, hi / n_ranks - z, float(alpha), gamma, int(n_ranks))


def ecdf_pvalue(ranks: np.ndarray, n_draws: int, rng: np.random.Generator, n_points: int | None = None,
                n_sim: int = N_SIMULATIONS) -> np.ndarray:
    """p-value of the ECDF test of uniformity: the share of null statistics at or below the observed one.

    Returns
    -------
    float or (n_params,), ``(1 + #{null <= observed}) / (1 + n_sim)``
    """
    ranks = np.asarray(ranks)
    k = _points(n_draws, n_points)
    null = np.sort(null_statistics(ranks.shape[0], k, n_sim, rng))
    obs = ecdf_statistic(ranks, n_draws, k)
    # the statistic is a tail probability computed twice the same way: compare with a relative tolerance
    return (1.0 + np.searchsorted(null, np.asarray(obs) * (1 + 1e-9), side="right")) / (1.0 + n_sim)


def chi_square_pvalue(ranks: np.ndarray, n_draws: int, n_bins: int = 20) -> np.ndarray:
    """Pearson chi-square test of uniformity on ``n_bins`` equal rank bins (``n_bins`` divides ``L + 1``).

    Returns
    -------
    float or (n_params,)
    """
    from scipy.stats import chi2

    k = _points(n_draws, n_bins)
    ranks = np.asarray(ranks)
    n = ranks.shape[0]
    counts = _bin_counts(ranks, n_draws, k)
    e = n / k
    return chi2.sf(((counts - e) ** 2 / e).sum(axis=0), k - 1)


def holm(p_values: Sequence[float], alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Holm's step-down procedure: which hypotheses are rejected at family-wise level ``alpha``.

    Returns
    -------
    reject : (m,) bool
    adjusted : (m,) Holm-adjusted p-values (reject iff ``adjusted <= alpha``)
    """
    p = np.asarray(p_values, dtype=float)
    m = p.size
    order = np.argsort(p)
    adj_sorted = np.minimum(1.0, np.maximum.accumulate((m - np.arange(m)) * p[order]))
    adjusted = np.empty(m)
    adjusted[order] = adj_sorted
    return adjusted <= alpha, adjusted


@dataclass(frozen=True)
class SbcCheck:
    """Uniformity of the SBC ranks of several parameters at a family-wise level.

    Attributes
    ----------
    names : (n_params,) parameter names
    n_replicates, n_draws : int
    p_ecdf : (n_params,) ECDF-test p-values (:func:`ecdf_pvalue`)
    p_chi2 : (n_params,) chi-square p-values (:func:`chi_square_pvalue`), for information
    p_holm : (n_params,) Holm-adjusted ECDF p-values
    alpha : float
        Family-wise level.
    passed : (n_params,) bool
        Not rejected by Holm at ``alpha``.
    """

    names: tuple
    n_replicates: int
    n_draws: int
    p_ecdf: np.ndarray
    p_chi2: np.ndarray
    p_holm: np.ndarray
    alpha: float
    passed: np.ndarray

    @property
    def all_passed(self) -> bool:
        return bool(np.all(self.passed))


def sbc_check(ranks: np.ndarray, n_draws: int, names: Sequence[str], rng: np.random.Generator, alpha: float = 0.01,
              n_points: int | None = None, n_bins: int | None = None, n_sim: int = N_SIMULATIONS) -> SbcCheck:
    """Test every parameter's ranks for uniformity (ECDF test) and combine them by Holm at ``alpha``.

    Parameters
    ----------
    ranks : (n_replicates, n_params) int in ``[0, n_draws]``
    n_draws : int, draws per replicate L
    names : parameter names
    rng : numpy.random.Generator, for the null simulation
    alpha : family-wise level
    n_points : evaluation points of the ECDF (a divisor of L + 1; default L + 1)
    n_bins : bins of the chi-square test (a divisor of L + 1; default the largest divisor up to 20)
    """
    ranks = np.asarray(ranks)
    if ranks.ndim != 2 or ranks.shape[1] != len(names):
        raise SetupError(f"sbc_check: ranks of shape {ranks.shape} for {len(names)} parameter names; "
                         "expected (n_replicates, n_params)")
    p_ecdf = np.atleast_1d(ecdf_pvalue(ranks, n_draws, rng, n_points, n_sim))
    if n_bins is None:
        n_bins = max(b for b in range(2, 21) if (n_draws + 1) % b == 0)
    p_chi2 = np.atleast_1d(chi_square_pvalue(ranks, n_draws, n_bins))
    reject, adjusted = holm(p_ecdf, alpha)
    return SbcCheck(tuple(names), int(ranks.shape[0]), int(n_draws), p_ecdf, p_chi2, adjusted, float(alpha), ~reject)
