"""Robust operating-point recommendation from per-draw stability limits.

The recommended point maximises the material removal rate index a·n (a_p a_e
f_z N n at fixed radial depth and feed per tooth) subject to

    P(stable | n', a') >= level  for every n' in [n (1 - t_n), n (1 + t_n)]
                                  and every a' <= a (1 + m_a), at every K in [K (1 - t_K), K (1 + t_K)]

with the spindle-speed tolerance t_n (default ±2 %: nobody holds a spindle
to the rpm), the depth margin m_a (default 10 %) and an optional tolerance
t_K on the cutting-force level (K_t and K_r scaled together; the limit
depth of every draw scales exactly as 1/K, so the worst case is K (1 + t_K)).
P(stable | n, a) = #{d : a < a_lim,d(n)}/N is computed directly from the
per-draw limits, so the result does not depend on any depth grid:

    a_level(n) = the ceil(level N)-th largest a_lim,d(n)      (P >= level  <=>  a < a_level)
    a_rob(n)   = min_{|n' - n| <= t_n n} a_level(n') / (1 + t_K)
    a(n)       = min(a_rob(n) / (1 + m_a), user depth limits)

Only speeds whose whole tolerance window lies inside the analysed range are
candidates (the range is a user limit: when the optimum sits at its end the
result says so).  The window minimum is taken on the speed grid and then
verified on a fine grid around the best candidates (``limits_at``), because
the sharp cusps between lobes can fall between grid speeds.

Also reported: the point-wise optimum (no tolerance, no margin) for
comparison, the margins to the nearest unstable region (rpm below and above
at the recommended depth; m above it at the recommended speed), the limit
that binds ("stability", "max_depth", "flute_length", "speed_range") and the
best point of each of the three largest stable pockets (regions under one
lobe, between two cusps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError

__all__ = ["Tolerances", "Recommendation", "level_limit", "recommend", "DEFAULT_SPEED_TOLERANCE",
           "DEFAULT_DEPTH_MARGIN"]

DEFAULT_SPEED_TOLERANCE = 0.02
DEFAULT_DEPTH_MARGIN = 0.10
_FINE_POINTS = 41
# the checked neighbourhood stays strictly inside the stable set (P uses a < a_lim): a relative gap of 1e-6
_INSIDE = 1.0 + 1e-6
_VERIFY_CANDIDATES = 12


@dataclass(frozen=True)
class Tolerances:
    """Neighbourhood of a robust operating point.

    Attributes
    ----------
    speed_rel : float in [0, 0.5), ± relative spindle-speed tolerance
    depth_margin : float in (0, 1], relative depth margin (the neighbourhood reaches a (1 + margin))
    force_rel : float in [0, 0.5), ± relative tolerance of the cutting-force level (K_t, K_r together)
    """

    speed_rel: float = DEFAULT_SPEED_TOLERANCE
    depth_margin: float = DEFAULT_DEPTH_MARGIN
    force_rel: float = 0.0

    def __post_init__(self) -> None:
        if not (0.0 <= self.speed_rel < 0.5):
            raise SetupError(f"speed tolerance {self.speed_rel!r}: expected a fraction in [0, 0.5)")
        if not (0.0 < self.depth_margin <= 1.0):
            raise SetupError(f"depth margin {self.depth_margin!r}: expected a fraction in (0, 1]")
        if not (0.0 <= self.force_rel < 0.5):
            raise SetupError(f"cutting-coefficient tolerance {self.force_rel!r}: expected a fraction in [0, 0.5)")


@dataclass(frozen=True)
class Recommendation:
    """A recommended operating point and its margins.

    Attributes
    ----------
    spindle_speed_rpm, depth_m : float
    p_stable : float, P(stable) at the point (nominal cutting coefficients)
    p_stable_neighbourhood : float, smallest P(stable) over the checked neighbourhood (>= level)
    mrr_index : float, m·rpm
    speed_window_rpm : (lo, hi) rpm, the spindle-speed tolerance window
    depth_checked_m : float, m, top of the checked neighbourhood a (1 + margin)
    margin_speed_rpm : (below, above) rpm to the nearest speed where the recommended depth is no longer
        stable at the level (None: not inside the analysed range)
    margin_depth_m : float, m, distance to the level contour straight above the point
    binding : str, the limit that sets the depth ("stability", "max_depth", "flute_length") and, when the
        tolerance window touches the end of the analysed speed range, "+speed_range"
    tolerances : Tolerances
    """

    spindle_speed_rpm: float
    depth_m: float
    p_stable: float
    mrr_index: float
    p_stable_neighbourhood: float = 1.0
    speed_window_rpm: tuple = (math.nan, math.nan)
    depth_checked_m: float = math.nan
    margin_speed_rpm: tuple = (None, None)
    margin_depth_m: float = math.nan
    binding: str = "stability"
    tolerances: Tolerances = field(default_factory=Tolerances)

    def as_dict(self) -> dict:
        """JSON-able record (SI units, rpm)."""
        return {
            "spindle_speed_rpm": self.spindle_speed_rpm,
            "depth_m": self.depth_m,
            "p_stable": self.p_stable,
            "p_stable_neighbourhood": self.p_stable_neighbourhood,
            "mrr_index": self.mrr_index,
            "speed_tolerance_rel": self.tolerances.speed_rel,
            "speed_window_rpm": list(self.speed_window_rpm),
            "depth_margin_rel": self.tolerances.depth_margin,
            "depth_checked_m": self.depth_checked_m,
            "cutting_force_tolerance_rel": self.tolerances.force_rel,
            "margin_speed_rpm": {"below": self.margin_speed_rpm[0], "above": self.margin_speed_rpm[1]},
            "margin_depth_m": self.margin_depth_m,
            "binding_limit": self.binding,
        }


def level_limit(depth_limit_m, level: float, presorted: bool = False) -> np.ndarray:
    """a_level(n): the depth below which P(stable) >= level, (n_speed,) m.

    P(stable | a) = #{d : a < a_lim,d}/N >= level  <=>  a < the k-th largest a_lim,d, k = ceil(level N).
    ``presorted``: the limits are already sorted over the draws (axis 0, increasing), as
    :func:`~bayes_rcsa.stability.probabilistic.lobes_from_frf_draws` passes them (no partial sort then).
    """
    if not (0.0 < level <= 1.0):
        raise SetupError(f"level={level!r}: expected a probability in (0, 1]")
    lim = np.atleast_2d(np.asarray(depth_limit_m, dtype=float))
    n = lim.shape[0]
    k = int(math.ceil(level * n - 1e-9))
    if presorted:
        return lim[n - k]
    # the k-th largest = the (n - k)-th smallest (0-based): a partial sort, the same value as a full one
    return np.partition(lim, n - k, axis=0)[n - k]


def _p_stable(lim: np.ndarray, a: float) -> float:
    return float(np.mean(a < lim))


def _window_min(n: np.ndarray, a: np.ndarray, tol: float) -> np.ndarray:
    """min of a over [n_i (1 - tol), n_i (1 + tol)] on the grid, (n_speed,).

    A sparse table of minima over 2^j consecutive speeds answers every window with two lookups (the window
    is the union of two overlapping power-of-two blocks): O(n log n), no loop over speeds.
    """
    lo = np.searchsorted(n, n * (1 - tol) - 1e-9 * n, side="left")
    hi = np.searchsorted(n, n * (1 + tol) + 1e-9 * n, side="right")
    length = hi - lo  # >= 1: every window holds its own speed
    levels = [np.asarray(a, dtype=float)]
    while (1 << len(levels)) <= int(length.max()):
        prev, half = levels[-1], 1 << (len(levels) - 1)
        levels.append(np.minimum(prev[:-half], prev[half:]))
    j = np.floor(np.log2(length)).astype(int)
    j = np.where((1 << (j + 1)) <= length, j + 1, j)  # guard log2 rounding at exact powers of two
    j = np.where((1 << j) > length, j - 1, j)
    out = np.empty(n.size)
    for level in np.unique(j):  # one pass per power of two (at most log2 of the widest window)
        sel = j == level
        table = levels[level]
        out[sel] = np.minimum(table[lo[sel]], table[hi[sel] - (1 << level)])
    return out


def _pockets(n: np.ndarray, a: np.ndarray, ok: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [i0, i1] of the stable pockets: between cusps (local minima) of a, merging shallow dips."""
    finite = np.isfinite(a) & ok
    idx = np.nonzero(finite)[0]
    if idx.size == 0:
        return []
    # split at gaps (inadmissible or unknown speeds) and at cusps
    runs = np.split(idx, np.nonzero(np.diff(idx) > 1)[0] + 1)
    pockets = []
    for run in runs:
        v = a[run]
        cuts = [0]
        for j in range(1, v.size - 1):
            if v[j] < v[j - 1] and v[j] <= v[j + 1]:
                left, right = v[cuts[-1] : j + 1].max(), v[j:].max()
                if v[j] < 0.8 * min(left, right):  # a real cusp, not a ripple of the quantile
                    cuts.append(j)
        cuts.append(v.size - 1)
        for c0, c1 in zip(cuts[:-1], cuts[1:]):
            pockets.append((int(run[c0]), int(run[c1])))
    return pockets


