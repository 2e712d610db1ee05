"""Probabilistic stability lobes from draws of the tool-point FRFs (e.g. posterior draws).

Every draw d gives a stability limit a_lim,d(Ω) (the *lowest* depth at which
chatter starts at speed Ω; stable islands above it are disregarded, which
is the conservative reading of a lobe diagram), computed per speed directly
by the chosen method of :data:`~bayes_rcsa.stability.methods.STABILITY_METHODS`
(no depth grid).  Then

    P(stable | Ω, a) = #{d : a < a_lim,d(Ω)} / N_draws,

which is non-increasing in a by construction.  Its 5/50/95 % contours in
depth are the 95/50/5 % quantiles of a_lim over the draws: ``q05`` is the
depth that 95 % of the draws consider stable.  The recommended operating
point (:mod:`.recommend`) is robust: P(stable) >= ``level`` over a
spindle-speed tolerance, a depth margin and optionally a cutting-force
tolerance, computed from the limits themselves.  The depth grid of the
P(stable) map (for plots and the ``.npz`` file) is sized from the limits
that matter for the recommendation, so the recommended point and the lobe
tips it sits under lie inside it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from .cutting import CuttingConditions
from .methods import STABILITY_METHODS, MethodOptions, method_names
from .recommend import Recommendation, Tolerances, level_limit, recommend

__all__ = [
    "ProbabilisticLobes",
    "Recommendation",
    "probability_map",
    "depth_quantiles",
    "recommend_operating_point",
    "lobes_from_frf_draws",
    "depth_grid",
]

QUANTILES = (0.05, 0.5, 0.95)
# (draw, speed) cells above which the P(stable) map is counted by the compiled loop (numba is loaded by then for
# the ZOA envelope; smaller maps, e.g. of the design and cuts modules, stay in numpy and import no compiler)
_COMPILED_MAP_CELLS = 1_000_000


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
    recommended : Recommendation or None (robust; None when no admissible speed reaches the level)
    level : float
    method : str
    modal_fits : list of (ModalFit x, ModalFit y) per draw (SDM only, else empty)
    pointwise : Recommendation or None, the optimum without tolerance or margin (for comparison)
    alternatives : list of dict, best robust point of each of the three largest stable pockets
    note : str, why there is no recommendation (else "")
    method_info : dict, details reported by the method
    envelope : (n_speed,) m or None, the robust envelope: the depth below which P(stable) >= level at
        each speed (the lower (1 - level) quantile of the limits over the draws, as the ceil(level N)-th
        largest limit; +inf where none is found); equal to the limit itself for one draw
    median_recommended : Recommendation or None, the recommendation at P(stable) >= 0.5 with the same
        tolerances (what the confidence ``level`` costs is measured against it)
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
    pointwise: Recommendation | None = None
    alternatives: list = field(default_factory=list)
    note: str = ""
    method_info: dict = field(default_factory=dict)
    envelope: np.ndarray | None = None
    median_recommended: Recommendation | None = None


def probability_map(depth_limit_m, depth_m, chunk: int | None = None) -> np.ndarray:
    """P(stable) = fraction of draws with a < a_lim.

    Parameters
    ----------
    depth_limit_m : (n_draws, n_speed) m (inf allowed)
    depth_m : (n_depth,) m, increasing
    chunk : ignored (kept for callers of the earlier, chunked version)

    Returns
    -------
    (n_speed, n_depth) in [0, 1], non-increasing along depth.

    Notes
    -----
    a_j < a_lim,d exactly when j < #{depths below a_lim,d} (one ``searchsorted`` of every limit in the depth
    grid), so the map is a per-speed histogram of those counts summed from the top: O(n_draws n_speed) instead
    of comparing every draw with every depth (compiled for large maps).  The counts are exact, so the values
    equal the direct mean.
    """
    lim = np.asarray(depth_limit_m, dtype=float)
    if lim.ndim == 1:
        lim = lim[None]
    if np.any(np.isnan(lim)):
        raise SetupError("depth limits contain NaN; cannot form a probability of stability")
    a = np.asarray(depth_m, dtype=float)
    n_draw, n_speed = lim.shape
    if a.size > 1 and np.any(np.diff(a) < 0):  # an unsorted grid (never ours): the direct comparison
        return np.mean(a[None, None, :] < lim[:, :, None], axis=0)
    if lim.size >= _COMPILED_MAP_CELLS:  # a fine grid: the compiled histogram, no (D, S) temporaries
        from ._zoa_kernel import stable_fractions

        out = np.empty((n_speed, a.size))
        stable_fractions(np.ascontiguousarray(lim), np.ascontiguousarray(a), out)
        return out
    below = np.searchsorted(a, lim, side="left")  # (D, S): number of depths a_j < a_lim,d
    cell = (np.arange(n_speed) * (a.size + 1))[None, :] + below
    hist = np.bincount(cell.ravel(), minlength=n_speed * (a.size + 1)).reshape(n_speed, a.size + 1)
    # #{d : a_j < a_lim,d} = #{d : below_d > j} = sum of hist[:, m] over m > j
    stable = np.cumsum(hist[:, :0:-1], axis=1)[:, ::-1]
    return stable / n_draw


def depth_quantiles(depth_limit_m, quantiles=QUANTILES, presorted: bool = False) -> dict:
    """Empirical quantiles of the depth limit over draws, (n_speed,) each.

    Linear interpolation between order statistics; a quantile that touches an
    infinite limit (no chatter in the FRF band) is +inf.  ``presorted``: the limits
    are already sorted over the draws (axis 0).
    """
    lim = np.atleast_2d(np.asarray(depth_limit_m, dtype=float))
    if not presorted:
        lim = np.sort(lim, axis=0)
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
    """Point-wise grid optimum: the grid point maximising a·n subject to P(stable) >= level and the limits.

    No tolerance or margin (see :func:`~bayes_rcsa.stability.recommend.recommend` for the robust
    recommendation); kept for maps computed elsewhere.

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
    return Recommendation(float(n[i]), float(a[j]), float(p[i, j]), float(n[i] * a[j]),
                          tolerances=Tolerances(0.0, 1.0, 0.0))


