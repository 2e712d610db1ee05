"""Modes matched one to one (bayes_rcsa.model.modes) and the discrepancy bookkeeping built on them.

The two-mode case with swapped prominence is built on purpose: the measured FRF's highest peak is its
upper mode, the model's highest peak its lower mode.  Comparing highest peak with highest peak would give a
frequency error of about -15 % between two different modes; mode k against mode k gives the true,
small errors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.discrepancy.detect import compare_peaks
from bayes_rcsa.discrepancy.evaluate import mode_entries, prediction_usability
from bayes_rcsa.errors import ModelError
from bayes_rcsa.model.modes import find_modes, match_modes, mode_windows, track_modes
from bayes_rcsa.model.natural_frequencies import natural_frequency

F = np.arange(900.0, 2100.0, 2.0)


def sdof(f, fn, zeta=0.02, k=1e6):
    w, wn = 2 * np.pi * f, 2 * np.pi * fn
    return 1 / (k * (1 - (w / wn) ** 2 + 2j * zeta * w / wn))


def two_mode(f_lo, f_hi, k_lo, k_hi, f=F):
    return sdof(f, f_lo, k=k_lo) + sdof(f, f_hi, k=k_hi)


# measured: the upper mode (1627 Hz) is the more prominent; model: the lower one (1385 Hz)
MEASURED = two_mode(1390.0, 1627.0, 1.3e6, 1.0e6)
MODEL = two_mode(1385.0, 1640.0, 1.0e6, 1.3e6)


def _peak(f, h):
    return f[np.argmax(np.abs(h))]


def test_find_modes_lists_both_modes_at_their_frequencies():
    modes = find_modes(F, MEASURED)
    assert len(modes) == 2
    # a sum of two 2 %-damped modes 17 % apart: the other mode's tail moves each peak by up to ~0.4 %
    assert modes[0].frequency_hz == pytest.approx(1390.0, rel=5e-3)
    assert modes[1].frequency_hz == pytest.approx(1627.0, rel=5e-3)
    assert modes[1].height > modes[0].height
    # the windows cut at the minimum between the modes and together cover the band
    (a0, b0), (a1, b1) = mode_windows(modes)
    assert a0 == 0 and b1 == F.size - 1 and b0 == a1 and 1390 < F[b0] < 1627


def test_noise_does_not_make_modes():
    rng = np.random.default_rng(11)
    h = sdof(F, 1500.0)
    counts = []
    for _ in range(30):
        noisy = h + 0.02 * np.abs(h) / np.sqrt(2) * (rng.standard_normal(F.size) + 1j * rng.standard_normal(F.size))
        noisy = noisy + 1e-9 * (rng.standard_normal(F.size) + 1j * rng.standard_normal(F.size))
        counts.append(len(find_modes(F, noisy)))
    # 2 % relative noise is 0.02 in ln|h|, ten times below the prominence threshold: never a spurious mode
    assert counts == [1] * 30


def test_match_keeps_order_and_gates_far_modes():
    meas, model = find_modes(F, MEASURED), find_modes(F, MODEL)
    assert match_modes(model, meas) == [(0, 0), (1, 1)]
    # a model with only the lower mode: the upper measured mode stays unmatched, not paired across 17 %
    lone = find_modes(F, sdof(F, 1385.0))
    assert match_modes(lone, meas) == [(0, 0)]
    # a model mode 30 % away from every measured mode is not the same mode
    far = find_modes(F, sdof(F, 1000.0))
    assert match_modes(far, find_modes(F, sdof(F, 1500.0))) == []


def test_track_modes_follows_each_mode_through_draws():
    ref = find_modes(F, MODEL)
    shifts = np.array([0.99, 1.0, 1.01])
    draws = np.stack([two_mode(1385.0 * s, 1640.0 * s, 1.0e6, 1.3e6) for s in shifts])
    out = track_modes(F, draws, mode_windows(ref))
    # each tracked frequency moves with its own mode (same parabola rule as natural_frequency)
    assert out[:, 0] == pytest.approx(1385.0 * shifts, rel=3e-3)
    assert out[:, 1] == pytest.approx(1640.0 * shifts, rel=3e-3)
    # a draw whose upper mode leaves the band's last window ends on the window edge: NaN, counted by callers
    gone = track_modes(F, two_mode(1385.0, 2150.0, 1.0e6, 1.3e6)[None], mode_windows(ref))
    assert np.isfinite(gone[0, 0]) and np.isnan(gone[0, 1])


def test_swapped_prominence_is_detected_and_no_error_is_computed_across_modes():
    cross = 100 * (_peak(F, MODEL) - _peak(F, MEASURED)) / _peak(F, MEASURED)
    assert cross < -10  # what "highest peak minus highest peak" would report
    r = compare_peaks(F, MEASURED, MODEL)
    assert r["prominent_mode_differs"]
    assert any("more prominent mode differs" in s for s in r["findings"])
    # headline: the measured highest peak (1627 Hz) against *its* model mode (1640 Hz): +0.8 %
    assert r["frequency_error_pct"] == pytest.approx(100 * (1640 - 1627) / 1627, abs=0.15)
    errs = sorted(m["frequency_error_pct"] for m in r["modes"])
    assert errs == pytest.approx([100 * (1385 - 1390) / 1390, 100 * (1640 - 1627) / 1627], abs=0.15)
    # the same measurement without the swap: no such finding
    assert not compare_peaks(F, MEASURED, two_mode(1385.0, 1640.0, 1.3e6, 1.0e6))["prominent_mode_differs"]


def _draws(rng, n=200, spread=0.002):
    s = 1 + spread * rng.standard_normal(n)
    return np.stack([two_mode(1385.0 * x, 1640.0 * x, 1.0e6, 1.3e6) for x in s])


def test_mode_entries_report_every_mode_with_consistent_intervals():
    rng = np.random.default_rng(3)
    hd = _draws(rng)
    noise = 0.02 * np.abs(hd) / np.sqrt(2) * (rng.standard_normal(hd.shape) + 1j * rng.standard_normal(hd.shape))
    me = mode_entries(F, MEASURED, MODEL, hd, hd + noise)
    assert me["prominent_mode_differs"] and me["unmatched_measured_hz"] == [] and len(me["modes"]) == 2
    for m in me["modes"]:
        q, qp = m["model_interval"], m["predictive_interval"]
        assert q["q05"] <= m["model_hz"] <= q["q95"] and m["model_hz"] == q["q50"]  # the median: inside its interval
        assert abs(m["model_map_hz"] - m["model_hz"]) < 5.0  # and near the MAP mode (draws spread ~0.2 % = 3 Hz)
        assert qp["q95"] - qp["q05"] >= q["q95"] - q["q05"]  # noise only widens
        assert m["error_pct"] == pytest.approx(100 * (m["model_hz"] - m["measured_hz"]) / m["measured_hz"])
    top = [m for m in me["modes"] if m["most_prominent_measured"]]
    assert len(top) == 1 and top[0]["measured_hz"] == pytest.approx(1627.0, rel=3e-3)
    assert not top[0]["most_prominent_model"]


def test_mode_entries_with_several_noise_realisations_per_draw_pair_each_with_its_own_draw():
    # evaluate() passes r noise realisations per draw in np.repeat order; the tracked model draws come back
    # repeated the same way, so predictive - model of a row is that draw's noise alone (the bias's observation
    # variance), never the difference of two draws' parameters
    rng = np.random.default_rng(5)
    hd = _draws(rng, n=40, spread=0.01)  # a parameter spread (~15 Hz) far above the noise's peak scatter
    rep = np.repeat(hd, 4, axis=0)
    noise = 0.002 * np.abs(rep) / np.sqrt(2) * (rng.standard_normal(rep.shape) + 1j * rng.standard_normal(rep.shape))
    fd, fp = mode_entries(F, MEASURED, MODEL, hd, rep + noise)["tracked"]
    assert fd.shape == fp.shape == (160, 2)
    # each model draw appears four times in a row, and each prediction sits next to its own draw: at 0.2 %
    # noise the peak moves by well under a line (2 Hz) while the draws differ by ~15 Hz
    assert np.array_equal(fd[::4], fd[3::4]) and np.nanmax(np.abs(fp - fd)) < 2.0 < np.nanstd(fd[:, 0])
    with pytest.raises(ModelError, match="whole number of replicates"):
        mode_entries(F, MEASURED, MODEL, hd, rep[:-1] + noise[:-1])


def test_mode_bookkeeping_error_is_caught_before_any_plot():
    # draws of a *different* structure (both modes 5 % lower): the MAP lies outside its own interval
    rng = np.random.default_rng(4)
    hd = np.stack([two_mode(1385.0 * 0.95 * x, 1640.0 * 0.95 * x, 1.0e6, 1.3e6)
                   for x in 1 + 0.001 * rng.standard_normal(50)])
    with pytest.raises(ModelError, match="outside its own 90 % interval"):
        mode_entries(F, MEASURED, MODEL, hd, hd)
    # a parameter on a prior bound excuses a MAP just beyond its one-sided draws, not 70 Hz beyond a 5-Hz interval
    with pytest.raises(ModelError, match="outside its own 90 % interval"):
        mode_entries(F, MEASURED, MODEL, hd, hd, truncated=("k_xf",))


def test_a_map_on_a_prior_bound_may_lie_beyond_its_one_sided_draws_and_is_flagged_not_refused():
    # A contact fitted at its softest allowed value: the prior cuts the Laplace draws on the soft side, so every
    # draw is stiffer and its modes higher than the MAP's (here 1-3 % higher).  That is no mix-up of modes
    # (rotor bench, contact damping 50x: the baseline went to every lower bound and the run was refused until
    # this); with the parameter named, the mode is kept and flagged.  Without a bound it is still an error.
    rng = np.random.default_rng(6)
    stiffer = 1.01 + np.abs(0.01 * rng.standard_normal(60))
    hd = np.stack([two_mode(1385.0 * x, 1640.0 * x, 1.0e6, 1.3e6) for x in stiffer])
    with pytest.raises(ModelError, match="outside its own 90 % interval"):
        mode_entries(F, MEASURED, MODEL, hd, hd)
    me = mode_entries(F, MEASURED, MODEL, hd, hd, truncated=("k_xf",))
    for m in me["modes"]:
        q = m["model_interval"]
        assert m["map_outside_interval"] and "k_xf on a prior bound" in m["map_outside_reason"]
        assert m["model_map_hz"] < q["q05"] <= m["model_hz"] <= q["q95"]  # the point is the draws' median
    # draws on both sides of the MAP: nothing flagged, with or without a bound
    both = mode_entries(F, MEASURED, MODEL, _draws(rng), _draws(rng), truncated=("k_xf",))
    assert not any(m["map_outside_interval"] for m in both["modes"])


def _eval(fitted_cover=True, unmatched=(), gap=0.01):
    mode = {"measured_hz": 1500.0, "covered_predictive_90": fitted_cover,
            "predictive_interval": {"q05": 1490.0, "q50": 1495.0, "q95": 1499.0}}
    m = {"fitted": True, "direction": "x", "clamping_length": 0.025, "modes": [mode],
         "unmatched_measured_hz": [u for u, _ in unmatched], "unmatched_measured_rel_height": [r for _, r in unmatched]}
    return {"measurements": [m], "gap": gap}


def test_prediction_usability_rules():
    before = {"gap": 0.02}
    assert prediction_usability(_eval(), before, 0.001) == (True, [])
    ok, why = prediction_usability(_eval(fitted_cover=False), before, 0.001)
    assert not ok and "misses it" in why[0] and "1500 Hz" in why[0]
    ok, why = prediction_usability(_eval(unmatched=[(1627.0, 0.9)]), before, 0.001)
    assert not ok and "1627 Hz has no counterpart" in why[0]
    assert prediction_usability(_eval(unmatched=[(1627.0, 0.1)]), before, 0.001)[0]  # weak peaks do not count
    ok, why = prediction_usability(_eval(gap=0.05), before, 0.001)
    assert not ok and "grew" in why[0]
    # a model whose FRF misses the fitted data by 30 % is not usable even where its frequencies are right
    shapeless = dict(_eval(gap=0.01), gap_fitted=0.3)
    ok, why = prediction_usability(shapeless, before, 0.001)
    assert not ok and "30 %" in why[0]
    assert prediction_usability(dict(_eval(gap=0.01), gap_fitted=0.1), before, 0.001)[0]
    # a named physical model: a near miss (measured 1500 Hz, median 1495 Hz, sd 4 Hz) is chance, a gross one is not
    near = _eval(fitted_cover=False)
    near["measurements"][0]["modes"][0]["predictive_sd_hz"] = 4.0
    assert prediction_usability(near, before, 0.001, remainder=False)[0]
    assert not prediction_usability(near, before, 0.001, remainder=True)[0]
    near["measurements"][0]["modes"][0]["predictive_sd_hz"] = 1.0
    assert not prediction_usability(near, before, 0.001, remainder=False)[0]


def test_single_mode_agrees_with_the_natural_frequency_rule():
    h = sdof(F, 1234.0)
    (m,) = find_modes(F, h)
    assert m.frequency_hz == pytest.approx(float(natural_frequency(F, h)), abs=1e-9)
    assert math.isfinite(m.width_hz) and m.width_hz == pytest.approx(2 * 0.02 * 1234.0, rel=0.05)


def _bias_case(rng, lengths, fitted_bias, held_bias, shared_sd=0.5, n=400):
    """Measurements and tracked draws of one mode: model line 1000 Hz + 10 Hz/mm, measured = model + bias."""
    meas, draws = [], []
    shared = shared_sd * rng.standard_normal((n, 1))  # a parameter spread shared by every length
    for l in lengths:
        f_model = 1000.0 + 10000.0 * (l - 0.025)
        fd = f_model + shared + 0.2 * rng.standard_normal((n, 1))
        fp = fd + 1.0 * rng.standard_normal((n, 1))  # measured-peak noise: 1 Hz
        fm = f_model + fitted_bias.get(l, held_bias)
        q = {"q05": 0.0, "q50": 0.0, "q95": 0.0}
        meas.append({"fitted": l in fitted_bias, "direction": "x", "clamping_length": l,
                     "modes": [{"measured_hz": fm, "model_hz": f_model, "error_pct": 0.0, "model_interval": q,
                                "predictive_interval": q}]})
        draws.append((fd, fp))
    return meas, draws


def test_a_bias_shared_by_all_lengths_is_carried_between_them_without_widening():
    # The model is 20 Hz low at every length (a wrong modulus, a softer holder), and the posterior draws
    # spread by 20 Hz together at every length (parameter uncertainty).  The constant of the bias is learned
    # from the fitted lengths and the parameter spread cancels per draw, so the held-out interval sits on
    # the truth with the width the 1 Hz peak noise leaves.  (A zero-mean bias with its amplitude taken from
    # every draw's bias, the rule before, gave a held-out sd of about 15 Hz here.)
    from bayes_rcsa.discrepancy.mode_bias import correct_mode_frequencies

    rng = np.random.default_rng(9)
    meas, draws = _bias_case(rng, (0.025, 0.030, 0.035, 0.040), {0.025: 20.0, 0.040: 20.0}, 20.0, shared_sd=20.0)
    correct_mode_frequencies(meas, draws, rng)
    for m in meas:
        md = m["modes"][0]
        q = md["model_interval"]
        # the truth is model + 20 Hz at every length; the constant rests on two fitted lengths with 1 Hz
        # peak noise (sd 0.7 Hz), so 1.5 Hz is two of its standard deviations
        assert md["bias_hz"]["mean"] == pytest.approx(20.0, abs=1.5)
        # 90 % width: about 2 x 1.645 x sqrt(noise var / 2 + the floor's between-length variation) < 8 Hz,
        # against the 20 Hz parameter spread of the uncorrected draws
        assert q["q95"] - q["q05"] < 8.0 and md["covered_model_90"]


def test_remainder_bias_moves_fitted_intervals_onto_the_data_and_interpolates_between():
    from bayes_rcsa.discrepancy.mode_bias import correct_mode_frequencies

    rng = np.random.default_rng(8)
    n = 400
    lengths = (0.025, 0.030, 0.040)
    bias = {0.025: 15.0, 0.040: 30.0}  # the model is 15 and 30 Hz low at the fitted lengths
    meas, draws = [], []
    for l in lengths:
        f_model = 1000.0 + 10000.0 * (l - 0.025)
        fd = f_model + 0.5 * rng.standard_normal((n, 1))
        fp = fd + 1.0 * rng.standard_normal((n, 1))  # measured-peak noise: 1 Hz
        fm = f_model + bias.get(l, 20.0)
        q = {"q05": 0.0, "q50": 0.0, "q95": 0.0}
        meas.append({"fitted": l in bias, "direction": "x", "clamping_length": l,
                     "modes": [{"measured_hz": fm, "model_hz": f_model, "error_pct": 0.0, "model_interval": q,
                                "predictive_interval": q}]})
        draws.append((fd, fp))
    notes = correct_mode_frequencies(meas, draws, rng)
    assert len(notes) == 1 and "+15.0, +30.0 Hz" in notes[0]
    for m in meas:
        md = m["modes"][0]
        q = md["model_interval"]
        assert q["q05"] <= md["model_hz"] <= q["q95"]  # the corrected point inside its corrected interval
        if m["fitted"]:
            # on the data within the 1 Hz peak noise (GP noise variance 1 Hz^2 against an amplitude ~24 Hz)
            assert md["bias_hz"]["mean"] == pytest.approx(bias[m["clamping_length"]], abs=0.5)
            # the posterior sd is at most the peak noise (1 Hz), estimated from 400 draws (~7 % sampling error)
            assert md["covered_predictive_90"] and md["bias_hz"]["sd"] < 1.15
        else:
            # between fitted lengths the bias follows its straight-line mean (15 Hz at 25 mm, 30 Hz at 40 mm:
            # 20 Hz at 30 mm, the truth here), uncertain by the two peaks' noise; it covers the truth
            assert md["bias_hz"]["mean"] == pytest.approx(20.0, abs=1.5) and md["covered_model_90"]
            assert 0.3 < md["bias_hz"]["sd"] < 3.0  # >0: the peaks' noise; <3: not the 15 Hz change itself
            assert md["uncorrected_model_interval"] == {"q05": 0.0, "q50": 0.0, "q95": 0.0}


def _two_length_case(seed: int, fitted: dict, held: dict, resonance: bool) -> tuple[list, dict, list]:
    """Two fitted lengths (25, 40 mm), two held out; the measured modes' truth is model + the given bias (Hz).

    The fitted lengths' peaks carry 1 Hz of noise in the predictive draws (as in :func:`_bias_case`); with
    ``resonance`` each fitted mode also carries the estimate from its whole resonance, 0.1 Hz sd.  Returns the
    corrected measurements, the truth per clamping length and the correction's notes.
    """
    from bayes_rcsa.discrepancy.mode_bias import correct_mode_frequencies

    rng = np.random.default_rng(seed)
    meas, draws = _bias_case(rng, (0.025, 0.030, 0.035, 0.040), fitted, 0.0)
    truth = {}
    for m in meas:
        l, md = m["clamping_length"], m["modes"][0]
        truth[l] = 1000.0 + 10000.0 * (l - 0.025) + (fitted[l] if m["fitted"] else held[l])
        if m["fitted"] and resonance:
            md["measured_fit_hz"], md["measured_fit_sd_hz"] = truth[l] + 0.1 * rng.standard_normal(), 0.1
        elif not m["fitted"]:
            md["measured_hz"] = truth[l]
    notes = correct_mode_frequencies(meas, draws, rng)
    return meas, truth, notes


def test_with_two_fitted_lengths_the_bend_scales_with_the_change_seen_at_the_resonances():
    # Two lengths cannot show how the bias bends between them.  Its scale is how much the bias was seen to
    # change over them, from the measured resonances (0.1 Hz sd), not the peak noise (1 Hz), which is the
    # measurement's property and widened an exact model's held-out intervals as much as a wrong one's.
    held = {0.030: "held", 0.035: "held"}
    for seed in (31, 32):
        # the model sits on the resonances at both ends: the held-out bias is the line through the two noisy
        # peaks alone, sd sqrt((2/3)^2 + (1/3)^2) x 1 Hz = 0.75 Hz at 30 mm; the peak-noise scale (the rule
        # before, still used when a resonance estimate is missing) adds its kernel: about 0.9 Hz
        exact = {0.025: 0.0, 0.040: 0.0}
        new, _, notes_new = _two_length_case(seed, exact, dict.fromkeys(held, 0.0), resonance=True)
        old, _, notes_old = _two_length_case(seed, exact, dict.fromkeys(held, 0.0), resonance=False)
        # the outputs say where the assumed amplitude came from
        assert "change seen at the measured resonances" in notes_new[0]
        assert "the peak noise's: no resonance estimate" in notes_old[0]
        for m_new, m_old in zip(new, old):
            if not m_new["fitted"]:
                sd_new, sd_old = m_new["modes"][0]["bias_hz"]["sd"], m_old["modes"][0]["bias_hz"]["sd"]
                # 0.85: 0.75 Hz plus the 400 draws' sampling error (~5 %) and the 0.2 Hz draw scatter
                assert sd_new < 0.85 < sd_old, (seed, sd_new, sd_old)
        # an offset the same at both ends (20 Hz: a wrong modulus, a softer holder) has shown no course to bend:
        # carried by the line, unwidened
        offset, _, _ = _two_length_case(seed, {0.025: 20.0, 0.040: 20.0}, dict.fromkeys(held, 20.0), resonance=True)
        for m in offset:
            md = m["modes"][0]
            assert md["bias_hz"]["mean"] == pytest.approx(20.0, abs=1.5) and md["covered_model_90"]
            if not m["fitted"]:
                assert md["bias_hz"]["sd"] < 0.85
        # a bias changing by 10 Hz over the span and bending 4.7 Hz above its chord at 30 mm: the change seen
        # widens the held-out intervals to cover it; the peak-noise scale (1 Hz) misses it at both held-out lengths
        bend_fit, bend_held = {0.025: 0.0, 0.040: 10.0}, {0.030: 8.0, 0.035: 9.5}
        for resonance, covered in ((True, True), (False, False)):
            meas, truth, _ = _two_length_case(seed, bend_fit, bend_held, resonance=resonance)
            for m in meas:
                q = m["modes"][0]["model_interval"]
                hit = q["q05"] <= truth[m["clamping_length"]] <= q["q95"]
                assert hit if m["fitted"] else hit == covered, (seed, resonance, m["clamping_length"], q)


def _bias_coverage(correct, departure_sd, seed, n_rep=1500, lengths=(0.025, 0.030, 0.035, 0.040),
                   fitted=(0.025, 0.030, 0.040), noise_sd=1.0, n_draws=200):
    """Coverage of the noise-free mode frequency by the corrected 90 % model interval, fitted and held out.

    Data drawn from the bias model's own assumptions: the truth is the model's line plus a constant offset,
    plus a smooth departure (squared-exponential, length scale half the fitted span, sd ``departure_sd`` Hz);
    the measured peak adds ``noise_sd`` Hz of Gaussian noise, which the predictive draws know.
    """
    rng = np.random.default_rng(seed)
    x = np.array(lengths)
    f_model = 1000.0 + 200.0 * (x - 0.025) / 0.015
    kern = departure_sd**2 * np.exp(-0.5 * ((x[:, None] - x[None, :]) / 0.0075) ** 2) + 1e-12 * np.eye(x.size)
    chol = np.linalg.cholesky(kern)
    # what every replicate shares, made once (the correction reads the draws, never writes them); the random
    # draws below come in the same order as ever
    is_fitted = [bool(np.isclose(l, fitted).any()) for l in x]
    model_draws = [np.full((n_draws, 1), f) for f in f_model]
    hits = {True: [0, 0], False: [0, 0]}
    for _ in range(n_rep):
        truth = f_model + rng.normal(0.0, 5.0) + chol @ rng.standard_normal(x.size)
        measured = truth + noise_sd * rng.standard_normal(x.size)
        meas, draws = [], []
        for i, l in enumerate(x.tolist()):
            q = {"q05": 0.0, "q50": 0.0, "q95": 0.0}
            meas.append({"fitted": is_fitted[i], "direction": "x", "clamping_length": l,
                         "modes": [{"measured_hz": float(measured[i]), "model_hz": float(f_model[i]),
                                    "error_pct": 0.0, "model_interval": q, "predictive_interval": q}]})
            fd = model_draws[i]
            draws.append((fd, fd + noise_sd * rng.standard_normal((n_draws, 1))))
        correct(meas, draws, rng)
        for i, m in enumerate(meas):
            q = m["modes"][0]["model_interval"]
            hits[m["fitted"]][0] += q["q05"] <= truth[i] <= q["q95"]
            hits[m["fitted"]][1] += 1
    return {k: v[0] / v[1] for k, v in hits.items()}


def test_bias_intervals_are_calibrated_on_data_drawn_from_their_own_model():
    # Three of four lengths fitted, 1500 replicated campaigns per case (4500 fitted, 1500 held-out intervals;
    # Clopper-Pearson 95 % half-widths about 0.9 and 1.5 points).  Seed 21, held out / fitted:
    #                         amplitude marginalised   REML plug-in     residual variance (the first rule)
    #   departure 0:          0.965 / 0.913            0.949 / 0.892    0.939 / 0.905
    #   departure = noise:    0.947 / 0.904            0.904 / 0.883    0.902 / 0.896
    #   departure = 2 noise:  0.888 / 0.886            0.850 / 0.870    0.810 / 0.874
    # One contrast cannot pin the kernel's amplitude: a plug-in takes the departure seen at face value and
    # under-covers where it is real, at the held-out length and (smoothing it towards the line) at the fitted
    # ones.  The lower bounds fail both plug-ins; the upper bounds: no coverage bought by width (0.97, issue
    # #19's ceiling for held-out lengths).
    from bayes_rcsa.discrepancy.mode_bias import correct_mode_frequencies

    correct = lambda meas, draws, rng: correct_mode_frequencies(meas, draws, rng)  # noqa: E731
    for departure, held_min, fitted_min in ((0.0, 0.93, 0.89), (1.0, 0.92, 0.89), (2.0, 0.86, 0.87)):
        cov = _bias_coverage(correct, departure, seed=21)
        assert held_min <= cov[False] <= 0.97, (departure, cov)
        assert fitted_min <= cov[True] <= 0.95, (departure, cov)


def test_measurement_noise_is_estimated_without_a_model():
    # 2 % circular complex noise on two resonances over 1001 lines: the second-difference estimate recovers it
    # within 10 % (the median of 1000 exponential variates has ~4 % sampling error; the peaks' own curvature
    # biases a few lines); a misfitting model's fitted scale, 4-6x larger on the rotor bench, plays no role
    from bayes_rcsa.discrepancy.noise import relative_noise_scale

    rng = np.random.default_rng(12)
    f = np.linspace(500.0, 3500.0, 1001)
    h = sdof(f, 1234.0) + 0.5 * sdof(f, 2600.0)
    noisy = h + 0.02 * np.abs(h) * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) / np.sqrt(2)
    assert relative_noise_scale(noisy) == pytest.approx(0.02, rel=0.10)
    assert relative_noise_scale(h) < 0.002  # a noise-free FRF: only the curvature of the peaks
    assert np.isnan(relative_noise_scale(h[:4]))


def test_bias_with_repeated_taps_at_one_length_is_a_constant_and_widens_away_from_it():
    # two taps at 25 mm, none elsewhere: no straight line can be fitted (a singular design would crash), the
    # bias is one constant, and at 35 mm its uncertainty includes the unseen change with length
    from bayes_rcsa.discrepancy.mode_bias import correct_mode_frequencies

    rng = np.random.default_rng(14)
    meas, draws = _bias_case(rng, (0.025, 0.025, 0.035), {0.025: 10.0}, 10.0)
    meas[1]["fitted"] = True
    correct_mode_frequencies(meas, draws, rng)
    fitted, held = meas[0]["modes"][0], meas[2]["modes"][0]
    assert fitted["bias_hz"]["mean"] == pytest.approx(10.0, abs=1.5)
    assert np.isfinite(held["bias_hz"]["sd"]) and held["bias_hz"]["sd"] > 2 * fitted["bias_hz"]["sd"]


def test_unexplained_feature_away_from_modes_flags_nearby_predictions_at_unmeasured_lengths():
    # a misfit band 1014-1028 Hz at a fitted length whose modes sit at 858 Hz (width 30 Hz): a feature; a band
    # on the mode itself is the mode's own misfit, not a feature.  The 30-mm mode predicted at 964 Hz (5 %
    # below the feature) is flagged, the one at 1250 Hz (22 % above) is not, nor any fitted mode.
    from bayes_rcsa.discrepancy.features import modes_near_features, unexplained_features

    det = [{"source": "a", "direction": "x", "clamping_length": 0.025,
            "bands": [{"lo_hz": 1014.0, "hi_hz": 1028.0}, {"lo_hz": 850.0, "hi_hz": 866.0}]}]
    fitted = {"source": "a", "direction": "x", "clamping_length": 0.025, "fitted": True,
              "modes": [{"measured_hz": 858.0, "measured_width_hz": 30.0, "model_hz": 858.5}]}
    held = {"source": "b", "direction": "x", "clamping_length": 0.030, "fitted": False,
            "modes": [{"measured_hz": 959.0, "measured_width_hz": 30.0, "model_hz": 964.0},
                      {"measured_hz": 1250.0, "measured_width_hz": 30.0, "model_hz": 1250.0}]}
    feats = unexplained_features(det, [fitted, held])
    assert [(b["lo_hz"], b["hi_hz"]) for b in feats] == [(1014.0, 1028.0)]
    reasons = modes_near_features([fitted, held], feats)
    assert len(reasons) == 1 and "30 mm (not fitted)" in reasons[0] and "1014-1028 Hz" in reasons[0]
    assert held["modes"][0]["near_unexplained_feature_hz"] == [1014.0, 1028.0]
    assert "near_unexplained_feature_hz" not in held["modes"][1]
    assert "near_unexplained_feature_hz" not in fitted["modes"][0]
    assert modes_near_features([fitted, held], []) == []
