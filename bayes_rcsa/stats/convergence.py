"""Convergence diagnostics of Markov chains: rank-normalised split R-hat, bulk and tail effective sample size.

The estimators of Vehtari, Gelman, Simpson, Carpenter & Buerkner (2021), "Rank-normalization, folding, and
localization: an improved R-hat for assessing convergence of MCMC", Bayesian Analysis 16(2):667-718:

* every chain is split into its first and last halves (the middle draw of an odd length is dropped);
* *rank normalisation*: the pooled draws are replaced by ``Phi^-1((r - 3/8) / (S + 1/4))`` of their average
  ranks ``r`` among all ``S`` draws (Blom's offset);
* R-hat is the larger of the split R-hat of the rank-normalised draws and of the rank-normalised draws folded
  about their median (``|x - median|``, which sees chains that differ in scale only);
* ESS from the chains' FFT autocovariances, truncated by Geyer's initial positive sequence and made monotone
  (Geyer 1992), with the autocorrelation time bounded below by ``1 / log10(S)``; *bulk* ESS of the
  rank-normalised draws, *tail* ESS the smaller of the ESS of the indicators ``x <= q_0.05`` and
  ``x <= q_0.95`` (quantiles of type 7, linear interpolation).

The same published algorithm as ArviZ's ``rhat(method="rank")``, ``ess(method="bulk")`` and
``ess(method="tail")`` (tests/test_stats.py checks they agree to 1e-9), vectorised over coordinates and without
importing ArviZ: an MCMC identification, every stage-2 fit of a tool library and each worker of a process pool
would otherwise load it (with xarray, pandas and scipy.stats: 1.5-2 s of start-up) and convert every chain to an
xarray Dataset first.

Walkers of an ensemble sampler are treated as chains.  They are not independent chains, but after the burn-in
they are exchangeable draws of the posterior, and the rank-normalised split R-hat across walkers detects walkers
that have not mixed (e.g. stuck in a second mode).
"""

from __future__ import annotations

import numpy as np

__all__ = ["rank_rhat", "ess_bulk", "ess_tail", "convergence_diagnostics"]

#: Fewest draws per chain for a diagnostic (two per split half); shorter chains give NaN.
MIN_DRAWS = 4
#: Tail probabilities of the tail ESS.
TAIL_PROBABILITIES = (0.05, 0.95)


def _split(x: np.ndarray) -> np.ndarray:
    """(..., m, n) -> (..., 2m, n // 2): each chain's first and last halves as chains of their own."""
    half = x.shape[-1] // 2
    return np.concatenate([x[..., :half], x[..., x.shape[-1] - half:]], axis=-2)


def _average_ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 1..S of the pooled values of each leading index, ties sharing their average rank; shape of ``x``."""
    lead = x.shape[:-2]
    flat = x.reshape(-1, x.shape[-2] * x.shape[-1])
    out = np.empty_like(flat, dtype=float)
    for i, row in enumerate(flat):  # one pass per coordinate (a handful), not per draw
        _, inverse, counts = np.unique(row, return_inverse=True, return_counts=True)
        start = np.cumsum(counts) - counts  # values below each distinct value
        out[i] = (start + (counts + 1) / 2.0)[inverse.ravel()]
    return out.reshape(lead + x.shape[-2:])


def _z_scale(x: np.ndarray) -> np.ndarray:
    from scipy.special import ndtri  # the standard normal quantile, without scipy.stats

    s = x.shape[-2] * x.shape[-1]
    return ndtri((_average_ranks(x) - 0.375) / (s + 0.25))


def _split_rhat(z: np.ndarray) -> np.ndarray:
    """Split-chain R-hat of already split chains (..., m, n) -> (...)."""
    n = z.shape[-1]
    between = n * np.var(z.mean(axis=-1), axis=-1, ddof=1)
    within = np.mean(np.var(z, axis=-1, ddof=1), axis=-1)
    return np.sqrt((between / within + n - 1) / n)


def _valid(x: np.ndarray, min_chains: int) -> np.ndarray:
    return np.full(x.shape[:-2], x.shape[-1] >= MIN_DRAWS and x.shape[-2] >= min_chains) & \
        ~np.isnan(x).any(axis=(-2, -1))


def rank_rhat(x) -> np.ndarray:
    """Rank-normalised split R-hat (the larger of bulk and folded).

    Parameters
    ----------
    x : (..., n_chains, n_draws) array
        Draws of each quantity in the leading axes.

    Returns
    -------
    (...) float
        NaN where a quantity has fewer than 2 chains or :data:`MIN_DRAWS` draws, or a NaN draw.
    """
    x = np.asarray(x, dtype=float)
    ok = _valid(x, 2)
    out = np.full(x.shape[:-2], np.nan)
    if not ok.any():
        return out
    s = _split(x[ok])
    out[ok] = _rank_rhat_of_split(s, _z_scale(s))
    return out


def _rank_rhat_of_split(s: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The larger split R-hat of the rank-normalised split chains ``z`` and of ``s`` folded about its median."""
    folded = np.abs(s - np.median(s.reshape(s.shape[0], -1), axis=1)[:, None, None])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.maximum(_split_rhat(z), _split_rhat(_z_scale(folded)))


