"""The discrepancy workflow on the second, independent bench (``bayes_rcsa.synthetic.rotor``).

The rotor bench was written by someone who had not read the model terms' code: a spindle on three bearing
sets and a flexible housing, a holder with its own mass distribution, a flute *profile*, modal
superposition.  These tests are reduced versions of ``benchmarks/discrepancy_generators.py`` (whose tables,
on seeds >= 1000 not used while developing, are in docs/discrepancy.md): 4 Hz lines, 25 and 40 mm fitted,
30 mm held out, both directions.

Comparisons are like with like: the final model's 90 % interval of mode k against the bench's noise-free
mode k (matched one to one, never the highest peak against the highest peak), the posterior-predictive
interval against the measured mode.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.discrepancy import DiscrepancyOptions, run_discrepancy
from bayes_rcsa.discrepancy.render import summary_markdown
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.model.modes import find_modes, match_modes
from bayes_rcsa.synthetic import rotor
from bayes_rcsa.vocabulary import effect_name

FIT = (0.025, 0.040)


def _config(effects, **overrides):
    return rotor.rotor_bench_config(hidden_effects=effects, frequency_step=4.0,
                                    clamping_lengths=(0.025, 0.030, 0.040), **overrides)


def _run(tmp_path_factory, effects, seed, full=False, **overrides):
    cfg = rotor.rotor_bench_config(hidden_effects=effects, **overrides) if full else _config(effects, **overrides)
    camp = rotor.generate_rotor_campaign(cfg, np.random.default_rng(seed))
    path = rotor.write_rotor_campaign(camp, tmp_path_factory.mktemp("rotor") / "c")
    return run_discrepancy(load_setup(path), DiscrepancyOptions(lengths=FIT, seed=seed)), cfg


def _truth_by_mode(res, cfg):
    """[((measurement, mode entry), noise-free true frequency Hz)] of the final model, mode k with mode k."""
    ev = res.evaluation["after"]
    out = []
    for m, f, hm in zip(res.report["measurements_after"], ev["frf"]["frequency_hz"], ev["frf"]["measured"]):
        truth = find_modes(f, rotor.true_tool_point_frf(cfg, m["direction"], m["clamping_length"], f))
        meas = find_modes(f, hm)
        true_of = {j: truth[i].frequency_hz for i, j in match_modes(truth, meas)}
        for md in m["modes"]:
            j = next(j for j, mo in enumerate(meas) if abs(mo.frequency_hz - md["measured_hz"]) < 1e-9)
            out.append(((m, md), true_of[j]))
    return out


def _truth_coverage(true_hz, fitted: bool):
    """(covered, total) of the final model's mode intervals against the noise-free truth (``_truth_by_mode``)."""
    hit = n = 0
    for (m, md), t in true_hz:
        if m["fitted"] == fitted:
            q = md["model_interval"]
            hit += bool(q["q05"] <= t <= q["q95"])
            n += 1
    return hit, n


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return _run(tmp_path_factory, {}, 3)


@pytest.fixture(scope="module")
def modulus(tmp_path_factory):
    # out of every term's library: the tool's Young's modulus 9 % below the declared value.  The default
    # campaign (2 Hz lines, 30 and 35 mm held out): the held-out lengths are what shows that a flexible term
    # fitted to 25 and 40 mm does not carry (the rate over campaigns is in the benchmark's table)
    return _run(tmp_path_factory, {"tool_modulus": True}, 21, full=True)


def test_clean_rotor_campaign_names_nothing(clean):
    res, _ = clean
    r = res.report
    assert r["named_effect"] is None and r["also_named"] == []
    assert r["usable_for_prediction"] and not r["gap_grew"]
    # one tool mode per measurement in the band, matched, no finding about modes
    for m in r["measurements_after"]:
        assert m["unmatched_measured_hz"] == [] and not m["prominent_mode_differs"] and len(m["modes"]) >= 1


