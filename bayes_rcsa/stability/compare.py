"""Comparison of stability predictions (the paper's Tables 8 and 9).

Table 9 of the paper rates a predicted lobe diagram by the share of points
on which it disagrees with the diagram computed from the measured FRFs; all
its entries are multiples of 1/75, i.e. the 75 cutting-test points of a case
(15 speeds x the 5 depths of Table 2).  Table 8 rates a diagram by the share
of test points whose observed outcome it mispredicts.  Both are provided
here, for points or for whole grids.
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError

__all__ = ["stable_at", "disagreement", "test_error", "limits_disagreement"]


def stable_at(speed_rpm, depth_limit_m, point_speed_rpm, point_depth_m) -> np.ndarray:
    """Predicted stability at arbitrary points from a lobe a_lim(n).

    The limit is interpolated linearly in speed; next to an infinite limit (no
    chatter found in the FRF band) the nearer grid speed's limit is used.

    Parameters
    ----------
    speed_rpm : (n_speed,) rpm, increasing
    depth_limit_m : (n_speed,) m
    point_speed_rpm, point_depth_m : (n_point,) rpm, m, speeds inside the lobe's range

    Returns
    -------
    (n_point,) bool
    """
    n = np.asarray(speed_rpm, dtype=float)
    lim = np.asarray(depth_limit_m, dtype=float)
    ps = np.atleast_1d(np.asarray(point_speed_rpm, dtype=float))
    pd = np.atleast_1d(np.asarray(point_depth_m, dtype=float))
    if np.any(ps < n[0]) or np.any(ps > n[-1]):
        raise DataError(f"test speeds {ps.min():g}-{ps.max():g} rpm lie outside the lobe range {n[0]:g}-{n[-1]:g} rpm")
    j = np.clip(np.searchsorted(n, ps, side="right") - 1, 0, n.size - 2) if n.size > 1 else np.zeros(ps.size, int)
    if n.size == 1:
        return pd < lim[0]
    t = (ps - n[j]) / (n[j + 1] - n[j])
    a0, a1 = lim[j], lim[j + 1]
    nearest = np.where(t > 0.5, a1, a0)
    with np.errstate(invalid="ignore"):
        val = np.where(np.isinf(a0) | np.isinf(a1), nearest, a0 + t * (a1 - a0))
    return pd < val


def disagreement(stable_a, stable_b) -> float:
    """Fraction of points (or grid cells) on which two stability predictions differ.

    Parameters
    ----------
    stable_a, stable_b : bool arrays of equal shape

    Returns
    -------
    float in [0, 1]
    """
    a = np.asarray(stable_a, dtype=bool)
    b = np.asarray(stable_b, dtype=bool)
    if a.shape != b.shape or a.size == 0:
        raise DataError(f"stability maps of shapes {a.shape} and {b.shape} cannot be compared")
    return float(np.mean(a != b))


def limits_disagreement(depth_limit_a, depth_limit_b, depth_m) -> float:
    """Table-9 style deviation of two lobes on a (speed x depth) grid.

    Each lobe (n_speed,) defines the map a < a_lim; returns the fraction of
    grid points on which the maps differ.
    """
    a = np.asarray(depth_m, dtype=float)
    la = np.asarray(depth_limit_a, dtype=float)[:, None]
    lb = np.asarray(depth_limit_b, dtype=float)[:, None]
    return disagreement(a[None, :] < la, a[None, :] < lb)


def test_error(predicted_stable, observed_stable) -> float:
    """Table-8 style test error: share of cutting tests whose outcome is mispredicted."""
    return disagreement(predicted_stable, observed_stable)


test_error.__test__ = False  # not a pytest test despite its name
