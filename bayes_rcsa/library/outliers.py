"""Outlier check: does a combination's own data agree with the population fitted without it?

For setup ``s`` of holder type ``t`` the statistic is the Mahalanobis
distance of its likelihood surrogate ``m_s`` from the leave-one-out
population predictive,

    D = (m_s - a - b x_s)^T (C_s + diag sigma^2)^-1 (m_s - a - b x_s) ~ chi2(d),

and the leave-one-out predictive p-value averages ``P(chi2_d > D)`` over the
hyperparameter posterior *without* ``s``: an exact refit of the type without
``s`` for small types (``n <= exact_max``), truncated importance sampling of
the full posterior's draws (weights ``1 / p(m_s | hyper)``, Ionides 2008)
for larger ones.  A setup is flagged when ``p < alpha / n_setups``
(Bonferroni over the library: a clean library is flagged anywhere with
probability <= alpha).  The only combination of its type cannot be checked.
"""

from __future__ import annotations

import math

import numpy as np

from .stage2 import Stage2Settings, TypeFit, _quad_logdet, fit_type

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


def loo_p_values(fit: TypeFit, hyper, rng: np.random.Generator, exact_max: int = EXACT_MAX,
                 settings: Stage2Settings = Stage2Settings(n_burn=300, ess_target=300)) -> list[dict]:
    """Leave-one-out predictive p-value of every setup of one holder type.

    Returns
    -------
    list of dict (setup order of ``fit``): ``name``, ``p_value`` (None when
    the type has one combination), ``method`` (``"exact"``, ``"importance"``
    or ``None``), ``distance_median``
    """
    from scipy.stats import chi2

    n, d = fit.m.shape
    out = []
    flat = fit.flat
    flat = flat[:: max(1, flat.shape[0] // 4000)]  # 4000 evenly thinned draws carry the importance weights
    for i, name in enumerate(fit.names):
        if n < 2:
            out.append({"name": name, "p_value": None, "method": None, "distance_median": None})
            continue
        if n <= exact_max:
            keep = np.arange(n) != i
            sub = fit_type(fit.holder_type, [fit.names[k] for k in np.flatnonzero(keep)], fit.x[keep], fit.m[keep],
                           fit.C[keep], hyper, rng, settings)
            D, _ = _distance(sub.flat, fit.m[i], fit.C[i], float(fit.x[i]))
            p = float(np.mean(chi2.sf(D, d)))
            method = "exact"
        else:
            D, ll = _distance(flat, fit.m[i], fit.C[i], float(fit.x[i]))
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
