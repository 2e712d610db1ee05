"""identify by importance sampling (``sampler="importance"``, :mod:`bayes_rcsa.inference.importance`).

A small campaign (x direction, 8-Hz lines, 25 and 40 mm): the importance posterior's 5/50/95 % points agree with
an MCMC reference; a proposal deliberately too narrow is refused by its Pareto k and the chain runs instead, with
the reason in summary.json; posterior.nc of the importance mode is read by ``load_posterior`` and ``predict``
works on it; the command line's ``--sampler`` and its refusal of ``--resume``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import bayes_rcsa
from bayes_rcsa.cli.main import main
from bayes_rcsa.errors import SetupError
from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.importance import systematic_resample
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
from bayes_rcsa.io.setup import load_setup

from test_api_identify import setup_file  # noqa: F401  (the module-scoped campaign of the API tests)
from test_inference_support import quick_settings

LENGTHS = (0.025, 0.040)
#: Spread (sd, in posterior sd) of a 5/50/95 % point between converged default chains of different seeds on this
#: bench (see test_importance_quantiles_agree_with_an_mcmc_reference).
CHAIN_SPREAD_SD = 0.17
#: the fall-back runs need no converged chain: they test the dispatch, not the chain.  100 steps (one check) still
#: give a tau and keep 17 thinned steps x 32 walkers to compare bit for bit; the 300 steps before cost ~2 s more
SHORT = dict(max_steps=100, check_every=100)


@pytest.fixture(scope="module")
def problem(setup_file):  # noqa: F811
    setup = load_setup(setup_file)
    return build_problem_from_setup(setup, IdentificationOptions.from_setup(setup.extra, lengths=LENGTHS))


@pytest.fixture(scope="module")
def by_importance(problem):
    return identify(problem, seed=5, sampler="importance", settings=quick_settings())


def test_importance_quantiles_agree_with_an_mcmc_reference(problem, by_importance):
    """Every parameter's 5/50/95 % point agrees with a converged chain's within the tail check's tolerance.

    :data:`bayes_rcsa.inference.tail_check.TOLERANCE_SD` (0.4 posterior sd) bounds the importance estimate's error;
    the reference chain's own error is added: twice the spread of that quantile between converged default chains of
    different seeds, 0.17 sd (95 % point of k_thetaM: 0.27, 0.58 and 0.61 sd above the importance estimate for
    seeds 102, 101 and 6, 0.35 sd for a long chain with ESS 4,000 and 21,250 steps), larger than the chain's ESS
    implies because walkers are not independent chains.  Without it the test was a coin toss: on this bench the
    importance posterior's 95 % point of k_thetaM is 0.35 sd short of the long chain's (issue #42).
    benchmarks/importance_accuracy.py compares with long stretch-move chains.
    """
    from bayes_rcsa.inference.tail_check import TOLERANCE_SD

    imp = by_importance.importance
    assert imp.accepted and by_importance.chain is None
    s = by_importance.summary
    assert s["converged"] is True and s["sampler"]["mode"] == "importance"
    assert s["sampler"]["pareto_k"] <= 0.7 and s["sampler"]["ess"] >= 1000
    assert s["tau"] is None and s["n_steps"] is None and "R-hat and tau do not apply" in s["stop_reason"]
    # the reference must be a converged chain.  Seed 6 was until the bench's solver was compiled (its data moved by
    # 1e-10 relative): on the new rounding that chain met the 20,000-step cap at R-hat 1.015 (tau of k_thetaM 198
    # against 54); the default chain's tau on this posterior varies 50-200 between seeds.  101 is the next seed tried.
    ref = identify(problem, seed=101, sampler="mcmc", settings=quick_settings())
    assert ref.summary["converged"]
    q_is = np.quantile(by_importance.flat_theta, (0.05, 0.5, 0.95), axis=0)
    q_ref = np.quantile(ref.flat_theta, (0.05, 0.5, 0.95), axis=0)
    sd = by_importance.flat_theta.std(axis=0)
    shift = np.abs(q_is - q_ref) / sd
    tolerance = TOLERANCE_SD + 2 * CHAIN_SPREAD_SD
    assert np.all(shift <= tolerance), (shift, tolerance)
    # and a posterior shifted by 1 sd would not pass: the test can fail
    assert np.any(np.abs(q_is + 1.0 * sd - q_ref) / sd > tolerance)


def test_resampled_draws_are_equally_weighted_and_systematic(by_importance):
    theta = by_importance.theta
    assert theta.shape == (1, 4000, by_importance.problem.parameters.ndim)
    assert np.all(np.isfinite(by_importance.log_prob))
    # systematic resampling: a draw of weight w appears floor(n w) or ceil(n w) times
    w = np.array([0.5, 0.3, 0.15, 0.05])
    counts = np.bincount(systematic_resample(w, 20, np.random.default_rng(0)), minlength=4)
    assert np.all(np.abs(counts - 20 * w) < 1)


def test_too_narrow_proposal_falls_back_to_the_chain_and_says_why(problem):
    res = identify(problem, seed=5, sampler="importance", settings=quick_settings(**SHORT),
                   importance_options={"proposal_shrink": 0.1, "max_proposals": 6000})
    block = res.summary["sampler"]
    assert not res.importance.accepted and res.chain is not None
    assert block["mode"] == "mcmc" and block["requested"] == "importance"
    assert block["pareto_k"] > 0.7
    assert "Pareto shape k" in block["fallback_reason"]
    assert res.summary["n_steps"] > 0 and res.summary["tau"] is not None
    assert any(w.startswith("importance sampling refused") for w in res.summary["warnings"])
    # the fall-back chain is the chain of sampler="mcmc" with the same seed (importance sampling has its own stream)
    plain = identify(problem, seed=5, sampler="mcmc", settings=quick_settings(**SHORT))
    np.testing.assert_array_equal(res.theta, plain.theta)
    # "auto": the same fall-back, noted in the sampler block but not a warning
    auto = identify(problem, seed=5, sampler="auto", settings=quick_settings(**SHORT),
                    importance_options={"proposal_shrink": 0.1, "max_proposals": 6000})
    assert auto.summary["sampler"]["fallback_reason"] == block["fallback_reason"]
    assert not any(w.startswith("importance sampling refused") for w in auto.summary["warnings"])


def test_importance_posterior_nc_is_read_and_predict_works(setup_file, tmp_path):  # noqa: F811
    out = tmp_path / "identify"
    post = bayes_rcsa.identify(setup_file, lengths=LENGTHS, seed=3, sampler="importance", out=out, plots=True)
    assert post.summary["sampler"]["mode"] == "importance"
    assert "importance sampling: Pareto k" in post.summary_line()
    assert (out / "corner.png").is_file() and (out / "frf.png").is_file()
    assert not (out / "trace.png").exists() and not (out / "chain.h5").exists()
    draws = bayes_rcsa.posterior.load_posterior(out / "posterior.nc")
    assert draws.n_draws == 4000
    kx = draws.values["k_xf"]
    q = post.summary["parameters"]["k_xf"]
    assert np.quantile(kx, 0.5) == pytest.approx(q["q50"], rel=1e-12)
    pred = bayes_rcsa.predict(setup_file, out / "posterior.nc", lengths=[0.030], max_draws=200)
    assert pred.converged is True and pred.document["n_draws"] == 200
    dominant = [m for m in pred.predictions if m["dominant"]][0]
    assert dominant["q05_hz"] < dominant["q50_hz"] < dominant["q95_hz"]


def test_cli_sampler_option_and_resume(setup_file, tmp_path, capsys):  # noqa: F811
    out = tmp_path / "cli"
    argv = ["identify", str(setup_file), "--out", str(out), "--lengths", "0.025,0.040", "--quiet", "--no-plots"]
    assert main([*argv, "--sampler", "importance"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sampler"]["mode"] == "importance" and summary["converged"] is True
    capsys.readouterr()
    # a resume continues a chain: with importance sampling it is refused in one line, before the folder is touched
    assert main([*argv, "--sampler", "importance", "--resume"]) == 2
    err = capsys.readouterr().err
    assert "--resume continues an MCMC checkpoint" in err and len(err.strip().splitlines()) == 1
    assert json.loads((out / "summary.json").read_text()) == summary
    with pytest.raises(SetupError, match="--sampler 'gibbs'"):
        bayes_rcsa.identify(setup_file, lengths=LENGTHS, sampler="gibbs")


def _noise_above_signal_campaign():
    """One length of the bundled example (x, 25 mm, 101 lines over 500-2500 Hz, the default noise prior
    [1e-4, 10]) simulated from the model at a stiff joint with noise twice the signal (log10 sigma_0 = 0.3):
    the configuration ``single`` of benchmarks/sbc.py, where SBC put every draw on one side of such truths."""
    from bayes_rcsa.data import example_setup
    from bayes_rcsa.inference.problem import build_problem
    from bayes_rcsa.inference.sbc import simulate_problem
    from bayes_rcsa.model.receptance import FRF

    setup = load_setup(example_setup())
    m = next(m for m in setup.measurements if m.configuration.direction == "x" and m.configuration.clamping_length == 0.025)
    f = m.frf.frequency_hz
    idx = np.nonzero((f >= 500.0) & (f <= 2500.0))[0][::10]
    options = IdentificationOptions(lengths=(0.025,), band=(500.0, 2500.0), tempering=1.0)
    problem = build_problem(setup.model(), [(m.configuration, FRF(f[idx], m.frf.values[idx], None, m.frf.source))],
                            setup.contact, options)
    assert problem.parameters.names == ("k_xf", "k_thetaM", "sigma_0")
    truth = np.array([8.9, 7.5, 0.3])  # log10 N/m, log10 N m/rad, log10 of the relative noise scale
    return simulate_problem(problem, truth, np.random.default_rng(3)), truth


def test_noise_above_signal_finds_the_mode_and_refuses_importance_sampling():
    """With noise above the signal (a) the optimum is the likelihood's, not the data-weighted grid's: that grid ranks
    a soft joint (k_xf 1e5, k_thetaM 2e3) with a larger noise scale first, 85 log units below the truth, and
    importance sampling around it was accepted with every draw below the true stiffnesses; (b) importance sampling
    is refused (noise scale at the optimum > 1) and the chain runs, with the reason in the summary."""
    from bayes_rcsa.inference.importance import MAX_NOISE_SCALE

    problem, truth = _noise_above_signal_campaign()
    # the fall-back chain is not under test here: a short fixed-steps one
    res = identify(problem, seed=5, sampler="auto", settings=quick_settings(n_walkers=8, n_steps=60, n_burn=20))
    optimum = res.optimum
    assert optimum.log_posterior >= float(problem.log_posterior()(truth[None])[0]) - 1.0, (optimum.x, optimum.message)
    assert "likelihood's own profile" in optimum.message
    assert 10 ** optimum.x[2] > MAX_NOISE_SCALE
    block = res.summary["sampler"]
    assert not res.importance.accepted and res.importance.n_proposals == 0 and res.chain is not None
    assert block["mode"] == "mcmc" and "noise above the signal" in block["fallback_reason"]


class _NarrowGaussian:
    """A Gaussian log posterior on a box [0, 1]^3 whose sds are 1e-6, 1e-2 and 0.1 box widths, correlated in the
    first two coordinates: the first direction is 100 times narrower than the Laplace Hessian's step."""

    def __init__(self):
        sd = np.array([1e-6, 1e-2, 0.1])
        corr = np.array([[1.0, 0.6, 0.0], [0.6, 1.0, 0.0], [0.0, 0.0, 1.0]])
        self.mu = np.array([0.4, 0.5, 0.6])
        self.cov = corr * np.outer(sd, sd)
        self.prec = np.linalg.inv(self.cov)

    def __call__(self, x):
        z = np.atleast_2d(x) - self.mu
        out = -0.5 * np.einsum("ni,ij,nj->n", z, self.prec, z)
        return np.where(np.all((x >= 0) & (x <= 1), axis=1), out, -np.inf)


def test_laplace_covariance_follows_a_direction_narrower_than_its_step():
    """A coordinate known to 1e-6 of its prior width (the statistical-discrepancy coefficients at very low noise):
    the covariance is the posterior's, not floored at the step (1e-4 widths), and importance sampling is accepted
    with the right spread.  Before the per-coordinate second measurement the proposal was 100 times too wide in that
    direction and importance sampling was refused (Pareto k of 7-50 in SBC replicates, docs/calibration.md)."""
    from bayes_rcsa.inference.importance import FD_STEP_OF_WIDTH, importance_posterior, laplace_covariance

    post = _NarrowGaussian()
    bounds = np.array([[0.0, 1.0]] * 3)
    cov, note = laplace_covariance(post, post.mu, bounds)
    assert 1e-6 < FD_STEP_OF_WIDTH / 10
    # the Hessian of a quadratic by central differences is exact up to round-off: 1e-6 relative here
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(post.cov)), rtol=1e-3)
    np.testing.assert_allclose(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]), 0.6, atol=1e-3)
    assert note == ""
    res = importance_posterior(post, post.mu, bounds, np.random.default_rng(4), 4000)
    assert res.accepted and res.pareto_k <= 0.7, (res.reason, res.pareto_k)
    # the resampled draws' sds within 10 % (4000 resampled draws of ESS >= 2000: sd error ~ 2-3 %)
    np.testing.assert_allclose(res.theta.std(axis=0), np.sqrt(np.diag(post.cov)), rtol=0.1)


