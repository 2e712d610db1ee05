"""The public API of identify and update (bayes_rcsa.identify -> Posterior, bayes_rcsa.update -> CutUpdate).

The same small runs as the command-line tests (tests/test_inference_cli.py, tests/test_cuts_cli.py): the API
returns what the command line writes, ``save`` -> ``load`` round-trips, figures and the notebook view work, and
the warnings of a run reach the result and its JSON.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import bayes_rcsa
from bayes_rcsa.cli.main import main
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign
from bayes_rcsa.units import hz, sci
from test_cuts_cli import world  # noqa: F401  (the module-scoped fixture of the update tests)

#: a chain of few steps: cheap, and the run is reported as not converged (a warning that must reach result and JSON;
#: the default importance sampling would converge)
SMALL = dict(lengths=(0.025, 0.040), seed=4, max_steps=300, check_every=100, sampler="mcmc")
SMALL_ARGV = ["--lengths", "0.025,0.040", "--seed", "4", "--max-steps", "300", "--check-every", "100", "--quiet",
              "--sampler", "mcmc"]


@pytest.fixture(scope="module")
def setup_file(tmp_path_factory):
    cfg = default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.030, 0.040), frequency_step=8.0)
    camp = generate_campaign(cfg, np.random.default_rng(21))
    return write_campaign(camp, tmp_path_factory.mktemp("campaign") / "bench")


@pytest.fixture(scope="module")
def cli_run(setup_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "identify"
    # --no-plots here and plots=False in the save compared with it: the PNGs (trace, corner, frf; 2.1-2.3 s of CPU
    # a set) are written and checked once, by test_identify_with_out_checkpoints_and_saves_there (the CLI's own
    # path: identify(out=...) -> Posterior._write, as save)
    assert main(["identify", str(setup_file), "--out", str(out), *SMALL_ARGV, "--no-plots"]) == 0
    return out


@pytest.fixture(scope="module")
def posterior(setup_file):
    return bayes_rcsa.identify(setup_file, **SMALL)


def _without_timing(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k != "timing"}


def test_identify_returns_what_the_command_line_writes(posterior, cli_run):
    assert isinstance(posterior, bayes_rcsa.Posterior)
    written = json.loads((cli_run / "summary.json").read_text())
    assert json.loads(json.dumps(_without_timing(posterior.to_dict()))) == _without_timing(written)
    assert posterior.path is None and posterior.setup is not None
    assert posterior.summary_line() == "Bayesian fit over the clamping lengths: NOT converged; results in memory"
    # in memory: the draws and the InferenceData posterior.nc holds
    assert posterior.draws.n_draws == written["n_draws"]
    ref = bayes_rcsa.Posterior.load(cli_run)
    np.testing.assert_array_equal(posterior.draws.values["k_xf"], ref.draws.values["k_xf"])
    np.testing.assert_array_equal(posterior.inference_data.posterior["k_xf"].values,
                                  ref.inference_data.posterior["k_xf"].values)


def test_save_writes_the_command_line_files_and_load_round_trips(posterior, cli_run, tmp_path):
    out = tmp_path / "saved"
    posterior.save(out, plots=False)  # as the CLI run (--no-plots); the plots: test_identify_with_out_checkpoints...
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in cli_run.iterdir() if p.name != "chain.h5")
    back = bayes_rcsa.Posterior.load(out)
    assert back.summary == json.loads(json.dumps(posterior.summary))
    assert back.path == out / "posterior.nc"
    for name, v in posterior.draws.values.items():
        np.testing.assert_array_equal(back.draws.values[name], v)
    with pytest.raises(bayes_rcsa.errors.SetupError, match="exists and is not empty"):
        posterior.save(out)


def test_load_decodes_the_inference_data_only_when_used_and_from_the_file_as_loaded(cli_run, tmp_path):
    import shutil
    import subprocess
    import sys

    folder = tmp_path / "copy"
    shutil.copytree(cli_run, folder)
    # a fresh interpreter: loading and reading the draws import no ArviZ/xarray (a batch worker or predict never
    # decodes the InferenceData); the first use of inference_data does
    probe = ("import sys, bayes_rcsa; p = bayes_rcsa.Posterior.load(sys.argv[1]); p.draws.values['k_xf'].sum(); "
             "before = 'arviz' in sys.modules or 'xarray' in sys.modules; "
             "p.inference_data.posterior; print(before, 'arviz' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", probe, str(folder)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["False", "True"]
    # the content is the file as it was loaded: replaced or removed afterwards, the loaded posterior is unchanged
    loaded = bayes_rcsa.Posterior.load(folder)
    expected = bayes_rcsa.Posterior.load(cli_run).inference_data.posterior["k_xf"].values
    (folder / "posterior.nc").write_bytes(b"not a netCDF file")
    np.testing.assert_array_equal(loaded.inference_data.posterior["k_xf"].values, expected)
    (folder / "posterior.nc").unlink()
    np.testing.assert_array_equal(loaded.inference_data.posterior["k_xf"].values, expected)
    import arviz

    # every ArviZ function takes it (az.summary, az.plot_posterior check the type)
    assert isinstance(loaded.inference_data, arviz.InferenceData)
    assert "k_xf" in arviz.summary(loaded.inference_data, var_names=["k_xf"], kind="stats").index


def test_warnings_reach_the_result_and_the_json(posterior, cli_run):
    assert not posterior.converged
    assert any(w.startswith("not converged") for w in posterior.warnings)
    assert list(posterior.warnings) == posterior.summary["warnings"]
    assert set(posterior.warnings) <= set(json.loads((cli_run / "summary.json").read_text())["warnings"])


def test_figures_and_notebook_view(posterior):
    from matplotlib.figure import Figure

    figs = posterior.figures()
    assert set(figs) == {"trace", "corner", "frf"} and all(isinstance(f, Figure) for f in figs.values())
    # the corner shows the model's parameters; the noise scales (one per measurement) are in the tables
    pm = posterior.identification.problem.parameters
    model = [n for n in pm.names if n not in pm.noise_names]
    assert model and len(pm.noise_names) > 0
    corner_labels = [ax.get_xlabel() for ax in figs["corner"].axes if ax.get_xlabel()]
    assert len(figs["corner"].axes) == len(model) ** 2 and len(corner_labels) == len(model)
    assert not any("noise" in lab for lab in corner_labels), corner_labels
    page = posterior._repr_html_()
    table = page.split("Warnings:")[0]  # the warnings below the table quote the sampler's own parameter names
    f = posterior.summary["natural_frequencies"][0]
    k = posterior.summary["stiffness"][0]["k_xf"]
    # the unit policy's forms (bayes_rcsa.units), the same as on stderr and in the reports
    assert hz(f["q50_hz"], f["q05_hz"], f["q95_hz"]) in table and "natural frequency at 25 mm" in table
    assert sci(k["q50"], 3, k["q05"], k["q95"], "N/m") in table
    assert "contact stiffness, translational (kxf) at 25 mm" in table
    assert "k_xf" not in table and "thetaM" not in table
    assert "not converged" in page  # the warnings are shown too
    assert posterior.summary_line() == f"Bayesian fit over the clamping lengths: NOT converged; results in {posterior.folder or 'memory'}"


def test_identify_with_out_checkpoints_and_saves_there(setup_file, tmp_path, cli_run):
    out = tmp_path / "run"
    # with plots: the one run of this file that writes the PNGs (what `bayes-rcsa identify --out` writes)
    post = bayes_rcsa.identify(setup_file, **SMALL, out=out)
    assert post.path == out / "posterior.nc" and (out / "chain.h5").is_file()
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [p.name for p in cli_run.iterdir()] + ["corner.png", "frf.png", "trace.png"])
    assert all((out / name).stat().st_size > 0 for name in ("corner.png", "frf.png", "trace.png"))
    assert _without_timing(json.loads((out / "summary.json").read_text())) == \
        _without_timing(json.loads((cli_run / "summary.json").read_text()))
    assert post.summary_line() == f"Bayesian fit over the clamping lengths: NOT converged; results in {out}"
    with pytest.raises(bayes_rcsa.errors.SetupError, match="use --force"):
        bayes_rcsa.identify(setup_file, **SMALL, out=out)


def test_deterministic_fit_has_no_draws(setup_file, tmp_path):
    post = bayes_rcsa.identify(setup_file, lengths=(0.025, 0.040), method="deterministic")
    assert post.draws is None and post.inference_data is None
    post.save(tmp_path / "det", plots=False)
    assert sorted(p.name for p in (tmp_path / "det").iterdir()) == ["summary.json"]
    back = bayes_rcsa.Posterior.load(tmp_path / "det")
    assert back.method == "deterministic" and back.path is None
    assert back.summary == json.loads(json.dumps(post.summary))


def test_refusals_name_the_option_before_any_work(setup_file):
    with pytest.raises(bayes_rcsa.errors.SetupError, match="--no-taps needs --library"):
        bayes_rcsa.identify(setup_file, no_taps=True)
    with pytest.raises(bayes_rcsa.errors.SetupError, match="--cuts needs a Bayesian method"):
        bayes_rcsa.identify(setup_file, method="deterministic", cuts={"path": "cuts.csv"})
    with pytest.raises(bayes_rcsa.errors.SetupError, match="--cuts needs --cut-flutes, --cut-kt, --cut-kr"):
        bayes_rcsa.identify(setup_file, lengths=(0.025, 0.040), cuts={"path": "cuts.csv"})


# -- update ------------------------------------------------------------------------------------------------------

UPDATE = dict(flutes=4, radial_immersion=0.5, kt=600e6, kt_tolerance=0.3, kr=180e6, clamping_length=0.03, draws=60,
              particles=16, min_ess=5.0, seed=3)
UPDATE_ARGV = ["--flutes", "4", "--immersion", "0.5", "--kt", "600e6±30%", "--kr", "180e6", "--clamping-length",
               "0.03", "--draws", "60", "--particles", "16", "--min-ess", "5", "--seed", "3"]


@pytest.fixture(scope="module")
def updated(world):  # noqa: F811
    return bayes_rcsa.update(world / "data" / "setup.toml", world / "posterior.nc", world / "cuts.csv", **UPDATE)


def test_update_returns_what_the_command_line_writes(world, updated, tmp_path):  # noqa: F811
    out = tmp_path / "cli"
    assert main(["update", str(world / "data" / "setup.toml"), "--posterior", str(world / "posterior.nc"), "--cuts",
                 str(world / "cuts.csv"), *UPDATE_ARGV, "--out", str(out)]) == 0
    written = json.loads((out / "update.json").read_text())
    doc = json.loads(json.dumps(updated.to_dict()))
    doc.pop("seconds"), written.pop("seconds")
    assert doc == written
    assert updated.kt_pa == written["kt_pa"]["after"] and updated.kt_pa[1] > 600e6


def test_update_save_load_and_posterior(world, updated, tmp_path):  # noqa: F811
    out = tmp_path / "upd"
    path = updated.save(out)
    assert path == out / "posterior.nc" and (out / "update.json").is_file()
    back = type(updated).load(out)
    assert (back.kt_pa, back.kr_pa, back.ess_draws, back.recommended) == \
        (updated.kt_pa, updated.kr_pa, updated.ess_draws, updated.recommended)
    assert back.summary_line() == updated.summary_line()
    post = back.posterior
    assert post.draws.n_draws == 60 and post.path == out / "posterior.nc"
    assert "cutting_kt_pa" in post.inference_data.posterior
    page = updated._repr_html_()
    assert "MPa" in page and "Kt" in page and "kt_pa" not in page


def test_update_plausibility_warning_reaches_result_and_json(world, tmp_path):  # noqa: F811
    res = bayes_rcsa.update(world / "data" / "setup.toml", world / "posterior.nc", world / "cuts.csv",
                            **{**UPDATE, "kr": 1.25e9}, allow_unusual=True)
    assert any("K_r/K_t" in w or "Kr/Kt" in w for w in res.warnings), res.warnings
    res.save(tmp_path / "u")
    assert json.loads((tmp_path / "u" / "update.json").read_text())["warnings"] == list(res.warnings)
