"""The relative noise level of a measured FRF, estimated from the FRF alone; the per-line noise model.

Estimator (:func:`relative_noise_scale`)
----------------------------------------
Second differences ``d_i = h_{i-1} - 2 h_i + h_{i+1}`` of a smooth FRF are small wherever the FRF varies slowly
over three lines; circular complex noise of relative standard deviation ``sigma`` (``E|e_i|^2 = sigma^2
|h_i|^2``) gives ``E|d_i|^2 = 6 sigma^2 |h_i|^2`` and ``|d_i|^2 / (6 sigma^2 |h_i|^2)`` exponentially
distributed, whose median is ``ln 2``::

    sigma = sqrt(median_i |d_i|^2 / (6 |h_i|^2) / ln 2)

The median over the band is robust to the few lines near a sharp peak or an antiresonance where the FRF's own
curvature dominates (Rice 1984 uses first differences the same way for a regression's noise variance).

Why second and not third differences (decision of issue #41, ``benchmarks/noise_estimator.py``)
-----------------------------------------------------------------------------------------------
Two estimators existed: these second differences (discrepancy workflow) and third differences ``D_k = H_{k+3} -
3 H_{k+2} + 3 H_{k+1} - H_k`` normalised by ``sqrt(sum_j c_j^2 |H_{k+j}|^2)`` (spindle identification).  On
simulated FRFs with known relative noise (200 realisations each; one lightly damped mode, two modes, six modes
with antiresonances, the synthetic bench's tool-point FRF and its spindle flange receptance; bias = mean of
estimate / truth - 1, spread = its standard deviation):

* on the spindle workflow's grid (3801 lines, 200-4000 Hz in 1-Hz steps) both are unbiased within the spread:
  flange receptance, 0.5 % noise: bias +0.4 % (second) / -0.1 % (third), spread 1.4 % / 1.6 %; 2 % noise:
  +0.0 % / -0.0 %, spread 1.5 % / 1.5 %; all five FRFs: bias -0.2..+0.9 % / -0.2..+0.2 %, spread 1.3-1.5 % /
  1.4-1.7 %, root-mean-square error at most 1.7 % for both;
* on 1000-2000 lines the third differences' spread is 0-15 % larger, their bias smaller (at most 2.7 % against
  8.9 %);
* on coarse grids, with fewer than about five lines per half-power bandwidth ``2 zeta f_r``, the FRF's own
  curvature leaks into the differences and both overestimate, the second differences much more: flange receptance
  on 500 lines, 0.5 % noise: +11 % / +4 %; 200 lines: +45 % / +13 %; six modes on 200 lines: +220 % / +49 %.

The second differences are kept: on the spindle workflow's 1-Hz grid the two are equally good (bias below the
spread, the same root-mean-square error), and the discrepancy workflow is calibrated with them (1.007 +- 0.045 of
the realised noise on its 2-Hz bands, docs/discrepancy.md), so its outputs stay as they are.  The third
differences' advantage is a smaller bias on coarser grids and at low noise, where the FRF's curvature weighs more
against the noise; an FRF with fewer than about five lines per half-power bandwidth gets an overestimated
(conservative) noise level from these second differences.  Switching the spindle identification from third to
second differences changes its estimated noise, on the same 3801-line data, by +0.0..+0.8 % on average with a
standard deviation of 0.8 % (the five FRFs above).

Noise model (:func:`noise_sigma`)
---------------------------------
Standard deviation of the complex noise per line ``relative |H| + floor`` (m/N): the relative part for
force/response calibration and impact variability, the floor for sensor and amplifier noise near antiresonances.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import DataError

__all__ = ["relative_noise_scale", "noise_sigma", "MIN_LINES"]

#: Fewest lines for an estimate: two second differences, whose median is still defined (callers that fit a noise
#: level per file ask for more, e.g. the spindle identification's 20).
MIN_LINES = 5


def relative_noise_scale(values, min_lines: int = MIN_LINES, strict: bool = False) -> float:
    """Relative noise standard deviation of a measured FRF, from its second differences (module docstring).

    Parameters
    ----------
    values : (n_freq,) complex, m/N, on equally spaced lines
    min_lines : int, fewest lines accepted (at least 3)
    strict : bool
        What an FRF without an estimate gives (fewer than ``min_lines`` lines, not 1-D, or zero on every line):
        ``False`` NaN (the caller falls back to another noise level), ``True`` a :class:`DataError` naming the
        reason (the caller has no fallback).

    Returns
    -------
    float, dimensionless: ``sigma`` with noise ``E|e|^2 = sigma^2 |h|^2`` (0.01 for 1 % noise), or NaN (``strict``
    False) when there is no estimate.

    Raises
    ------
    DataError
        ``strict`` and no estimate (see above).
    """
    h = np.asarray(values, dtype=complex)
    if h.ndim != 1 or h.size < max(int(min_lines), 3):
        if strict:
            raise DataError(f"noise estimate: need a 1-D FRF of at least {min_lines} lines, got shape {h.shape}")
        return math.nan
    d2 = h[:-2] - 2.0 * h[1:-1] + h[2:]
    mag2 = np.abs(h[1:-1]) ** 2
    ok = mag2 > 0
    if not ok.any():
        if strict:
            raise DataError("noise estimate: the FRF is zero on every line")
        return math.nan
    return float(math.sqrt(np.median(np.abs(d2[ok]) ** 2 / (6.0 * mag2[ok])) / math.log(2.0)))


def noise_sigma(values, relative: float, floor: float = 0.0) -> np.ndarray:
    """Standard deviation of the complex noise per line, ``relative |H| + floor``.

    Parameters
    ----------
    values : (n_freq,) complex, m/N
    relative : float, dimensionless
    floor : float, m/N

    Returns
    -------
    (n_freq,) float, m/N
    """
    return relative * np.abs(np.asarray(values)) + floor
