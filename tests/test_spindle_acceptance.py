"""Acceptance of the spindle identification on synthetic artifact tests (independent FE bench).

The artifact hammer tests come from the bench's finite-element spindle +
bonded artifact (``bayes_rcsa.synthetic.artifact``), with 1 % noise; the
truth is the bench's flange receptance of the spindle alone.  Natural
frequencies are found here with the tests' own parabola through three
lines of ln|h| on a fine grid (not the library's rule).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.io import read_spindle_csv, write_frf_csv
from bayes_rcsa.io.toml_writer import dump_toml
from bayes_rcsa.model import FRF, Configuration, ConfigurationStack, PointReceptance, ToolPointModel
from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel
from bayes_rcsa.spindle import is_passive, is_reciprocal, load_artifact, load_spindle_samples
from bayes_rcsa.spindle.identification import identify_direction
from bayes_rcsa.spindle.uncertainty import SpindleSamples
from bayes_rcsa.synthetic import default_bench_config, true_contact, true_tool_point_frf
from bayes_rcsa.synthetic.artifact import default_bench_artifact, generate_artifact_tests, write_artifact_tests

DIRECTION = "x"
N_SAMPLES = 9  # three per mode count (BIC-best and two larger): enough to show the spread, cheap


def peak_frequency(f, h):
    """Vertex of the parabola through ln|h| at the largest line and its neighbours."""
    y = np.log(np.abs(h))
    i = np.clip(np.argmax(y, axis=-1), 1, f.size - 2)
    take = lambda k: np.take_along_axis(y, (i + k)[..., None], axis=-1)[..., 0]  # noqa: E731
    y0, y1, y2 = take(-1), take(0), take(1)
    step = f[1] - f[0]
    return f[i] + 0.5 * step * (y0 - y2) / (y0 - 2 * y1 + y2)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    cfg = default_bench_config()
    art = default_bench_artifact(noise_relative=0.01)
    tests = generate_artifact_tests(cfg, art, np.random.default_rng(11), directions=(DIRECTION,))
    path = write_artifact_tests(tests, tmp_path_factory.mktemp("artifact") / "tests")
    setup = load_artifact(path)
    result = identify_direction(setup, DIRECTION, n_samples=N_SAMPLES, rng=np.random.default_rng(5))
    return {"config": cfg, "tests": tests, "path": path, "setup": setup, "result": result,
            "truth": tests.true_spindle[DIRECTION]}


def test_identified_flange_h_within_5_percent_over_the_tool_mode_band(campaign):
    r, truth = campaign["result"], campaign["truth"].block
    f = r.frequency_hz
    band = (f >= 500) & (f <= 3000)
    err = np.abs(np.abs(r.smoothed[band, 0, 0]) - np.abs(truth[band, 0, 0])) / np.abs(truth[band, 0, 0])
    assert err.max() < 0.05, f"max |h| error {err.max():.3%} at {f[band][np.argmax(err)]:g} Hz"
    # away from the flagged bands the smoothing is far better than 5 %
    ok = band & ~r.unreliable
    assert np.median(np.abs(np.abs(r.smoothed[ok, 0, 0]) / np.abs(truth[ok, 0, 0]) - 1)) < 0.005


def test_tool_point_frequency_with_identified_spindle_within_1_percent(campaign):
    cfg, r = campaign["config"], campaign["result"]
    f = r.frequency_hz
    identified = PointReceptance(f, r.smoothed)
    grid = np.arange(500.0, 3000.0, 2.0)
    for cl in cfg.clamping_lengths:
        c = true_contact(cfg, cl)
        conf = Configuration(cl, DIRECTION)
        freqs = []
        for spindle in (identified, campaign["truth"]):
            model = ToolPointModel(cfg.holder, {"tool": cfg.tool}, {DIRECTION: spindle})
            freqs.append(peak_frequency(grid, model.frf(conf, grid, c["k_xf"], c["k_thetaM"], c["c_xf"], c["c_thetaM"])))
        assert abs(freqs[0] / freqs[1] - 1) < 0.01, (cl, freqs)


def test_smoothed_block_and_samples_are_reciprocal_and_passive(campaign):
    r = campaign["result"]
    assert np.array_equal(r.smoothed[:, 0, 1], r.smoothed[:, 1, 0])
    assert is_reciprocal(r.smoothed) and is_passive(r.smoothed)
    assert r.samples.shape == (N_SAMPLES, r.frequency_hz.size, 2, 2)
    assert all(is_reciprocal(s) and is_passive(s) for s in r.samples)
    s = r.summary()
    assert s["reciprocal"] and s["passive"] and s["modal_model"]["n_modes"] >= 3


def test_unreliable_bands_cover_the_spindle_resonance(campaign):
    """The inversion is ill-conditioned at the spindle's flange mode near 1.9 kHz and fine between modes."""
    r = campaign["result"]
    f = r.frequency_hz
    assert any(lo <= 1916.0 <= hi for lo, hi in r.bands)
    quiet = (f >= 1000) & (f <= 1500)
    assert not r.unreliable[quiet].any()
    assert r.unreliable.mean() < 0.2
    # the estimated noise level matches the simulated 1 %
    assert all(abs(v / 0.01 - 1) < 0.1 for v in r.noise_relative.values())


