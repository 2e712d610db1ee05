"""The scripts in examples/ run and print what their docstrings promise."""

from __future__ import annotations

import json
import runpy
from pathlib import Path

import pytest

from bayes_rcsa.data import example_dir

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
TRUTH = {(m["clamping_length"], m["direction"]): m["dominant_frequency_hz"]
         for m in json.loads((example_dir() / "truth.json").read_text())["measurements"]}


def _run(name: str):
    return runpy.run_path(str(EXAMPLES / name))["main"]()


def test_forward_model_example_brackets_the_true_frequencies(capsys):
    out = _run("forward_model.py")
    assert sorted(out) == [0.025, 0.030, 0.035, 0.040]
    for length, (lo, mid, hi) in out.items():
        # the example scatters the stiffness around the bench's true law, so its 5-95 % range of the
        # first natural frequency brackets the bench's noise-free value
        assert lo < TRUTH[(length, "x")] < hi
        assert lo < mid < hi
    assert "clamping 30.0 mm" in capsys.readouterr().out


def test_identify_and_predict_example_predicts_held_out_lengths():
    out = _run("identify_and_predict.py")
    assert sorted(out) == [0.030, 0.035]
    for length, q in out.items():
        # held-out lengths: within 0.1 % of the bench truth (noise-free FE value)
        assert q["q50"] == pytest.approx(TRUTH[(length, "x")], rel=1e-3)
