"""The scripts in examples/ run (reduced mode) and print what their docstrings promise.

Every example has a reduced mode (``quick=True``, the same as ``--quick`` or ``BAYES_RCSA_QUICK=1``):
coarse frequency lines where it builds its own campaign and 80 sampler steps.  Those chains are not
converged, but the quantities asserted here (medians of natural frequencies and stiffnesses, the
ordering of transfer errors) are settled within a few dozen steps from the global optimum the
sampler starts from; each tolerance says why it is safe.  Budget: about a minute in all.
"""

from __future__ import annotations

import csv
import json
import runpy
from pathlib import Path

import pytest

from bayes_rcsa.data import example_dir
from bayes_rcsa.synthetic import default_bench_config

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
TRUTH = {(m["clamping_length"], m["direction"]): m["dominant_frequency_hz"]
         for m in json.loads((example_dir() / "truth.json").read_text())["measurements"]}
BENCH = default_bench_config()  # the true contact of the bench (k at 25 mm, growth to 40 mm)


def _main(name: str):
    return runpy.run_path(str(EXAMPLES / name))["main"]


def _run(name: str, **kwargs):
    return _main(name)(**kwargs)


def test_forward_model_example_brackets_the_true_frequencies(capsys):
    out = _run("forward_model.py", quick=True)
    assert sorted(out) == [0.025, 0.030, 0.035, 0.040]
    for length, (lo, mid, hi) in out.items():
        # the example scatters the stiffness around the bench's true law, so its 5-95 % range of the
        # first natural frequency brackets the bench's noise-free value
        assert lo < TRUTH[(length, "x")] < hi
        assert lo < mid < hi
    assert "clamping 30.0 mm" in capsys.readouterr().out


def test_identify_and_predict_example_predicts_held_out_lengths():
    out = _run("identify_and_predict.py", quick=True)
    assert sorted(out) == [0.030, 0.035]
    for length, q in out.items():
        # held-out lengths: within 0.1 % of the bench truth (noise-free FE value)
        assert q["q50"] == pytest.approx(TRUTH[(length, "x")], rel=1e-3)


def test_paper_study_multi_length_transfers_better_than_single_length(capsys):
    out = _run("paper_study.py", quick=True)
    text = capsys.readouterr().out
    for n in (3, 4, 5, 6, 7, 9):
        assert f"Table {n} analogue" in text
    err = out["errors"]
    multi = err["Method II 25+40 mm (Bayes)"]
    for d in ("x", "y"):
        # The far length of each single-length set: 40 mm for set 1 (25 mm), 25 mm for set 2 (40 mm).
        # Trial runs: the single-length sets miss the far length by 12-14 % (paper: 12.8-16.6 %), the
        # multi-length posterior by < 0.1 %; the Bayesian and deterministic single fits agree to 0.05 %.
        for label in ("set 1: 25 mm (Bayes)", "set 1: 25 mm (deterministic)"):
            assert abs(err[label][(0.04, d)]) > 5.0 > 10 * abs(multi[(0.04, d)]), (label, d)
        for label in ("set 2: 40 mm (Bayes)", "set 2: 40 mm (deterministic)"):
            assert abs(err[label][(0.025, d)]) > 5.0 > 10 * abs(multi[(0.025, d)]), (label, d)
        for length in (0.030, 0.035):  # the lengths nobody fitted: Method II wins against both sets
            assert abs(multi[(length, d)]) < min(abs(err[s][(length, d)]) for s in err if s.startswith("set"))
    # Table 3: Method II recovers the bench's contact at 25 mm (trial runs: within 0.1 % for k_xf) and
    # its growth to 40 mm (bench: k(40 mm) = 1.45 k(25 mm))
    qx25, _ = out["stiffness"]["Method II 25+40 mm (Bayes)"][0.025]
    qx40, _ = out["stiffness"]["Method II 25+40 mm (Bayes)"][0.04]
    assert qx25[1] == pytest.approx(BENCH.k_xf, rel=0.02)
    assert qx40[1] / qx25[1] == pytest.approx(1 + BENCH.growth, rel=0.05)
    # Table 9: at each set's far case its lobes deviate more from the measured-FRF lobes than Method II's
    dev = out["deviation"]
    assert dev["d"]["Method II 25+40 mm (Bayes)"][1] < dev["d"]["set 1: 25 mm (Bayes)"][1]
    assert dev["a"]["Method II 25+40 mm (Bayes)"][1] < dev["a"]["set 2: 40 mm (Bayes)"][1]
    for case in dev.values():
        for q05, q50, q95 in case.values():
            assert 0.0 <= q05 <= q50 <= q95 <= 100.0


