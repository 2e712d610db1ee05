"""``bayes-rcsa lobes`` in measured-FRF mode (and the pending posterior mode)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.stability import CuttingConditions, ModalModel, stable_at, zoa_lobes

F = np.arange(500.0, 3000.0, 2.5)
MX = ModalModel([1287.0], [0.02], [1.0e6])
MY = ModalModel([1340.0], [0.03], [1.3e6])
CUT = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, milling="down", feed="y")
COMMON = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.7", "--milling", "down", "--feed", "y"]


def write_frf(path, f, g):
    lines = ["# synthetic tool-point FRF", "frequency_hz,real,imag"]
    lines += [f"{float(a)!r},{float(b.real)!r},{float(b.imag)!r}" for a, b in zip(f, g)]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.fixture()
def frfs(tmp_path):
    return write_frf(tmp_path / "fx.csv", F, MX.frf(F)), write_frf(tmp_path / "fy.csv", F, MY.frf(F))


def test_measured_zoa_outputs(tmp_path, frfs, capsys):
    tests = tmp_path / "cases.csv"
    tests.write_text(
        "# cutting tests (Table 2 style)\nspindle_speed_rpm,depth_m,outcome\n"
        "9000,0.00010,stable\n9000,0.00020,chatter\n13000,0.00005,stable\n13000,0.00012,stable\n"
    )
    out = tmp_path / "out"
    argv = ["lobes", "--measured-x", frfs[0], "--measured-y", frfs[1], *COMMON, "--speeds", "5000:30000:300"]
    assert main(argv + ["--tests", str(tests), "--out", str(out)]) == 0
    assert "recommended" in capsys.readouterr().err
    doc = json.loads((out / "lobes.json").read_text())
    n = np.array(doc["spindle_speed_rpm"])
    np.testing.assert_allclose(n, np.linspace(5000, 30000, 300))
    q = {k: np.array(v, dtype=float) for k, v in doc["depth_limit_m"].items()}
    np.testing.assert_array_equal(q["q05"], q["q50"])  # deterministic: all quantiles equal
    np.testing.assert_array_equal(q["q95"], q["q50"])
    ref = zoa_lobes(MX.frf(F), MY.frf(F), F, CUT, n).depth_limit_m
    np.testing.assert_allclose(q["q50"], ref, rtol=1e-12)
    rec = doc["recommended"]
    assert rec["p_stable"] == 1.0 and rec["depth_m"] < doc["depth_grid_m"]["max"]
    assert rec["depth_m"] < np.interp(rec["spindle_speed_rpm"], n, ref)
    npz = np.load(out / "p_stable.npz")
    assert npz["p_stable"].shape == (300, doc["depth_grid_m"]["count"])
    assert set(np.unique(npz["p_stable"])) <= {0.0, 1.0}
    assert (out / "lobes.png").stat().st_size > 10_000
    # test markers and the Table-8 test error
    ts, td = np.array([9000.0, 9000, 13000, 13000]), np.array([1e-4, 2e-4, 5e-5, 1.2e-4])
    observed = np.array([True, False, True, True])
    predicted = stable_at(n, ref, ts, td)
    assert [t["predicted"] == "stable" for t in doc["tests"]] == list(predicted)
    assert doc["test_error"] == pytest.approx(np.mean(predicted != observed))


def test_measured_sdm_small_grid(tmp_path, frfs):
    out = tmp_path / "sdm"
    argv = ["lobes", "--measured-x", frfs[0], "--measured-y", frfs[1], *COMMON, "--speeds", "9000:14000:12"]
    argv += ["--method", "sdm", "--max-depth", "2.5e-4", "--depth-points", "25", "--out", str(out)]
    assert main(argv) == 0
    doc = json.loads((out / "lobes.json").read_text())
    assert doc["method"] == "sdm"
    assert doc["modal_fit"]["x"]["natural_frequency_hz"] == pytest.approx([1287.0], rel=1e-9)
    assert doc["modal_fit"]["y"]["damping_ratio"] == pytest.approx([0.03], rel=1e-6)
    q50 = np.array(doc["depth_limit_m"]["q50"], dtype=float)
    zoa = zoa_lobes(MX.frf(F), MY.frf(F), F, CUT, np.array(doc["spindle_speed_rpm"])).depth_limit_m
    # the limits are found per speed (no depth grid), also where the lobe rises above --max-depth
    assert np.all(np.isfinite(q50)) and np.any(zoa > 2.5e-4)
    np.testing.assert_allclose(q50, zoa, rtol=0.05)  # ZOA and SDM agree closely at 70 % immersion
    rec = doc["recommended"]
    assert rec["depth_m"] <= 2.5e-4 and doc["depth_grid_m"]["max"] <= 1.1 * 2.5e-4 * (1 + 1e-12)


def test_y_file_on_another_grid_is_interpolated(tmp_path, frfs):
    fy2 = write_frf(tmp_path / "fy2.csv", np.arange(400.0, 3200.0, 0.5), MY.frf(np.arange(400.0, 3200.0, 0.5)))
    a, b = tmp_path / "a", tmp_path / "b"
    base = ["lobes", "--measured-x", frfs[0], *COMMON, "--speeds", "6000:20000:50", "--max-depth", "3e-4"]
    assert main(base + ["--measured-y", frfs[1], "--out", str(a)]) == 0
    assert main(base + ["--measured-y", fy2, "--out", str(b)]) == 0
    qa = np.array(json.loads((a / "lobes.json").read_text())["depth_limit_m"]["q50"], dtype=float)
    qb = np.array(json.loads((b / "lobes.json").read_text())["depth_limit_m"]["q50"], dtype=float)
    np.testing.assert_allclose(qa, qb, rtol=2e-3)  # linear interpolation of a 0.5 Hz grid


def test_posterior_mode_with_missing_setup_fails_cleanly(tmp_path, capsys):
    out = tmp_path / "post"
    setup = tmp_path / "missing_setup.toml"
    argv = ["lobes", str(setup), "--posterior", str(tmp_path / "posterior.nc"), "--clamping-length", "0.03", *COMMON]
    assert main(argv + ["--speeds", "5000:30000", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "missing_setup.toml" in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize(
    "extra,message",
    [
        (["--tests", "BAD"], "outcome"),
        (["--speeds", "30000:5000"], "--speeds"),
        (["--immersion", "1.5"], "radial_immersion"),
        (["--level", "2"], "--level"),
    ],
)
def test_bad_input_exits_2_without_output(tmp_path, frfs, capsys, extra, message):
    bad = tmp_path / "bad.csv"
    bad.write_text("spindle_speed_rpm,depth_m,outcome\n9000,0.0001,maybe\n")
    extra = [str(bad) if e == "BAD" else e for e in extra]
    args = {"--speeds": "5000:30000", "--immersion": "0.7"}
    for k in ("--speeds", "--immersion"):
        if k in extra:
            args[k] = extra[extra.index(k) + 1]
            extra = extra[: extra.index(k)] + extra[extra.index(k) + 2 :]
    common = [c for c in COMMON if c not in ("--immersion", "0.7")]
    out = tmp_path / "o"
    argv = ["lobes", "--measured-x", frfs[0], "--measured-y", frfs[1], *common, "--immersion", args["--immersion"]]
    argv += ["--speeds", args["--speeds"], *extra, "--out", str(out)]
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_measured_mode_needs_both_files(tmp_path, frfs, capsys):
    argv = ["lobes", "--measured-x", frfs[0], *COMMON, "--speeds", "5000:30000", "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    assert "--measured-y" in capsys.readouterr().err


def test_no_plots_writes_every_number_but_no_figure_and_a_forced_run_leaves_no_stale_figure(tmp_path, frfs, capsys):
    out = tmp_path / "lobes"
    argv = ["lobes", "--measured-x", frfs[0], "--measured-y", frfs[1], *COMMON, "--speeds", "9000:14000:40",
            "--out", str(out)]
    assert main(argv) == 0
    assert (out / "lobes.png").exists() and "lobes.png" in capsys.readouterr().err
    # again into the same folder without the figure: the earlier run's lobes.png must not stay beside these lobes
    assert main(argv + ["--force", "--no-plots"]) == 0
    err = capsys.readouterr().err
    assert not (out / "lobes.png").exists() and "lobes.png" not in err and "p_stable.npz" in err
    assert (out / "lobes.json").exists() and (out / "p_stable.npz").exists()
