"""Depth limits of FRF draws that carry their own cutting coefficients (e.g. after ``bayes-rcsa update``).

The zero-order and semi-discretisation limits are exactly inversely
proportional to the cutting-force level at a fixed ratio K_r/K_t (the
regenerative force is ``a (K_t A + K_r B) Δq``): with a reference
``cutting`` of coefficients (K_t0, ρ K_t0),

    a_lim(K_t, ρ K_t) = a_lim(K_t0, ρ K_t0) K_t0 / K_t.

Draws are therefore grouped by their ratio ρ = K_r/K_t (a handful of
distinct values: the update samples the ratio on a few nodes) and each group
is evaluated once by the registered method and scaled per draw; no
approximation is made.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import SetupError
from .methods import MethodResult

__all__ = ["ratio_groups", "limits_with_coefficients", "MAX_RATIO_GROUPS", "COEFFICIENT_VARIABLES", "read_coefficient_draws"]

#: More distinct ratios than this would make one method call per draw; refused (the update writes <= 15).
MAX_RATIO_GROUPS = 64


def ratio_groups(kt, kr) -> tuple[np.ndarray, np.ndarray]:
    """Distinct ratios K_r/K_t of the draws and the group of every draw.

    Ratios equal to 1e-9 relative are one group.

    Returns
    -------
    ratios : (n_groups,), group : (n_draws,) int
    """
    kt = np.asarray(kt, dtype=float)
    kr = np.asarray(kr, dtype=float)
    if kt.shape != kr.shape or kt.ndim != 1 or not (np.all(np.isfinite(kt) & (kt > 0)) and np.all(np.isfinite(kr) & (kr >= 0))):
        raise SetupError("per-draw cutting coefficients must be finite 1-D arrays of one length with K_t > 0, K_r >= 0")
    key = np.round(np.log(np.maximum(kr / kt, 1e-300)) * 1e9)
    uniq, group = np.unique(key, return_inverse=True)
    ratios = np.array([float(np.median((kr / kt)[group == g])) for g in range(uniq.size)])
    return ratios, group


def limits_with_coefficients(impl, frf_x, frf_y, frequency_hz, cutting, speeds_rpm, kt, kr, options,
                             progress=None) -> MethodResult:
    """Per-draw depth limits with per-draw cutting coefficients.

    Parameters
    ----------
    impl : a registered stability method (:mod:`.methods`)
    frf_x, frf_y : (n_draws, n_freq) complex, m/N
    frequency_hz : (n_freq,) Hz
    cutting : CuttingConditions, the geometry (flutes, immersion, feed, pitch); its K_t is the reference
    speeds_rpm : (n_speed,) rpm
    kt, kr : (n_draws,) Pa, the coefficients of every draw
    options : MethodOptions

    Returns
    -------
    MethodResult with (n_draws, n_speed) limits and ``limits_at`` combining the groups the same way.
    """
    ratios, group = ratio_groups(kt, kr)
    if ratios.size > MAX_RATIO_GROUPS:
        raise SetupError(f"the draws carry {ratios.size} distinct ratios K_r/K_t; at most {MAX_RATIO_GROUPS} are "
                         "evaluated (give --kt/--kr to use fixed coefficients)")
    kt = np.asarray(kt, dtype=float)
    scale = cutting.kt / kt  # exact: the limit is inversely proportional to the force level at a fixed ratio
    parts = []
    for g, rho in enumerate(ratios):  # a handful of groups, each vectorised over its draws
        idx = np.nonzero(group == g)[0]
        c = replace(cutting, kr=float(cutting.kt * rho))
        part = impl.depth_limits(frf_x[idx], frf_y[idx], frequency_hz, c, speeds_rpm, options,
                                 None if progress is None else (lambda x, g=g: progress((g + x) / ratios.size)))
        parts.append((idx, part))
    n = np.asarray(frf_x).shape[0]

    def combine(get, k):
        out = np.empty((n, k))
        for idx, part in parts:
            out[idx] = np.atleast_2d(get(part)) * scale[idx, None]
        return out

    limits = combine(lambda p: p.depth_limit_m, np.size(speeds_rpm))
    limits_at = None
    if all(p.limits_at is not None for _, p in parts):
        def limits_at(s):
            return combine(lambda p: p.limits_at(s), np.size(s))
    fits = [None] * n if any(p.modal_fits for _, p in parts) else []
    for idx, p in parts:
        for i, fit in zip(idx, p.modal_fits):
            fits[i] = fit
    info = {"coefficient_draws": {"ratio_groups": [float(r) for r in ratios],
                                  "kt_quantiles_pa": [float(q) for q in np.quantile(kt, [0.05, 0.5, 0.95])]}}
    if len(parts) == 1:
        info.update(parts[0][1].info)
    return MethodResult(limits, fits, info, limits_at)


#: Variables of a posterior.nc (written by ``bayes-rcsa update``) with per-draw cutting coefficients (Pa).
COEFFICIENT_VARIABLES = ("cutting_kt_pa", "cutting_kr_pa")


def read_coefficient_draws(posterior_path, index=None, inference_data=None):
    """Per-draw (K_t, K_r) in Pa stored in ``posterior_path``, or None when it has none (a hammer-only fit).

    Parameters
    ----------
    posterior_path : path of posterior.nc
    index : int array or None, the draws to keep (the same subset as the FRF draws)
    inference_data : arviz.InferenceData or None, the file's content when already read (not opened again)

    Returns
    -------
    (kt (n,), kr (n,)) or None
    """
    from ..errors import DataError
    from ..store import read_posterior

    post = (read_posterior(posterior_path, option=None, arrays=True) if inference_data is None else inference_data).posterior
    if not all(v in post.data_vars for v in COEFFICIENT_VARIABLES):
        return None
    kt, kr = (np.asarray(post[v].values, dtype=float).reshape(-1) for v in COEFFICIENT_VARIABLES)
    if not (np.all(np.isfinite(kt) & (kt > 0)) and np.all(np.isfinite(kr) & (kr >= 0))):
        raise DataError(f"{posterior_path}: {COEFFICIENT_VARIABLES} must be finite, K_t > 0 and K_r >= 0")
    if index is not None:
        kt, kr = kt[index], kr[index]
    return kt, kr
