"""Probabilistic stability lobes from draws of the tool-point FRFs (e.g. posterior draws).

Every draw d gives a stability limit a_lim,d(Ω) (the *lowest* depth at which
chatter starts at speed Ω; stable islands above it are disregarded, which
is the conservative reading of a lobe diagram).  Then

    P(stable | Ω, a) = #{d : a < a_lim,d(Ω)} / N_draws,

which is non-increasing in a by construction.  Its 5/50/95 % contours in
depth are the 95/50/5 % quantiles of a_lim over the draws: ``q05`` is the
depth that 95 % of the draws consider stable.  The recommended operating
point maximises the material removal rate, proportional to a·n at fixed
radial depth and feed per tooth, over the grid points with
P(stable) >= ``level`` inside the user's speed and depth limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from .cutting import CuttingConditions
from .modal_fit import fit_modal_model
from .sdm import sdm_stability_map
from .zoa import zoa_lobes

__all__ = [
    "ProbabilisticLobes",
    "Recommendation",
    "probability_map",
    "depth_quantiles",
    "recommend_operating_point",
    "lobes_from_frf_draws",
    "auto_depth_grid",
]

QUANTILES = (0.05, 0.5, 0.95)


@dataclass(frozen=True)
class Recommendation:
    """Operating point with the largest a·n among grid points with P(stable) >= level.

    Attributes
    ----------
    spindle_speed_rpm : float, rpm
    depth_m : float, m
    p_stable : float
    mrr_index : float, m·rpm (a_p n; MRR = a_p a_e f_z N n is proportional to it)
    """

    spindle_speed_rpm: float
    depth_m: float
    p_stable: float
    mrr_index: float


@dataclass(frozen=True)
class ProbabilisticLobes:
    """Result of :func:`lobes_from_frf_draws`.

    Attributes
    ----------
    speed_rpm : (n_speed,) rpm
    depth_m : (n_depth,) m, grid of the probability map
    p_stable : (n_speed, n_depth) probability of stability
    depth_limit_m : (n_draws, n_speed) m, per-draw limit (+inf: no chatter found)
    quantiles : dict float -> (n_speed,) m, depth-limit quantiles over the draws (0.05, 0.5, 0.95)
    recommended : Recommendation or None (no grid point reaches the level)
    level : float
    method : str
    modal_fits : list of (ModalFit x, ModalFit y) per draw (SDM only, else empty)
    """

    speed_rpm: np.ndarray
    depth_m: np.ndarray
    p_stable: np.ndarray
    depth_limit_m: np.ndarray
    quantiles: dict
    recommended: Recommendation | None
    level: float
    method: str
    modal_fits: list


def probability_map(depth_limit_m, depth_m, chunk: int = 64) -> np.ndarray:
    """P(stable) = fraction of draws with a < a_lim.

    Parameters
    ----------
    depth_limit_m : (n_draws, n_speed) m (inf allowed)
    depth_m : (n_depth,) m

    Returns
    -------
    (n_speed, n_depth) in [0, 1], non-increasing along depth.
    """
    lim = np.asarray(depth_limit_m, dtype=float)
    if lim.ndim == 1:
        lim = lim[None]
    if np.any(np.isnan(lim)):
        raise SetupError("depth limits contain NaN; cannot form a probability of stability")
    a = np.asarray(depth_m, dtype=float)
    out = np.empty((lim.shape[1], a.size))
    for s in range(0, lim.shape[1], chunk):  # bounds memory at n_draws * chunk * n_depth
        out[s : s + chunk] = np.mean(a[None, None, :] < lim[:, s : s + chunk, None], axis=0)
    return out


def depth_quantiles(depth_limit_m, quantiles=QUANTILES) -> dict:
    """Empirical quantiles of the depth limit over draws, (n_speed,) each.

    Linear interpolation between order statistics; a quantile that touches an
    infinite limit (no chatter in the FRF band) is +inf.
    """
    lim = np.sort(np.atleast_2d(np.asarray(depth_limit_m, dtype=float)), axis=0)
    n = lim.shape[0]
    out = {}
    for q in quantiles:
        pos = q * (n - 1)
        lo = int(np.floor(pos))
        hi = min(lo + 1, n - 1)
        t = pos - lo
        a, b = lim[lo], lim[hi]
        with np.errstate(invalid="ignore"):
            val = np.where(np.isinf(b) & (t > 0), np.inf, a + t * np.where(np.isinf(b), 0.0, b - a))
        out[float(q)] = np.where(np.isinf(a), np.inf, val)
    return out


def recommend_operating_point(
    speed_rpm, depth_m, p_stable, level: float = 0.95, speed_limits=None, max_depth=None
) -> Recommendation | None:
    """Grid point maximising a·n subject to P(stable) >= level and the limits.

    Parameters
    ----------
    speed_rpm : (n_speed,) rpm
    depth_m : (n_depth,) m
    p_stable : (n_speed, n_depth)
    level : float in (0, 1]
    speed_limits : (lo, hi) rpm or None (whole grid)
    max_depth : float m or None (whole grid)

    Returns
    -------
    Recommendation, or None when no admissible grid point reaches ``level``.
    """
    if not (0.0 < level <= 1.0):
        raise SetupError(f"level={level!r}: expected a probability in (0, 1]")
    n = np.asarray(speed_rpm, dtype=float)
    a = np.asarray(depth_m, dtype=float)
    p = np.asarray(p_stable, dtype=float)
    ok = p >= level
    if speed_limits is not None:
        ok &= ((n >= speed_limits[0]) & (n <= speed_limits[1]))[:, None]
    if max_depth is not None:
        ok &= (a <= max_depth)[None, :]
    score = np.where(ok, n[:, None] * a[None, :], -np.inf)
    if not np.any(ok):
        return None
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    return Recommendation(float(n[i]), float(a[j]), float(p[i, j]), float(n[i] * a[j]))


def auto_depth_grid(depth_limit_m, points: int = 200) -> np.ndarray:
    """Default depth grid: ``points`` levels up to 1.2 x the 90th percentile over speeds of the median limit.

    The percentile keeps the isolated tall peaks of the first lobes from
    stretching the grid while showing the lobes and their pockets.

    Raises
    ------
    SetupError
        When no finite limit exists (no chatter in the FRF band at any speed).
    """
    q50 = depth_quantiles(depth_limit_m, (0.5,))[0.5]
    finite = q50[np.isfinite(q50)]
    if finite.size == 0:
        raise SetupError("no chatter limit found at any speed inside the FRF band; give the depth range explicitly")
    top = 1.2 * float(np.quantile(finite, 0.9))
    return np.linspace(top / points, top, points)


def _check_draws(frf_x, frf_y, frequency_hz):
    gx = np.atleast_2d(np.asarray(frf_x, dtype=complex))
    gy = np.atleast_2d(np.asarray(frf_y, dtype=complex))
    f = np.asarray(frequency_hz, dtype=float)
    if gx.ndim != 2 or gx.shape != gy.shape or gx.shape[1] != f.size:
        raise SetupError(
            f"FRF draws must be (n_draws, n_freq) with equal shapes and n_freq = {f.size}; got {gx.shape} and {gy.shape}"
        )
    return gx, gy, f


def lobes_from_frf_draws(
    frf_x_draws,
    frf_y_draws,
    frequency_hz,
    cutting: CuttingConditions,
    speeds_rpm,
    depths_m=None,
    method: str = "zoa",
    level: float = 0.95,
    max_depth: float | None = None,
    depth_points: int = 200,
    intervals=None,
    max_modes: int = 4,
) -> ProbabilisticLobes:
    """Probabilistic stability lobes from draws of the tool-point FRFs in X and Y.

    Parameters
    ----------
    frf_x_draws, frf_y_draws : (n_draws, n_freq) complex, m/N (one draw: (n_freq,) also accepted)
    frequency_hz : (n_freq,) Hz
    cutting : CuttingConditions
    speeds_rpm : (n_speed,) rpm, increasing
    depths_m : (n_depth,) m or None
        Grid of the probability map; default ``depth_points`` levels up to
        ``max_depth`` or, without it, :func:`auto_depth_grid` from the ZOA limits.
    method : {"zoa", "sdm"}
        "zoa": zero-order approximation directly on the FRFs (fast path).
        "sdm": modal fit of each draw (:func:`~bayes_rcsa.stability.modal_fit.fit_modal_model`)
        and semi-discretisation on (speeds x depths); the per-draw limit is the
        first crossing on the depth grid.
    level : float, P(stable) required for the recommendation
    max_depth : float or None, m, depth limit of the recommendation (and of the default grid)
    intervals : SDM intervals per tooth period (default rule of :mod:`.sdm`)
    max_modes : int, largest mode count of the SDM modal fits

    Returns
    -------
    ProbabilisticLobes
    """
    if method not in ("zoa", "sdm"):
        raise SetupError(f"method={method!r}: expected 'zoa' or 'sdm'")
    gx, gy, f = _check_draws(frf_x_draws, frf_y_draws, frequency_hz)
    speeds = np.asarray(speeds_rpm, dtype=float)
    zoa = None
    if method == "zoa" or depths_m is None:
        zoa = zoa_lobes(gx, gy, f, cutting, speeds).depth_limit_m
    if depths_m is None:
        if max_depth is not None:
            depths = np.linspace(max_depth / depth_points, max_depth, depth_points)
        else:
            depths = auto_depth_grid(zoa, depth_points)
    else:
        depths = np.asarray(depths_m, dtype=float)
        if depths.ndim != 1 or np.any(depths <= 0) or np.any(np.diff(depths) <= 0):
            raise SetupError("depths_m must be a strictly increasing 1-D array of positive depths")
    fits = []
    if method == "zoa":
        limits = zoa
    else:
        limits = np.empty((gx.shape[0], speeds.size))
        for d in range(gx.shape[0]):  # each draw needs its own modal fit; the SDM grid is vectorised
            fx = fit_modal_model(f, gx[d], max_modes=max_modes, source=f"draw {d} X")
            fy = fit_modal_model(f, gy[d], max_modes=max_modes, source=f"draw {d} Y")
            fits.append((fx, fy))
            limits[d] = sdm_stability_map(fx.model, fy.model, cutting, speeds, depths, intervals=intervals).depth_limit_m
    p = probability_map(limits, depths)
    rec = recommend_operating_point(speeds, depths, p, level=level, max_depth=max_depth)
    return ProbabilisticLobes(
        speed_rpm=speeds,
        depth_m=depths,
        p_stable=p,
        depth_limit_m=limits,
        quantiles=depth_quantiles(limits),
        recommended=rec,
        level=level,
        method=method,
        modal_fits=fits,
    )
