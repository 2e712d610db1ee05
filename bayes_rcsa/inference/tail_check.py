"""An importance-sampling check of the posterior's interval ends, independent of the chain's mixing.

R-hat, the autocorrelation time and the ESS are computed from the chain itself: a sampler that mixes quickly
in the bulk and seldom enters a long one-sided tail passes them all.  That is what identify's old default emcee
moves did (emcee's DESnookerMove is not in detailed balance) where a stiffness is bounded by the data from one side
only (docs/identification.md, "Sampler moves and the tails"; ``benchmarks/sampler_tail.py``); identify runs this
check by default as part of its convergence report.  This check samples the same log posterior by importance sampling
from a multivariate t fitted to the draws (``df`` degrees of freedom, covariance ``scale`` times the draws',
refitted once to a weighted pilot), which needs no mixing, smooths the weights (PSIS, Vehtari et al. 2024) and compares the 5 % and 95 % points
of every parameter with the chain's.

Verdicts:

* ``"consistent"``: every end agrees within :data:`TOLERANCE_SD` posterior standard deviations;
* ``"disagrees"``: some end does not (named, with both values): the chain's interval is not to be trusted
  there;
* ``"unreliable"``: the Pareto shape ``k`` exceeds 0.7 (:data:`bayes_rcsa.stats.weights.PARETO_K_MAX`) or the
  weights' ESS is below :data:`MIN_ESS` (the t proposal does not cover the posterior, e.g. a second mode far from
  the draws): no verdict.
"""

from __future__ import annotations

import math

import numpy as np

from ..stats.weights import (MIN_ESS_COVARIANCE, MIN_ESS_INTERVAL_END, MIN_ESS_PER_DIMENSION, PARETO_K_MAX,
                             effective_sample_size, importance_reliable, normalise_log_weights,
                             pareto_smoothed_log_weights)

__all__ = ["importance_tail_check", "importance_resample", "check_identification", "TOLERANCE_SD", "MIN_ESS",
           "TAIL_CHECK_RULE", "N_FIRST", "EARLY_ESS"]

#: Largest difference of an interval end, in posterior standard deviations, counted as agreement.  The 95 %
#: point of 400 effective chain draws has a Monte Carlo error of about 0.1 sd, and the importance estimate's
#: is smaller; 0.4 sd is four times the former (well-mixed long chains of the library bench differ by
#: 0.14-0.30 sd), while the benchmark's missed tail of k_thetaM is 0.57 sd.
TOLERANCE_SD = 0.4
#: Smallest effective sample size of the smoothed weights for a verdict (why 1000:
#: :data:`bayes_rcsa.stats.weights.MIN_ESS_INTERVAL_END`).
MIN_ESS = MIN_ESS_INTERVAL_END
#: Importance draws of a first round (the pilot is a quarter of it); the full ``n`` is drawn only when the first
#: round's smoothed weights are not decisive (:data:`EARLY_ESS`).  25,000 log-posterior evaluations instead of
#: 125,000 cost about 0.4 s instead of 2 s on the bundled example, where the first round's ESS is 8,000-14,000.
N_FIRST = 20_000
#: ESS of the smoothed weights at which the first round stands: the 5 % point's Monte Carlo error is then
#: sqrt(0.05 * 0.95 / 4000) / phi(1.645) = 0.034 posterior sd (normal posterior), a third of the chain's
#: (400 effective draws) and a twelfth of :data:`TOLERANCE_SD`, so drawing the full ``n`` would not change a
#: verdict; with fewer, or a Pareto shape above 0.7, the full ``n`` is drawn from the same proposal.
EARLY_ESS = 4 * MIN_ESS_INTERVAL_END


TAIL_CHECK_RULE = ("importance sampling of the same log posterior from a multivariate t (3 degrees of freedom, "
                   "twice the covariance of the draws, refitted once to a weighted pilot), Pareto-smoothed weights "
                   f"({N_FIRST:,} draws, up to 100,000 while the weights' ESS < {EARLY_ESS} or k > {PARETO_K_MAX:g}); "
                   "the 5 % and 95 % points of every parameter compared with the chain's: "
                   f"agreement within {TOLERANCE_SD} posterior sd; no verdict "
                   f"when the Pareto shape k > {PARETO_K_MAX:g} or the weights' ESS < {MIN_ESS}")


def _weighted_quantiles(x: np.ndarray, w: np.ndarray, qs) -> np.ndarray:
    """Quantiles ``qs`` of the columns of ``x`` (n, d) under normalised weights ``w`` (n,); (len(qs), d)."""
    o = np.argsort(x, axis=0)
    cw = np.cumsum(w[o], axis=0)
    idx = np.stack([np.minimum((cw < q).sum(axis=0), x.shape[0] - 1) for q in qs])  # (len(qs), d)
    return np.take_along_axis(x[o, np.arange(x.shape[1])], idx, axis=0)


