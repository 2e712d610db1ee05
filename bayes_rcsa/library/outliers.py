"""Outlier check: does a combination's own data agree with the population fitted without it?

For setup ``s`` of holder type ``t`` the statistic is the Mahalanobis
distance of its likelihood surrogate ``m_s`` from the leave-one-out
population predictive,

    D = (m_s - a - b x_s)^T (C_s + diag sigma^2)^-1 (m_s - a - b x_s) ~ chi2(d),

and the leave-one-out predictive p-value averages ``P(chi2_d > D)`` over the
hyperparameter posterior *without* ``s``: for small types (``n <= exact_max``)
an exact refit of the coupled library without ``s``, with the type's mean and
slope integrated out (the predictive given the spreads is normal, so ``a, b``
enter ``D`` through their conditional mean and covariance); for larger types
truncated importance sampling of the full posterior's draws of ``(a, b,
sigma)`` (weights ``1 / p(m_s | hyper)``, Ionides 2008).  A setup is flagged when ``p < alpha / n_setups``
(Bonferroni over the library: a clean library is flagged anywhere with
probability <= alpha).  The only combination of its type cannot be checked.
"""

from __future__ import annotations

import math

import numpy as np

from .hierarchy import HyperFit, Stage2Settings, fit_hyper, predictive_of_setup
from .stage2 import _quad_logdet

__all__ = ["loo_p_values", "flag_outliers", "ALPHA", "EXACT_MAX"]

#: Family-wise false-flag rate of a clean library.
ALPHA = 0.05
#: Types with at most this many combinations are refitted without each setup (exact leave-one-out).
EXACT_MAX = 16


def _distance(theta: np.ndarray, m: np.ndarray, C: np.ndarray, x: float) -> tuple[np.ndarray, np.ndarray]:
    """(D, log marginal likelihood) per hyperparameter draw for one setup; theta (H, 3d)."""
    d = m.shape[0]
    a, b, s = theta[:, :d], theta[:, d:2 * d], theta[:, 2 * d:]
    r = (m[None, :] - a - b * x).T[:, :, None]  # (d, H, 1)
    q, logdet = _quad_logdet(C[:, :, None], s * s, r)
    q, logdet = q[:, 0], logdet[:, 0]
    return q, -0.5 * (q + logdet + d * math.log(2 * math.pi))


def loo_p_values(fit: HyperFit, hyper, rng: np.random.Generator, exact_max: int = EXACT_MAX,
                 settings: Stage2Settings = Stage2Settings(n_burn=200, ess_target=300),
                 n_draws: int = 1000) -> list[dict]:
    """Leave-one-out predictive p-value of every setup of the library (types in the order of ``fit.groups``).

    Parameters
    ----------
    fit : HyperFit, the coupled stage-2 posterior (``Stage2Result.fit``)
    hyper : Hyperprior
    rng : numpy Generator
    exact_max : int, types of at most this many combinations are checked by exact refits
    settings : Stage2Settings of the refits
    n_draws : int, refit draws (evenly thinned) the p-value averages over

    Returns
    -------
    list of dict: ``name``, ``p_value`` (None for the only combination of its
    type), ``method`` (``"exact"``, ``"importance"`` or ``None``),
    ``distance_median``
    """
    from scipy.stats import chi2

    out = []
    for t, g in enumerate(fit.groups):
        n, d = g.m.shape
        flat = fit.types[g.holder_type].flat
        flat = flat[:: max(1, flat.shape[0] // 4000)]  # 4000 evenly thinned draws carry the importance weights
        for i, name in enumerate(g.names):
            if n < 2:
                out.append({"name": name, "p_value": None, "method": None, "distance_median": None})
                continue
            if n <= exact_max:
                groups = tuple(gg.without(i) if k == t else gg for k, gg in enumerate(fit.groups))
                sub = fit_hyper(groups, hyper, rng, settings, start_from=fit.theta, type_draws=False)
                theta = sub.theta[:: max(1, sub.theta.shape[0] // n_draws)]
                D = predictive_of_setup(theta, groups, hyper, t, g.m[i], g.C[i], float(g.x[i]))
                p = float(np.mean(chi2.sf(D, d)))
                method = "exact"
            else:
                D, ll = _distance(flat, g.m[i], g.C[i], float(g.x[i]))
                lw = -ll - np.max(-ll)
                w = np.exp(lw)
                w = np.minimum(w, np.mean(w) * math.sqrt(w.size))  # truncated importance sampling
                p = float(np.sum(w * chi2.sf(D, d)) / np.sum(w))
                method = "importance"
            out.append({"name": name, "p_value": p, "method": method, "distance_median": float(np.median(D))})
    return out


def flag_outliers(p_rows: list[dict], n_setups: int, alpha: float = ALPHA) -> tuple[list[dict], list[str]]:
    """Flag setups with ``p < alpha / n_setups``; returns the rows with ``outlier`` and the warnings."""
    threshold = alpha / max(1, n_setups)
    warns = []
    rows = []
    for r in p_rows:
        p = r["p_value"]
        flagged = p is not None and p < threshold
        rows.append({**r, "threshold": threshold, "outlier": bool(flagged)})
        if flagged:
            warns.append(f"setup {r['name']}: outlier -- its data disagree with its holder type's population "
                         f"(leave-one-out p = {p:.2g} < {threshold:.2g}); check the clamping (a badly clamped tool is "
                         "the usual cause) or a hidden effect")
        elif p is None:
            warns.append(f"setup {r['name']}: the only combination of its holder type; it cannot be checked against "
                         "a population")
    return rows, warns