def depth_grid(depth_limit_m, level: float, points: int = 200, recommended: Recommendation | None = None,
               max_depth: float | None = None, presorted: bool = False) -> np.ndarray:
    """Depth grid of the P(stable) map, (points,) m, from top/points to top.

    ``top`` is 1.25 x the highest finite depth below which P(stable) >= level at some speed
    (the lobe tips the recommendation is chosen under), at least 1.25 x the checked
    neighbourhood of the recommended point, and at most 1.1 x ``max_depth``: the recommended
    point and the tips lie strictly inside.  ``presorted``: the limits are sorted over the draws (axis 0).

    Raises
    ------
    SetupError
        When no finite limit exists (no chatter in the analysed range at any speed) and no max_depth is given.
    """
    a_lvl = level_limit(depth_limit_m, level, presorted)
    q50 = depth_quantiles(depth_limit_m, (0.5,), presorted)[0.5]
    finite = np.concatenate([a_lvl[np.isfinite(a_lvl)], q50[np.isfinite(q50)]])
    if finite.size == 0 and max_depth is None:
        raise SetupError("no chatter limit found at any speed inside the analysed range; give --max-depth")
    top = 1.25 * float(np.max(a_lvl[np.isfinite(a_lvl)], initial=0.0))
    if recommended is not None:
        top = max(top, 1.25 * recommended.depth_checked_m if np.isfinite(recommended.depth_checked_m)
                  else 1.25 * recommended.depth_m)
    if top <= 0:
        top = 1.25 * float(np.max(finite, initial=0.0))
    if max_depth is not None:
        top = min(top, 1.1 * max_depth) if top > 0 else 1.1 * max_depth
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
    tolerances: Tolerances | None = None,
    flute_length: float | None = None,
    progress=None,
    coefficients=None,
    exact: bool = False,
) -> ProbabilisticLobes:
    """Probabilistic stability lobes and a robust recommendation from draws of the tool-point FRFs in X and Y.

    Parameters
    ----------
    frf_x_draws, frf_y_draws : (n_draws, n_freq) complex, m/N (one draw: (n_freq,) also accepted)
    frequency_hz : (n_freq,) Hz
    cutting : CuttingConditions
    speeds_rpm : (n_speed,) rpm, increasing; the analysed range (a user limit of the recommendation)
    depths_m : (n_depth,) m or None
        Grid of the probability map only; default :func:`depth_grid` (``depth_points`` levels).
    method : a name of :data:`~bayes_rcsa.stability.methods.STABILITY_METHODS` ("zoa", "sdm")
    level : float, P(stable) required over the recommendation's neighbourhood
    max_depth : float or None, m, user depth limit of the recommendation
    depth_points : int, levels of the default map grid
    intervals : SDM intervals per tooth period (default rule of :mod:`.sdm`)
    max_modes : int, largest mode count of the SDM modal fits
    tolerances : Tolerances or None (default ±2 % speed, 10 % depth margin)
    flute_length : float or None, m, the tool's flute length (depth limit)
    progress : callable(fraction) or None
    coefficients : (kt (n_draws,), kr (n_draws,)) Pa or None
        Per-draw cutting coefficients (an updated posterior); ``cutting`` then gives the geometry and
        the reference level (:func:`~bayes_rcsa.stability.coefficients.limits_with_coefficients`, exact).
    exact : bool
        Compute every draw with the method itself (SDM: no surrogate from a subset of exact draws; see
        :mod:`bayes_rcsa.stability.sdm_draws`).

    Returns
    -------
    ProbabilisticLobes
    """
    names = method_names()
    if method not in names:
        raise SetupError(f"method={method!r}: expected one of {', '.join(names)}")
    impl = STABILITY_METHODS.get(method)
    options = MethodOptions(intervals=intervals, max_modes=max_modes, exact=exact)
    impl.check(options)
    gx, gy, f = _check_draws(frf_x_draws, frf_y_draws, frequency_hz)
    speeds = np.asarray(speeds_rpm, dtype=float)
    if speeds.ndim != 1 or speeds.size < 2 or np.any(speeds <= 0) or np.any(np.diff(speeds) <= 0):
        raise SetupError("speeds_rpm must be a strictly increasing 1-D array of >= 2 positive speeds")
    if depths_m is not None:
        depths = np.asarray(depths_m, dtype=float)
        if depths.ndim != 1 or np.any(depths <= 0) or np.any(np.diff(depths) <= 0):
            raise SetupError("depths_m must be a strictly increasing 1-D array of positive depths")
    if coefficients is None:
        result = impl.depth_limits(gx, gy, f, cutting, speeds, options, progress)
    else:
        from .coefficients import limits_with_coefficients

        result = limits_with_coefficients(impl, gx, gy, f, cutting, speeds, coefficients[0], coefficients[1], options,
                                          progress)
    limits = np.atleast_2d(result.depth_limit_m)
    if np.any(np.isnan(limits)):
        raise SetupError("depth limits contain NaN; cannot form a probability of stability")
    # the order statistics over the draws once: every later use counts draws below a depth or takes a
    # quantile, which the order of the draws does not change
    ordered = np.sort(limits, axis=0)
    rec = recommend(speeds, ordered, level, tolerances, max_depth=max_depth, flute_length=flute_length,
                    limits_at=result.limits_at, presorted=True)
    if depths_m is None:
        depths = depth_grid(ordered, level, depth_points, rec["recommended"], max_depth, presorted=True)
    p = probability_map(ordered, depths)
    if limits.shape[0] == 1 or level == 0.5:
        median = rec["recommended"]
    else:
        median = recommend(speeds, ordered, 0.5, tolerances, max_depth=max_depth, flute_length=flute_length,
                           limits_at=result.limits_at, presorted=True)["recommended"]
    return ProbabilisticLobes(
        speed_rpm=speeds,
        depth_m=depths,
        p_stable=p,
        depth_limit_m=limits,
        quantiles=depth_quantiles(ordered, presorted=True),
        recommended=rec["recommended"],
        level=level,
        method=method,
        modal_fits=result.modal_fits,
        pointwise=rec["pointwise"],
        alternatives=rec["alternatives"],
        note=rec["note"],
        method_info=result.info,
        envelope=level_limit(ordered, level, presorted=True),
        median_recommended=median,
    )
