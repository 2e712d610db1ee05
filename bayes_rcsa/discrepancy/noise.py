"""The measurement's own noise level, estimated from the measured FRF alone.

A model that misses the data absorbs the misfit into its fitted noise scale:
on the rotor bench with a slotted holder the remainder model's scale at
40 mm was 0.07-0.13 against the bench's 2 %.  The scatter of a measured
resonance peak, and with it the posterior-predictive interval of a measured
mode and the observation variance of the mode-frequency bias, is set by the
noise of the *measurement*, not by the misfit of the model, nor by the
part of the noise that a flexible model (the remainder's smooth FRF
discrepancy) absorbs and so leaves out of its fitted scale.  This module
estimates that noise without any model; the discrepancy workflow uses it
alone for the measured peak's scatter.

Second differences ``d_i = h_{i-1} - 2 h_i + h_{i+1}`` of a smooth FRF are
small wherever the FRF varies slowly over three lines; circular complex
noise of relative standard deviation ``sigma`` (``E|e_i|^2 = sigma^2
|h_i|^2``) gives ``E|d_i|^2 = 6 sigma^2 |h_i|^2`` and ``|d_i|^2 / (6 sigma^2
|h_i|^2)`` exponentially distributed, whose median is ``ln 2``.  The median
over the band is robust to the few lines near a sharp peak where the FRF's
own curvature dominates (Rice 1984 uses first differences the same way for
a regression's noise variance).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["relative_noise_scale"]


def relative_noise_scale(values: np.ndarray) -> float:
    """Relative noise standard deviation of a measured FRF, from its second differences.

    Parameters
    ----------
    values : (n_freq,) complex, m/N, on equally spaced lines (n_freq >= 5)

    Returns
    -------
    float, dimensionless: ``sigma`` with noise ``E|e|^2 = sigma^2 |h|^2``; NaN with fewer than 5 lines or
    no line with a non-zero value.
    """
    h = np.asarray(values, dtype=complex)
    if h.size < 5:
        return math.nan
    d2 = h[:-2] - 2.0 * h[1:-1] + h[2:]
    mag2 = np.abs(h[1:-1]) ** 2
    ok = mag2 > 0
    if not ok.any():
        return math.nan
    return float(math.sqrt(np.median(np.abs(d2[ok]) ** 2 / (6.0 * mag2[ok])) / math.log(2.0)))
