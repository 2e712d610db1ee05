"""Compiled lower envelope of the zero-order lobe segments (:mod:`bayes_rcsa.stability.zoa`).

Every (draw, line pair, eigenvalue branch, lobe) segment covers a few grid speeds; the stability limit at a
grid speed is the lowest segment over it.  The numpy version materialised every (segment, grid speed) pair
(about 10^8 for 500 draws at 1 rpm steps) and sorted them: memory-bound and 20-40x slower than this loop,
which keeps one running minimum per (draw, speed) and visits each pair once.

The arithmetic (segment speeds, the interpolation parameter, the interpolated depth and chatter frequency) is
written exactly as the numpy version wrote it, and ties keep the first segment in (line, branch, lobe) order
as its stable sort did, so the results are bitwise identical.  The transcendental part (arctan of the
eigenvalues) stays in numpy, outside, for the same reason.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["lower_envelope"]


@njit(cache=True, nogil=True, inline="always")
def _search(speeds, x, right, uniform, n0, step):  # pragma: no cover - compiled
    """``searchsorted(speeds, x, side="right" if right else "left")``: O(1) from a guess on a uniform grid
    (walked to the exact position, so ties land as numpy puts them), else binary search."""
    if not uniform:
        return np.searchsorted(speeds, x, side="right") if right else np.searchsorted(speeds, x, side="left")
    m = speeds.size
    g = (x - n0) / step
    i = 0 if g <= 0.0 else (m if g >= m else int(g))
    # left: the first speed >= x; right: the first speed > x
    while i > 0 and (speeds[i - 1] > x or (not right and speeds[i - 1] == x)):
        i -= 1
    while i < m and (speeds[i] < x or (right and speeds[i] == x)):
        i += 1
    return i


@njit(cache=True, nogil=True)
def lower_envelope(depth_pts, eps, omega, f, flutes, lobes, speeds, uniform, depth, chat, lobe,
                   track):  # pragma: no cover - compiled
    """Fill the lower envelope of all lobe segments in place.

    Parameters
    ----------
    depth_pts : (D, F, 2) m, 1/(2 Re μ) per line and branch; +inf where Re μ <= 0 (no segment ends there)
    eps : (D, F, 2) rad, phase ε = π + 2 arctan κ per line and branch
    omega : (F,) rad/s
    f : (F,) Hz
    flutes : int
    lobes : int, K
    speeds : (S,) rpm, increasing
    uniform : bool, ``speeds`` is an equally spaced grid (index guesses in O(1))
    depth : (D, S) m, filled with +inf on entry; the limit on return
    chat : (D, S) Hz, nan on entry; the chatter frequency of the limiting segment (``track``)
    lobe : (D, S) int, -1 on entry; the lobe number of the limiting segment (``track``)
    track : bool, fill ``chat`` and ``lobe`` too (else they are not touched and may be any small arrays)
    """
    n_draw, n_freq = depth_pts.shape[0], depth_pts.shape[1]
    m = speeds.size
    lo_grid = speeds[0]
    hi_grid = speeds[m - 1]
    step = (hi_grid - lo_grid) / (m - 1) if m > 1 else 1.0
    two_pi = 2 * np.pi
    for d in range(n_draw):
        for j in range(n_freq - 1):
            c0 = 60.0 * omega[j]
            c1 = 60.0 * omega[j + 1]
            for b in range(2):
                y0 = depth_pts[d, j, b]
                y1 = depth_pts[d, j + 1, b]
                if not (np.isfinite(y0) and np.isfinite(y1)):
                    continue
                e0 = eps[d, j, b]
                e1 = eps[d, j + 1, b]
                for k in range(lobes):
                    x0 = c0 / (flutes * (e0 + two_pi * k))
                    x1 = c1 / (flutes * (e1 + two_pi * k))
                    lo = min(x0, x1)
                    hi = max(x0, x1)
                    if hi < lo_grid:
                        break  # speeds fall with k: every later lobe lies below the grid too
                    if lo > hi_grid:
                        continue
                    i0 = _search(speeds, lo, False, uniform, lo_grid, step)
                    i1 = _search(speeds, hi, True, uniform, lo_grid, step)
                    span = x1 - x0
                    for i in range(i0, i1):
                        x = speeds[i]
                        t = (x - x0) / span if span != 0 else 0.0
                        val = y0 + t * (y1 - y0)
                        if val < depth[d, i]:
                            depth[d, i] = val
                            if track:
                                chat[d, i] = f[j] + t * (f[j + 1] - f[j])
                                lobe[d, i] = k


@njit(cache=True, nogil=True)
def stable_fractions(lim, depths, out):  # pragma: no cover - compiled
    """P(stable) map in place: ``out[s, j] = #{d : depths[j] < lim[d, s]} / n_draws``.

    Parameters
    ----------
    lim : (D, S) m, per-draw limits (+inf allowed, no NaN)
    depths : (P,) m, increasing
    out : (S, P) float, filled on return

    One binary search per (draw, speed) puts the limit above the depths below it (a histogram per speed);
    the counts summed from the top give the map, divided by D exactly as the numpy mean divides its sum.
    """
    n_draw, n_speed = lim.shape
    n_depth = depths.size
    hist = np.zeros((n_speed, n_depth + 1), dtype=np.int64)
    for d in range(n_draw):  # draws outer: lim is read in memory order
        for s in range(n_speed):
            hist[s, np.searchsorted(depths, lim[d, s], side="left")] += 1
    for s in range(n_speed):
        acc = 0
        for j in range(n_depth - 1, -1, -1):
            acc += hist[s, j + 1]
            out[s, j] = acc / n_draw
