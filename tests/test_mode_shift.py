"""The measured mode's frequency from its whole resonance (``discrepancy/mode_shift.py``).

Stand-in FRFs are single-degree-of-freedom receptances on 2-Hz lines with 2 % relative complex noise, the
noise of the benches.  The reference is the *noise-free* FRF's peak by the project's natural-frequency rule,
the same convention the model's mode frequencies use.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.discrepancy.mode_shift import shifted_template_frequency
from bayes_rcsa.model.modes import find_modes, mode_windows

F = np.arange(800.0, 1400.0, 2.0)


def sdof(fn, zeta=0.02, amp=1e-5):
    w, wn = 2 * np.pi * F, 2 * np.pi * fn
    return amp * wn**2 / (wn**2 - w**2 + 2j * zeta * wn * w)


def noisy(h, rng, sigma=0.02):
    return h * (1 + sigma * (rng.standard_normal(h.size) + 1j * rng.standard_normal(h.size)) / math.sqrt(2))


def _estimates(model, truth, n, seed):
    rng = np.random.default_rng(seed)
    pm = find_modes(F, model)
    win = mode_windows(pm)[0]
    out = np.array([shifted_template_frequency(F, noisy(truth, rng), model, win, pm[0].frequency_hz, 0.02)
                    for _ in range(n)])
    peaks = np.array([find_modes(F, noisy(truth, rng))[0].frequency_hz for _ in range(n)])
    return out[:, 0], out[:, 1], peaks


def test_resonance_estimate_is_unbiased_calibrated_and_ten_times_better_than_the_peak():
    model, truth = sdof(1100.0), sdof(1100.7)  # the model's mode 0.7 Hz (a third of a line) too low
    ref = find_modes(F, truth)[0].frequency_hz
    est, sd, peaks = _estimates(model, truth, 200, 11)
    assert np.all(np.isfinite(est)) and np.all(sd > 0)
    # bias within 3 standard errors of the mean of 200 (sd ~0.1 Hz: 0.02 Hz)
    assert abs(est.mean() - ref) < 3 * est.std() / math.sqrt(200)
    # its claimed sd is the scatter it has (the serial-correlation factor may add up to ~25 % on white noise)
    assert 0.9 < np.median(sd) / est.std() < 1.35
    # 90 % intervals over 200 replicates: Clopper-Pearson 95 % of 180/200 is [0.85, 0.94]; allow [0.84, 0.99]
    hits = np.mean(np.abs(est - ref) <= 1.645 * sd)
    assert 0.84 <= hits <= 0.99, hits
    # the peak line scatters by ~1.8 Hz here; the whole resonance pins the mode ten times better
    assert est.std() < 0.15 * peaks.std()


def test_a_resonance_of_the_wrong_shape_widens_its_own_uncertainty():
    """The model's damping twice the truth's: the shifted template cannot match the resonance, and its
    reduced chi-square and correlated residual widen the estimate's sd so that it still covers the truth."""
    model, truth = sdof(1100.0, zeta=0.04), sdof(1100.7)
    ref = find_modes(F, truth)[0].frequency_hz
    est, sd, _ = _estimates(model, truth, 40, 12)
    assert np.median(sd) > 5 * 0.1  # far above the 0.1 Hz of a matching shape
    assert np.mean(np.abs(est - ref) <= 1.645 * sd) >= 0.9


@pytest.mark.parametrize("case", ["too few lines", "no noise scale", "mode off the window"])
def test_no_estimate_where_the_resonance_cannot_give_one(case):
    model = sdof(1100.0)
    pm = find_modes(F, model)
    win, f0 = mode_windows(pm)[0], pm[0].frequency_hz
    rng = np.random.default_rng(13)
    meas = noisy(sdof(1100.0), rng)
    if case == "too few lines":
        model, meas = sdof(1100.0, zeta=0.002), noisy(sdof(1100.0, zeta=0.002), rng)
        pm = find_modes(F, model)
        win, f0 = mode_windows(pm)[0], pm[0].frequency_hz
        sigma = 0.02
    elif case == "no noise scale":
        sigma = math.nan
    else:  # the measured mode lies far beyond the resonance's own width
        meas, sigma = noisy(sdof(1250.0), rng), 0.02
    f, sd = shifted_template_frequency(F, meas, model, win, f0, sigma)
    assert math.isnan(f) and math.isnan(sd)
