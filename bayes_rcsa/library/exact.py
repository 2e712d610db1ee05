"""Stage 2 re-weighted to the exact two-stage target (docs/library.md, "Stage 2", "The exact two-stage option").

Stage 2 (:mod:`.stage2`) replaces each setup's stage-1 posterior ``p_s(z) ~ L_s(z) pi_s(z)`` by a Gaussian
likelihood surrogate ``N(m_s, C_s)``, so every hyperparameter draw carries the factor ``N(m_s; mu_s, C_s +
Sigma_t)`` (``mu_s = a_t + b_t x_s``, ``Sigma_t = diag sigma_t^2``) where the two-stage target (Lunn et al., Stat.
Med. 2013: each setup's stage-1 draws are its likelihood, its stage-1 box included, as :mod:`.joint` samples it)
has

    int N(z; mu_s, Sigma_t) L_s(z) 1_box(z) dz  ~  mean_i N(z_si; mu_s, Sigma_t) / pi_s(z_si)

over the setup's stage-1 draws ``z_si``.  The importance weight of a hyperparameter draw is the product over
the setups of these ratios; the draws are then resampled (systematic resampling with the caller's generator)
into an equally weighted set of the same size, which every later step (population.nc, predictions, the outlier
check) uses unchanged.

Sound only where the weights do not degenerate: their effective sample size must be at least
:data:`EXACT_ESS_FRACTION` of the draws, and every setup's site average must rest on at least
:data:`SITE_ESS_MIN` effective stage-1 draws at the typical hyperparameter draw (a population spread far
narrower than the spacing of the stage-1 draws makes that average a noisy kernel estimate).  The cost is
``setups x stage-1 draws (at most max_draws each) x hyperparameter draws`` kernel evaluations;
``exact="auto"`` skips libraries above :data:`EXACT_MAX_PAIRS`, where the weights of hundreds of setups would
degenerate anyway.
"""

from __future__ import annotations

import dataclasses

import math

import numpy as np

from ..stats.weights import MIN_ESS, effective_sample_size, normalise_log_weights
from .population import covariate

__all__ = ["two_stage_log_weights", "site_log_integrals", "systematic_resample", "reweight_exact",
           "EXACT_ESS_FRACTION", "SITE_ESS_MIN", "EXACT_MAX_PAIRS", "EXACT_MAX_DRAWS"]

#: Smallest effective sample size of the two-stage weights, as a fraction of the hyperparameter draws, for the
#: re-weighted result to replace the surrogate's (below it a handful of draws would carry the result).
EXACT_ESS_FRACTION = 0.1
#: Smallest effective number of stage-1 draws (median over the hyperparameter draws) behind a setup's site average
#: (the package's least ESS of a weighted estimate, :data:`bayes_rcsa.stats.weights.MIN_ESS`).
SITE_ESS_MIN = MIN_ESS
#: ``exact="auto"`` re-weights only if setups x stage-1 draws x hyperparameter draws stays below this (a few
#: seconds on one core; a 12-combination library with 2,000 draws each and 8,000 hyperparameter draws is 1.9e8).
EXACT_MAX_PAIRS = 4e8
#: Stage-1 draws (evenly thinned) per setup in the site averages.
EXACT_MAX_DRAWS = 2000

_BLOCK = 1000  # hyperparameter draws per block: bounded memory (block x stage-1 draws)


