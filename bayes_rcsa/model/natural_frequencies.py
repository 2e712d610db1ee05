"""The natural-frequency rule, applied identically to measured and predicted FRFs.

Rule
----
Within the frequency band ``[lo, hi]`` (default: the whole grid), the
natural frequency of the dominant mode is the location of the largest
``|h|``, refined by the vertex of the parabola through ``ln|h|`` at that
line and its two neighbours (exact for any grid spacing, uniform or not).
A maximum on the first or last line of the band is not a resonance inside
the band and gives ``NaN`` (callers report how many draws did so instead
of clipping them to the band edge).

Measured and predicted FRFs must be evaluated on the same frequency lines
for the comparison to be fair: the parabolic refinement removes most, but
not all, of the grid quantisation, and the same residual bias then affects
both.  The function is vectorised over any leading axes (posterior draws).
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError

__all__ = ["natural_frequency", "NATURAL_FREQUENCY_RULE"]

NATURAL_FREQUENCY_RULE = (
    "frequency of the largest |h| within the band, refined by the vertex of the parabola through ln|h| "
    "at that line and its two neighbours; NaN if the maximum is on a band edge"
)


def natural_frequency(frequency_hz, h, band: tuple[float, float] | None = None) -> np.ndarray:
    """Natural frequency of the dominant mode of FRFs ``h``.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz, strictly increasing
    h : (..., n_freq) complex (or real magnitude), receptance
    band : (lo, hi) Hz, optional
        Restrict the search to these lines.

    Returns
    -------
    (...) float, Hz; NaN where the maximum lies on the first or last line of
    the band.

    Raises
    ------
    DataError
        If fewer than three lines lie in the band.
    """
    f = np.asarray(frequency_hz, dtype=float)
    h = np.asarray(h)
    if band is not None:
        mask = (f >= band[0]) & (f <= band[1])
        f = f[mask]
        h = h[..., mask]
    if f.size < 3:
        raise DataError(f"natural frequency: {f.size} lines in the band, at least 3 are needed")
    mag = np.abs(h)
    i = np.argmax(mag, axis=-1)
    edge = (i == 0) | (i == f.size - 1)
    ic = np.clip(i, 1, f.size - 2)  # edge cases are replaced by NaN below
    # ln|h| of the three lines only (an elementwise log: the values of the log of every line, at a fraction of it)
    y3 = np.take_along_axis(mag, ic[..., None] + np.arange(-1, 2), axis=-1)
    with np.errstate(divide="ignore"):
        y3 = np.log(y3)
    y0, y1, y2 = y3[..., 0], y3[..., 1], y3[..., 2]
    u0 = f[ic - 1] - f[ic]
    u2 = f[ic + 1] - f[ic]
    d0, d2 = y0 - y1, y2 - y1
    det = u0 * u2 * (u0 - u2)
    a = (d0 * u2 - d2 * u0) / det
    b = (d2 * u0**2 - d0 * u2**2) / det
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = np.where(a < 0, -b / (2 * a), 0.0)
    # the vertex of a concave parabola through a maximum lies between the neighbours
    shift = np.where(np.isfinite(shift), shift, 0.0)
    out = f[ic] + shift
    return np.where(edge, np.nan, out)