def _ess(x: np.ndarray) -> np.ndarray:
    """ESS of split chains (k, m, n) -> (k,) (Geyer's initial monotone sequence; see the module notes)."""
    k, m, n = x.shape
    size = m * n
    out = np.empty(k)
    const = (x.max(axis=(1, 2)) - x.min(axis=(1, 2))) < np.finfo(float).resolution
    out[const] = size  # a constant chain: its draws are as good as independent (and the formula is 0/0)
    rows = ~const
    if not rows.any():
        return out
    y = x[rows]
    from scipy.fft import next_fast_len

    length = next_fast_len(2 * n)
    centred = y - y.mean(axis=2, keepdims=True)
    spec = np.fft.rfft(centred, n=length, axis=2)
    acov = np.fft.irfft(spec * np.conjugate(spec), n=length, axis=2)[..., :n] / n  # (k, m, n), biased
    mean_acov = acov.mean(axis=1)  # (k, n)
    mean_var = mean_acov[:, 0] * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n
    if m > 1:
        var_plus = var_plus + np.var(y.mean(axis=2), axis=1, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = 1.0 - (mean_var[:, None] - mean_acov) / var_plus[:, None]
    rho[:, 0] = 1.0
    # pairs P_j = rho_2j + rho_2j+1 for j = 0 .. j_max (lags up to 2 j_max + 1 <= n - 1)
    j_max = max((n - 1) // 2 - 1, 0)
    n_pairs = j_max + 1
    pairs = rho[:, 0:2 * n_pairs:2] + rho[:, 1:2 * n_pairs:2]  # (k, n_pairs)
    # K: the last pair the positive sequence looks at -- the first pair j >= 1 with P_j <= 0, else j_max;
    # 0 when P_0 <= 0 already
    stop = np.concatenate([pairs[:, 1:] <= 0, np.ones((pairs.shape[0], 1), dtype=bool)], axis=1)
    last = np.minimum(np.argmax(stop, axis=1) + 1, j_max)
    last = np.where(pairs[:, 0] > 0, last, 0)
    # the monotone sequence: each pair no larger than the one before (a running minimum), summed over pairs < K
    mono = np.minimum.accumulate(np.where(np.isnan(pairs), np.inf, pairs), axis=1)
    below = np.arange(n_pairs)[None, :] < last[:, None]
    total = np.sum(np.where(below, mono, 0.0), axis=1)
    # and half of the last pair: its even lag where that pair was kept (P_K >= 0) or its even lag is positive
    even = rho[np.arange(rho.shape[0]), 2 * last]
    p_last = pairs[np.arange(rho.shape[0]), last]
    tail = np.where(last == 0, 1.0, np.where((p_last >= 0) | (even > 0), even, 0.0))
    tau = -1.0 + 2.0 * total + tail
    tau = np.maximum(tau, 1.0 / np.log10(size))
    ess = size / tau
    ess[np.isnan(rho).any(axis=1)] = np.nan
    out[rows] = ess
    return out


def _over_valid(x, fn) -> np.ndarray:
    """``fn`` of the quantities with enough draws and no NaN, NaN for the others; x (..., m, n) -> (...)."""
    x = np.asarray(x, dtype=float)
    ok = _valid(x, 1)
    out = np.full(x.shape[:-2], np.nan)
    if ok.any():
        out[ok] = fn(x[ok])
    return out


def _tail(y: np.ndarray) -> np.ndarray:
    flat = y.reshape(y.shape[0], -1)
    esses = [_ess(_split((y <= np.quantile(flat, p, axis=1)[:, None, None]).astype(float)))  # type 7 quantiles
             for p in TAIL_PROBABILITIES]
    return np.minimum(*esses)


def ess_bulk(x) -> np.ndarray:
    """Bulk effective sample size: ESS of the rank-normalised split chains.

    Parameters
    ----------
    x : (..., n_chains, n_draws) array

    Returns
    -------
    (...) float
        NaN where a quantity has fewer than :data:`MIN_DRAWS` draws or a NaN draw.
    """
    return _over_valid(x, lambda y: _ess(_z_scale(_split(y))))


def ess_tail(x) -> np.ndarray:
    """Tail effective sample size: the smaller ESS of the 5 % and 95 % quantile indicators (same shapes as
    :func:`ess_bulk`)."""
    return _over_valid(x, _tail)


def convergence_diagnostics(x) -> dict[str, np.ndarray]:
    """:func:`rank_rhat`, :func:`ess_bulk` and :func:`ess_tail` at once (the rank normalisation shared).

    Parameters
    ----------
    x : (..., n_chains, n_draws) array

    Returns
    -------
    dict with ``"rhat"``, ``"ess_bulk"``, ``"ess_tail"``, each (...) float
    """
    x = np.asarray(x, dtype=float)
    ok = _valid(x, 1)
    out = {k: np.full(x.shape[:-2], np.nan) for k in ("rhat", "ess_bulk", "ess_tail")}
    if not ok.any():
        return out
    s = _split(x[ok])
    z = _z_scale(s)
    out["ess_bulk"][ok] = _ess(z)
    out["ess_tail"][ok] = _tail(x[ok])
    if x.shape[-2] >= 2:
        out["rhat"][ok] = _rank_rhat_of_split(s, z)
    return out