def _batched(log_posterior, x: np.ndarray, batch: int) -> np.ndarray:
    return np.concatenate([np.asarray(log_posterior(x[i:i + batch]), dtype=float) for i in range(0, x.shape[0], batch)])


def _importance(log_posterior, theta: np.ndarray, rng: np.random.Generator, n: int, df: float, scale: float,
                batch: int, n_first: int | None = N_FIRST):
    """Importance draws ``x`` (m, d) inside the support, normalised PSIS weights ``w`` (m,), Pareto ``k``, weights'
    ESS, ``m`` and the number of draws made after the pilot, from a multivariate t fitted to ``theta`` (n_draws, d).

    One adaptation step first (adaptive importance sampling, Cappe et al. 2004): a pilot of a quarter of the
    first round's draws from the t fitted to the chain, then the t refitted to the pilot's weighted draws.  The
    chain's own covariance is narrowest exactly where it missed a tail, and the refitted proposal reaches into it
    (on the library bench's 16-mm fits the Pareto shape fell from 0.48-0.74 to 0.26-0.62).  The first round
    draws ``n_first`` (``None``: ``n``) from the refitted t; when its weights are not decisive
    (:data:`EARLY_ESS`) the rest of ``n`` follows from the same t and the weights are smoothed over all.
    """
    # scipy.stats on use only: importing it costs ~1.5 s, and identify imports this module whether or not
    # its run needs the check (an accepted importance-sampled posterior does not)
    from scipy import stats

    first = n if n_first is None or n_first >= n else int(n_first)
    mu, cov = theta.mean(axis=0), np.atleast_2d(np.cov(theta, rowvar=False))
    m = max(first // 4, 2)
    prop = stats.multivariate_t(loc=mu, shape=scale * cov, df=df, seed=rng)
    x = np.atleast_2d(prop.rvs(m)).reshape(m, -1)
    lp = _batched(log_posterior, x, batch)
    ok = np.isfinite(lp)
    if ok.sum() < 2:
        return x[ok], np.full(int(ok.sum()), 1.0 / max(int(ok.sum()), 1)), math.nan, 0.0, int(ok.sum()), m
    x = x[ok]
    lw, _ = pareto_smoothed_log_weights(lp[ok] - prop.logpdf(x))
    w = normalise_log_weights(lw, refuse=False)
    # refit the proposal to the pilot where the pilot's weights carry enough draws to estimate a covariance
    if effective_sample_size(w, normalised=True) >= max(MIN_ESS_COVARIANCE, MIN_ESS_PER_DIMENSION * x.shape[1]):
        mu_p = w @ x
        cov_p = (w[:, None] * (x - mu_p)).T @ (x - mu_p)
        ev = np.linalg.eigvalsh(cov_p)
        if np.all(np.isfinite(cov_p)) and ev.min() > 1e-12 * ev.max():
            mu, cov = mu_p, cov_p
    prop = stats.multivariate_t(loc=mu, shape=scale * cov, df=df, seed=rng)
    xs, lrs, total = [], [], 0
    for size in (first, n - first):
        if size <= 0:
            break
        total += size
        xr = np.atleast_2d(prop.rvs(size)).reshape(size, -1)
        lp = _batched(log_posterior, xr, batch)
        ok = np.isfinite(lp)
        xs.append(xr[ok])
        lrs.append(lp[ok] - prop.logpdf(xr[ok]))
        x = np.concatenate(xs)
        if x.shape[0] < 2:
            return x, np.full(x.shape[0], 1.0 / max(x.shape[0], 1)), math.nan, 0.0, int(x.shape[0]), total
        lw, k = pareto_smoothed_log_weights(np.concatenate(lrs))
        w = normalise_log_weights(lw, refuse=False)
        ess = effective_sample_size(w, normalised=True)
        if k <= PARETO_K_MAX and ess >= EARLY_ESS:
            break
    return x, w, k, ess, int(x.shape[0]), total


def importance_resample(log_posterior, theta: np.ndarray, rng: np.random.Generator, size: int, n: int = 100_000,
                        df: float = 3.0, scale: float = 2.0, batch: int = 4000) -> dict:
    """Draws of the posterior by importance sampling, resampled to ``size`` equally weighted ones.

    The same proposal and smoothing as :func:`importance_tail_check`; used where the chain's draws are known to
    miss a tail (the check disagreed) and the importance estimate is reliable.

    Returns
    -------
    dict: ``draws`` ((size, d) sampling coordinates, or None when unreliable), ``pareto_k``, ``ess``, ``used`` and
    ``reason``.
    """
    x, w, k, ess, n_in, n = _importance(log_posterior, np.asarray(theta, dtype=float), rng, n, df, scale, batch,
                                        n_first=None)
    if not (n_in >= MIN_ESS and importance_reliable(k, ess, MIN_ESS)):
        return {"draws": None, "pareto_k": k, "ess": ess, "used": False,
                "reason": f"importance sampling unreliable here (Pareto shape k = {k:.2f}, weights' ESS {ess:.0f}, "
                          f"{n_in} of {n} draws inside the prior)"}
    idx = rng.choice(x.shape[0], size=size, replace=True, p=w)
    return {"draws": x[idx], "pareto_k": k, "ess": ess, "used": True, "reason": ""}


def importance_tail_check(log_posterior, theta: np.ndarray, names, rng: np.random.Generator, n: int = 100_000,
                          df: float = 3.0, scale: float = 2.0, batch: int = 4000, resample: int | None = None,
                          n_first: int | None = N_FIRST) -> dict:
    """Compare the chain's 5 % and 95 % points with an importance-sampling estimate of the same posterior.

    Parameters
    ----------
    log_posterior : callable, (m, d) sampling coordinates -> (m,) log posterior (vectorised; -inf outside)
    theta : (n_draws, d) the chain's kept draws in sampling coordinates
    names : sequence of d parameter names
    rng : numpy.random.Generator
    n : number of importance draws (log-posterior evaluations)
    df, scale : the t proposal's degrees of freedom and covariance factor
    resample : int or None
        With a verdict ``"disagrees"``, also return this many equally weighted draws resampled from the same
        importance draws (``draws``, (resample, d) sampling coordinates), what
        :func:`importance_resample` would give, without sampling the posterior a second time.  All ``n`` draws
        are then made (resampled draws are used as a posterior, not only compared).
    n_first : int or None
        Draws of the first round (:data:`N_FIRST`); the rest of ``n`` only when its weights are not decisive
        (:data:`EARLY_ESS`).  ``None``: all ``n`` at once.

    Returns
    -------
    dict: ``verdict``, ``reason``, ``pareto_k``, ``ess``, ``n``, ``rule`` and per parameter ``chain`` and
    ``importance`` (q05, q95) with ``shift_sd`` (the larger end difference in posterior sd); ``draws`` when
    ``resample`` was asked and the verdict is ``"disagrees"``.
    """
    names = list(names)
    theta = np.asarray(theta, dtype=float)
    x, w, k, ess, n_in, n = _importance(log_posterior, theta, rng, n, df, scale, batch,
                                        n_first=None if resample else n_first)
    out = {"n": int(n), "rule": TAIL_CHECK_RULE, "parameters": {}}
    if n_in < MIN_ESS:
        return {**out, "verdict": "unreliable", "reason": f"only {n_in} of {n} importance draws lie inside "
                "the prior", "pareto_k": math.nan, "ess": 0.0}
    out.update(pareto_k=k, ess=ess)
    q_is = _weighted_quantiles(x, w, (0.05, 0.95))
    q_ch = np.quantile(theta, (0.05, 0.95), axis=0)
    sd = np.sqrt(np.sum(w[:, None] * (x - np.sum(w[:, None] * x, axis=0)) ** 2, axis=0))
    shift = np.max(np.abs(q_is - q_ch), axis=0) / np.where(sd > 0, sd, np.inf)
    for j, name in enumerate(names):
        out["parameters"][name] = {"chain": [float(v) for v in q_ch[:, j]], "importance": [float(v) for v in q_is[:, j]],
                                   "shift_sd": float(shift[j])}
    if not importance_reliable(k, ess, MIN_ESS):
        return {**out, "verdict": "unreliable", "reason": f"Pareto shape k = {k:.2f} (> {PARETO_K_MAX:g} is "
                f"unreliable) or weights' ESS {ess:.0f} < {MIN_ESS}: the t proposal does not cover the posterior"}
    bad = [names[j] for j in np.flatnonzero(shift > TOLERANCE_SD)]
    if not bad:
        return {**out, "verdict": "consistent", "reason": f"every 5 % and 95 % point within {TOLERANCE_SD} sd"}
    if resample:
        out["draws"] = x[rng.choice(x.shape[0], size=int(resample), replace=True, p=w)]
    detail = "; ".join(f"{b}: chain [{out['parameters'][b]['chain'][0]:.4g}, {out['parameters'][b]['chain'][1]:.4g}], "
                       f"importance [{out['parameters'][b]['importance'][0]:.4g}, "
                       f"{out['parameters'][b]['importance'][1]:.4g}] (sampling coordinates)" for b in bad)
    return {**out, "verdict": "disagrees", "reason": f"the chain's 90 % interval ends differ from importance sampling "
            f"by more than {TOLERANCE_SD} posterior sd: {detail}"}


def check_identification(result, rng: np.random.Generator, n: int = 100_000) -> dict:
    """:func:`importance_tail_check` of an identify result, under the log posterior it was sampled from.

    Parameters
    ----------
    result : IdentificationResult of a Bayesian method (a chain, ``theta`` in sampling coordinates)
    rng : numpy.random.Generator
    n : number of importance draws

    The log posterior is the sampled one: the result's problem carries its extra likelihood terms.
    """
    problem = result.problem
    lp = problem.log_posterior(result.tempering)
    return importance_tail_check(lp, result.flat_theta, problem.priors.names, rng, n=n)
