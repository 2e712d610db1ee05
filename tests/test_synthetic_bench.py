"""Synthetic bench: cross-check with the RCSA model, hidden effects, noise, campaign files.

Peak estimation here is the tests' own (a parabola through five lines
around the largest |H| in a band), not the library's ``dominant_peak``.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from bayes_rcsa.errors import SetupError
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.model import Configuration, ToolPointModel
from bayes_rcsa.synthetic import (
    CANONICAL_EFFECTS, DEFAULT_MAGNITUDES, default_bench_config, exported_spindle_receptance, generate_campaign,
    load_bench_config, measured_mean_frf, true_contact, true_spindle_receptance, true_tool_point_frf, write_campaign,
)
from bayes_rcsa.synthetic.noise import add_measurement_noise

N_SEEDS = 12  # noise realisations per clamping length for the scatter estimate


def peak(f, h, lo=None, hi=None):
    """(frequency Hz, |H| m/N) of the largest |H| in [lo, hi], refined by a 5-line parabola."""
    a = np.abs(h)
    band = np.ones(f.size, bool) if lo is None else (f >= lo) & (f <= hi)
    idx = np.nonzero(band)[0]
    i = idx[np.argmax(a[idx])]
    sl = slice(i - 2, i + 3)
    c = np.polyfit(f[sl] - f[i], a[sl], 2)
    x = -c[1] / (2 * c[0])
    return f[i] + x, np.polyval(c, x)


def rcsa_prediction(cfg, configuration, f, spindle=None):
    """The user's RCSA model at the true contact parameters."""
    spindle = spindle or exported_spindle_receptance(cfg, configuration.direction, f)
    model = ToolPointModel(cfg.holder, {"tool": cfg.tool}, {configuration.direction: spindle})
    c = true_contact(cfg, configuration.clamping_length)
    return model.frf(configuration, f, c["k_xf"], c["k_thetaM"], c["c_xf"], c["c_thetaM"])


# ------------------------------------------------------------ cross-check --


@pytest.mark.parametrize("direction", ["x", "y"])
def test_lumped_fe_agrees_with_rcsa_forward_model(direction):
    """Acceptance: no hidden effect, lumped contact -> FE and RCSA agree within 0.5 % in frequency."""
    cfg = default_bench_config()
    for cl in cfg.clamping_lengths:
        conf = Configuration(cl, direction)
        coarse = cfg.frequency_hz
        f0, _ = peak(coarse, true_tool_point_frf(cfg, conf, coarse))
        f = np.arange(f0 - 30.0, f0 + 30.0, 0.05)
        fe = true_tool_point_frf(cfg, conf, f)
        rcsa = rcsa_prediction(cfg, conf, f)
        (ffe, afe), (fr, ar) = peak(f, fe), peak(f, rcsa)
        assert 700 < ffe < 1400  # the dominant tool mode, not a spindle mode
        assert abs(ffe / fr - 1) < 0.005  # acceptance bound; observed ~2e-6
        # Much tighter in fact: both are converged Timoshenko models of the same
        # physics (observed 2e-6 in frequency, 1e-6 in peak height).
        assert abs(ffe / fr - 1) < 1e-4
        assert abs(afe / ar - 1) < 1e-3


def test_distributed_contact_tends_to_lumped_when_stiff_and_is_softer_otherwise():
    f = np.arange(600.0, 3000.0, 1.0)
    stiff = dict(k_xf=1e11, k_thetaM=1e11)
    conf = Configuration(0.03, "x")
    lumped = peak(f, true_tool_point_frf(default_bench_config(**stiff), conf, f))[0]
    spread = peak(f, true_tool_point_frf(default_bench_config(contact_model="distributed", **stiff), conf, f))[0]
    # Perfect bond along the clamped length = the composite section of the lumped model.
    assert spread == pytest.approx(lumped, rel=1e-3)
    soft_l = peak(f, true_tool_point_frf(default_bench_config(), conf, f), 700, 1300)[0]
    soft_d = peak(f, true_tool_point_frf(default_bench_config(contact_model="distributed"), conf, f), 700, 1300)[0]
    assert soft_d < 0.95 * soft_l  # the shank now bends inside the bore


