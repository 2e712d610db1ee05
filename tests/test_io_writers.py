"""Output helpers: the FRF writer registry, strict JSON, the demo index page."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_setup
from bayes_rcsa.errors import SetupError
from bayes_rcsa.io import read_frf, write_frf
from bayes_rcsa.io.jsonable import dumps_strict, to_jsonable
from bayes_rcsa.io.writers import FRF_WRITERS, FRFWriter, frf_writer_for, register_frf_writer
from bayes_rcsa.model import FRF
from bayes_rcsa.report import demo_index_html

SIM = ["--clamping-length", "0.03", "--kx", "2e7", "--ktheta", "3e5", "--freq", "600,2000,4"]


def test_simulate_chooses_the_format_by_suffix(tmp_path):
    csv, uff = tmp_path / "h.csv", tmp_path / "h.UFF"
    assert main(["simulate", str(example_setup()), *SIM, "--out", str(csv)]) == 0
    assert main(["simulate", str(example_setup()), *SIM, "--out", str(uff)]) == 0
    a, b = read_frf(csv), read_frf(uff)
    assert uff.read_bytes()[:6] == b"    -1"  # a universal file, not CSV text
    np.testing.assert_array_equal(a.frequency_hz, b.frequency_hz)
    np.testing.assert_array_equal(a.values, b.values)  # both formats are lossless


def test_a_new_format_is_one_registration(tmp_path):
    written = []

    def write_npy(path, frf, comments):
        np.save(path, np.column_stack([frf.frequency_hz, frf.values.real, frf.values.imag]))
        written.append((path, comments))

    register_frf_writer(FRFWriter("npy", (".npy",), write_npy))
    try:
        frf = FRF(np.array([100.0, 200.0]), np.array([1e-7 - 1e-7j, -1e-7 - 2e-7j]))
        write_frf(tmp_path / "h.npy", frf, comments=["note"])
        assert written == [(tmp_path / "h.npy", ["note"])]
        np.testing.assert_array_equal(np.load(tmp_path / "h.npy")[:, 2], frf.values.imag)
        with pytest.raises(SetupError, match=r"suffix\(es\) \['.csv'\] belong to 'csv'"):
            register_frf_writer(FRFWriter("csv2", (".csv",), write_npy))
    finally:
        FRF_WRITERS.unregister("npy")
    with pytest.raises(SetupError, match=r"--out h.npy: unsupported FRF output type '.npy'; expected one of .csv"):
        frf_writer_for("h.npy")


def test_to_jsonable_and_strict_dumps():
    doc = {"a": np.float32(1.5), "b": np.arange(3), 1: (np.bool_(True), math.nan), "c": [np.inf, None]}
    assert to_jsonable(doc) == {"a": 1.5, "b": [0, 1, 2], "1": [True, None], "c": [None, None]}
    assert json.loads(dumps_strict(doc)) == to_jsonable(doc)
    with pytest.raises(SetupError, match="non-finite number nan"):
        to_jsonable({"x": [1.0, float("nan")]}, nonfinite="error")


def test_demo_index_page_shows_the_numbers_it_is_given():
    summary = {"converged": True, "warnings": ["k_xf <piles> at a bound"],
               "stiffness": [{"clamping_length": 0.025, "k_xf": {"q05": 1e7, "q50": 1.5e7, "q95": 2e7},
                              "k_thetaM": {"q05": 3e5, "q50": 3.5e5, "q95": 4e5}}]}
    freqs = {"predictions": [
        {"mode": 1, "clamping_length": 0.03, "direction": "x", "q05_hz": 950.0, "q50_hz": 960.0, "q95_hz": 970.0,
         "measured_hz": 962.0},
        {"mode": 2, "clamping_length": 0.03, "direction": "x", "q05_hz": 1.0, "q50_hz": 2.0, "q95_hz": 3.0},
    ]}
    lobes = {"recommended": {"spindle_speed_rpm": 14184.0, "depth_m": 0.000115, "p_stable": 0.96}}
    page = demo_index_html(summary, freqs, lobes)
    # model interval, median, predictive interval of a new measured peak (none given: a dash), measured, error
    assert "<td>950–970</td><td>960</td><td>&mdash;</td><td>962.0</td><td>-0.21 %</td>" in page
    with_pred = {"predictions": [dict(freqs["predictions"][0], predictive_peak_q05_hz=940.0,
                                      predictive_peak_q95_hz=980.0)]}
    assert "<td>940–980</td><td>962.0</td>" in demo_index_html(summary, with_pred, lobes)
    assert "<td>15.0×10⁶ (10.0×10⁶–20.0×10⁶)</td><td>350×10³ (300×10³–400×10³)</td>" in page  # docs/data-formats.md
    assert "14184 rpm" in page and "0.115 mm" in page
    assert "contact stiffness, translational (kxf) &lt;piles&gt; at a bound" in page  # escaped, in words
    assert "<td>2</td>" not in page and "<td>2.0</td>" not in page  # only the first mode is tabulated
    assert "no speed reaches" in demo_index_html(summary, freqs, {"recommended": None})
