"""Robust recommendation on the bundled example, unit-slip checks and lobes-level input errors (issue 13, 12)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.io.frf import read_frf
from bayes_rcsa.registry import Registry
from bayes_rcsa.stability import CuttingConditions, Tolerances, recommend, zoa_lobes
from bayes_rcsa.stability.methods import STABILITY_METHODS, MethodResult

EXAMPLE = Path(__file__).resolve().parent.parent / "bayes_rcsa" / "data" / "example"
FX, FY = str(EXAMPLE / "tip_x_30mm.csv"), str(EXAMPLE / "tip_y_30mm.csv")
# the demo's lobes case (bayes_rcsa/cli/demo.py): paper case b, 30 mm clamping; deterministic lobes of the measured
# FRFs as they are (the files' '# averages = 5' header would otherwise draw 500 realisations of their random error)
CASE = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95", "--milling", "down", "--feed", "y",
        "--speeds", "5000:30000:400", "--deterministic"]
CUT = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.95, milling="down", feed="y")


def run_lobes(tmp_path, name, *extra):
    out = tmp_path / name
    assert main(["lobes", "--measured-x", FX, "--measured-y", FY, *CASE, *extra, "--out", str(out), "--quiet",
                 "--no-plots"]) == 0
    return json.loads((out / "lobes.json").read_text())


def test_bundled_example_recommendation_inside_grid_under_the_lobe_tip(tmp_path):
    # before issue 13: 14 398 rpm at 0.082-0.084 mm, the top edge of the default depth grid
    doc = run_lobes(tmp_path, "default")
    tip = run_lobes(tmp_path, "tip", "--max-depth", "0.001")
    n = np.array(doc["spindle_speed_rpm"])
    rec = doc["recommended"]
    # the lobe tip that --max-depth 0.001 finds (the point-wise optimum there)
    tip_n = tip["pointwise_optimum"]["spindle_speed_rpm"]
    assert abs(rec["spindle_speed_rpm"] / tip_n - 1) < 0.05
    assert tip["recommended"]["spindle_speed_rpm"] == rec["spindle_speed_rpm"]  # the limit does not bind here
    assert rec["depth_m"] > 0.082e-3
    # strictly inside the depth grid and the speed range, and set by stability, not by an edge
    grid = doc["depth_grid_m"]
    assert grid["min"] < rec["depth_m"] < grid["max"] and grid["min"] < rec["depth_checked_m"] < grid["max"]
    assert n[0] < rec["speed_window_rpm"][0] and rec["speed_window_rpm"][1] < n[-1]
    assert rec["binding_limit"] == "stability"
    # its neighbourhood (±2 % speed, depth up to +10 %) is stable: checked against the lobe of the same FRFs,
    # recomputed here on a fine speed grid across the window
    fx, fy = read_frf(FX), read_frf(FY)
    fine = np.linspace(*rec["speed_window_rpm"], 401)
    lim = zoa_lobes(fx.values, fy.values, fx.frequency_hz, CUT, fine).depth_limit_m
    assert np.all(rec["depth_checked_m"] < lim)
    assert rec["p_stable_neighbourhood"] >= doc["level"]
    assert rec["depth_checked_m"] == pytest.approx(1.1 * rec["depth_m"], rel=1e-12)
    # margins in rpm and mm are reported, and the alternatives include the recommended pocket
    assert rec["margin_speed_rpm"]["below"] > 0 and rec["margin_speed_rpm"]["above"] > 0
    assert rec["margin_depth_m"] > 0
    assert 1 <= len(doc["alternatives"]) <= 3 and any(a["contains_recommended"] for a in doc["alternatives"])


def test_speed_tolerance_moves_the_point_off_a_narrow_lobe_tip():
    fx, fy = read_frf(FX), read_frf(FY)
    n = np.linspace(5000, 30000, 400)

    def limits(s):
        return np.atleast_2d(zoa_lobes(fx.values, fy.values, fx.frequency_hz, CUT, s).depth_limit_m)

    out = recommend(n, limits(n), 0.95, Tolerances(0.02, 0.1), limits_at=limits)
    pw, rob = out["pointwise"], out["recommended"]
    # the point-wise optimum sits on a tip narrower than ±2 %: inside its window the lobe drops below its depth
    window = np.linspace(0.98 * pw.spindle_speed_rpm, 1.02 * pw.spindle_speed_rpm, 201)
    assert limits(window).min() < 0.75 * pw.depth_m
    # ... so the robust point differs, and its own window holds its checked depth everywhere
    assert rob.depth_m < pw.depth_m and rob.spindle_speed_rpm != pw.spindle_speed_rpm
    window = np.linspace(*rob.speed_window_rpm, 201)
    assert limits(window).min() > rob.depth_checked_m
    # without tolerance and with a tiny margin the robust point tends to the point-wise one
    tight = recommend(n, limits(n), 0.95, Tolerances(0.0, 1e-3))["recommended"]
    assert tight.spindle_speed_rpm == pw.spindle_speed_rpm and tight.depth_m == pytest.approx(pw.depth_m, rel=2e-3)
    assert np.isfinite(rob.margin_depth_m) and rob.margin_depth_m > 0


def test_cutting_force_tolerance_scales_the_depth_and_user_limits_bind(tmp_path):
    base = run_lobes(tmp_path, "base")["recommended"]
    tol = run_lobes(tmp_path, "tol", "--kt", "790e6±5%")["recommended"]  # later --kt wins in argparse
    assert tol["cutting_force_tolerance_rel"] == pytest.approx(0.05)
    assert tol["depth_m"] == pytest.approx(base["depth_m"] / 1.05, rel=1e-9)  # a_lim ∝ 1/K, exactly
    capped = run_lobes(tmp_path, "cap", "--max-depth", "0.0001")
    rec = capped["recommended"]
    assert rec["depth_m"] == pytest.approx(1e-4) and rec["binding_limit"].startswith("max_depth")
    assert capped["depth_grid_m"]["max"] > rec["depth_m"]  # the limit binds, and the file says so
    flute = run_lobes(tmp_path, "flute", "--flute-length", "0.00005")["recommended"]
    assert flute["depth_m"] <= 5e-5 and flute["binding_limit"].startswith("flute_length")
    # the recommended speed never leaves --speeds; here (a flat lobe floor, rising a.n) the range end binds
    narrow = run_lobes(tmp_path, "narrow", "--speeds", "20000:30000:100")["recommended"]
    assert 20000 * 1.02 <= narrow["spindle_speed_rpm"] * 1.0000001 and narrow["spindle_speed_rpm"] * 1.02 <= 30000 * 1.0000001
    assert narrow["binding_limit"].endswith("+speed_range")


@pytest.mark.parametrize(
    "kt,kr,expected",
    [
        ("790", "230", "790e6 Pa"),  # MPa typed without e6
        ("790e6", "230e9", "230e6 Pa"),  # a factor 1000
        ("790e6", "7900e6", "Kr/Kt = 10"),  # ratio outside 0.05-2
        ("1e300", "230e6", "--kt 1e300"),  # issue 12 (11): one line, not nine warnings
        ("-790e6", "230e6", "must be > 0"),  # issue 12 (12): a clear reason, not argparse's "expected one argument"
    ],
)
def test_implausible_cutting_coefficients_exit_2_with_one_line(tmp_path, capsys, kt, kr, expected):
    out = tmp_path / "o"
    argv = ["lobes", "--measured-x", FX, "--measured-y", FY, "--flutes", "4", "--kt", kt, "--kr", kr,
            "--immersion", "0.95", "--speeds", "5000:30000:50", "--out", str(out)]
    with _no_warnings():
        assert main(argv) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1, err
    assert not out.exists()


class _no_warnings:
    def __enter__(self):
        import warnings

        self._ctx = warnings.catch_warnings()
        self._ctx.__enter__()
        warnings.simplefilter("error")  # any RuntimeWarning would fail the run

    def __exit__(self, *exc):
        return self._ctx.__exit__(*exc)


def test_allow_unusual_warns_and_proceeds(tmp_path, capsys):
    doc = run_lobes(tmp_path, "unusual", "--kt", "60e6", "--allow-unusual")
    assert doc["warnings"] and "60e6" in doc["warnings"][0]
    assert "warning" in capsys.readouterr().err


def test_sdm_with_zero_modes_is_a_one_line_error(tmp_path, capsys):
    argv = ["lobes", "--measured-x", FX, "--measured-y", FY, *CASE, "--method", "sdm", "--max-modes", "0",
            "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--max-modes" in err and err.count("\n") == 1


def test_measured_frf_with_the_other_sign_convention_is_refused(tmp_path, capsys):
    # issue 12 (1): imaginary part negated (e^{-iωt} convention) -> not passive with x = Re{X e^{+iωt}}
    fx = read_frf(FX)
    bad = tmp_path / "fx_conj.csv"
    lines = ["frequency_hz,real,imag"] + [f"{float(f)!r},{float(g.real)!r},{float(-g.imag)!r}" for f, g in zip(fx.frequency_hz, fx.values)]
    bad.write_text("\n".join(lines) + "\n")
    out = tmp_path / "o"
    assert main(["lobes", "--measured-x", str(bad), "--measured-y", FY, *CASE, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fx_conj.csv" in err and "passive" in err and "sign" in err
    assert not out.exists()


def test_method_registry_drives_the_cli(tmp_path, capsys):
    assert {"zoa", "sdm"} <= set(STABILITY_METHODS.names())
    assert isinstance(STABILITY_METHODS, Registry)

    class Half:
        """A toy method: half the zero-order limit (one file + one registration)."""

        name = "half"
        summary = "half the ZOA limit (test)"

        def check(self, options):
            return None

        def estimate_seconds(self, n_draws, n_speeds, n_freq):
            return 0.0

        def depth_limits(self, gx, gy, f, cutting, speeds, options, progress=None):
            return MethodResult(0.5 * np.atleast_2d(zoa_lobes(gx, gy, f, cutting, speeds).depth_limit_m))

    STABILITY_METHODS.register("half", Half())
    try:
        half = run_lobes(tmp_path, "half", "--method", "half")
        full = run_lobes(tmp_path, "full")
        q_half = np.array(half["depth_limit_m"]["q50"], dtype=float)
        np.testing.assert_allclose(q_half, 0.5 * np.array(full["depth_limit_m"]["q50"], dtype=float))
    finally:
        STABILITY_METHODS.unregister("half")


def test_estimate_and_budget_advice_on_stderr(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["lobes", "--measured-x", FX, "--measured-y", FY, *CASE, "--method", "sdm", "--speeds", "12000:15000:4",
            "--budget", "0.01", "--out", str(out)]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "estimated" in err and "--draws" in err and "--method zoa" in err


def test_flute_length_of_the_example_tool_limits_posterior_mode():
    from bayes_rcsa.io import load_setup
    from bayes_rcsa.stability.posterior_frf import flute_length

    setup = load_setup(EXAMPLE / "setup.toml", load_data=False)
    tool = next(iter(setup.tools.values()))
    # the example's fluted segment (diameter_ratio 0.8) is 30 mm long, the shank follows
    assert flute_length(tool) == pytest.approx(0.03)


class _Terminal(__import__("io").StringIO):
    """A text stream that says it is a terminal (the bar redraws its line only there)."""

    def isatty(self):
        return True


def test_progress_bar_draws_only_for_long_jobs_and_ends_its_line():
    from bayes_rcsa.stability.progress import ProgressBar, format_seconds

    quiet = _Terminal()
    bar = ProgressBar("job", stream=quiet, quiet_seconds=60.0)
    bar(0.5)
    bar.close()
    assert quiet.getvalue() == ""  # a short job prints nothing
    out = _Terminal()
    bar = ProgressBar("job", stream=out, quiet_seconds=0.0, interval=0.0)
    bar(0.25)
    bar(0.5)
    bar.close()
    text = out.getvalue()
    assert "job [" in text and " 50 %" in text and text.endswith("\n") and text.count("\n") == 1
    assert format_seconds(12) == "12 s" and format_seconds(600) == "10.0 min" and format_seconds(7200) == "2.0 h"


def test_progress_bar_writes_one_plain_line_when_not_a_terminal():
    import io

    from bayes_rcsa.stability.progress import ProgressBar

    log = io.StringIO()  # a redirected stderr: no carriage returns, one final line for a long job
    bar = ProgressBar("job", stream=log, quiet_seconds=0.0, interval=0.0)
    for f in (0.25, 0.5, 0.75):
        bar(f)
    bar.close()
    text = log.getvalue()
    assert "\r" not in text and text.count("\n") == 1 and text.startswith("job [") and " 100 %" in text
    short = io.StringIO()
    bar = ProgressBar("job", stream=short, quiet_seconds=60.0)
    bar(0.5)
    bar.close()
    assert short.getvalue() == ""  # a short job prints nothing there either
