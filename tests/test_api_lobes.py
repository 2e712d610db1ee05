"""``bayes_rcsa.workflows.stability_lobes``: the API result equals what ``bayes-rcsa lobes`` writes, round-trips through its
files, and in posterior mode reads the setup once and posterior.nc once."""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.stability import ModalModel
from bayes_rcsa.workflows.stability_lobes import Lobes, lobes

from test_params_posterior import fitted  # noqa: F401  (a small fit written to DIR/posterior.nc)

F = np.arange(500.0, 3000.0, 2.5)
SPEEDS = "8000:20000:40"
CUT = {"flutes": 4, "kt": 790e6, "kr": 230e6, "radial_immersion": 0.7, "feed": "y"}
CUT_ARGS = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.7", "--feed", "y"]


@pytest.fixture(scope="module")
def frfs(tmp_path_factory):
    """Measured X/Y FRFs with a coherence column and 5 averages (probabilistic lobes)."""
    root = tmp_path_factory.mktemp("frf")
    rng = np.random.default_rng(3)
    paths = []
    for name, m in (("fx", ModalModel([1287.0], [0.02], [1.0e6])), ("fy", ModalModel([1340.0], [0.03], [1.3e6]))):
        g = m.frf(F)
        coh = np.clip(0.97 + 0.02 * rng.standard_normal(F.size), 0.5, 1.0)
        rows = [f"{float(a)!r},{float(b.real)!r},{float(b.imag)!r},{float(c)!r}" for a, b, c in zip(F, g, coh)]
        (root / f"{name}.csv").write_text("\n".join(["# averages = 5", "frequency_hz,real,imag,coherence", *rows])
                                          + "\n")
        paths.append(str(root / f"{name}.csv"))
    return paths


@pytest.fixture(scope="module")
def measured(frfs, tmp_path_factory):
    """The API result and the CLI's output directory for the same measured inputs (K_t below the metals' range,
    allowed: a warning)."""
    out = tmp_path_factory.mktemp("cli") / "lobes"
    kw = {**CUT, "kt": 5e7, "kr": 1.5e7}
    res = lobes(measured_x=frfs[0], measured_y=frfs[1], draws=12, seed=4, allow_unusual=True, **kw,
                speeds_rpm=np.linspace(8000, 20000, 40), max_depth=0.004)
    rc = main(["lobes", "--measured-x", frfs[0], "--measured-y", frfs[1], "--draws", "12", "--seed", "4",
               "--allow-unusual", "--flutes", "4", "--kt", "5e7", "--kr", "1.5e7", "--immersion", "0.7", "--feed", "y",
               "--speeds", SPEEDS, "--max-depth", "0.004", "--quiet", "--out", str(out)])
    assert rc == 0
    return res, out


def test_measured_result_equals_the_cli_files(measured):
    res, out = measured
    assert isinstance(res, Lobes)
    assert res.to_dict() == json.loads((out / "lobes.json").read_text())
    with np.load(out / "p_stable.npz") as z:
        np.testing.assert_array_equal(res.p_stable, z["p_stable"])
        np.testing.assert_array_equal(res.speed_rpm, z["spindle_speed_rpm"])
    # the coefficient warning (--allow-unusual) reaches the result and the file
    assert any(w.startswith("--kt 50e6 Pa is outside") for w in res.warnings), res.warnings
    assert list(res.warnings) == res.to_dict()["warnings"]


def test_save_load_round_trip_and_figures(measured, tmp_path):
    res, _ = measured
    path = res.save(tmp_path / "api")
    assert path == tmp_path / "api" / "lobes.json" and (tmp_path / "api" / "lobes.png").is_file()
    back = Lobes.load(tmp_path / "api")
    assert back.to_dict() == res.to_dict()
    np.testing.assert_array_equal(back.p_stable, res.p_stable)
    np.testing.assert_array_equal(back.depth_m, res.depth_m)
    assert back.summary_line() == res.summary_line() and back.summary_data() == res.summary_data()
    assert back.warnings == res.warnings
    # the figure drawn from the files has the same curves as the one of the computed result
    fig_now, fig_back = res.figures()["lobes"], back.figures()["lobes"]
    lines_now = [ln.get_ydata() for ln in fig_now.axes[0].get_lines()]
    lines_back = [ln.get_ydata() for ln in fig_back.axes[0].get_lines()]
    assert len(lines_now) == len(lines_back) > 1
    for a, b in zip(lines_now, lines_back):
        np.testing.assert_allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    with pytest.raises(Exception, match="not empty"):
        res.save(tmp_path / "api")


def test_repr_html_shows_the_recommendation_with_units(measured):
    res, _ = measured
    rec = res.recommended
    assert rec is not None
    html = res._repr_html_()
    assert f"{rec['spindle_speed_rpm']:.0f} rpm" in html and f"{rec['depth_m'] * 1e3:.3f} mm" in html
    assert "kt_pa" not in html and "k_xf" not in html and "spindle_speed_rpm" not in html


