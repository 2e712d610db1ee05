"""One sampler driver and extra likelihood terms as part of the problem (#41).

* ``Problem.extra_terms`` / ``with_extra_terms`` / ``log_posterior``: the log posterior of a problem is its priors
  plus its (tempered) FRF likelihood plus its extra terms, and nothing else (no context variable);
* the resume fingerprint tells a run with extra terms from one without;
* :func:`bayes_rcsa.inference.sampler.run_ensemble` is the only place that builds an emcee sampler, identify, the
  library's joint check and stage 2 go through it, and its fixed-steps mode reports tau, R-hat and bulk ESS and
  says "not converged" where the chain is too short to measure its autocorrelation time.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import bayes_rcsa
from bayes_rcsa.errors import SetupError
from bayes_rcsa.inference.fingerprint import resume_state, run_fingerprint
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.inference.sampler import SamplerSettings, run_ensemble

from test_inference_support import bench, bench_model, contact_spec, quick_settings

PACKAGE = Path(bayes_rcsa.__file__).parent


class _Term:
    """An extra likelihood term linear in the first sampling coordinate."""

    name = "linear"

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        return 3.0 * theta[:, 0]


@pytest.fixture(scope="module")
def problem():
    cfg, camp = bench()
    return build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                         IdentificationOptions(lengths=(0.025, 0.040), band=(800.0, 1300.0),
                                               priors={"k_xf": [1e6, 4e6], "k_thetaM": [1e5, 2e6]}))


def _inside(problem, n: int = 5) -> np.ndarray:
    """n points inside the prior support (sampling coordinates), (n, ndim)."""
    lo, hi = np.array(problem.priors.optimisation_bounds()).T
    return lo + (hi - lo) * np.random.default_rng(0).uniform(0.2, 0.8, (n, lo.size))


def test_log_posterior_of_a_problem_is_priors_plus_tempered_likelihood_plus_its_extra_terms(problem):
    theta = _inside(problem)
    prior = problem.priors.ln_prob(theta)
    lik = problem.likelihood(theta)
    term = _Term()
    assert problem.extra_terms == ()
    np.testing.assert_allclose(problem.log_posterior()(theta), prior + lik, rtol=1e-12)
    with_term = problem.with_extra_terms(term)
    assert with_term.extra_terms == (term,) and problem.extra_terms == ()  # a copy; the problem is unchanged
    np.testing.assert_allclose(with_term.log_posterior()(theta), prior + lik + term(theta), rtol=1e-12)
    # tempering scales the FRF likelihood only
    beta = 0.3
    tempered = problem.likelihood.with_tempering(beta)(theta)
    assert not np.allclose(tempered, lik)
    np.testing.assert_allclose(with_term.log_posterior(beta)(theta), prior + tempered + term(theta), rtol=1e-12)
    np.testing.assert_allclose(problem.log_posterior(beta)(theta), prior + tempered, rtol=1e-12)
    # terms accumulate, in order
    assert with_term.with_extra_terms(term).extra_terms == (term, term)


def test_no_context_variable_carries_likelihood_terms():
    pattern = re.compile(r"_EXTRA_TERMS|extra_likelihood_terms|active_likelihood_terms|ContextVar")
    hits = [f"{p.relative_to(PACKAGE)}:{i + 1}" for p in PACKAGE.rglob("*.py")
            for i, line in enumerate(p.read_text().splitlines()) if pattern.search(line)]
    assert hits == []


class _Checkpoint:
    """Stands in for :class:`bayes_rcsa.inference.checkpoint.Checkpoint` holding a stored fingerprint."""

    def __init__(self, fingerprint):
        self.state = type("State", (), {"meta": {"fingerprint": fingerprint}, "iteration": 10})()
        self.repaired = False

    def exists(self):
        return True

    def read(self):
        return self.state

    def repair(self, state):
        self.repaired = True


def test_a_checkpoint_without_extra_terms_never_resumes_a_run_with_them(problem):
    settings = SamplerSettings()
    plain = run_fingerprint(problem, 3, settings, 32)
    joint = run_fingerprint(problem.with_extra_terms(_Term()), 3, settings, 32)
    # a run without terms keeps the fingerprint it always had (its checkpoints still resume)
    assert "extra_terms" not in plain and "sampler" not in plain
    assert {k: v for k, v in joint.items() if k != "extra_terms"} == plain and joint["extra_terms"]
    for stored, now in ((plain, joint), (joint, plain)):
        with pytest.raises(SetupError, match="the extra likelihood terms"):
            resume_state(_Checkpoint(stored), "chain.h5", now)
    ckpt = _Checkpoint(joint)
    assert resume_state(ckpt, "chain.h5", joint) is ckpt.state and ckpt.repaired


def test_emcee_sampler_is_built_in_the_sampler_driver_only():
    hits = sorted({str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                   if re.search(r"EnsembleSampler\(|\.run_mcmc\(", p.read_text())})
    assert hits == ["inference/sampler.py"]


def _counting(monkeypatch, module, calls: list):
    def counted(*args, **kwargs):
        calls.append(module.__name__)
        return run_ensemble(*args, **kwargs)

    monkeypatch.setattr(module, "run_ensemble", counted)


def test_identify_library_joint_and_stage2_sample_through_run_ensemble(problem, monkeypatch):
    import importlib

    # the package's attribute ``identify`` is the function: take the module itself
    identify_module = importlib.import_module("bayes_rcsa.inference.identify")
    sampler_module = importlib.import_module("bayes_rcsa.inference.sampler")
    import bayes_rcsa.library.hierarchy as hierarchy
    from bayes_rcsa.library.joint import gaussian_log_likelihood, sample_joint
    from bayes_rcsa.library.population import Hyperprior, covariate

    calls: list = []
    for module in (identify_module, sampler_module, hierarchy):
        _counting(monkeypatch, module, calls)
    identify_module.identify(problem, seed=1, settings=quick_settings(max_steps=20, check_every=10), sampler="mcmc")
    assert calls == ["bayes_rcsa.inference.identify"]

    hyper = Hyperprior.from_box(("k_xf", "g_xf"), np.array([[4.0, 10.0], [0.0, 1.5]]), 1.5)
    types, x = np.array([0, 0, 1, 1]), covariate(np.array([0.006, 0.013, 0.009, 0.018]))
    exact = [(np.array([7.0 + 0.1 * i, 0.6]), np.diag([0.04, 0.02])) for i in range(4)]
    calls.clear()
    out = sample_joint([gaussian_log_likelihood(m, C) for m, C in exact], types, x, hyper, np.random.default_rng(2),
                       n_steps=30, n_burn=20, n_walkers=64, n_runs=2)
    assert calls == ["bayes_rcsa.inference.sampler"] * 2
    run = out["runs"][0]
    assert out["types"][0].shape == (2 * 30 * 64, 6)
    assert run["converged"] is False and "not converged" in run["convergence"]
    assert run["rhat"].shape == run["tau_steps"].shape == (out["runs"][0]["rhat"].size,)
    assert np.all(np.isfinite(run["ess_bulk"])) and np.all(run["tau_steps"] > 0)

    groups = [hierarchy.Group(f"T{t}", tuple(f"s{i}" for i in np.flatnonzero(types == t)), x[types == t],
                              np.array([exact[i][0] for i in np.flatnonzero(types == t)]),
                              np.array([exact[i][1] for i in np.flatnonzero(types == t)])) for t in (0, 1)]
    calls.clear()
    hierarchy.fit_hyper(groups, hyper, np.random.default_rng(1), hierarchy.Stage2Settings(n_burn=20, max_steps=40),
                        type_draws=False)
    assert calls == ["bayes_rcsa.library.hierarchy"] * 2


class _Gaussian:
    """A correlated two-dimensional normal density (the :class:`LogDensity` protocol)."""

    ndim = 2

    def __init__(self, rho: float = 0.9):
        self.precision = np.linalg.inv(np.array([[1.0, rho], [rho, 1.0]]))

    def __call__(self, theta):
        theta = np.atleast_2d(theta)
        return -0.5 * np.einsum("wi,ij,wj->w", theta, self.precision, theta)

    def check_inside(self, theta, what):
        pass


def _start(n_walkers: int = 32) -> np.ndarray:
    return 0.1 * np.random.default_rng(0).standard_normal((n_walkers, 2))


def test_fixed_steps_mode_reports_tau_rhat_ess_and_flags_a_chain_too_short_to_measure_tau():
    short = run_ensemble(_Gaussian(), SamplerSettings(n_steps=30, check_every=10, progress=False),
                         initial=_start(), rng=np.random.default_rng(4))
    assert short.n_steps == 30 and short.n_new_steps == 30
    assert np.all(np.isfinite(short.tau)) and short.tau.shape == (2,)
    assert set(short.diagnostics) >= {"rhat", "ess_bulk"} and short.diagnostics["rhat"].shape == (2,)
    assert short.converged is False
    assert "not converged" in short.reason and "too short to measure tau" in short.reason, short.reason
    assert short.burn == min(int(np.ceil(3 * short.tau.max())), 15)

    long = run_ensemble(_Gaussian(), SamplerSettings(n_steps=1500, check_every=250, progress=False),
                        initial=_start(), rng=np.random.default_rng(4))
    assert long.n_steps == 1500 and long.converged, long.reason
    assert long.reason == "n_steps = 1500 run: converged"
    assert np.all(long.diagnostics["rhat"] < 1.01) and np.all(long.diagnostics["ess_bulk"] >= 400)
    assert long.n_steps > 50 * long.tau.max() and long.burn == int(np.ceil(3 * long.tau.max()))
    # the same seed gives the same chain; the first 30 steps are those of the short run
    np.testing.assert_array_equal(long.chain[:30], short.chain)


def test_a_fixed_burn_in_shorter_than_three_tau_is_not_converged_and_stored_rows_follow_the_burn_in():
    s = SamplerSettings(n_steps=20 + 3 * 40, n_burn=20, store_every=3, check_every=35, move="stretch",
                        progress=False)
    run = run_ensemble(_Gaussian(0.99), s, initial=_start(), rng=np.random.default_rng(5))
    # every third step is kept, ending at the last: the rows after the burn-in are the 40 requested
    assert run.chain.shape == (47, 32, 2) and run.burn == 7 and run.chain.shape[0] - run.burn == 40
    assert run.steps_run == 140 and run.store_every == 3
    assert not run.converged and "burn-in of 20 steps is shorter than 3 autocorrelation times" in run.reason
    full = run_ensemble(_Gaussian(0.99), SamplerSettings(n_steps=140, n_burn=20, check_every=35, move="stretch",
                                                         progress=False), initial=_start(), rng=np.random.default_rng(5))
    np.testing.assert_array_equal(run.chain[-40:], full.chain[22::3])
    with pytest.raises(SetupError, match="n_burn"):
        SamplerSettings(n_burn=10)  # a fixed burn-in belongs to the fixed-steps mode
    with pytest.raises(SetupError, match="move"):
        SamplerSettings(move="walk")
