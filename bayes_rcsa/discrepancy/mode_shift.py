"""Where a measured mode sits relative to the model's, from the whole resonance rather than its peak line.

The peak of a measured FRF (the parabola through the largest ``|h|`` and its
neighbours) scatters by about a line under 2 % noise, because it rests on
three lines.  The model's mode frequency, fitted to every line of the band,
is known ten times better.  A bias of the model's mode judged against the
measured *peak* can therefore not be seen below a line, while the model's
interval is a tenth of a line wide: on the independent rotor bench the
intervals of an adequate model were 0.1-0.5 Hz wide and the noise-free truth
lay 0.1-0.4 Hz beside them.

This module estimates the measured mode's frequency from every line of the
resonance instead: the measured FRF around the mode is compared with the
model's FRF *shifted in frequency* and scaled by a free complex factor,

    h_meas(f) ~ a h_model(f / (1 + delta)),

and ``delta`` minimises the weighted squared residual over the lines where
the model's ``|h|`` is at least half its peak (the half-power region and a
little more).  The weights are those of relative noise, ``2 / (sigma^2
|h_model|^2)`` with ``sigma`` the measurement's own noise scale
(:mod:`.noise`), so the minimum is a chi-square with ``2 n - 3`` degrees of
freedom and the variance of ``delta`` is ``2 / chi2''`` (profile likelihood),
inflated by the reduced chi-square when the model's resonance has the wrong
shape, and by the residual's serial correlation over the first
:data:`MAX_LAG` lines (``1 + 2 sum rho_k``, the effective-sample-size factor
of correlated errors): a shape misfit runs over neighbouring lines, and it
makes the shift less certain, never more.  The measured
mode frequency is then ``f_model (1 + delta)``.  The free factor ``a``
absorbs a wrong height or phase, so only the position is estimated.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["shifted_template_frequency", "SHIFT_RULE"]

SHIFT_RULE = ("measured mode frequency from its whole resonance: the model's FRF shifted in frequency and scaled "
              "by a free complex factor fitted to the measured FRF on the lines where the model's |h| >= half its "
              "peak, relative-noise weights from the measurement's own noise scale; sd from the profile "
              "chi-square's curvature, inflated by the reduced chi-square")

#: Fewest lines a resonance needs for the shift (three parameters, two real values per line).
MIN_LINES = 7
#: Grid of trial shifts per side (the minimum is then refined by a parabola).
N_GRID = 100
#: Lags of the residual's autocorrelation counted in the variance inflation.
MAX_LAG = 3


def shifted_template_frequency(frequency_hz, measured, model, window: tuple[int, int], model_hz: float,
                               sigma: float) -> tuple[float, float]:
    """Frequency (Hz) and standard deviation (Hz) of the measured mode that the model's mode ``model_hz`` matches.

    Parameters
    ----------
    frequency_hz : (n,) Hz, the measurement's lines
    measured, model : (n,) complex m/N, measured FRF and the model's (MAP) FRF on those lines
    window : (lo, hi) inclusive line indices of the model mode (:func:`~bayes_rcsa.model.modes.mode_windows`)
    model_hz : float, Hz, the model mode's frequency (its peak on these lines)
    sigma : float, relative noise scale of the measurement (``E|e|^2 = sigma^2 |h|^2``)

    Returns
    -------
    (frequency, sd) : floats, Hz; NaN when the resonance has fewer than :data:`MIN_LINES` lines above half its
    peak, ``sigma`` is not a positive number, or the best shift lies on the edge of the trial range (the
    measured mode is farther away than the resonance is wide: the peak line is then the better estimate).
    """
    f = np.asarray(frequency_hz, dtype=float)
    hd, hm = np.asarray(measured, dtype=complex), np.asarray(model, dtype=complex)
    lo, hi = window
    if not (math.isfinite(sigma) and sigma > 0 and math.isfinite(model_hz) and model_hz > 0) or hi - lo < 2:
        return math.nan, math.nan
    mag = np.abs(hm[lo : hi + 1])
    top = lo + int(np.argmax(mag))
    keep = np.abs(hm) >= 0.5 * np.abs(hm[top])
    a, b = top, top
    while a - 1 >= lo and keep[a - 1]:
        a -= 1
    while b + 1 <= hi and keep[b + 1]:
        b += 1
    n = b - a + 1
    if n < MIN_LINES:
        return math.nan, math.nan
    fs, ds, ms = f[a : b + 1], hd[a : b + 1], hm[a : b + 1]
    w = 2.0 / (sigma**2 * np.abs(ms) ** 2)  # relative noise: two real components of variance sigma^2 |h|^2 / 2
    # trial shifts up to the resonance's own extent on either side (beyond it the fit would slide off the data)
    reach = (fs[-1] - fs[0]) / model_hz
    delta = np.linspace(-reach, reach, 2 * N_GRID + 1)
    spline = CubicSpline(f, np.column_stack([hm.real, hm.imag]), axis=0)
    tpl = spline(fs[None, :] / (1.0 + delta[:, None]))
    t = tpl[..., 0] + 1j * tpl[..., 1]  # (n_grid, n)
    scale = np.sum(w * np.conj(t) * ds, axis=1) / np.sum(w * np.abs(t) ** 2, axis=1)
    chi2 = np.sum(w * np.abs(ds[None, :] - scale[:, None] * t) ** 2, axis=1)
    k = int(np.argmin(chi2))
    if k == 0 or k == delta.size - 1:
        return math.nan, math.nan
    # parabola through the minimum and its neighbours: position and curvature of the profile chi-square
    c0, c1, c2 = chi2[k - 1], chi2[k], chi2[k + 1]
    step = delta[1] - delta[0]
    curv = (c0 - 2.0 * c1 + c2) / step**2
    if not curv > 0:
        return math.nan, math.nan
    d_hat = delta[k] + 0.5 * step * (c0 - c2) / (c0 - 2.0 * c1 + c2)
    chi2_min = c1 - 0.125 * (c0 - c2) ** 2 / (c0 - 2.0 * c1 + c2)
    z = (ds - scale[k] * t[k]) * np.sqrt(w)  # whitened residual at the best shift on the grid
    energy = float(np.sum(np.abs(z) ** 2))
    rho = [float(np.real(np.sum(z[lag:] * np.conj(z[:-lag])))) / energy for lag in range(1, min(MAX_LAG, n - 1) + 1)]
    serial = 1.0 + 2.0 * sum(max(r, 0.0) * (1.0 - (lag + 1) / n) for lag, r in enumerate(rho))
    inflate = max(1.0, chi2_min / (2 * n - 3)) * serial
    sd = math.sqrt(2.0 / curv * inflate)
    return float(model_hz * (1.0 + d_hat)), float(model_hz * sd)
