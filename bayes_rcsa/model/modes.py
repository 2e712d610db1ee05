"""Modes of an FRF, matched one to one between model and measurement.

The natural-frequency rule of :mod:`.natural_frequencies` takes the largest
peak.  When an FRF has two modes of similar height (a tool mode beside a
spindle or holder mode), the *most prominent* one may be a different mode in
the model and in the measurement, and "highest peak minus highest peak" is
then a difference between two different modes.  This module makes every
frequency comparison mode k against mode k:

* :func:`find_modes` lists every resonance of one FRF inside a band (the
  local maxima of ``ln|h|`` with a documented prominence), each refined with
  the same parabola as the natural-frequency rule;
* :func:`match_modes` pairs the modes of two FRFs one to one, keeping their
  order along frequency (modes of a driving-point FRF do not cross on a
  fixed grid of lines), by the smallest total cost of frequency distance and
  residue dissimilarity, with a gate beyond which two modes are not the same
  mode;
* :func:`mode_windows` and :func:`track_modes` follow each mode of a
  reference FRF (the MAP model) through a batch of FRFs (posterior draws,
  with or without measurement noise): the band is cut at the minima of
  ``|h_ref|`` between consecutive modes, and in each window the draw's mode
  is the largest ``|h|`` there, refined, or NaN when it lies on the window's
  edge (the mode left its window, which callers count).

Everything is vectorised over draws; loops run over modes only (a handful).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from .natural_frequencies import natural_frequency

__all__ = ["Mode", "find_modes", "match_modes", "mode_windows", "track_modes", "MODE_RULE",
           "MIN_PROMINENCE", "MIN_REL_HEIGHT", "MATCH_GATE"]

#: Least rise of ``ln|h|`` of a peak above the higher of the two minima that separate it from the next
#: higher peaks (scipy's prominence), natural-log units: 0.2 is a 22 % rise, ten times the standard
#: deviation of ``ln|h|`` under the 2 % relative noise of a good hammer test, so noise never makes a mode.
MIN_PROMINENCE = 0.2
#: Least peak height relative to the band's largest ``|h|``: weaker peaks carry little of the tool-point
#: dynamics and, near anti-resonances, sit in the noise floor of the measurement.
MIN_REL_HEIGHT = 0.05
#: Largest ``|ln(f_a / f_b)|`` of two modes that can be the same mode (about 22 %).
MATCH_GATE = 0.2
#: Weight of the residue dissimilarity ``|ln(R_a / R_b)|`` against the frequency distance in the matching cost.
RESIDUE_WEIGHT = 0.1

MODE_RULE = (f"modes: local maxima of ln|h| in the band with prominence >= {MIN_PROMINENCE:g} and height >= "
             f"{MIN_REL_HEIGHT:g} x the band's largest |h|, each refined by the natural-frequency parabola; "
             f"model and measured modes matched one to one in frequency order (cost |ln f_a/f_b| + "
             f"{RESIDUE_WEIGHT:g} |ln R_a/R_b|, R = peak |h| x frequency x half-power width, gate "
             f"|ln f_a/f_b| <= {MATCH_GATE:g})")


@dataclass(frozen=True)
class Mode:
    """One resonance of an FRF.

    Attributes
    ----------
    index : int
        Line of the peak (in the band's lines).
    frequency_hz : float
        Hz, parabola-refined peak of ``|h|``.
    height : float
        Peak ``|h|`` (unit of ``h``).
    width_hz : float
        Half-power width (Hz), NaN where the -3 dB level is not reached on both sides.
    lo, hi : int
        Lines of the minima of ``|h|`` separating it from its neighbours (the band's ends for the outer modes).
    """

    index: int
    frequency_hz: float
    height: float
    width_hz: float
    lo: int
    hi: int

    @property
    def residue(self) -> float:
        """Residue magnitude estimate ``|h|_peak * f * width`` (single-mode ``|A| = |h|_peak 2 zeta w^2``)."""
        w = self.width_hz if math.isfinite(self.width_hz) else 0.0
        return self.height * self.frequency_hz * w if w > 0 else self.height * self.frequency_hz

    def as_dict(self) -> dict:
        return {"frequency_hz": self.frequency_hz, "height": self.height, "width_hz": self.width_hz}


def _half_power_width(f: np.ndarray, mag: np.ndarray, i: int, lo: int, hi: int) -> float:
    level = mag[i] / math.sqrt(2.0)
    left = np.nonzero(mag[lo:i] < level)[0]
    right = np.nonzero(mag[i : hi + 1] < level)[0]
    if left.size == 0 or right.size == 0:
        return math.nan
    a = lo + left[-1]
    b = i + right[0]
    fl = np.interp(level, [mag[a], mag[a + 1]], [f[a], f[a + 1]])
    fr = np.interp(level, [mag[b], mag[b - 1]], [f[b], f[b - 1]])
    return float(fr - fl)


def find_modes(frequency_hz, h, min_prominence: float = MIN_PROMINENCE,
               min_rel_height: float = MIN_REL_HEIGHT) -> list[Mode]:
    """Every resonance of one FRF inside its lines, in increasing frequency.

    Parameters
    ----------
    frequency_hz : (n,) Hz, strictly increasing
    h : (n,) complex (or magnitude)
    min_prominence : float
        Natural-log units (:data:`MIN_PROMINENCE`).
    min_rel_height : float
        Fraction of the largest ``|h|`` (:data:`MIN_REL_HEIGHT`).

    Returns
    -------
    list of Mode; a peak on the first or last line is not a resonance inside the lines and is left out.

    Raises
    ------
    DataError
        Fewer than three lines, or a non-finite value of ``h``.
    """
    from scipy.signal import find_peaks

    f = np.asarray(frequency_hz, dtype=float)
    mag = np.abs(np.asarray(h))
    if f.ndim != 1 or mag.shape != f.shape or f.size < 3:
        raise DataError(f"find_modes: expected (n,) frequencies and values with n >= 3, got {f.shape} and {mag.shape}")
    if not np.all(np.isfinite(mag)):
        raise DataError("find_modes: the FRF has non-finite values")
    top = float(mag.max())
    if top <= 0:
        return []
    with np.errstate(divide="ignore"):
        y = np.log(mag)
    y = np.where(np.isfinite(y), y, np.log(top) - 50.0)
    peaks, _ = find_peaks(y, prominence=min_prominence, height=math.log(min_rel_height * top))
    peaks = [int(p) for p in peaks if 0 < p < f.size - 1]
    modes = []
    for k, p in enumerate(peaks):
        lo = 0 if k == 0 else peaks[k - 1] + int(np.argmin(mag[peaks[k - 1] : p + 1]))
        hi = f.size - 1 if k == len(peaks) - 1 else p + int(np.argmin(mag[p : peaks[k + 1] + 1]))
        fr = float(natural_frequency(f[p - 1 : p + 2], mag[p - 1 : p + 2])) if 0 < p < f.size - 1 else math.nan
        modes.append(Mode(p, fr, float(mag[p]), _half_power_width(f, mag, p, lo, hi), lo, hi))
    return modes


def match_modes(a: list[Mode], b: list[Mode], gate: float = MATCH_GATE,
                residue_weight: float = RESIDUE_WEIGHT) -> list[tuple[int, int]]:
    """One-to-one, order-preserving pairing of the modes ``a`` and ``b`` (each in increasing frequency).

    Dynamic programming over the two ordered lists (sequence alignment): a pair ``(i, j)`` costs
    ``|ln(f_i / f_j)| + residue_weight |ln(R_i / R_j)|`` and is allowed only when ``|ln(f_i / f_j)| <= gate``;
    leaving a mode unpaired costs ``gate``, so two modes inside the gate are always paired rather than both
    left out, and the pairing with the least total cost wins.

    Returns
    -------
    list of (i, j) index pairs, increasing in both.
    """
    na, nb = len(a), len(b)
    big = math.inf
    cost = np.full((na + 1, nb + 1), big)
    move = np.zeros((na + 1, nb + 1), dtype=int)  # 0 pair, 1 skip a, 2 skip b
    cost[0, :] = gate * np.arange(nb + 1)
    cost[:, 0] = gate * np.arange(na + 1)
    move[1:, 0], move[0, 1:] = 1, 2
    for i in range(1, na + 1):
        for j in range(1, nb + 1):
            best, how = cost[i - 1, j] + gate, 1
            if cost[i, j - 1] + gate < best:
                best, how = cost[i, j - 1] + gate, 2
            d = abs(math.log(a[i - 1].frequency_hz / b[j - 1].frequency_hz))
            if d <= gate:
                c = d + residue_weight * abs(math.log(a[i - 1].residue / b[j - 1].residue))
                if cost[i - 1, j - 1] + c <= best:
                    best, how = cost[i - 1, j - 1] + c, 0
            cost[i, j], move[i, j] = best, how
    pairs = []
    i, j = na, nb
    while i > 0 or j > 0:
        how = move[i, j]
        if how == 0:
            pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif how == 1:
            i -= 1
        else:
            j -= 1
    return pairs[::-1]


def mode_windows(modes: list[Mode]) -> list[tuple[int, int]]:
    """Line windows ``(lo, hi)`` (inclusive) of each mode: cut at the minima between consecutive modes."""
    return [(m.lo, m.hi) for m in modes]


def track_modes(frequency_hz, h, windows: list[tuple[int, int]]) -> np.ndarray:
    """Frequency of each windowed mode in a batch of FRFs.

    Parameters
    ----------
    frequency_hz : (n,) Hz
    h : (..., n) complex, e.g. (n_draws, n) posterior draws
    windows : list of (lo, hi) line indices, from :func:`mode_windows` of a reference FRF

    Returns
    -------
    (..., n_modes) Hz; NaN where a draw's largest ``|h|`` in a window lies on its first or last line.
    """
    f = np.asarray(frequency_hz, dtype=float)
    h = np.asarray(h)
    out = np.full(h.shape[:-1] + (len(windows),), np.nan)
    for k, (lo, hi) in enumerate(windows):
        if hi - lo + 1 < 3:
            continue
        out[..., k] = natural_frequency(f[lo : hi + 1], h[..., lo : hi + 1])
    return out
