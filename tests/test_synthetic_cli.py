"""``bayes-rcsa synthesize``: output, reproducibility, atomicity, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.io.frf_csv import read_frf_csv
from bayes_rcsa.io.receptance_csv import read_spindle_csv
from bayes_rcsa.io.setup import load_setup

# Small campaign: 2 lengths x 1 direction on a 301-line grid keeps each run ~0.3 s.
SMALL = """
[campaign]
clamping_lengths = [0.025, 0.035]
directions = ["x"]
[frequency]
start = 600.0
stop = 1500.0
step = 3.0
[hidden_effects]
tip_mass = true
"""


@pytest.fixture
def config(tmp_path):
    p = tmp_path / "bench.toml"
    p.write_text(SMALL)
    return p


def test_synthesize_writes_a_readable_campaign(tmp_path, config, capsys):
    out = tmp_path / "camp"
    assert main(["synthesize", str(config), "--out", str(out), "--seed", "4"]) == 0
    msg = capsys.readouterr().err
    assert "2 tool-point FRFs" in msg and "mass at the tool tip = 0.002" in msg
    setup = load_setup(out / "setup.toml")
    assert [m.file.name for m in setup.measurements] == ["tip_x_25mm.csv", "tip_x_35mm.csv"]
    frf = read_frf_csv(out / "tip_x_25mm.csv")
    assert frf.frequency_hz.size == 301 and frf.coherence is not None
    assert read_spindle_csv(out / "spindle_x.csv").block.shape == (301, 2, 2)
    truth = json.loads((out / "truth.json").read_text())
    assert truth["seed"] == 4 and truth["hidden_effects"] == {"tip_mass": 0.002}
    assert "tip_mass" not in (out / "setup.toml").read_text()  # the user does not know


def test_same_seed_gives_byte_identical_directories(tmp_path, config):
    runs = [tmp_path / "a", tmp_path / "b"]
    for d in runs:
        assert main(["synthesize", str(config), "--out", str(d), "--seed", "7"]) == 0
    files = sorted(p.name for p in runs[0].iterdir())
    assert files == sorted(p.name for p in runs[1].iterdir())
    for name in files:
        assert (runs[0] / name).read_bytes() == (runs[1] / name).read_bytes(), name
    assert main(["synthesize", str(config), "--out", str(tmp_path / "c"), "--seed", "8"]) == 0
    assert (tmp_path / "c" / "tip_x_25mm.csv").read_bytes() != (runs[0] / "tip_x_25mm.csv").read_bytes()


@pytest.mark.parametrize("text, needle", [
    ("[hidden_effects]\nwobble = 1\n", "unknown hidden effect"),
    ("[frequency]\nstep = 0\n", "frequency_step"),
    ("not toml at all = = =\n", "invalid TOML"),
    ("[noise]\naverages = 0\n", "n_averages"),
])
def test_bad_config_is_one_line_and_exit_2(tmp_path, capsys, text, needle):
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    out = tmp_path / "never"
    assert main(["synthesize", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bayes-rcsa synthesize: error:") and needle in err
    assert not out.exists()


def test_missing_config_is_exit_2(tmp_path, capsys):
    assert main(["synthesize", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "not found" in capsys.readouterr().err


def test_failure_during_generation_leaves_no_output(tmp_path, capsys):
    # Line width so large that the first line's band reaches below 0 Hz: detected
    # only while simulating, after the configuration was accepted.
    bad = tmp_path / "bench.toml"
    bad.write_text(SMALL.replace("step = 3.0", "step = 3.0\nresolution = 2000.0"))
    assert main(["synthesize", str(bad), "--out", str(tmp_path / "out")]) == 2
    assert "resolution_hz" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.toml"]


def test_existing_directory_needs_force(tmp_path, config, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.csv").write_text("keep me")
    assert main(["synthesize", str(config), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "old.csv").read_text() == "keep me"
    assert main(["synthesize", str(config), "--out", str(out), "--force"]) == 0
    assert not (out / "old.csv").exists() and (out / "setup.toml").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.toml", "out"]


def test_help_describes_the_command(capsys):
    with pytest.raises(SystemExit) as info:
        main(["synthesize", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    assert "truth.json" in text and "--seed" in text and "hidden" in text


def test_seed_default_comes_from_config(tmp_path, config):
    config.write_text(SMALL + "[noise]\nseed = 7\n")
    assert main(["synthesize", str(config), "--out", str(tmp_path / "a")]) == 0
    assert main(["synthesize", str(config), "--out", str(tmp_path / "b"), "--seed", "7"]) == 0
    a = read_frf_csv(tmp_path / "a" / "tip_x_35mm.csv").values
    b = read_frf_csv(tmp_path / "b" / "tip_x_35mm.csv").values
    np.testing.assert_array_equal(a, b)