def test_default_campaign_matches_design_targets():
    cfg = default_bench_config()
    k25, k40 = true_contact(cfg, 0.025), true_contact(cfg, 0.040)
    assert k25["k_xf"] == pytest.approx(1.8e6) and k25["k_thetaM"] == pytest.approx(4.5e5)
    assert 2.5e6 < k40["k_xf"] < 2.9e6 and 6.3e5 < k40["k_thetaM"] < 6.9e5
    assert cfg.growth <= cfg.growth_bound  # the truth lies inside the user's prior
    assert cfg.frequency_hz.size == 1501
    f = cfg.frequency_hz
    freqs = [peak(f, true_tool_point_frf(cfg, Configuration(cl, "x"), f))[0] for cl in cfg.clamping_lengths]
    assert np.all(np.diff(freqs) > 0)  # stiffer and shorter with clamping length
    assert 800 < freqs[0] < 900 and 1150 < freqs[-1] < 1250


# ---------------------------------------------------------- hidden effects --

# How each effect shows itself: in the data (true structure) or in the user's
# prediction (exported spindle file); which length(s) and quantity are documented
# in docs/synthetic.md.
_IN_USER_MODEL = {"spindle_error", "spindle_rotation_omitted"}


@pytest.fixture(scope="module")
def baseline():
    cfg = default_bench_config(directions=("x",))
    f = cfg.frequency_hz
    out = {}
    for cl in cfg.clamping_lengths:
        conf = Configuration(cl, "x")
        clean = true_tool_point_frf(cfg, conf, f)
        f0 = peak(f, clean)[0]
        band = (0.75 * f0, 1.25 * f0)
        est = np.array([
            peak(f, add_measurement_noise(clean, cfg.noise_relative, cfg.noise_floor, cfg.n_averages,
                                          np.random.default_rng(seed))[0], *band)
            for seed in range(N_SEEDS)
        ])
        out[cl] = {"band": band, "mean": est.mean(axis=0), "scatter": est.std(axis=0, ddof=1),
                   "user": np.array(peak(f, rcsa_prediction(cfg, conf, f), *band))}
    return cfg, f, out


@pytest.mark.parametrize("name", sorted(DEFAULT_MAGNITUDES))
def test_each_hidden_effect_moves_the_tool_mode_beyond_noise(baseline, name):
    """Acceptance: default magnitude shifts frequency or peak height by > 3x the noise scatter."""
    cfg0, f, base = baseline
    cfg = cfg0.with_effects(**{name: True})
    assert cfg.hidden_effects == {name: DEFAULT_MAGNITUDES[name]}
    ratios = []
    for cl, b in base.items():
        conf = Configuration(cl, "x")
        if name in _IN_USER_MODEL:
            shift = np.array(peak(f, rcsa_prediction(cfg, conf, f), *b["band"])) - b["user"]
        else:
            shift = np.array(peak(f, true_tool_point_frf(cfg, conf, f), *b["band"])) - b["mean"]
        ratios.append(np.abs(shift) / b["scatter"])
    assert np.max(ratios) > 3.0, f"{name}: shift / noise scatter per length (f, |H|) = {np.round(ratios, 1).tolist()}"


def test_canonical_effect_names():
    assert CANONICAL_EFFECTS == (
        "contact_damping", "tip_mass", "fluted_section", "extra_mode", "nonlinear_stiffness_law")
    assert set(CANONICAL_EFFECTS) <= set(DEFAULT_MAGNITUDES)


def test_nonlinear_law_keeps_end_values_and_is_stiffer_inside():
    lin = default_bench_config()
    sat = lin.with_effects(nonlinear_stiffness_law=4.0)
    for cl in lin.clamping_range:
        assert true_contact(sat, cl)["k_xf"] == pytest.approx(true_contact(lin, cl)["k_xf"], rel=1e-12)
    x = 1 / 3  # 30 mm in [25, 40] mm
    expected = lin.k_xf * (1 + lin.growth * (1 - math.exp(-4 * x)) / (1 - math.exp(-4)))
    assert true_contact(sat, 0.030)["k_xf"] == pytest.approx(expected, rel=1e-12)
    assert true_contact(sat, 0.030)["k_xf"] > 1.15 * true_contact(lin, 0.030)["k_xf"]


