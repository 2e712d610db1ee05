"""posterior.nc carries the parameter model: products use it even after the setup was edited."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.outputs import write_outputs
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
from bayes_rcsa.io import load_setup
from bayes_rcsa.params import ParameterModel
from bayes_rcsa.posterior import load_posterior
from bayes_rcsa.posterior.prediction_outputs import frequencies_document, run_prediction
from bayes_rcsa.stability.posterior_frf import posterior_frf_draws
from bayes_rcsa.store import read_posterior
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

from test_inference_support import quick_settings


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A fit of a small x/y campaign written to DIR/posterior.nc, and its setup file."""
    cfg = default_bench_config(directions=("x", "y"), clamping_lengths=(0.025, 0.040), frequency_step=8.0)
    camp = generate_campaign(cfg, np.random.default_rng(17))
    setup_path = write_campaign(camp, tmp_path_factory.mktemp("camp") / "bench")
    # fit the x measurements only (cheaper); lobes still needs both spindle files, which stay listed
    head, *blocks = setup_path.read_text().split("[[measurement]]")
    setup_path.write_text("[[measurement]]".join([head] + [b for b in blocks if 'direction = "x"' in b]))
    setup = load_setup(setup_path)
    problem = build_problem_from_setup(setup, IdentificationOptions(lengths=(0.025, 0.040)))
    # a chain stopped short: the posterior's not-converged status is what the tests below follow downstream
    res = identify(problem, seed=2, sampler="mcmc",
                   settings=quick_settings(n_walkers=16, max_steps=200, check_every=200, ess_min=1e12))
    out = tmp_path_factory.mktemp("fit")
    write_outputs(res, out, plots=False)
    return setup_path, out / "posterior.nc", problem.parameters


def _edited(setup_path, tmp_path):
    """A copy of the setup with other damping and stiffness priors (as if edited after the fit)."""
    dst = tmp_path / "edited"
    shutil.copytree(setup_path.parent, dst)
    text = (dst / "setup.toml").read_text()
    text = text.replace("translational_damping = 10.0", "translational_damping = 55.0")
    text = text.replace("rotational_stiffness = [1000.0, 100000000.0]", "rotational_stiffness = [10000.0, 10000000.0]")
    assert "55.0" in text and "10000000.0]" in text
    (dst / "setup.toml").write_text(text)
    return dst / "setup.toml"


def test_posterior_nc_holds_the_parameter_model(fitted):
    _, posterior, pm = fitted
    idata = read_posterior(posterior)
    attrs = {k: v for g in idata.groups() for k, v in idata[g].attrs.items()}
    assert ParameterModel.from_dict(json.loads(attrs["parameter_model"])) == pm
    draws = load_posterior(posterior)
    assert draws.parameters == pm and draws.parameter_model_source == "posterior"
    assert np.all(draws.values["c_xf"] == 10.0)


def test_predict_and_lobes_use_the_posterior_after_the_setup_was_edited(fitted, tmp_path):
    setup_path, posterior, pm = fitted
    edited = _edited(setup_path, tmp_path)
    run = run_prediction(load_setup(edited), posterior, [0.030], max_draws=40, seed=1)
    assert run.meta["parameter_model_source"] == "posterior"
    notes = run.meta["parameter_model_notes"]
    assert any("translational_damping = 55 differs" in n and "c_xf = 10" in n for n in notes), notes
    assert any("rotational_stiffness" in n for n in notes) and not any("translational_stiffness" in n for n in notes)
    assert np.all(run.draws.values["c_xf"] == 10.0)  # the fit's damping, not the edited 55
    # identifiability uses the fit's recorded priors, not the edited ones
    assert run.identifiability["k_thetaM"]["prior"] == pm.priors["k_thetaM"].describe()
    doc = frequencies_document(run)
    assert doc["parameter_model_source"] == "posterior" and doc["contact_parameters"]["c_xf"]["sampled"] is False
    # the prediction itself equals the one made with the original setup
    same = run_prediction(load_setup(setup_path), posterior, [0.030], max_draws=40, seed=1)
    for a, b in zip(run.prediction.bands, same.prediction.bands):
        np.testing.assert_array_equal(a.magnitude, b.magnitude)
    # lobes --posterior: the posterior-predictive FRFs do not change with the edit either
    rng = lambda: np.random.default_rng(5)  # noqa: E731
    a = posterior_frf_draws(edited, posterior, 0.030, 20, rng())
    b = posterior_frf_draws(setup_path, posterior, 0.030, 20, rng())
    np.testing.assert_array_equal(a.frf_x, b.frf_x)
    np.testing.assert_array_equal(a.frf_y, b.frf_y)


def test_predict_cli_says_when_the_setup_disagrees_with_the_posterior(fitted, tmp_path, capsys):
    from bayes_rcsa.cli.main import main

    setup_path, posterior, _ = fitted
    edited = _edited(setup_path, tmp_path)
    out = tmp_path / "pred"
    rc = main(["predict", str(edited), "--posterior", str(posterior), "--lengths", "0.030", "--max-draws", "30",
               "--no-plots", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 0
    lines = [ln for ln in err.splitlines() if "translational_damping" in ln]
    assert len(lines) == 1 and lines[0].startswith("bayes-rcsa predict: warning:") and "posterior" in lines[0], err
    doc = json.loads((out / "frequencies.json").read_text())
    assert doc["parameter_model_source"] == "posterior"


def test_lobes_cli_records_the_posterior_provenance_and_status(fitted, tmp_path, capsys):
    from bayes_rcsa.cli.main import main

    setup_path, posterior, _ = fitted
    out = tmp_path / "lobes"
    rc = main(["lobes", str(setup_path), "--posterior", str(posterior), "--clamping-length", "0.030",
               "--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.7", "--speeds", "8000:20000:100",
               "--draws", "20", "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 0, err
    # the fixture's 200-step chain is not converged (ess_min = 1e12): lobes must say so, once, in one line
    assert sum("did not converge" in ln for ln in err.splitlines()) == 1, err
    doc = json.loads((out / "lobes.json").read_text())
    src = doc["source"]
    assert src["parameter_model_source"] == "posterior" and src["posterior_status"]["converged"] is False
    assert src["fixed_parameters"]["c_xf"] == 10.0
    assert any("did not converge" in w for w in doc["warnings"])