def test_optimum_searches_the_model_terms_parameters_when_the_fit_stays_poor():
    """A 14 g tip mass at 7 mm, little noise (log10 sigma_0 = -3.24): the term-free grid (tip mass held at 0)
    finds the stiffnesses of another ridge, and its polish stopped at k_xf 1e9 with the noise scale on its bound
    0.3, 1,428 log units below the truth (SBC of ``tip_mass_noise03``, docs/calibration.md: every draw on one
    side of such truths).  With the grid searched again at the tip mass's prior 10, 50 and 90 % points the optimum is the
    data's mode."""
    from bayes_rcsa.data import example_setup
    from bayes_rcsa.inference.problem import build_problem
    from bayes_rcsa.inference.sampler import find_optimum
    from bayes_rcsa.inference.sbc import simulate_problem
    from bayes_rcsa.model.receptance import FRF

    setup = load_setup(example_setup())
    m = next(m for m in setup.measurements if m.configuration.direction == "x" and m.configuration.clamping_length == 0.025)
    f = m.frf.frequency_hz
    idx = np.nonzero((f >= 500.0) & (f <= 2500.0))[0][::10]
    options = IdentificationOptions(lengths=(0.025,), band=(500.0, 2500.0), tempering=1.0,
                                    model={"terms": ["tip_mass"]}, noise_scale=(1e-4, 0.3))
    problem = build_problem(setup.model(), [(m.configuration, FRF(f[idx], m.frf.values[idx], None, m.frf.source))],
                            setup.contact, options)
    assert problem.parameters.names == ("k_xf", "k_thetaM", "tip_mass_kg", "tip_mass_offset_m", "sigma_0")
    truth = np.array([6.232, 4.816, 0.014, 0.007, -3.238])
    lp = simulate_problem(problem, truth, np.random.default_rng(22)).log_posterior(1.0)
    optimum = find_optimum(lp)
    assert "levels of the model terms' parameters" in optimum.message
    # a maximum, so at least the truth's value (the truth is 6 log units below the mode with these data)
    assert optimum.log_posterior >= float(lp(truth[None])[0]), (optimum.x, optimum.message)
    np.testing.assert_allclose(optimum.x[:4], truth[:4], atol=0.05)