def test_contact_damping_and_extra_mode_are_hidden_from_the_user():
    cfg = default_bench_config(directions=("x",), clamping_lengths=(0.03,), hidden_effects={
        "contact_damping": 5.0, "extra_mode": True, "tip_mass": True, "fluted_section": True})
    camp = generate_campaign(cfg, np.random.default_rng(1))
    assert camp.setup["contact"]["translational_damping"] == cfg.c_xf
    assert camp.truth["damping"]["c_xf"] == 5.0 * cfg.c_xf
    assert camp.setup["tool"]["segments"][0]["diameter_ratio"] == 0.8
    assert camp.truth["tool"]["segments"][0]["diameter_ratio"] == pytest.approx(0.72)
    # The exported spindle is the spindle alone: no resonator.
    np.testing.assert_array_equal(camp.spindle["x"].block, true_spindle_receptance(cfg, "x", cfg.frequency_hz).block)
    assert camp.truth["hidden_effect_details"]["extra_mode"]["frequency_hz"] == cfg.extra_mode_frequency


def test_spindle_export_is_reciprocal_passive_and_perturbable():
    cfg = default_bench_config()
    f = cfg.frequency_hz
    sx, sy = (true_spindle_receptance(cfg, d, f).block for d in "xy")
    np.testing.assert_allclose(sx[:, 0, 1], sx[:, 1, 0], rtol=1e-9, atol=1e-9 * np.abs(sx[:, 0, 1]).max())
    assert np.all(sx[:, 0, 0].imag <= 0) and np.all(sx[:, 1, 1].imag <= 0)
    assert not np.allclose(sx, sy)  # bearing anisotropy
    dropped = exported_spindle_receptance(cfg.with_effects(spindle_rotation_omitted=1.0), "x", f).block
    np.testing.assert_array_equal(dropped[:, 0, 0], sx[:, 0, 0])
    assert not dropped[:, 0, 1].any() and not dropped[:, 1, 1].any()
    err = exported_spindle_receptance(cfg.with_effects(spindle_error=0.15), "x", f).block
    assert np.abs(err[:, 0, 0]).max() < np.abs(sx[:, 0, 0]).max()  # stiffer bearings, lower flange peaks


def test_a_spindle_file_with_softer_bearings_and_the_range_of_the_change():
    # another day's preload or temperature: the file's bearings can be softer as well as stiffer (issue #43)
    cfg = default_bench_config()
    f = cfg.frequency_hz
    sx = true_spindle_receptance(cfg, "x", f).block
    soft = exported_spindle_receptance(cfg.with_effects(spindle_error=-0.25), "x", f).block
    assert np.abs(soft[:, 0, 0]).max() > np.abs(sx[:, 0, 0]).max()  # softer bearings, higher flange peaks
    # the lowest flange resonance moves down (bearing-dominated), never up
    assert f[np.argmax(np.abs(soft[:, 0, 0]))] < f[np.argmax(np.abs(sx[:, 0, 0]))]
    assert np.all(soft[:, 0, 0].imag <= 0) and np.all(soft[:, 1, 1].imag <= 0)  # still passive
    for bad, match in ((-0.5, "> -0.5 other than 0"), (-0.7, "> -0.5 other than 0"), (0.0, "other than 0")):
        with pytest.raises(SetupError, match=match):
            cfg.with_effects(spindle_error=bad)
    with pytest.raises(SetupError, match="expected a finite magnitude > 0"):
        cfg.with_effects(tip_mass=-0.001)  # an effect without a direction stays positive


# ------------------------------------------------------------------ noise --