def test_out_of_library_effect_is_not_named_with_confidence_and_fitted_intervals_are_honest(modulus):
    res, cfg = modulus
    r = res.report
    # the best-fitting stand-in, a flute with less bending stiffness than the circle of its area (a modulus
    # change over the fluted length), is refused as physically impossible (ModelTerm.implausible)
    flute = next(c for c in r["candidates"] if c["effect"] == "fluted_section")
    assert flute["implausible"] and r["named_effect"] != "fluted_section"
    # not named with confidence: nothing, or a name the report itself says it cannot tell from another
    # (the rate over campaigns, at most 2 of 10 confident names, is the benchmark's table)
    assert r["named_effect"] is None or r["confounded_with"], (r["named_effect"], r["confounded_with"])
    assert r["usable_for_prediction"], r["usable_for_prediction_reasons"]
    if r["final_model"] == "statistical_discrepancy":
        assert r["mode_bias"]["applied"]
    # the bench's noise-free FRF at every measurement, computed once for both branches below
    true_hz = _truth_by_mode(res, cfg)
    hit, n = _truth_coverage(true_hz, fitted=True)
    if r["final_model"] == "statistical_discrepancy":
        # the remainder was given the fitted lengths' data: every mode's predictive interval covers the measured
        # mode (issue #19)
        for m in r["measurements_after"]:
            if m["fitted"]:
                assert all(md["covered_predictive_90"] for md in m["modes"]), m["modes"]
        # and its model intervals are calibrated for the noise-free truth, fitted and held out.  Their centre
        # follows the measured peaks (the bias is learned from them), so one campaign's peak noise moves all of a
        # direction's intervals together: in this campaign both x peaks sit 1.4 and 3.0 Hz above the truth (about
        # 2 sd of the peak noise), and the x intervals miss the truth by a few tenths of a Hz at 25 and 40 mm (and
        # follow at 30 and 35 mm).  The rate is the benchmark's table (fitted and held-out coverage over 10
        # campaigns per effect); here every mode's truth lies within 3 sd of its interval's centre (sd = half the
        # 90 % width / 1.645; |z| > 3 has probability 0.003 per mode, so a miss of the calibration by a
        # factor 1.5 or a bias of a few sd fails this)
        n_all = 0
        for (m, md), t in true_hz:
            q = md["model_interval"]
            sd = (q["q95"] - q["q05"]) / (2 * 1.6448536269514722)
            assert abs(t - 0.5 * (q["q05"] + q["q95"])) < 3.0 * sd, (m["clamping_length"], m["direction"], q, t)
            n_all += 1
        assert n_all >= 8 and n >= 4
        # held out (30, 35 mm): the law between the fitted lengths lies between the parallel and the series
        # interface law through the fitted ends, which on this bench's growth (0.45 over 25-40 mm) differ by
        # about 2 % of the growth, so the intervals are set by the mode bias, not by the law: under 1 % of the
        # frequency wide (the previous form, the full series saturation either way whatever the growth, gave
        # 1.2-1.6 % here; measured now 0.3-0.4 %)
        for m in r["measurements_after"]:
            for md in m["modes"] if not m["fitted"] else ():
                q = md["model_interval"]
                assert q["q95"] - q["q05"] < 0.01 * md["measured_hz"], (m["clamping_length"], q)
    else:
        # a named physical model's 90 % intervals miss one fitted mode in ten by chance (usable_for_prediction
        # above already excludes gross misses); of four modes, two or more missed has probability 0.05
        assert n >= 4 and hit >= n - 1, (hit, n)


def test_summary_of_an_unusable_result_writes_no_trustworthy_interval(modulus):
    res, _ = modulus
    report = dict(res.report, usable_for_prediction=False,
                  usable_for_prediction_reasons=["x 25 mm: the 90 % predictive interval [1, 2] Hz misses it"],
                  gap_grew=True)
    text = summary_markdown(report)
    assert "Not usable for prediction" in text and "misses it" in text
    assert "grew" in text and "stay honest" not in text
    rows = [line for line in text.splitlines() if line.startswith("| x 25 mm") or line.startswith("| y 25 mm")]
    assert rows and all("(not usable)" in line for line in rows if "no matching" not in line)