def test_spindle_uncertainty_widens_tool_point_intervals_and_covers_the_truth(campaign):
    """Fixed contact draws, predicted with the nominal spindle and with every spindle sample.

    The contact draws are a narrow log-normal cloud around the true contact
    (0.02 %: a posterior so tight that the spindle matters).  Without spindle
    uncertainty every draw uses the nominal identified block; with it, every
    draw is evaluated with every sample (a full cross product, so the
    comparison is not at the mercy of which draw met which sample).
    """
    cfg, r = campaign["config"], campaign["result"]
    cl = cfg.clamping_lengths[0]
    conf = Configuration(cl, DIRECTION)
    c = true_contact(cfg, cl)
    coarse = np.arange(700.0, 1000.0, 1.0)
    f_true0 = peak_frequency(coarse, true_tool_point_frf(cfg, conf, coarse))
    fine = np.arange(f_true0 - 2.0, f_true0 + 2.0, 0.01)
    truth = peak_frequency(fine, true_tool_point_frf(cfg, conf, fine))  # the FE bench, independent of RCSA

    rng = np.random.default_rng(17)
    n = 100
    kx = c["k_xf"] * np.exp(2e-4 * rng.standard_normal(n))
    kt = c["k_thetaM"] * np.exp(2e-4 * rng.standard_normal(n))
    f = r.frequency_hz
    samples = SpindleSamples(f, {DIRECTION: r.smoothed}, {DIRECTION: r.samples})
    model = ToolPointModel(cfg.holder, {"tool": cfg.tool}, {DIRECTION: samples.receptance(DIRECTION)})
    without = peak_frequency(fine, model.precompute(conf, fine).frf(kx, kt, c["c_xf"], c["c_thetaM"]))
    # every draw with every sample: the draws repeated once per sample, sample j for the j-th copy
    pm = ParameterModel.from_priors(GrowthLaw(cl, cl), {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8)},
                                    {"c_xf": c["c_xf"], "c_thetaM": c["c_thetaM"], "g_xf": 0.0, "g_thetaM": 0.0})
    forward = ForwardModel(pm, ConfigurationStack([model.precompute(conf, fine)]), model, spindle_samples=samples)
    values = {"k_xf": np.tile(kx, N_SAMPLES), "k_thetaM": np.tile(kt, N_SAMPLES),
              **{name: np.full(n * N_SAMPLES, v) for name, v in pm.fixed.items()}}
    with_ = peak_frequency(fine, forward.frf(values, np.repeat(np.arange(N_SAMPLES), n)))

    lo0, hi0 = np.quantile(without, [0.025, 0.975])
    lo1, hi1 = np.quantile(with_, [0.025, 0.975])
    assert hi1 - lo1 > hi0 - lo0
    assert np.std(with_) > np.std(without)
    assert lo1 <= truth <= hi1, (truth, lo1, hi1, lo0, hi0)


