"""Acceptance tests of the identification on the synthetic bench (lumped contact, no hidden effect, 2 % noise)."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.inference.identify import identify, posterior_stiffness, predict_frf
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.model import Configuration
from bayes_rcsa.posterior import natural_frequency

from test_inference_support import bench, bench_model, contact_spec, quick_settings, true_k, true_natural_frequency

MEASURED = (0.025, 0.040)
UNMEASURED = (0.030, 0.035)


@pytest.fixture(scope="module")
def campaign():
    return bench(seed=11)


@pytest.fixture(scope="module")
def multi(campaign):
    cfg, camp = campaign
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                         IdentificationOptions(lengths=MEASURED))
    # the chain, whose own diagnostics (tau, R-hat, ESS, acceptance) these tests check
    return identify(prob, seed=2024, settings=quick_settings(), sampler="mcmc")


@pytest.fixture(scope="module")
def single_deterministic(campaign):
    cfg, camp = campaign
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                         IdentificationOptions(method="deterministic", lengths=(0.025,)))
    return identify(prob, seed=1)


def test_two_lengths_converged_and_diagnostics(multi):
    s = multi.summary
    assert s["converged"] is True
    assert s["n_steps"] > 50 * max(s["tau"].values())
    for name, p in s["parameters"].items():
        assert p["rhat"] < 1.01, name
        assert p["ess_bulk"] > 400, name
    assert 0.1 < s["acceptance_fraction"] < 0.9
    assert s["burn_in"] > 0 and s["thin"] >= 1
    assert s["warnings"] == []


def test_true_stiffness_inside_90_interval(multi, campaign):
    cfg, _ = campaign
    entries = {round(e["clamping_length"], 6): e for e in multi.summary["stiffness"]}
    for length in MEASURED:
        e = entries[round(length, 6)]
        assert e["used_in_fit"]
        assert e["k_xf"]["q05"] <= true_k(cfg, length) <= e["k_xf"]["q95"], (length, e, true_k(cfg, length))


def test_unmeasured_natural_frequency_within_1_percent(multi, campaign):
    cfg, camp = campaign
    f = camp.measurements[0][1].frequency_hz
    for length in UNMEASURED:
        truth = true_natural_frequency(cfg, length, f)
        pred = natural_frequency(f, predict_frf(multi, Configuration(length, "x"), f, max_draws=400,
                                                rng=np.random.default_rng(0)))
        med = float(np.median(pred))
        assert abs(med - truth) / truth < 0.01, (length, med, truth)
        # and the summary reports the same rule on the measured (noisy) FRF at that length
        e = next(e for e in multi.summary["natural_frequencies"] if abs(e["clamping_length"] - length) < 1e-9)
        assert not e["used_in_fit"]
        assert abs(e["q50_hz"] - truth) / truth < 0.01


def test_deterministic_single_length_transfers_worse(multi, single_deterministic, campaign):
    cfg, camp = campaign
    f = camp.measurements[0][1].frequency_hz
    det = {round(e["clamping_length"], 6): e for e in single_deterministic.summary["natural_frequencies"]}
    bay = {round(e["clamping_length"], 6): e for e in multi.summary["natural_frequencies"]}
    own = true_natural_frequency(cfg, 0.025, f)
    assert abs(det[0.025]["q50_hz"] - own) / own < 0.005
    # Tables 5-7 pattern: the single-length fit drifts away at other lengths, the multi-length
    # posterior median does not (errors against the noise-free truth).
    for length in (0.030, 0.035, 0.040):
        truth = true_natural_frequency(cfg, length, f)
        err_det = abs(det[round(length, 6)]["q50_hz"] - truth) / truth
        err_bay = abs(bay[round(length, 6)]["q50_hz"] - truth) / truth
        assert err_det > 3 * err_bay, (length, err_det, err_bay)
    assert abs(det[0.040]["q50_hz"] - true_natural_frequency(cfg, 0.040, f)) / det[0.040]["q50_hz"] > 0.03


def test_posterior_stiffness_follows_growth_law(multi):
    kx, _ = posterior_stiffness(multi, [0.025, 0.0325, 0.040])
    np.testing.assert_allclose(kx[:, 1], 0.5 * (kx[:, 0] + kx[:, 2]), rtol=1e-12)  # linear in l
    assert np.all(kx[:, 2] >= kx[:, 0])
    assert np.all(kx[:, 2] - kx[:, 0] <= 0.5 * kx[:, 0] * (1 + 1e-12))  # bounded by Q = 0.5


def test_same_seed_same_posterior(campaign):
    cfg, camp = campaign
    # narrow priors, short chains: determinism does not need a converged chain.  100 steps (two convergence
    # checks, 32 walkers x 6 parameters) cost 0.7 s a chain against 1.4-2.7 s for 300, and stay far from converging
    # on seeds 7 and 8: tau 7.8-8.4 (50 tau = 390-420 steps needed), bulk ESS 90-119 (400 needed), R-hat 1.27-1.36
    # (1.01 needed)
    priors = {"k_xf": [1e6, 4e6], "k_thetaM": [1e5, 2e6]}
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                         IdentificationOptions(lengths=MEASURED, band=(800.0, 1300.0), priors=priors))
    s = quick_settings(max_steps=100, check_every=50)
    a = identify(prob, seed=7, settings=s, sampler="mcmc")
    b = identify(prob, seed=7, settings=s, sampler="mcmc")
    c = identify(prob, seed=8, settings=s, sampler="mcmc")
    np.testing.assert_array_equal(a.chain.chain, b.chain.chain)
    np.testing.assert_array_equal(a.theta, b.theta)
    assert a.summary["parameters"] == b.summary["parameters"]
    assert not np.array_equal(a.chain.chain, c.chain.chain)
    assert a.summary["converged"] is False and "max_steps" in a.summary["stop_reason"]
    assert any("not converged" in w for w in a.summary["warnings"])
    # the default (importance sampling, accepted here): the same seed gives the same draws, another seed others
    d, e, f = identify(prob, seed=7), identify(prob, seed=7), identify(prob, seed=8)
    assert d.chain is None and d.summary["sampler"]["mode"] == "importance"
    np.testing.assert_array_equal(d.theta, e.theta)
    assert d.summary["parameters"] == e.summary["parameters"]
    assert not np.array_equal(d.theta, f.theta)


@pytest.mark.slow
def test_growth_beyond_bound_is_flagged():
    # True growth 1.0 over the range, the user's bound Q = 0.5: a prior-data conflict that must be
    # reported, not silently truncated.  The chain need not converge for the pile-up to show: importance sampling
    # is refused here (noise scale 2.1 at the optimum), and 500 steps of the chain (2.2 s against 7 s for 1500) put
    # 97 % of the draws within 5 % of Q (95 % after 1500 steps; the warning needs 25 %) and 0.97 of them above
    # 0.475 (0.95 after 1500; 0.5 needed)
    cfg, camp = bench(seed=5, growth=1.0, clamping_lengths=(0.025, 0.040), frequency_step=8.0)
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp), IdentificationOptions())
    res = identify(prob, seed=3, settings=quick_settings(max_steps=500))
    warnings = res.summary["warnings"]
    assert any(w.startswith("g_xf:") and "growth bound" in w for w in warnings), warnings
    assert np.mean(res.values()["g_xf"] > 0.475) > 0.5
    # and the healthy campaign of the other tests raises no such warning (test_two_lengths_...: warnings == [])


@pytest.mark.parametrize("effect, lo, hi", [(None, 0.0, 1.5), ("fluted_section", 5.0, np.inf)])
def test_tempering_engages_only_with_model_discrepancy(effect, lo, hi):
    # Without a hidden effect the residuals at the optimum are white (beta = 1: no widening);
    # a tool whose fluted section is thinner than the setup says leaves a smooth, correlated
    # discrepancy spanning many lines, and the likelihood must be tempered accordingly.
    from bayes_rcsa.inference.likelihood import residual_correlation_length
    from bayes_rcsa.inference.posterior import LogPosterior
    from bayes_rcsa.inference.sampler import find_optimum

    kw = {} if effect is None else {"hidden_effects": {effect: True}}
    cfg, camp = bench(seed=3, clamping_lengths=(0.025, 0.040), frequency_step=4.0, **kw)
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp), IdentificationOptions())
    opt = find_optimum(LogPosterior(prob.priors, prob.likelihood))
    tau = residual_correlation_length(prob.likelihood.normalised_residuals(opt.x), prob.likelihood.stack.slices)
    assert lo <= tau <= hi, tau