def _thin(z: np.ndarray, max_draws: int) -> np.ndarray:
    """Evenly thinned rows of ``z`` (at most ~``2 max_draws``; every row if fewer than ``2 max_draws``)."""
    return z[::max(1, z.shape[0] // max_draws)]


def site_log_integrals(z: np.ndarray, ln_prior: np.ndarray, mu: np.ndarray, sigma: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``ln mean_i N(z_i; mu_h, diag sigma_h^2) / pi(z_i)`` and its effective number of draws, per hyperparameter draw.

    Parameters
    ----------
    z : (n, d) stage-1 draws of one setup, population coordinates
    ln_prior : (n,) stage-1 prior log density of the draws (finite: the draws lie in the box)
    mu, sigma : (H, d) population mean of the setup and spread per hyperparameter draw

    Returns
    -------
    ln_site : (H,) up to a constant common to all draws (the ``(2 pi)^(d/2)`` is left out, as in
        :func:`surrogate_log_density`)
    site_ess : (H,) ``(sum_i k_i)^2 / sum_i k_i^2`` of the kernel values ``k_i``
    """
    c = z.mean(axis=0)  # centred: the expanded square below then loses no digits for narrow spreads
    zc = z - c
    z2 = zc * zc
    H = mu.shape[0]
    ln_site, site_ess = np.empty(H), np.empty(H)
    for lo in range(0, H, _BLOCK):  # blocks of hyperparameter draws, each one BLAS product
        m = mu[lo:lo + _BLOCK] - c
        p = sigma[lo:lo + _BLOCK] ** -2.0
        # -0.5 sum_j (z_ij - m_hj)^2 p_hj = -0.5 (z2 p^T - 2 z (m p)^T + sum m^2 p); the (n, h) arrays are
        # updated in place (two buffers per block, not eight): the same operations, without the allocations
        lk = z2 @ p.T  # (n, h)
        t = zc @ (m * p).T
        t *= 2.0
        lk -= t
        lk += np.sum(m * m * p, axis=1)[None, :]
        lk *= -0.5
        lk -= ln_prior[:, None]
        top = lk.max(axis=0)
        lk -= top
        k = np.exp(lk, out=lk)
        s1 = k.sum(axis=0)
        ln_site[lo:lo + _BLOCK] = top + np.log(s1 / z.shape[0]) - np.sum(np.log(sigma[lo:lo + _BLOCK]), axis=1)
        site_ess[lo:lo + _BLOCK] = s1 * s1 / np.sum(np.multiply(k, k, out=t), axis=0)
    return ln_site, site_ess


def surrogate_log_density(m: np.ndarray, C: np.ndarray, mu: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """``ln N(m; mu_h, C + diag sigma_h^2)`` (H,) without the ``(2 pi)^(d/2)``; ``m`` (d,), ``C`` (d, d), ``mu``,
    ``sigma`` (H, d)."""
    d = m.shape[0]
    V = C[None] + (sigma * sigma)[:, :, None] * np.eye(d)[None]
    L = np.linalg.cholesky(V)
    w = np.linalg.solve(L, (m[None] - mu)[..., None])[..., 0]
    return -0.5 * np.sum(w * w, axis=1) - np.sum(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1)


def two_stage_log_weights(fit, setups, max_draws: int = EXACT_MAX_DRAWS) -> tuple[np.ndarray, dict]:
    """Log importance weights (H,) of stage 2's hyperparameter draws for the exact two-stage target.

    Parameters
    ----------
    fit : HyperFit of stage 2 (its types' surrogates ``m``, ``C`` and draws ``(a_t, b_t, sigma_t)``; row ``h`` of
        every type belongs to the same draw)
    setups : sequence of SetupDraws, all those in ``fit``
    max_draws : int, stage-1 draws (evenly thinned) per setup

    Returns
    -------
    lw : (H,) log weights up to a constant
    site_ess : dict setup name -> (H,) effective stage-1 draws behind its site average per hyperparameter draw
    """
    lw = 0.0
    site_ess = {}
    for s in setups:
        tf = fit.types[s.holder_type]
        th = tf.flat
        d = th.shape[1] // 3
        mu = th[:, :d] + th[:, d:2 * d] * float(covariate(s.diameter))
        sigma = th[:, 2 * d:]
        z = _thin(s.z, max_draws)
        ln_site, site_ess[s.name] = site_log_integrals(z, s.ln_prior(z), mu, sigma)
        i = list(tf.names).index(s.name)
        lw = lw + ln_site - surrogate_log_density(tf.m[i], tf.C[i], mu, sigma)
    return np.asarray(lw, float), site_ess


def systematic_resample(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices (H,) of ``H`` equally weighted draws from normalised weights ``w`` (H,), in increasing order
    (systematic resampling: one uniform offset, the least added noise of the standard schemes)."""
    H = w.size
    c = np.cumsum(w)
    c[-1] = 1.0
    return np.searchsorted(c, (rng.uniform() + np.arange(H)) / H)


def reweight_exact(fit, setups, rng: np.random.Generator, mode="auto", max_draws: int = EXACT_MAX_DRAWS,
                   ess_fraction: float = EXACT_ESS_FRACTION, site_ess_min: float = SITE_ESS_MIN,
                   max_pairs: float = EXACT_MAX_PAIRS):
    """Stage 2's draws re-weighted to the exact two-stage target and resampled, where that is sound.

    Parameters
    ----------
    fit : HyperFit
    setups : sequence of SetupDraws
    rng : numpy Generator (the resampling)
    mode : ``"auto"`` (re-weight if the cost is below ``max_pairs`` and the weights are sound), ``True`` (re-weight
        whatever the cost, if sound) or ``False`` (never)
    max_draws, ess_fraction, site_ess_min, max_pairs : see the module constants

    Returns
    -------
    fit : HyperFit, the resampled one where used, else ``fit`` itself
    info : dict ``used`` (bool), ``sound`` (None where not judged: off, or above the cost bound; else whether the
        weights passed the checks), ``mode``, ``reason`` (why not used, or None), ``pairs`` (the cost), ``n_draws``,
        ``weight_ess`` and ``weight_ess_fraction`` (None if not computed), ``site_ess_median_min`` (smallest over
        the setups of the median site ESS) and its setup ``site_ess_setup``, ``effective_draws`` (stage 2's chain
        ESS x the weights' ESS fraction, where used)
    """
    if mode not in ("auto", True, False):
        raise ValueError(f"exact must be 'auto', True or False; got {mode!r}")
    H = next(iter(fit.types.values())).flat.shape[0]
    pairs = float(sum(_thin(s.z, max_draws).shape[0] for s in setups)) * H
    info = {"used": False, "sound": None, "mode": mode, "reason": None, "pairs": pairs, "n_draws": H,
            "weight_ess": None, "weight_ess_fraction": None, "site_ess_median_min": None, "site_ess_setup": None,
            "effective_draws": None}
    if mode is False:
        info["reason"] = "exact = False: the Gaussian-surrogate result"
        return fit, info
    if mode == "auto" and pairs > max_pairs:
        info["reason"] = (f"library too large for the exact re-weighting: {pairs:.2g} kernel evaluations (setups x "
                          f"stage-1 draws x hyperparameter draws) > {max_pairs:.2g}; the Gaussian-surrogate result")
        return fit, info
    for s in setups:  # a stage-1 draw outside its own prior box has no density there: inconsistent input
        n_out = int(np.sum(~np.isfinite(s.ln_prior(_thin(s.z, max_draws)))))
        if n_out:
            info.update(sound=False, reason=f"setup {s.name}: {n_out} of its stage-1 draws lie outside its stage-1 "
                        "prior box; the Gaussian-surrogate result")
            return fit, info
    lw, site = two_stage_log_weights(fit, setups, max_draws)
    ok = np.isfinite(lw)
    if not ok.any():
        info.update(sound=False, reason="no finite two-stage weight; the Gaussian-surrogate result")
        return fit, info
    w = normalise_log_weights(np.where(ok, lw, -np.inf))  # a non-finite weight counts as zero
    ess = effective_sample_size(w, normalised=True)
    med = {n: float(np.median(v)) for n, v in site.items()}
    worst = min(med, key=med.get)
    info.update(weight_ess=ess, weight_ess_fraction=ess / H, site_ess_median_min=med[worst], site_ess_setup=worst)
    info["sound"] = bool(ess >= ess_fraction * H and med[worst] >= site_ess_min)
    if ess < ess_fraction * H:
        info["reason"] = (f"the two-stage weights degenerate: ESS {ess:.0f} of {H} draws < {ess_fraction:g} x {H}; "
                          "the Gaussian-surrogate result is kept")
        return fit, info
    if med[worst] < site_ess_min:
        info["reason"] = (f"setup {worst}: its site average rests on {med[worst]:.1f} effective stage-1 draws "
                          f"(median over the hyperparameter draws) < {site_ess_min:g} (too few stage-1 draws, or a "
                          "population spread narrower than their spacing); the Gaussian-surrogate result is kept")
        return fit, info
    idx = systematic_resample(w, rng)
    types = {t: dataclasses.replace(tf, chain=tf.flat[idx].reshape(tf.chain.shape)) for t, tf in fit.types.items()}
    # None where the chain's ESS is unknown (too short to measure its tau): no effective draws are vouched for
    info.update(used=True, effective_draws=float(fit.ess * ess / H) if math.isfinite(fit.ess) else None)
    return dataclasses.replace(fit, theta=fit.theta[idx], types=types), info
