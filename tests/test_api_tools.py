"""The public API of simulate, synthesize, identify_spindle and identifiability: the same numbers and files as
their commands, save/load round trips, figures, the notebook view and the warnings (docs/api.md)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import bayes_rcsa
from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir
from bayes_rcsa.errors import DataWarning, SetupError
from bayes_rcsa.spindle.uncertainty import SpindleSamples, load_spindle_samples
from bayes_rcsa.workflows.identifiability_study import Identifiability
from bayes_rcsa.workflows.simulation import SimulatedFRF
from bayes_rcsa.workflows.spindle import SpindleInterface
from bayes_rcsa.workflows.synthesis import Campaign
from test_synthetic_cli import SMALL as BENCH  # noqa: E402  (2 lengths x 1 direction, 301 lines)

SIM = dict(clamping_length=0.03, kx=2e6, ktheta=5e5, cx=1.0, ctheta=0.5)
SIM_ARGS = ["--clamping-length", "0.03", "--kx", "2e6", "--ktheta", "5e5", "--cx", "1", "--ctheta", "0.5"]
INTERNAL = ("k_xf", "k_thetaM", "c_xf", "c_thetaM", "g_xf")


def _files(folder) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _same_campaign(a: Campaign, b: Campaign) -> None:
    assert (a.kind, a.seed, a.document, a.n_spindle_files, a.cuts_truth, a.holder_types) == (
        b.kind, b.seed, b.document, b.n_spindle_files, b.cuts_truth, b.holder_types)
    assert a.frfs.keys() == b.frfs.keys()
    for name, frf in a.frfs.items():
        np.testing.assert_array_equal(frf.frequency_hz, b.frfs[name].frequency_hz)
        np.testing.assert_array_equal(frf.values, b.frfs[name].values)


def _no_internal_names(html: str) -> None:
    assert not [n for n in INTERNAL if n in html], html


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    dst = tmp_path_factory.mktemp("api_tools") / "example"
    shutil.copytree(example_dir(), dst)
    return dst / "setup.toml"


# -- simulate ----------------------------------------------------------------------------------------------------
def test_simulate_is_the_command_and_round_trips(example, tmp_path, capsys):
    result = bayes_rcsa.simulate(example, **SIM)
    assert isinstance(result, SimulatedFRF) and result.h.shape == result.frequency_hz.shape
    assert main(["simulate", str(example), *SIM_ARGS, "--out", str(tmp_path / "cli.csv"), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    path = result.save(tmp_path / "api.csv")
    assert path.read_bytes().replace(b"api.csv", b"cli.csv") == (tmp_path / "cli.csv").read_bytes()
    assert printed["peak_hz"] == result.peak_hz and printed["n_lines"] == result.frequency_hz.size
    assert {k: printed[k] for k in result.summary_data()} == result.summary_data()
    back = SimulatedFRF.load(path)
    np.testing.assert_array_equal(back.h, result.h)
    assert (back.clamping_length, back.kx, back.ktheta, back.cx, back.ctheta, back.tool, back.direction) == (
        0.03, 2e6, 5e5, 1.0, 0.5, result.tool, "x")
    assert back.to_dict() == {**result.to_dict(), "warnings": []}
    with pytest.raises(SetupError, match="exists; use --force"):
        result.save(path)
    figs = result.figures()  # one call: each draws the figure anew (~1 s)
    assert set(figs) == {"frf"} and figs["frf"].axes
    html = result._repr_html_()
    assert "30 mm" in html and "2.00×10⁶ N/m" in html and "m/N" in html
    _no_internal_names(html)


def test_simulate_warnings_reach_the_result(example, tmp_path):
    """A slightly non-reciprocal spindle file (cross terms 26 % apart) is used with a warning."""
    folder = tmp_path / "ex"
    shutil.copytree(example.parent, folder)
    lines = (folder / "spindle_x.csv").read_text().splitlines()
    head = [i for i, ln in enumerate(lines) if ln.startswith("frequency_hz")][0]
    cols = lines[head].split(",")
    n = [cols.index("n_real"), cols.index("n_imag")]
    for i in range(head + 1, len(lines)):
        v = lines[i].split(",")
        for j in n:
            v[j] = repr(1.3 * float(v[j]))
        lines[i] = ",".join(v)
    (folder / "spindle_x.csv").write_text("\n".join(lines) + "\n")
    with pytest.warns(DataWarning, match="cross terms differ"):  # a script sees it at once, too
        result = bayes_rcsa.simulate(folder / "setup.toml", **SIM)
    assert any("cross terms differ by 26 %" in w for w in result.warnings), result.warnings
    assert result.to_dict()["warnings"] == list(result.warnings)
    assert "cross terms differ" in result._repr_html_()


# -- synthesize --------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    root = tmp_path_factory.mktemp("bench")
    (root / "bench.toml").write_text(BENCH)
    return root


def test_synthesize_is_the_command_and_round_trips(bench, tmp_path, capsys):
    result = bayes_rcsa.synthesize(bench / "bench.toml", seed=4)
    assert isinstance(result, Campaign) and result.kind == "campaign" and len(result.frfs) == 2
    assert main(["synthesize", str(bench / "bench.toml"), "--out", str(tmp_path / "cli"), "--seed", "4",
                 "--json"]) == 0
    cap = capsys.readouterr()
    printed = json.loads(cap.out)
    assert result.to_dict() == json.loads((tmp_path / "cli" / "truth.json").read_text())
    setup = result.save(tmp_path / "api")
    assert setup == (tmp_path / "api" / "setup.toml").resolve()
    assert _files(tmp_path / "api") == _files(tmp_path / "cli")  # byte-identical folder
    assert cap.err.strip() == f"bayes-rcsa synthesize: {result.summary_line().replace('/api', '/cli')}"
    assert {k: printed[k] for k in result.summary_data()} == result.summary_data()
    assert result.hidden_effects == {"tip_mass": 0.002}
    back = Campaign.load(tmp_path / "api")
    _same_campaign(back, result)
    assert back.path == result.path
    assert back.summary_line() == result.summary_line()
    with pytest.raises(SetupError, match="loaded from"):
        back.save(tmp_path / "again")
    fig = result.figures()["frfs"]
    assert len(fig.axes[0].lines) == 2
    html = result._repr_html_()
    assert "25, 35 mm" in html and "mass at the tool tip = 0.002" in html
    _no_internal_names(html)


def test_synthesize_takes_a_loaded_configuration_and_refuses_cuts_with_artifact(bench):
    from bayes_rcsa.synthetic import load_bench_config

    a = bayes_rcsa.synthesize(load_bench_config(bench / "bench.toml"), seed=4)
    b = bayes_rcsa.synthesize(bench / "bench.toml", seed=4)
    _same_campaign(a, b)
    with pytest.raises(SetupError, match="cannot be combined with --artifact"):
        bayes_rcsa.synthesize(bench / "bench.toml", artifact=True, cuts=3)


# -- identify_spindle --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def artifact(tmp_path_factory):
    from bayes_rcsa.synthetic import default_bench_config
    from bayes_rcsa.synthetic.artifact import default_bench_artifact, generate_artifact_tests, write_artifact_tests

    # 8 Hz lines (276): every assertion below compares the API with the command or with itself, whatever the grid;
    # a spindle fit costs 2.4 s of CPU here against 4.5 s at 4 Hz (6 and 7 modes, no warning either way), and this
    # file makes three
    art = default_bench_artifact(frequency_start=400.0, frequency_stop=2600.0, frequency_step=8.0)
    tests = generate_artifact_tests(default_bench_config(), art, np.random.default_rng(2), directions=("x",))
    return write_artifact_tests(tests, tmp_path_factory.mktemp("artifact") / "tests")


@pytest.fixture(scope="module")
def spindle(artifact):
    return bayes_rcsa.identify_spindle(artifact, samples=2, seed=1, workers=1)


def test_identify_spindle_is_the_command_and_exposes_its_samples(artifact, spindle, tmp_path, capsys):
    assert isinstance(spindle, SpindleInterface) and isinstance(spindle.samples, SpindleSamples)
    assert spindle.samples.n_samples == 2 and spindle.directions == ("x",)
    np.testing.assert_array_equal(spindle.samples.nominal["x"], spindle.receptances["x"].block)
    assert main(["spindle", str(artifact), "--out", str(tmp_path / "cli"), "--samples", "2", "--seed", "1",
                 "--workers", "1", "--quiet", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    written = json.loads((tmp_path / "cli" / "spindle_summary.json").read_text())
    assert spindle.to_dict() == written and written["warnings"] == list(spindle.warnings)
    assert {k: printed[k] for k in spindle.summary_data()} == spindle.summary_data()
    spindle.save(tmp_path / "api")
    cli, api = _files(tmp_path / "cli"), _files(tmp_path / "api")
    assert cli.keys() == api.keys() == set(written["files"])
    assert {k: v for k, v in api.items() if not k.endswith((".png", ".npz"))} == \
        {k: v for k, v in cli.items() if not k.endswith((".png", ".npz"))}
    np.testing.assert_array_equal(load_spindle_samples(tmp_path / "api" / "spindle_samples.npz").samples["x"],
                                  spindle.samples.samples["x"])
    back = SpindleInterface.load(tmp_path / "api")
    assert back.summary == spindle.summary and back.warnings == spindle.warnings
    np.testing.assert_array_equal(back.receptances["x"].block, spindle.receptances["x"].block)
    np.testing.assert_array_equal(back.raw["x"].block, spindle.raw["x"].block)
    np.testing.assert_array_equal(back.samples.samples["x"], spindle.samples.samples["x"])
    with pytest.raises(SetupError, match="loaded from"):
        back.figures()


def test_identify_spindle_without_samples_saves_no_samples_file(artifact, spindle, tmp_path):
    none = bayes_rcsa.identify_spindle(artifact, samples=0, workers=1)
    assert none.samples is None and none.summary["samples_file"] is None
    none.save(tmp_path / "out", plots=False)
    assert not (tmp_path / "out" / "spindle_samples.npz").exists() and not (tmp_path / "out" / "spindle_x.png").exists()
    np.testing.assert_array_equal(none.receptances["x"].block, spindle.receptances["x"].block)  # the fit is seed-free
    assert none.summary_line() == f"wrote spindle_x.csv in {tmp_path / 'out'}"


def test_identify_spindle_figures_and_notebook_view(spindle):
    figs = spindle.figures()
    assert set(figs) == {"spindle_x", "artifact_x"} and len(figs["spindle_x"].axes) == 6
    html = spindle._repr_html_()
    n_modes = spindle.summary["directions"]["x"]["modal_model"]["n_modes"]
    assert f"{n_modes} modes" in html and " Hz" in html and "2 per direction" in html
    _no_internal_names(html)


def test_identify_spindle_refuses_bad_options_before_any_work(artifact):
    with pytest.raises(SetupError, match=r"--max-modes 30: expected an integer in \[1, 20\]"):
        bayes_rcsa.identify_spindle(artifact, max_modes=30)
    with pytest.raises(SetupError, match="has no measurement for \\['y'\\]"):
        bayes_rcsa.identify_spindle(artifact, directions=("y",))


# -- identifiability ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def study(example):
    """One length (one fit), a chain of a few dozen steps: not converged, which is one of the warnings tested."""
    return bayes_rcsa.identifiability(example, lengths=[0.025], max_steps=40, check_every=20, walkers=18,
                                      sampler="mcmc")


def test_identifiability_saves_the_command_files_and_round_trips(study, tmp_path):
    assert isinstance(study, Identifiability) and [f["name"] for f in study.fits] == ["single_25mm"]
    doc = study.to_dict()
    path = study.save(tmp_path / "out")
    assert json.loads(path.read_text()) == doc and set(doc["plots"]) == {"corner_overlay.png", "forest.png"}
    assert {"identifiability.md", "identifiability.html", "forest.png", "corner_overlay.png"} <= set(
        p.name for p in (tmp_path / "out").iterdir())
    assert (tmp_path / "out" / "fits" / "single_25mm" / "posterior.nc").is_file()
    back = Identifiability.load(tmp_path / "out")
    assert back.to_dict() == doc and back.warnings == study.warnings and back.seed == 0
    assert back.summary_line() == study.summary_line() == f"1 fit(s), 1 NOT converged; results in {tmp_path / 'out'}"
    assert back.summary_data() == {"fits_not_converged": ["single_25mm"]}
    assert doc["sampler"]["requested"] == "mcmc"  # what the fixture asked for, recorded
    np.testing.assert_array_equal(back.draws["single_25mm"].values["k_xf"], study.draws["single_25mm"].values["k_xf"])
    assert set(back.posteriors) == {"single_25mm"}
    study.save(tmp_path / "bare", plots=False, posteriors=False)
    assert "plots" not in json.loads((tmp_path / "bare" / "identifiability.json").read_text())
    assert not (tmp_path / "bare" / "fits").exists()


def test_identifiability_warnings_figures_and_notebook_view(study):
    assert "fit single_25mm did not converge: its verdicts are not reliable" in study.warnings
    assert set(study.figures()) == {"corner_overlay", "forest"}
    html = study._repr_html_()
    assert "25 mm" in html and "translational contact stiffness" in html and "did not converge" in html
    _no_internal_names(html)