def test_method_one_predicts_a_held_out_tool_and_separates_the_stiffnesses(capsys):
    result = _run("method_one.py", quick=True)
    out = result["frequencies"]
    assert set(out) == {"em_90", "em_102", "em_115", "em_127"}
    for tool, (measured, q05, q50, q95) in out.items():
        # Same contact for every tool: the held-out tool's frequency is predicted like the fitted ones;
        # trial runs: |error| < 0.1 %, the noise on a measured peak (2 % FRF noise, 8 Hz lines) < 0.3 %.
        assert abs(q50 - measured) / measured < 0.005, tool
        assert q05 <= q50 <= q95
    # the longer the tool, the lower its first bending frequency
    assert out["em_90"][2] > out["em_102"][2] > out["em_115"][2] > out["em_127"][2]
    # Tools of different overhang weigh k_xf and k_thetaM differently, so one clamping length separates
    # them: marginal / conditional width 2.4 in the trial run (corr -0.91), against ~5 (corr -0.98) for
    # one tool at one length; both stiffnesses come out plainly "identified".
    for name in ("k_xf", "k_thetaM"):
        e = result["identifiability"][name]
        assert e["verdict"] == "identified" and e["width_ratio"] < 3.0, (name, e["verdict"], e["width_ratio"])
    text = capsys.readouterr().out
    assert "held out" in text and "k_thetaM" in text


@pytest.fixture(scope="module")
def sampled(tmp_path_factory):
    out = tmp_path_factory.mktemp("posterior_sampling")
    return _run("posterior_sampling.py", quick=True, out=out)


def test_posterior_sampling_round_trip_predicts_the_held_out_lengths(sampled):
    assert sampled["posterior"].is_file()
    for (length, d), q in sampled["frequencies"].items():
        # held-out 30 and 35 mm: within 0.1 % of the bench's noise-free value (trial runs: < 0.05 %)
        assert q["q50"] == pytest.approx(TRUTH[(length, d)], rel=1e-3)
        assert q["q05"] <= q["q50"] <= q["q95"]
    assert sorted(sampled["frequencies"]) == [(0.03, "x"), (0.03, "y"), (0.035, "x"), (0.035, "y")]
    # the reloaded draws carry the growth law: k_xf grows with clamping length
    kx = [sampled["stiffness"][length][0][1] for length in (0.025, 0.030, 0.035, 0.040)]
    assert kx == sorted(kx) and kx[-1] / kx[0] == pytest.approx(1 + BENCH.growth, rel=0.05)


def test_credible_interval_report_writes_a_plausible_table(sampled, tmp_path):
    rows = _run("credible_interval_report.py", posterior=sampled["posterior"], out=tmp_path)
    assert (tmp_path / "natural_frequencies.png").stat().st_size > 10_000
    with open(tmp_path / "natural_frequencies.csv") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == len(rows) == 14  # 25, 27.5, ..., 40 mm in x and y
    for d in ("x", "y"):
        r = [row for row in rows if row["direction"] == d]
        med = [row["q50_hz"] for row in r]
        assert med == sorted(med)  # shorter overhang, higher frequency
        for row in r:
            assert row["q05_hz"] <= row["q25_hz"] <= row["q50_hz"] <= row["q75_hz"] <= row["q95_hz"]
            # the predictive interval of a noisy peak contains the model's credible interval
            assert row["predictive_q05_hz"] <= row["q05_hz"] and row["q95_hz"] <= row["predictive_q95_hz"]
    measured = [row for row in rows if row["measured_hz"] is not None]
    assert len(measured) == 8
    inside = sum(row["predictive_q05_hz"] <= row["measured_hz"] <= row["predictive_q95_hz"] for row in measured)
    # a 90 % predictive interval: 8 measurements, P(fewer than 5 inside) = 0.5 % for a calibrated interval
    assert inside >= 5, inside
    for row, csv_row in zip(rows, table):
        assert float(csv_row["q50_hz"]) == pytest.approx(row["q50_hz"], rel=1e-12)


def test_identifiability_example_contrasts_single_and_multi(tmp_path, capsys):
    doc = _run("identifiability_single_vs_multi.py", quick=True, out=tmp_path)
    fits = {f["name"]: f for f in doc["fits"]}
    assert set(fits) == {"single_25mm", "single_40mm", "multi"}
    for name in ("single_25mm", "single_40mm"):
        # one length: corr(log k_xf, log k_thetaM) ~ -0.98, width ratio ~5 (threshold 3)
        assert fits[name]["parameters"]["k_xf"]["verdict"] == "identified only in combination with k_thetaM"
        assert fits[name]["parameters"]["k_thetaM"]["width_ratio"] > 3.0
        assert min(fits[name]["transfer_error_pct"].values()) > 3.0  # trial runs: 4-14 %
    assert max(fits["multi"]["transfer_error_pct"].values()) < 0.5  # trial runs: < 0.1 %
    assert (tmp_path / "corner_overlay.png").stat().st_size > 10_000
    text = capsys.readouterr().out
    assert "1 - " not in text and "prior width / posterior width" in text


def test_uff_roundtrip_gives_the_csv_result():
    out = _run("uff_roundtrip.py", quick=True)
    # binary double-precision UFF58 is lossless, so the same seed gives the same draws
    assert out["identical"] is True
    assert out["csv"] == out["uff"]
