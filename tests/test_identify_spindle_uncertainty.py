"""``identify --spindle-uncertainty``: spindle samples widen the predicted natural-frequency intervals."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir
from bayes_rcsa.io import load_setup
from bayes_rcsa.spindle.uncertainty import SpindleSamples, save_spindle_samples


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("spindle_unc")
    shutil.copytree(example_dir(), root / "ex")
    setup_path = root / "ex" / "setup.toml"
    setup = load_setup(setup_path, load_data=False, load_spindle=True)
    f = setup.spindle["x"].frequency_hz
    # A crude stand-in for bootstrap samples: the whole flange block scaled by +-4 % (a stiffer or
    # softer spindle), which moves the tool mode by a few Hz -- far more than the contact posterior.
    scale = np.array([0.96, 0.98, 1.0, 1.02, 1.04])[:, None, None, None]
    nominal = {d: setup.spindle[d].interpolate(f) for d in ("x", "y")}
    samples = SpindleSamples(f, nominal, {d: nominal[d][None] * scale for d in nominal}, source="test")
    npz = save_spindle_samples(root / "spindle_samples.npz", samples)
    common = [str(setup_path), "--lengths", "0.025,0.040", "--seed", "3", "--max-steps", "1000", "--quiet", "--no-plots"]
    assert main(["identify", *common, "--out", str(root / "plain")]) == 0
    assert main(["identify", *common, "--out", str(root / "mixed"), "--spindle-uncertainty", str(npz)]) == 0
    load = lambda name: json.loads((root / name / "summary.json").read_text())  # noqa: E731
    return load("plain"), load("mixed"), root, npz


def test_same_posterior_with_and_without_spindle_samples(runs):
    plain, mixed, _, _ = runs
    for name, p in plain["parameters"].items():
        assert mixed["parameters"][name]["q50"] == p["q50"]  # the sampler's random streams are unchanged
    assert mixed["spindle_uncertainty"]["n_samples"] == 5


def test_spindle_samples_widen_natural_frequency_intervals(runs):
    plain, mixed, _, _ = runs
    ratios = []
    for a, b in zip(plain["natural_frequencies"], mixed["natural_frequencies"]):
        assert (a["clamping_length"], a["direction"]) == (b["clamping_length"], b["direction"])
        ratios.append((b["q95_hz"] - b["q05_hz"]) / (a["q95_hz"] - a["q05_hz"]))
    # +-4 % on the flange block moves the tool mode by a fraction of a Hz to a few tenths: every
    # interval widens, on average by half again (the contact, not the spindle, dominates the mode)
    assert min(ratios) > 1.0 and np.mean(ratios) > 1.5, ratios


def test_samples_missing_a_direction_is_a_clean_error(runs, tmp_path, capsys):
    _, _, root, npz = runs
    data = np.load(npz, allow_pickle=False)
    s = SpindleSamples(data["frequency_hz"], {"x": data["nominal_x"]}, {"x": data["samples_x"]}, source="x only")
    only_x = save_spindle_samples(tmp_path / "x_only.npz", s)
    out = tmp_path / "run"
    argv = ["identify", str(root / "ex" / "setup.toml"), "--out", str(out), "--spindle-uncertainty", str(only_x), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "x_only.npz" in err and "'y'" in err and err.count("\n") == 1