def test_value_checks_live_in_the_workflow(frfs):
    from bayes_rcsa.errors import SetupError

    base = dict(measured_x=frfs[0], measured_y=frfs[1], draws=4, speeds_rpm=np.linspace(8000, 20000, 10))
    with pytest.raises(SetupError, match=r"--level 1.5: expected a probability in \(0, 1\]"):
        lobes(**base, **CUT, level=1.5)
    with pytest.raises(SetupError, match="give exactly one of --immersion"):
        lobes(**base, **{**CUT, "entry_angle": 0.0, "exit_angle": 1.0})
    with pytest.raises(SetupError, match="give both --kt and --kr"):
        lobes(**base, **{**CUT, "kr": None})
    with pytest.raises(SetupError, match="--spindle-uncertainty: only for posterior draws"):
        lobes(**base, **CUT, spindle_samples="spindle_samples.npz")


# ------------------------------------------------------------------------------------------ posterior mode --
def _count(monkeypatch, module, name, counter, key):
    original = getattr(module, name)

    def wrapper(*a, **kw):
        counter[key] = counter.get(key, 0) + 1
        return original(*a, **kw)

    monkeypatch.setattr(module, name, wrapper)


def _count_reads(monkeypatch) -> dict:
    """Count the reads of the setup (load_setup, under both its names) and the opens of posterior.nc."""
    import importlib

    import bayes_rcsa.io as io
    import bayes_rcsa.io.setup as io_setup

    calls: dict = {}
    _count(monkeypatch, io_setup, "load_setup", calls, "setup")
    _count(monkeypatch, io, "load_setup", calls, "setup")
    # every read of posterior.nc goes through the store's one opener
    _count(monkeypatch, importlib.import_module("bayes_rcsa.store.posterior_file"), "_open_posterior", calls,
           "posterior")
    return calls


POSTERIOR_KW = dict(clamping_length=0.030, draws=20, seed=0, speeds_rpm=np.linspace(8000, 20000, 40), **CUT)


def test_posterior_mode_reads_the_setup_once_and_posterior_nc_once(fitted, tmp_path, monkeypatch, capsys):  # noqa: F811
    setup_path, posterior, _ = fitted
    calls = _count_reads(monkeypatch)
    rc = main(["lobes", str(setup_path), "--posterior", str(posterior), "--clamping-length", "0.030", *CUT_ARGS,
               "--speeds", SPEEDS, "--draws", "20", "--quiet", "--out", str(tmp_path / "cli")])
    assert rc == 0, capsys.readouterr().err
    assert calls == {"setup": 1, "posterior": 1}, calls
    calls.clear()
    res = lobes(setup=str(setup_path), posterior=str(posterior), **POSTERIOR_KW)
    assert calls == {"setup": 1, "posterior": 1}, calls
    assert res.to_dict() == json.loads((tmp_path / "cli" / "lobes.json").read_text())
    # the unconverged fixture fit: the result says so, and so does lobes.json
    assert any("did not converge" in w for w in res.warnings) and res.summary_data()["posterior_converged"] is False


def test_a_loaded_posterior_and_setup_are_not_read_again(fitted, monkeypatch):  # noqa: F811
    from bayes_rcsa.store import read_posterior
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.posterior import load_posterior

    setup_path, posterior, _ = fitted
    setup = load_setup(setup_path, load_data=False, load_spindle=True)
    idata = read_posterior(posterior)
    loaded = SimpleNamespace(draws=load_posterior(posterior, setup, inference_data=idata), inference_data=idata,
                             summary=json.loads(posterior.with_name("summary.json").read_text()), path=posterior)
    by_path = lobes(setup=setup_path, posterior=posterior, **POSTERIOR_KW)
    calls = _count_reads(monkeypatch)
    by_object = lobes(setup=setup, posterior=loaded, **POSTERIOR_KW)
    assert calls == {}, calls
    assert by_object.to_dict() == by_path.to_dict()


def test_a_setup_of_another_geometry_warns_in_the_result_and_the_file(fitted, tmp_path):  # noqa: F811
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.posterior.setup_match import GEOMETRY_KEY, setup_geometry

    setup_path, original, _ = fitted
    # the record 'bayes-rcsa identify' writes beside the posterior (the fixture's fit did not write it)
    shutil.copytree(original.parent, tmp_path / "fit")
    posterior = tmp_path / "fit" / original.name
    summary = json.loads(posterior.with_name("summary.json").read_text())
    summary[GEOMETRY_KEY] = setup_geometry(load_setup(setup_path, load_data=False))
    posterior.with_name("summary.json").write_text(json.dumps(summary))
    shutil.copytree(setup_path.parent, tmp_path / "edited")
    edited = tmp_path / "edited" / setup_path.name
    text = edited.read_text()
    assert "youngs_modulus = 580000000000.0" in text
    edited.write_text(text.replace("youngs_modulus = 580000000000.0", "youngs_modulus = 600000000000.0"))
    from bayes_rcsa.errors import DataWarning

    with pytest.warns(DataWarning, match="youngs_modulus"):  # raised to the caller too, not only recorded
        res = lobes(setup=edited, posterior=posterior, **POSTERIOR_KW)
    line = [w for w in res.warnings if "youngs_modulus" in w]
    assert len(line) == 1 and "differs from" in line[0], res.warnings
    path = res.save(tmp_path / "out")
    assert line[0] in json.loads(path.read_text())["warnings"]