def test_noise_level_and_coherence():
    cfg = default_bench_config()
    f = cfg.frequency_hz
    clean = true_tool_point_frf(cfg, Configuration(0.025, "x"), f)
    noisy, coh = add_measurement_noise(clean, 0.02, 1e-8, 5, np.random.default_rng(3))
    sigma = 0.02 * np.abs(clean) + 1e-8
    z = (noisy - clean) / sigma
    # E|z|^2 = 1 for circular complex noise; 1501 lines -> sampling error ~ 2.6 %.
    assert np.mean(np.abs(z) ** 2) == pytest.approx(1.0, abs=0.1)
    assert abs(np.mean(z.real * z.imag)) < 0.05
    assert np.all((coh >= 0) & (coh <= 1))
    i_peak, i_anti = np.argmax(np.abs(clean)), np.argmin(np.abs(clean))
    assert coh[i_peak] > 0.99 and coh[i_anti] < coh[i_peak] - 0.1


def test_resolution_averaging_is_close_to_point_sampling_for_narrow_lines():
    cfg = default_bench_config()
    f = np.arange(700.0, 1000.0, 2.0)
    conf = Configuration(0.025, "x")
    point = true_tool_point_frf(cfg, conf, f)
    narrow = measured_mean_frf(dataclasses.replace(cfg, resolution_hz=0.01), conf, f)
    # Line width 0.01 Hz vs half-power bandwidth ~20 Hz: second-order smearing ~1e-6.
    np.testing.assert_allclose(narrow, point, rtol=1e-4)
    wide = measured_mean_frf(dataclasses.replace(cfg, resolution_hz=8.0), conf, f)
    assert np.abs(wide).max() < np.abs(point).max()  # averaging flattens the peak


# --------------------------------------------------------------- campaign --


def _small(**kw):
    return default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.04), **kw)


def test_campaign_truth_and_setup_are_consistent():
    cfg = _small(hidden_effects={"nonlinear_stiffness_law": True})
    camp = generate_campaign(cfg, np.random.default_rng(0))
    assert [c.clamping_length for c, _ in camp.measurements] == [0.025, 0.04]
    assert [m["file"] for m in camp.setup["measurement"]] == [frf.source for _, frf in camp.measurements]
    assert camp.truth["hidden_effects"] == {"nonlinear_stiffness_law": 4.0}
    assert camp.truth["law"]["kind"] == "saturating"
    assert json.loads(json.dumps(camp.truth)) == camp.truth  # JSON-able
    for entry, (conf, frf) in zip(camp.truth["measurements"], camp.measurements):
        assert entry["direction"] == conf.direction
        assert frf.coherence is not None and frf.coherence.shape == frf.values.shape
        f_est, a_est = peak(frf.frequency_hz, frf.values)
        assert f_est == pytest.approx(entry["dominant_frequency_hz"], rel=3e-3)  # noisy vs clean, ~1e-3 scatter


def test_written_campaign_reads_back_through_project_loaders(tmp_path):
    cfg = _small()
    camp = generate_campaign(cfg, np.random.default_rng(5))
    setup_path = write_campaign(camp, tmp_path / "camp")
    assert setup_path == tmp_path / "camp" / "setup.toml"
    setup = load_setup(setup_path)
    assert setup.contact.clamping_range == cfg.clamping_range
    assert setup.contact.translational_damping == cfg.c_xf
    assert setup.holder == cfg.holder and setup.tools["tool"].segments == cfg.tool.segments
    for spec, (conf, frf) in zip(setup.measurements, camp.measurements):
        assert spec.configuration == conf
        np.testing.assert_array_equal(spec.frf.values, frf.values)  # repr-exact CSV round trip
        np.testing.assert_array_equal(spec.frf.coherence, frf.coherence)
    np.testing.assert_array_equal(setup.spindle["x"].block, camp.spindle["x"].block)
    truth = json.loads((tmp_path / "camp" / "truth.json").read_text())
    assert truth["contact"][1]["k_xf"] == pytest.approx(cfg.k_xf * (1 + cfg.growth))
    # The user's own model at the true parameters reproduces the clean data.
    h = setup.model().frf(setup.measurements[0].configuration, setup.measurements[0].frf.frequency_hz,
                          **{k: truth["contact"][0][k] for k in ("k_xf", "k_thetaM", "c_xf", "c_thetaM")})
    assert peak(setup.measurements[0].frf.frequency_hz, h)[0] == pytest.approx(
        truth["measurements"][0]["dominant_frequency_hz"], rel=1e-4)