# ------------------------------------------------------------------ CLI --


@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory):
    """A cheaper artifact campaign (400-2600 Hz, 2 Hz) for command-line tests."""
    cfg = default_bench_config()
    art = default_bench_artifact(frequency_start=400.0, frequency_stop=2600.0, frequency_step=2.0)
    tests = generate_artifact_tests(cfg, art, np.random.default_rng(2), directions=("x",))
    return write_artifact_tests(tests, tmp_path_factory.mktemp("small") / "tests")


def test_cli_writes_spindle_files_samples_and_plots(small_campaign, tmp_path, capsys):
    """End to end, with the noise level given and artifact-model uncertainty in the bootstrap."""

    def options(doc, work):
        doc["noise"] = {"relative": 0.01}
        doc["uncertainty"] = {"youngs_modulus": 0.01}

    path = _edited(small_campaign, tmp_path, options)
    out = tmp_path / "out"
    code = main(["spindle", path, "--out", str(out), "--samples", "2", "--quiet", "--json"])
    assert code == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["spindle_files"] == {"x": "spindle_x.csv"}
    rec = read_spindle_csv(out / "spindle_x.csv")
    assert is_reciprocal(rec.block) and is_passive(rec.block)
    samples = load_spindle_samples(out / "spindle_samples.npz")
    assert samples.n_samples == 2 and np.array_equal(samples.nominal["x"], rec.block)
    assert not np.array_equal(samples.samples["x"][0], samples.samples["x"][1])
    summary = json.loads((out / "spindle_summary.json").read_text())
    d = summary["directions"]["x"]
    assert d["passive"] and d["reciprocal"] and summary["samples_file"] == "spindle_samples.npz"
    assert not d["noise_estimated_from_data"] and set(d["noise_relative"].values()) == {0.01}
    for name in ("spindle_x_raw.csv", "spindle_x_reliability.csv", "spindle_x.png", "artifact_x.png"):
        assert (out / name).stat().st_size > 0
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary leftovers


def test_artifact_file_accepts_uff58_measurements(small_campaign, tmp_path):
    from bayes_rcsa.io import read_frf_csv, write_frf_uff

    def to_uff(doc, work):
        for m in doc["measurement"]:
            for key in ("h11", "h12", "h21", "h22"):
                write_frf_uff(work / (m[key][:-4] + ".uff"), read_frf_csv(work / m[key]))
                m[key] = m[key][:-4] + ".uff"

    setup = load_artifact(_edited(small_campaign, tmp_path, to_uff))
    csv = load_artifact(small_campaign)
    for key in ("h11", "h12", "h21", "h22"):
        a = getattr(setup.measurements["x"], key)
        b = getattr(csv.measurements["x"], key)
        np.testing.assert_array_equal(a.values, b.values)  # UFF58 double precision: lossless


def _edited(small_campaign, tmp_path, edit) -> str:
    import shutil
    import tomllib

    work = tmp_path / "edited"
    shutil.copytree(small_campaign.parent, work)
    doc = tomllib.loads((work / "artifact.toml").read_text())
    edit(doc, work)
    (work / "artifact.toml").write_text(dump_toml(doc))
    return str(work / "artifact.toml")


def _points_coincide(doc, work):
    doc["points"]["point2"] = doc["points"]["point1"]


def _no_cross(doc, work):
    for m in doc["measurement"]:
        m.pop("h12")
        m.pop("h21")


def _other_grid(doc, work):
    f = np.arange(400.0, 2600.0, 4.0)
    write_frf_csv(work / "h22_x.csv", FRF(f, np.full(f.size, 1e-8 - 1e-9j)))


@pytest.mark.parametrize("edit, message", [
    (_points_coincide, "coincide"),
    (_no_cross, "missing cross FRF"),
    (_other_grid, "frequency axes differ"),
])
def test_cli_bad_input_exits_2_with_a_clear_message(small_campaign, tmp_path, capsys, edit, message):
    path = _edited(small_campaign, tmp_path, edit)
    out = tmp_path / "out"
    assert main(["spindle", path, "--out", str(out), "--samples", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()