def test_a_fit_on_the_limit_of_its_range_that_outranks_is_a_warning_and_a_summary_line(modulus):
    """When a candidate on the limit of its term's physical range outranks the possible ones (select.decide,
    ``outranked_by_edge``), the run's most useful hint is that effect beyond its range: it is a warning (printed and
    in discrepancy.json) and a reason in summary.md; without it neither appears."""
    import copy

    from bayes_rcsa.discrepancy.document import build_report

    res, _ = modulus
    assert not any("limit of its physical range" in w for w in res.report["warnings"])
    assert "limit of the physical range" not in summary_markdown(res.report)
    over, other = res.refits[0], res.refits[1]
    fake = copy.copy(res)
    fake.decision = dict(res.decision, range_limits_reached={over.effect: ["flute_area_ratio", "flute_inertia_ratio"]},
                         partial=[{"effect": other.effect, "criterion": other.criterion, "systematic_gap_ratio": 0.34,
                                   "outranked_by_edge": over.effect, "outranking_criterion": over.criterion}])
    report = build_report(fake)
    hint = [w for w in report["warnings"] if "limit of its physical range" in w]
    assert len(hint) == 1 and hint[0].startswith(over.effect) and "flute_area_ratio, flute_inertia_ratio" in hint[0]
    assert f"(criterion {over.criterion:+.1f})" in hint[0] and "check the values the setup declares" in hint[0]
    text = summary_markdown(report)
    assert (f"{effect_name(other.effect)} improves the fit decisively, but {effect_name(over.effect)} explains the "
            "data far better") in text
    assert f"criterion {over.criterion:+.1f} against {other.criterion:+.1f}" in text
    assert "limit of the physical range its prior allows" in text
    cand = next(c for c in report["candidates"] if c["effect"] == over.effect)
    assert cand["parameters_on_range_limit"] == ["flute_area_ratio", "flute_inertia_ratio"]
    assert "only with flute area ratio, flute inertia ratio on the limit" in text
    # the pair rule's case: a pair not clearly better than the edge-bound single fit, whose criterion is then not
    # far above the partial candidate's own: "far better" would be false
    close = dict(fake.decision["partial"][0], criterion=over.criterion - 1.0)
    fake.decision = dict(fake.decision, partial=[close])
    report = build_report(fake)
    hint = [w for w in report["warnings"] if "limit of its physical range" in w]
    assert len(hint) == 1 and "far better" not in hint[0] and "a pair included" in hint[0]
    text = summary_markdown(report)
    assert "far better" not in text and "explains the data as well as it does together with a second known effect" in text


def test_summary_marks_held_out_intervals_of_a_two_length_remainder_as_resting_on_an_assumption(modulus):
    # two fitted lengths leave the remainder's bias between them a straight line by assumption (docs/
    # discrepancy.md, "Why the held-out rows miss"): its held-out rows say so, its fitted rows do not
    res, _ = modulus
    r = res.report
    assert r["final_model"] == "statistical_discrepancy" and r["usable_for_prediction"]
    text = summary_markdown(r)
    rows = [line for line in text.splitlines() if line.startswith(("| x ", "| y ")) and "no matching" not in line
            and "prominent mode differs" not in line]
    held = [line for line in rows if line.split("|")[2].strip() == "no"]
    fitted = [line for line in rows if line.split("|")[2].strip() == "yes"]
    assert held and fitted
    assert all("(straight-line bias assumed)" in line for line in held)
    assert not any("assumed" in line for line in fitted)


def test_summary_says_what_the_number_of_fitted_lengths_leaves_of_the_bend(modulus):
    # the remainder's bias between lengths: assumed straight with two fitted lengths, judged from one difference
    # per mode with three (intervals on the wide side; docs/discrepancy.md, "What a fourth tap buys")
    import copy

    res, _ = modulus
    r = res.report
    two = summary_markdown(r)
    assert "straight line that the data cannot test" in two and "fourth measured length" not in two
    three = copy.deepcopy(r)
    extra = next(m for m in three["measurements_after"] if not m["fitted"])
    for m in three["measurements_after"]:
        if m["clamping_length"] == extra["clamping_length"]:
            m["fitted"] = True
    text = summary_markdown(three)
    assert "one difference per mode" in text and "A fourth measured length narrows them" in text
    assert "straight line that the data cannot test" not in text
    one = copy.deepcopy(r)
    first = next(m for m in one["measurements_after"] if m["fitted"])
    for m in one["measurements_after"]:
        m["fitted"] = m["clamping_length"] == first["clamping_length"]
    text = summary_markdown(one)
    assert "With one measured length" in text and "two measured lengths" not in text


def test_adequate_at_the_fitted_lengths_but_not_carrying_says_so(clean):
    res, _ = clean
    r = res.report
    # the clean two-length fit carries to the held-out length: nothing to say
    assert r["gap_held_out_after"] is not None and "does not carry" not in summary_markdown(r)
    # a fit that explains its own lengths but misses the others by 130 % (one fitted length) must say so
    text = summary_markdown(dict(r, adequate=True, gap_held_out_after=1.3))
    assert "explains the measurements it was fitted to" in text and "does not carry" in text and "130 %" in text


