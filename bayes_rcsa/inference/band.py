"""Frequency band of the likelihood: the default rule and user overrides.

Default rule (applied to each measured tool-point FRF separately)
-----------------------------------------------------------------
1. The dominant peak ``f_d`` is the line of largest ``|H|`` in the file.
2. The *dominant tool modes* are the local maxima of ``|H|`` that reach at
   least ``rel_height`` (default 0.5) of that peak and lie within a factor
   of two of ``f_d``, so a close pair of modes (as at 40 mm clamping in
   the reference paper) is kept together.
3. The band runs from the lowest of those peaks divided by ``ratio`` to the
   highest multiplied by ``ratio`` (default 1.25, i.e. about -20 %/+25 %
   around a single peak), intersected with the file's frequency range.

The tool modes carry the information about the contact; lines far from
them mostly reflect the spindle receptance, whose errors would otherwise be
read as contact information.  An explicit ``[lo, hi]`` (setup
``[likelihood] band`` or ``--band``) replaces the rule for every
measurement.  A band that contains no line of a file is an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError, SetupError
from ..model.receptance import FRF

__all__ = ["Band", "default_band", "resolve_band", "band_mask", "band_peak_warning", "MIN_LINES", "PEAK_WINDOW"]

MIN_LINES = 3


@dataclass(frozen=True)
class Band:
    """A closed frequency interval ``[lo_hz, hi_hz]`` and how it was chosen.

    Attributes
    ----------
    lo_hz, hi_hz : float
        Hz.
    rule : str
        ``"default"`` or ``"user"`` (for the record in summary.json).
    """

    lo_hz: float
    hi_hz: float
    rule: str = "default"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lo_hz) and np.isfinite(self.hi_hz) and 0 <= self.lo_hz < self.hi_hz):
            raise SetupError(f"frequency band [{self.lo_hz!r}, {self.hi_hz!r}] Hz: expected finite 0 <= lo < hi")

    def as_dict(self) -> dict:
        return {"lo_hz": self.lo_hz, "hi_hz": self.hi_hz, "rule": self.rule}


def default_band(frf: FRF, rel_height: float = 0.5, ratio: float = 1.25) -> Band:
    """The documented default band around the dominant tool modes of ``frf``.

    Parameters
    ----------
    frf : FRF
    rel_height : float
        Peaks reaching this fraction of the largest ``|H|`` count as dominant.
    ratio : float
        > 1, multiplicative margin below the lowest and above the highest
        dominant peak.

    Returns
    -------
    Band
    """
    if not ratio > 1:
        raise SetupError(f"band ratio = {ratio!r}: expected > 1")
    f = frf.frequency_hz
    mag = np.abs(frf.values)
    i_max = int(np.argmax(mag))
    f_d = f[i_max]
    interior = np.zeros(mag.size, dtype=bool)
    if mag.size >= 3:
        interior[1:-1] = (mag[1:-1] >= mag[:-2]) & (mag[1:-1] >= mag[2:])
    interior[i_max] = True
    peaks = interior & (mag >= rel_height * mag[i_max]) & (f >= f_d / 2) & (f <= 2 * f_d)
    lo = max(f[peaks].min() / ratio, f[0])
    hi = min(f[peaks].max() * ratio, f[-1])
    if not lo < hi:
        raise DataError(f"{frf.source}: cannot form a frequency band around the peak at {f_d:g} Hz (one line only?)")
    return Band(float(lo), float(hi), "default")


def resolve_band(frf: FRF, user_band: tuple[float, float] | None, **rule) -> Band:
    """The band for one measurement: the user's ``[lo, hi]`` or the default rule."""
    if user_band is None:
        return default_band(frf, **rule)
    lo, hi = user_band
    return Band(float(lo), float(hi), "user")


def band_mask(frf: FRF, band: Band) -> np.ndarray:
    """Boolean mask (n_freq,) of the lines of ``frf`` inside ``band``.

    Raises
    ------
    DataError
        If the band contains fewer than ``MIN_LINES`` (3) lines of the file:
        a peak cannot be located, nor a contact identified, from fewer.
    """
    f = frf.frequency_hz
    mask = (f >= band.lo_hz) & (f <= band.hi_hz)
    n = int(np.count_nonzero(mask))
    if n < MIN_LINES:
        what = "no frequency line" if n == 0 else f"only {n} frequency line(s)"
        raise DataError(
            f"{frf.source}: the frequency band {band.lo_hz:g}-{band.hi_hz:g} Hz contains {what} "
            f"(file covers {f[0]:g}-{f[-1]:g} Hz; at least {MIN_LINES} lines are needed)"
        )
    return mask


#: Half-width of the window around the model's predicted tool mode in which the measured peak is sought (relative).
PEAK_WINDOW = 0.2


def band_peak_warning(frf: FRF, band: Band, model_peak_hz: float | None = None) -> str | None:
    """A warning when the band leaves out the peak that carries the contact information, else ``None``.

    Rule: warn when the band does not contain (a) the largest peak of the
    measurement (the line of largest ``|H|`` in the file), or (b) the largest
    measured peak within ``+-PEAK_WINDOW`` (20 %) of ``model_peak_hz``, the
    model's predicted tool mode at the optimum.  A fit to a band without
    the tool mode reports a natural frequency and stiffness that describe
    some other part of the spectrum.

    Parameters
    ----------
    frf : FRF
        The whole measurement.
    band : Band
    model_peak_hz : float, optional
        Frequency of the model's largest ``|H|`` on the measured lines.
    """
    f = frf.frequency_hz
    mag = np.abs(frf.values)
    inside = lambda x: band.lo_hz <= x <= band.hi_hz  # noqa: E731
    problems = []
    top = float(f[int(np.argmax(mag))])
    if not inside(top):
        problems.append(f"the measurement's largest peak at {top:.6g} Hz")
    if model_peak_hz is not None and np.isfinite(model_peak_hz):
        near = (f >= model_peak_hz * (1 - PEAK_WINDOW)) & (f <= model_peak_hz * (1 + PEAK_WINDOW))
        if np.any(near):
            peak = float(f[near][int(np.argmax(mag[near]))])
            if not inside(peak) and abs(peak - top) > 1e-9 * top:
                problems.append(f"the measured peak at {peak:.6g} Hz next to the model's tool mode "
                                f"({model_peak_hz:.6g} Hz at the optimum)")
    if not problems:
        return None
    return (f"{frf.source}: the likelihood band {band.lo_hz:.6g}-{band.hi_hz:.6g} Hz ({band.rule}) leaves out "
            f"{' and '.join(problems)}; the fit then describes another part of the spectrum, not the tool mode "
            f"(check --band / [likelihood] band)")