def recommend(
    speed_rpm,
    depth_limit_m,
    level: float = 0.95,
    tolerances: Tolerances | None = None,
    max_depth: float | None = None,
    flute_length: float | None = None,
    limits_at=None,
    presorted: bool = False,
) -> dict:
    """Robust recommendation, point-wise optimum and alternatives.

    Parameters
    ----------
    speed_rpm : (n_speed,) rpm, increasing (the analysed range, a user limit)
    depth_limit_m : (n_draws, n_speed) m, per-draw limits (+inf: none found)
    level : float in (0, 1]
    tolerances : Tolerances (default ±2 % speed, 10 % depth margin, no force tolerance)
    max_depth, flute_length : float m or None, user/tool depth limits
    limits_at : callable (speeds (k,) rpm) -> (n_draws, k) m, or None
        Evaluates the limits between grid speeds to verify the window minimum.
    presorted : bool, ``depth_limit_m`` is sorted over the draws (axis 0); every use here counts draws or
        takes an order statistic, so the result is the same, without re-sorting

    Returns
    -------
    dict with "recommended" (Recommendation or None), "pointwise" (Recommendation or None),
    "alternatives" (list of dicts) and "note" (str, why there is no recommendation).
    """
    tol = Tolerances() if tolerances is None else tolerances
    n = np.asarray(speed_rpm, dtype=float)
    lim = np.atleast_2d(np.asarray(depth_limit_m, dtype=float))
    if lim.shape[1] != n.size or n.size < 2 or np.any(np.diff(n) <= 0):
        raise SetupError("recommend: speeds must increase and match the limits' columns")
    if np.any(np.isnan(lim)):
        raise SetupError("depth limits contain NaN; cannot recommend an operating point")
    caps = [(v, name) for v, name in ((max_depth, "max_depth"), (flute_length, "flute_length")) if v is not None]
    for v, name in caps:
        if not (math.isfinite(v) and v > 0):
            raise SetupError(f"{name}={v!r}: expected a depth > 0 in m")
    cap = min([v for v, _ in caps], default=math.inf)
    a_lvl = level_limit(lim, level, presorted)
    kf = 1.0 + tol.force_rel
    inside = (n * (1 - tol.speed_rel) >= n[0] * (1 - 1e-12)) & (n * (1 + tol.speed_rel) <= n[-1] * (1 + 1e-12))
    a_rob = _window_min(n, a_lvl / kf, tol.speed_rel)
    usable = inside & np.isfinite(a_rob) & (a_rob > 0)
    depth = np.where(usable, np.minimum(a_rob / ((1 + tol.depth_margin) * _INSIDE), cap), -np.inf)
    score = n * depth
    verified = np.zeros(n.size, dtype=bool)
    best = None
    for _ in range(_VERIFY_CANDIDATES):
        if not np.any(np.isfinite(score)):
            break
        i = int(np.argmax(score))
        if verified[i]:
            best = i
            break
        if limits_at is not None and tol.speed_rel > 0:
            # about 4 checks per grid step across the window (at most _FINE_POINTS, at least 5)
            step = float(np.min(np.diff(n)))
            k_fine = int(np.clip(np.ceil(8 * tol.speed_rel * n[i] / step) + 1, 5, _FINE_POINTS))
            fine = np.linspace(n[i] * (1 - tol.speed_rel), n[i] * (1 + tol.speed_rel), k_fine)
            a_f = level_limit(np.atleast_2d(limits_at(fine)), level) / kf
            a_rob[i] = min(a_rob[i], float(np.min(a_f)))
            if not (np.isfinite(a_rob[i]) and a_rob[i] > 0):
                score[i] = -np.inf
                continue
            depth[i] = min(a_rob[i] / ((1 + tol.depth_margin) * _INSIDE), cap)
            score[i] = n[i] * depth[i]
        verified[i] = True
    else:
        best = int(np.argmax(score)) if np.any(np.isfinite(score)) else None
    out = {"recommended": None, "pointwise": None, "alternatives": [], "note": ""}
    if best is None or not np.isfinite(score[best]):
        out["note"] = (f"no speed whose ±{100 * tol.speed_rel:g} % window lies inside the analysed range reaches "
                       f"P(stable) >= {level:g} with a finite stability limit")
    else:
        out["recommended"] = _describe(n, lim, a_lvl, kf, best, depth[best], a_rob[best], tol, level, cap, caps)
    # point-wise optimum: P(stable) >= level at the point only
    a_pt = np.where(np.isfinite(a_lvl) & (a_lvl > 0), np.minimum(a_lvl * (1 - 1e-9), cap), -np.inf)
    if np.any(np.isfinite(a_pt)):
        j = int(np.argmax(n * a_pt))
        out["pointwise"] = Recommendation(float(n[j]), float(a_pt[j]), _p_stable(lim[:, j], a_pt[j]),
                                          float(n[j] * a_pt[j]),
                                          binding="stability" if a_pt[j] < cap else _cap_name(caps, cap),
                                          tolerances=Tolerances(0.0, 1.0, 0.0))
    # best robust point of each of the three largest pockets (area under a_level over the pocket)
    pockets = _pockets(n, a_lvl, np.isfinite(a_lvl))
    ranked = []
    for i0, i1 in pockets:
        seg = slice(i0, i1 + 1)
        area = float(np.trapezoid(a_lvl[seg], n[seg])) if i1 > i0 else 0.0
        cand = np.arange(i0, i1 + 1)[np.isfinite(score[seg])]
        if cand.size == 0:
            continue
        k = int(cand[np.argmax(score[cand])])
        ranked.append((area, i0, i1, k))
    ranked.sort(reverse=True)
    for area, i0, i1, k in ranked[:3]:
        rec = out["recommended"]
        out["alternatives"].append({
            "pocket_rpm": [float(n[i0]), float(n[i1])],
            "pocket_area_m_rpm": area,
            "spindle_speed_rpm": float(n[k]),
            "depth_m": float(depth[k]),
            "mrr_index": float(score[k]),
            "contains_recommended": bool(rec is not None and n[i0] <= rec.spindle_speed_rpm <= n[i1]),
        })
    return out


