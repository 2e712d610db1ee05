"""The last silent inputs (#45 items 4 and 8): each gets one line naming the file or option and the cause,
before any computation and without leaving a folder behind."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir
from bayes_rcsa.errors import DataError, SetupError


def _one_error(capsys, command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"bayes-rcsa {command}: error: "), err
    return err[0]


@pytest.fixture()
def example(tmp_path) -> Path:
    dst = tmp_path / "example"
    shutil.copytree(example_dir(), dst)
    return dst


# -- lengths in metres, speeds in rpm --------------------------------------------------------------------------

LOBES = ["--posterior", "p.nc", "--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95"]


@pytest.mark.parametrize("argv, said", [
    (["predict", "setup.toml", "--posterior", "p.nc", "--lengths", "25,40"],
     "--lengths '25,40': lengths are in metres; did you mean 0.025,0.04?"),
    (["identify", "setup.toml", "--lengths", "30"], "--lengths '30': lengths are in metres; did you mean 0.03?"),
    (["lobes", "setup.toml", *LOBES, "--clamping-length", "30", "--speeds", "5000:30000"],
     "--clamping-length '30': lengths are in metres; did you mean 0.03?"),
    (["lobes", "setup.toml", *LOBES, "--clamping-length", "0.03", "--speeds", "-5000:30000"],
     "--speeds '-5000:30000': spindle speeds are in rpm and must be > 0"),
    (["lobes", "setup.toml", *LOBES, "--clamping-length", "0.03", "--speeds=-5000:30000"],
     "--speeds '-5000:30000': spindle speeds are in rpm and must be > 0"),
    (["lobes", "setup.toml", *LOBES, "--clamping-length", "0.03", "--speeds", "30000:5000"],
     "--speeds '30000:5000': STOP must be above START"),
    (["lobes", "setup.toml", *LOBES, "--clamping-length", "0.03", "--speeds", "a:b"],
     "--speeds 'a:b': START and STOP must be numbers in rpm"),
], ids=["predict-mm", "identify-mm", "lobes-mm", "speeds-negative", "speeds-negative-equals", "speeds-reversed",
        "speeds-letters"])
def test_lengths_and_speeds_are_refused_before_anything_runs(argv, said, tmp_path, capsys, monkeypatch):
    """No file is read (setup.toml and p.nc do not exist): the refusal comes before the command starts."""
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    assert said in _one_error(capsys, argv[0])
    assert not (tmp_path / "out").exists()


def test_a_setup_length_in_millimetres_is_named_with_its_value_in_metres(example):
    from bayes_rcsa.io.setup import load_setup

    text = (example / "setup.toml").read_text()
    (example / "setup.toml").write_text(text.replace("total_length = 0.1016", "total_length = 101.6"))
    with pytest.raises(SetupError, match=r"\[tool\] total_length = 101.6: lengths are in metres; did you mean 0.1016\?"):
        load_setup(example / "setup.toml", load_data=False)


# -- a tool-point band without a resonance ---------------------------------------------------------------------


def _cut_band(path: Path, lo: float, hi: float) -> None:
    keep = []
    for line in path.read_text().splitlines():
        if line[:1].isdigit() and not lo <= float(line.split(",")[0]) <= hi:
            continue
        keep.append(line)
    path.write_text("\n".join(keep) + "\n")


def test_a_band_that_holds_only_a_bump_is_no_resonance(example, tmp_path, capsys):
    """500-596 Hz of the example holds a weak bump (1.3 x its ends, 39 deg of phase), not the 860 Hz tool mode."""
    from bayes_rcsa.io.checks import resonance_problem
    from bayes_rcsa.io.frf import read_frf

    _cut_band(example / "tip_x_25mm.csv", 500.0, 596.0)
    frf = read_frf(example / "tip_x_25mm.csv")
    assert "no resonance inside its band 500-596 Hz" in resonance_problem(frf.frequency_hz, frf.values)
    full = read_frf(example_dir() / "tip_x_25mm.csv")
    k = np.argmax(np.abs(full.values))
    near = slice(k - 10, k + 11)  # +-20 Hz about the 860 Hz mode: a narrow band that does hold it
    assert resonance_problem(full.frequency_hz[near], full.values[near]) is None
    out = tmp_path / "out"
    rc = main(["identify", str(example / "setup.toml"), "--method", "deterministic", "--lengths", "0.025",
               "--out", str(out)])
    assert rc == 2 and not out.exists()
    line = _one_error(capsys, "identify")
    assert "tip_x_25mm.csv: no resonance inside its band" in line and "--allow-no-resonance" in line


# -- a CSV whose header repeats ---------------------------------------------------------------------------------


def test_a_header_row_repeated_in_mid_file_is_named(tmp_path):
    from bayes_rcsa.io.frf import read_frf
    from bayes_rcsa.stability.tests_io import read_cutting_tests

    lines = (example_dir() / "tip_x_25mm.csv").read_text().splitlines()
    h = next(i for i, line in enumerate(lines) if line.startswith("frequency_hz"))
    joined = lines[: h + 1] + lines[h + 1: h + 50] + [lines[h]] + lines[h + 50:]
    (tmp_path / "joined.csv").write_text("\n".join(joined) + "\n")
    with pytest.raises(DataError, match=rf"joined.csv: line {h + 51}: the header row repeats in mid-file"):
        read_frf(tmp_path / "joined.csv")
    (tmp_path / "cuts.csv").write_text("spindle_speed_rpm,depth_m,outcome\n9000,0.001,stable\n"
                                       "Spindle_Speed_rpm, depth_m, outcome\n12000,0.002,chatter\n")
    with pytest.raises(DataError, match=r"cuts.csv:3: the header row repeats in mid-file"):
        read_cutting_tests(tmp_path / "cuts.csv")


# -- a spindle file with h and l exchanged -----------------------------------------------------------------------


def test_a_spindle_file_with_h_and_l_exchanged_is_refused(tmp_path):
    """h's columns hold l and l's and n's hold h: still passive and reciprocal, only the magnitudes tell."""
    from bayes_rcsa.io.receptance_csv import read_spindle_csv, write_spindle_csv

    good = read_spindle_csv(example_dir() / "spindle_x.csv")
    b = good.block.copy()
    h, l = b[:, 0, 0].copy(), b[:, 0, 1].copy()
    b[:, 0, 0], b[:, 0, 1], b[:, 1, 0] = l, h, h
    write_spindle_csv(tmp_path / "swapped.csv", type(good)(good.frequency_hz, b))
    with pytest.raises(DataError, match=r"swapped.csv: the h and l/n columns look swapped: median \|l\|"):
        read_spindle_csv(tmp_path / "swapped.csv")


# -- a batch entry that names no setup file ----------------------------------------------------------------------


def test_a_batch_entry_naming_no_setup_file_is_refused_before_any_folder(example, tmp_path, capsys):
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "library.toml").write_text('[[setup]]\nname = "outside"\nfile = "../example/tip_x_25mm.csv"\n'
                                      'method = "deterministic"\npredict = false\nlobes = false\n')
    out = tmp_path / "out"
    assert main(["batch", str(lib / "library.toml"), "--out", str(out)]) == 2
    line = _one_error(capsys, "batch")
    assert "[[setup]] 'outside' file = '../example/tip_x_25mm.csv'" in line and "malformed TOML" in line
    assert not out.exists()