def test_same_seed_gives_byte_identical_files(tmp_path):
    cfg = _small(hidden_effects={"tip_mass": True})
    dirs = []
    for i, seed in enumerate((11, 11, 12)):
        d = tmp_path / f"run{i}"
        write_campaign(generate_campaign(cfg, np.random.default_rng(seed)), d)
        dirs.append(d)
    names = sorted(p.name for p in dirs[0].iterdir())
    assert names == ["setup.toml", "spindle_x.csv", "tip_x_25mm.csv", "tip_x_40mm.csv", "truth.json"]
    for name in names:
        assert (dirs[0] / name).read_bytes() == (dirs[1] / name).read_bytes()
    assert (dirs[0] / "tip_x_25mm.csv").read_bytes() != (dirs[2] / "tip_x_25mm.csv").read_bytes()
    assert (dirs[0] / "spindle_x.csv").read_bytes() == (dirs[2] / "spindle_x.csv").read_bytes()


def test_write_campaign_leaves_nothing_on_error(tmp_path, monkeypatch):
    import bayes_rcsa.io.frf_csv as frf_csv

    camp = generate_campaign(_small(), np.random.default_rng(0))
    calls = []

    def failing(path, frf, comments=()):
        calls.append(path)
        if len(calls) == 2:
            raise OSError("disk full")
        return original(path, frf, comments)

    original = frf_csv.write_frf_csv
    monkeypatch.setattr(frf_csv, "write_frf_csv", failing)
    with pytest.raises(OSError, match="disk full"):
        write_campaign(camp, tmp_path / "out")
    assert list(tmp_path.iterdir()) == []  # neither the target nor a temporary directory


def test_write_campaign_refuses_non_empty_directory_unless_overwriting(tmp_path):
    camp = generate_campaign(_small(), np.random.default_rng(0))
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    with pytest.raises(SetupError, match="not empty"):
        write_campaign(camp, out)
    assert (out / "keep.txt").exists()
    write_campaign(camp, out, overwrite=True)
    assert not (out / "keep.txt").exists() and (out / "truth.json").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


# ----------------------------------------------------------------- config --


def test_example_config_is_the_default():
    from pathlib import Path

    import bayes_rcsa.synthetic as syn

    assert load_bench_config(Path(syn.__file__).parent / "example_bench.toml") == default_bench_config()


@pytest.mark.parametrize("text, match", [
    ("[hidden_effects]\nwobble = 1.0\n", "unknown hidden effect 'wobble'"),
    ("[noise]\nrelative = -0.1\n", "noise_relative"),
    ("[campaign]\nclamping_lengths = [0.07]\n", "bore depth"),
    ("[contact]\nk_xf = 'stiff'\n", "contact.k_xf"),
    ("colour = 'red'\n", "unknown top-level key 'colour'"),
    ("[frequency\n", "invalid TOML"),
    ("contact_model = 'glued'\n", "contact_model"),
])
def test_bad_bench_config_is_rejected_with_a_named_key(tmp_path, text, match):
    p = tmp_path / "bench.toml"
    p.write_text(text)
    with pytest.raises(SetupError, match=match) as info:
        load_bench_config(p)
    assert str(p) in str(info.value)


def test_partial_config_overrides_only_given_keys(tmp_path):
    p = tmp_path / "bench.toml"
    p.write_text("[hidden_effects]\ntip_mass = true\nextra_mode = 0.3\n[campaign]\ndirections = ['y']\n")
    cfg = load_bench_config(p)
    assert cfg.hidden_effects == {"extra_mode": 0.3, "tip_mass": DEFAULT_MAGNITUDES["tip_mass"]}
    assert cfg.directions == ("y",)
    assert dataclasses.replace(cfg, hidden_effects={}, directions=("x", "y")) == default_bench_config()


def test_separate_rotational_growth():
    cfg = default_bench_config(growth_thetaM=0.2)
    c40 = true_contact(cfg, 0.040)
    assert c40["k_xf"] == pytest.approx(cfg.k_xf * 1.45) and c40["k_thetaM"] == pytest.approx(cfg.k_thetaM * 1.2)