def test_hysteretic_joint_is_named_as_a_joint_loss_not_as_viscous_damping(tmp_path_factory):
    """The rotor bench's author replaced the viscous joint damping by a loss factor of 0.05 (unknown to the
    term): the workflow names ``joint_loss_factor``, with ``contact_damping`` among the candidates, and the
    named model keeps the fitted measured modes inside its predictive intervals."""
    res, _ = _run(tmp_path_factory, {"hysteretic_joint": True}, 8)
    r = res.report
    assert r["named_effect"] == "joint_loss_factor", (r["named_effect"], r["confounded_with"])
    assert "contact_damping" in [c["effect"] for c in r["candidates"]]
    assert r["gap_after"] <= 0.5 * r["gap_before"]
    eta = next(c for c in r["candidates"] if c["effect"] == "joint_loss_factor")["parameters"]["joint_loss_factor"]
    # the viscous damping the user assumed stays in the model, so the fitted loss factor is below the bench's
    # 0.05 (noise-free fit: 0.032), and clearly off the prior's lower bound
    assert 0.01 < eta["q50"] < 0.06, eta
    # a named model's modes are corrected by the bias learned from each measured mode's whole resonance, which
    # pins the measured mode far better than its noisy peak line (docs/discrepancy.md, "The mode bias of a named
    # model")
    assert r["mode_bias"]["applied"] and r["mode_bias"]["observation"] == "resonance"
    for m in r["measurements_after"]:
        for md in m["modes"]:
            assert 0 < md["measured_fit_sd_hz"] < 0.25 * md["predictive_sd_hz"], md
            if m["fitted"]:
                assert "bias_hz" in md and md["uncorrected_model_interval"] != md["model_interval"]


def test_the_peak_noise_is_the_measurement_s_own_not_the_final_model_s_fitted_scale(modulus):
    # The scatter of a measured peak (the predictive intervals, the mode bias's observation variance) is the
    # measurement's noise.  The remainder's fitted scale is biased both ways: a misfit inflates it, and its
    # smooth FRF discrepancy absorbs part of the noise and deflates it; the smaller of the two, the rule before,
    # took the deflated one (docs/discrepancy.md, "Why the fitted cells sat at 0.88-0.89").  The own estimate
    # from second differences is 1.00-1.02 of the realised noise on both benches.
    from bayes_rcsa.discrepancy.fit import laplace_draws
    from bayes_rcsa.discrepancy.noise import relative_noise_scale
    from bayes_rcsa.discrepancy.evaluate import _all_stack, _noise_sd
    from bayes_rcsa.inference.band import band_mask

    res, _ = modulus
    prob = res.final.problem
    vals = prob.parameters.values(laplace_draws(res.final, np.random.default_rng(5), 50))
    _, measured, _ = _all_stack(prob)
    own = [relative_noise_scale(frf.values[band_mask(frf, prob.band_of(frf))]) for _, frf in prob.all_measurements]
    used = {(o.configuration, o.source): j for j, o in enumerate(prob.observations)}
    # here the final model's fitted scales lie 6-15 % above the measurement's own; a model whose scale absorbed
    # noise is the same model with its scales 0.8x and 1.25x of that: the peak noise must not follow either
    for factor in (1.0, 0.8, 1.25):
        v = dict(vals)
        for name in prob.parameters.noise_names:
            v[name] = factor * np.asarray(vals[name])
        out = _noise_sd(prob, v, measured, measured)
        sampled = prob.parameters.noise(v)
        below = 0
        for (cfg, frf), (scale, _, _), o in zip(prob.all_measurements, out, own):
            assert np.all(scale == o), (factor, cfg, o, np.unique(scale))
            j = used.get((cfg, frf.source))
            below += j is not None and bool(np.median(sampled[:, j]) < o)
        assert len(used) == 4 and (below == 4 if factor == 0.8 else below == 0), (factor, below)


@pytest.mark.slow
def test_a_holder_resonance_is_named_as_a_resonance_not_as_a_spindle_file_error(tmp_path_factory):
    """The rotor bench's ring resonator (default campaign, seed 51040 of issue #43's naming re-run): with the
    likelihood's noise floor the model's own band maximum and that floor free to move within a Gauss-Newton solve,
    the resonator's refit ran to 1 kg at its damping bound (criterion 22) and ``spindle_error`` was named; with
    the floor held over each solve the resonator explains the data (criterion about 340 against the spindle
    term's 244) and is named, the gap closed to the noise floor."""
    res, _ = _run(tmp_path_factory, {"extra_mode": True}, 51040, full=True)
    crit = {r.effect: r.criterion for r in res.refits}
    assert res.report["named_effect"] == "extra_mode", crit
    # by far, not by the noise: ln 100 = 4.6 decides
    assert crit["extra_mode"] > crit["spindle_error"] + 50, crit
    assert res.report["gap_after"] <= 0.5 * res.report["gap_before"]