@pytest.mark.parametrize("terms, expected", [
    ((), []),
    (("tip_mass",), [(m, e) for m in (0.002, 0.010, 0.018) for e in (-0.008, 0.0, 0.008)]),
    (("statistical_discrepancy",), []),  # six coefficients: 729 combinations, more than the limit of 9
])
def test_term_levels_span_the_prior_box_of_at_most_two_term_parameters(terms, expected):
    """The levels of the second grid search: every combination of each sampled term parameter at its prior's 10,
    50 and 90 % points (uniform priors: tip mass on [0, 20] g, offset on [-10, 10] mm), none for many
    coefficients or no term."""
    from bayes_rcsa.data import example_setup
    from bayes_rcsa.inference.problem import build_problem
    from bayes_rcsa.inference.search import MAX_TERM_COMBINATIONS, term_levels

    setup = load_setup(example_setup())
    m = next(m for m in setup.measurements if m.configuration.direction == "x" and m.configuration.clamping_length == 0.025)
    options = IdentificationOptions(lengths=(0.025,), band=(500.0, 2500.0), model={"terms": list(terms)})
    problem = build_problem(setup.model(), [(m.configuration, m.frf)], setup.contact, options)
    levels = term_levels(problem.likelihood, problem.priors)
    assert len(levels) <= MAX_TERM_COMBINATIONS
    got = [(lv["tip_mass_kg"], lv["tip_mass_offset_m"]) for lv in levels]
    np.testing.assert_allclose(np.array(got).reshape(-1, 2), np.array(expected, dtype=float).reshape(-1, 2),
                               atol=1e-12)
