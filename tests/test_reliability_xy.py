"""X and Y tool-point files of one clamping that do not belong together (io.checks.xy_pair_warnings)."""

from __future__ import annotations

import numpy as np

from bayes_rcsa.data import example_dir
from bayes_rcsa.io.checks import xy_pair_warnings
from bayes_rcsa.io.frf import read_frf


def _pair():
    fx = read_frf(example_dir() / "tip_x_30mm.csv")
    fy = read_frf(example_dir() / "tip_y_30mm.csv")
    return fx.frequency_hz, fx.values, fy.values


def test_bundled_pair_is_accepted():
    f, x, y = _pair()
    assert xy_pair_warnings("x.csv", "y.csv", f, x, y) == []


def test_amplitude_factor_between_x_and_y_is_named():
    f, x, y = _pair()
    for factor in (5.0, 30.0, 1000.0):
        (w,) = xy_pair_warnings("x.csv", "y.csv", f, x, y * factor)
        assert "sensor sensitivity or unit error in y.csv" in w
    # a real column scaled by 1000 (the property test's silent case) is caught the same way
    (w,) = xy_pair_warnings("x.csv", "y.csv", f, x.real * 1000 + 1j * x.imag, y)
    assert "in x.csv" in w
    # the directions of one tool differ by tens of per cent: no alarm
    assert xy_pair_warnings("x.csv", "y.csv", f, x, y * 1.5) == []