def _cap_name(caps, cap):
    return min(caps, key=lambda c: c[0])[1] if caps else "stability"


def _describe(n, lim, a_lvl, kf, i, a, a_rob_i, tol, level, cap, caps) -> Recommendation:
    lo, hi = n[i] * (1 - tol.speed_rel), n[i] * (1 + tol.speed_rel)
    win = (n >= lo - 1e-9 * lo) & (n <= hi + 1e-9 * hi)
    top = a * (1 + tol.depth_margin)
    p_neigh = min(_p_stable(lim[:, j] / kf, top) for j in np.nonzero(win)[0])
    binding = "stability" if a_rob_i / ((1 + tol.depth_margin) * _INSIDE) <= cap else _cap_name(caps, cap)
    cand = np.nonzero((n * (1 - tol.speed_rel) >= n[0] * (1 - 1e-12)) & (n * (1 + tol.speed_rel) <= n[-1] * (1 + 1e-12)))[0]
    if cand.size and i in (cand[0], cand[-1]):  # the first or last speed whose window fits in the range
        binding += "+speed_range"
    # nearest speed, below and above, where depth a is no longer stable at the level
    bad = ~(a < a_lvl / kf)
    below = np.nonzero(bad[:i])[0]
    above = np.nonzero(bad[i + 1 :])[0]
    m_below = float(n[i] - n[below[-1]]) if below.size else None
    m_above = float(n[i + 1 + above[0]] - n[i]) if above.size else None
    return Recommendation(
        spindle_speed_rpm=float(n[i]), depth_m=float(a), p_stable=_p_stable(lim[:, i], a), mrr_index=float(n[i] * a),
        p_stable_neighbourhood=float(p_neigh), speed_window_rpm=(float(lo), float(hi)), depth_checked_m=float(top),
        margin_speed_rpm=(m_below, m_above), margin_depth_m=float(a_lvl[i] / kf - a), binding=binding, tolerances=tol,
    )
