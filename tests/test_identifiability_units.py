"""Unit tests of the identifiability diagnostics: prior moments, contraction, verdicts, ridges, Fisher.

References are independent of the library: Monte Carlo moments, known Gaussian covariances, and a
second-difference Hessian of the weighted FRF misfit for the Fisher information.  Budget: ~10 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.params.priors import LogNormal, LogUniform, Normal, PriorSet, Uniform
from bayes_rcsa.posterior.identifiability import (
    COMBINATION_RATIO,
    combination_name,
    combination_statement,
    conditional_width,
    contraction,
    fisher_information,
    fmt_contraction,
    log_space,
    parameter_identifiability,
    prior_moments,
    ridge_analysis,
    stiffness_ridge,
    transfer_errors,
    verdict,
)


@pytest.mark.parametrize("prior", [
    Uniform(0.0, 0.5), LogUniform(1e3, 1e8), Normal(1.0, 2.0, lo=0.0), LogNormal(2e6, 0.5, lo=1e6, hi=1e7),
])
def test_prior_moments_match_monte_carlo(prior):
    u = prior.sample(np.random.default_rng(0), 400_000)
    mean, var = prior_moments(prior)
    # 4e5 draws: relative standard error of the variance sqrt(2/n) ~ 0.2 %, of the mean far smaller
    assert var == pytest.approx(np.var(u), rel=0.01)
    assert mean == pytest.approx(np.mean(u), abs=0.01 * math.sqrt(var))


def test_contraction_of_prior_draws_is_zero_and_of_a_narrow_posterior_is_known():
    p = LogUniform(1e3, 1e8)
    rng = np.random.default_rng(1)
    assert abs(contraction(p.sample(rng, 100_000), p)) < 0.02
    sd = 0.1
    c = contraction(rng.normal(5.5, sd, 100_000), p)
    assert c == pytest.approx(1 - sd**2 / (25 / 12), abs=1e-4)


def test_verdict_thresholds():
    assert verdict(0.2, None) == "not identified"
    assert verdict(0.7, None) == "weakly identified"
    assert verdict(0.995, None) == "identified"
    assert verdict(0.995, "upper") == "weakly identified"
    assert verdict(0.995, None, 5.0, "k_thetaM") == "identified only in combination with k_thetaM"
    assert verdict(0.995, None, 1.2, "k_thetaM") == "identified"
    # a weak or bound-held verdict is not upgraded by a ridge
    assert verdict(0.7, None, 5.0, "k_thetaM") == "weakly identified"
    assert verdict(float("nan"), None) == "not identified"


def test_conditional_width_of_a_gaussian_ridge_matches_the_closed_form():
    # Independent reference: for a bivariate normal, Var(a | b) = s_a^2 (1 - rho^2), so the ratio of the
    # marginal to the conditional sd is 1/sqrt(1 - rho^2) = 5.03 at rho = -0.98.
    rho, sa, sb = -0.98, 0.02, 0.5
    cov = [[sa**2, rho * sa * sb], [rho * sa * sb, sb**2]]
    z = np.random.default_rng(5).multivariate_normal([6.0, 5.5], cov, 200_000)
    w = conditional_width(z[:, 0], z[:, 1])
    # 2e5 draws: the sample correlation is within ~1e-4 of rho, the ratio within ~0.5 %
    assert w["correlation"] == pytest.approx(rho, abs=1e-3)
    assert w["width_ratio"] == pytest.approx(1 / math.sqrt(1 - rho**2), rel=0.01)
    assert w["conditional_sd"] == pytest.approx(sa * math.sqrt(1 - rho**2), rel=0.01)
    # the conditional sd really is the spread of a at (nearly) fixed b
    near = np.abs(z[:, 1] - 5.5) < 0.01
    assert np.std(z[near, 0]) == pytest.approx(w["conditional_sd"], rel=0.05)


def test_ridge_verdict_is_identified_only_in_combination():
    # Both stiffnesses contracted far beyond 99 %, but along a ridge (rho = 0.99, ratio 7.1): each is
    # pinned only together with the other.  Independent ones are simply identified.
    priors = PriorSet({"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8)})
    rng = np.random.default_rng(6)
    cov = np.array([[1e-4, 0.99 * 1e-4], [0.99 * 1e-4, 1e-4]])
    out = parameter_identifiability(rng.multivariate_normal([6.25, 5.65], cov, 20_000), priors)
    assert out["k_xf"]["verdict"] == "identified only in combination with k_thetaM"
    assert out["k_thetaM"]["verdict"] == "identified only in combination with k_xf"
    assert out["k_xf"]["width_ratio"] == pytest.approx(1 / math.sqrt(1 - 0.99**2), rel=0.05)
    assert out["k_xf"]["width_ratio"] > COMBINATION_RATIO
    # prior sd of log10 k over 4 decades is 4/sqrt(12) = 1.155; posterior sd 0.01
    assert out["k_xf"]["prior_to_posterior_width"] == pytest.approx(115.5, rel=0.02)
    text = combination_statement("k_xf", out["k_xf"], "N/m")
    assert text.startswith("The contact stiffness, translational (kxf) is identified only in combination with the "
                           "contact stiffness, rotational (kθM): its 90 % posterior range ")
    assert (f"is {out['k_xf']['width_ratio']:.2g} times wider than its range at a fixed contact stiffness, "
            "rotational (kθM)") in text
    assert "not each alone" in text and "contraction" not in text
    out = parameter_identifiability(rng.multivariate_normal([6.25, 5.65], np.diag([1e-4, 1e-4]), 20_000), priors)
    assert out["k_xf"]["verdict"] == out["k_thetaM"]["verdict"] == "identified"
    assert out["k_xf"]["width_ratio"] == pytest.approx(1.0, abs=0.01)


def test_stiffness_ridge_names_the_tradeoff_in_physical_terms():
    # A single-length-like ridge: log k_xf sd 0.001 decades, log k_thetaM sd 0.04 decades, rho = -0.98.
    # Reference values from the bivariate normal: regression shift of log kt per +1 sd of log kx is
    # rho * 0.04 = -0.0392 decades (-8.6 %); conditional sd of log kt 0.04 * sqrt(1 - 0.98^2) = 0.00796
    # decades (1.85 %); the best determined direction (1, 1) in standardised coordinates is
    # log kx / 0.001 + log kt / 0.04, i.e. k_xf^1 * k_thetaM^0.025, with sd sqrt(1 - 0.98) * 0.001 decades.
    rho, sx, st = -0.98, 0.001, 0.04
    cov = [[sx**2, rho * sx * st], [rho * sx * st, st**2]]
    z = np.random.default_rng(7).multivariate_normal([6.25, 5.65], cov, 200_000)
    r = stiffness_ridge(z[:, 0], z[:, 1])
    # 2e5 draws: sample sds and correlation within ~0.3 %
    assert r["tradeoff_pct"] == pytest.approx(100 * (10 ** (rho * st) - 1), rel=0.02)
    assert r["conditional_pct"]["k_thetaM"] == pytest.approx(100 * (10 ** (st * math.sqrt(1 - rho**2)) - 1), rel=0.02)
    assert r["stiff"]["combination"] == "k_xf^1 * k_thetaM^0.025"
    assert r["stiff"]["sd_decades"] == pytest.approx(math.sqrt(1 + rho) * sx, rel=0.05)
    assert r["sloppy"]["combination"] == "k_xf^1 * k_thetaM^-0.025"
    assert "goes with k_thetaM -8.6 %" in r["statement"] and "k_thetaM would be known to ±1.8" in r["statement"]


def test_contractions_are_printed_as_percentages_or_width_ratios():
    assert fmt_contraction(0.78593) == "78.6 %"
    # 1 - 3.9e-8: posterior sd = prior sd * sqrt(3.9e-8) -> width ratio 1/sqrt(3.9e-8) = 5064
    assert fmt_contraction(1 - 3.9e-8) == "prior width / posterior width = 5100"
    assert "1 - " not in fmt_contraction(1 - 3.9e-8)
    assert fmt_contraction(float("nan")) == "—"


def test_one_sided_posterior_is_weakly_identified_despite_high_contraction():
    # A stiffness bounded only from below: uniform over the top 25 % of a 5-decade log-uniform prior.
    # Its variance is 1/16 of the prior's (contraction ~0.94), but the prior bound ends it.
    priors = PriorSet({"k_thetaM": LogUniform(1e3, 1e8), "k_xf": LogUniform(1e5, 1e9)})
    rng = np.random.default_rng(2)
    theta = np.column_stack([rng.uniform(6.75, 8.0, 20_000), rng.normal(6.25, 0.001, 20_000)])
    out = parameter_identifiability(theta, priors)
    assert out["k_thetaM"]["contraction"] == pytest.approx(1 - 1 / 16, abs=0.01)
    assert out["k_thetaM"]["bound"] == "upper" and out["k_thetaM"]["verdict"] == "weakly identified"
    assert out["k_xf"]["bound"] is None and out["k_xf"]["verdict"] == "identified"
    assert out["k_xf"]["q50"] == pytest.approx(10**6.25, rel=1e-3)
    # posterior = prior: not identified
    theta = np.column_stack([rng.uniform(3, 8, 20_000), rng.uniform(5, 9, 20_000)])
    out = parameter_identifiability(theta, priors)
    assert out["k_thetaM"]["verdict"] == "not identified" and out["k_thetaM"]["bound"] == "both"


def test_ridge_analysis_recovers_a_known_covariance():
    cov = np.array([[1e-6, -0.98 * 1e-3 * 0.05], [-0.98 * 1e-3 * 0.05, 0.05**2]])
    z = np.random.default_rng(3).multivariate_normal([6.25, 5.65], cov, 200_000)
    r = ridge_analysis(z, ["k_xf", "k_thetaM"])
    assert r["correlation"][0][1] == pytest.approx(-0.98, abs=0.002)
    lam = np.linalg.eigvalsh(cov)
    # sample eigenvalues of 2e5 Gaussian draws: relative error ~ sqrt(2/n) ~ 0.3 %
    np.testing.assert_allclose(r["eigenvalues"], lam, rtol=0.02)
    assert r["sloppy"]["combination"].startswith("k_thetaM^1")
    assert "k_xf^-0.019" in r["sloppy"]["combination"] or "k_xf^-0.02" in r["sloppy"]["combination"]


def test_combination_names_and_log_space():
    assert combination_name(np.array([0.5, -1.0]), ["k_xf", "g_xf"]) == "(1+g_xf)^1 * k_xf^-0.5"
    z, labels = log_space({"k_xf": np.array([1e6]), "g_xf": np.array([0.25])}, ["k_xf", "g_xf"])
    np.testing.assert_allclose(z, [[6.0, math.log10(1.25)]])
    assert labels == ["log10 k_xf", "log10(1+g_xf)"]


def test_fisher_information_equals_the_hessian_of_the_misfit(tmp_path):
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
    from bayes_rcsa.io import load_setup
    from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

    config = default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.040))
    setup = load_setup(write_campaign(generate_campaign(config, np.random.default_rng(0)), tmp_path / "c"))
    problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(setup.extra, method="multi"))
    lik = problem.likelihood
    names = ["k_xf", "k_thetaM", "g_xf", "g_thetaM"]
    truth = {"k_xf": 1.8e6, "k_thetaM": 4.5e5, "g_xf": 0.45, "g_thetaM": 0.45, "sigma_0": 0.02, "sigma_1": 0.03}
    theta0 = problem.priors.to_sampling(truth)
    beta = 0.7
    fim = fisher_information(lik, theta0, names, tempering=beta)
    f = np.array(fim["matrix"])

    # Independent reference: Hessian of phi(z) = beta sum_n w_n |H(z) - H(z0)|^2 / sigma_n^2 by second
    # differences of the scalar misfit (for zero residual it equals 2 beta Re(J^H W J) exactly).
    z0 = np.array([math.log10(1.8e6), math.log10(4.5e5), math.log10(1.45), math.log10(1.45)])
    h0 = lik.model_frf(theta0[None, :])[0]
    s2 = np.array([0.02, 0.03])[lik.stack.index] ** 2

    def theta(z):
        t = theta0.copy()
        t[0], t[1] = z[0], z[1]  # log-uniform priors: the sampling coordinate is log10 k
        t[2], t[3] = 10 ** z[2] - 1, 10 ** z[3] - 1
        return t

    def phi(z):
        r = lik.model_frf(theta(z)[None, :])[0] - h0
        return beta * float(np.sum(lik.weight * (r.real**2 + r.imag**2) / s2))

    e = 2e-4  # decades: phi is smooth; truncation ~e^2 relative, round-off ~1e-16 / e^2 * phi_max
    hess = np.zeros((4, 4))
    for i in range(4):
        for j in range(4):
            di, dj = np.eye(4)[i] * e, np.eye(4)[j] * e
            hess[i, j] = (phi(z0 + di + dj) - phi(z0 + di - dj) - phi(z0 - di + dj) + phi(z0 - di - dj)) / (4 * e * e)
    assert np.linalg.norm(f - hess) / np.linalg.norm(hess) < 1e-3
    # the smallest eigenvalue is ~1e-6 of the largest: compare it on its own
    assert fim["eigenvalues"][0] == pytest.approx(np.linalg.eigvalsh(hess)[0], rel=0.02)
    assert fim["condition_number"] == pytest.approx(fim["eigenvalues"][-1] / fim["eigenvalues"][0])


def test_transfer_errors_split_fitted_and_transferred_lengths():
    entries = [
        {"clamping_length": 0.025, "direction": "x", "measured_hz": 1000.0, "q05_hz": 999.0, "q50_hz": 1000.5,
         "q95_hz": 1001.0, "used_in_fit": True},
        {"clamping_length": 0.040, "direction": "x", "measured_hz": 1200.0, "q05_hz": 1100.0, "q50_hz": 1104.0,
         "q95_hz": 1108.0, "used_in_fit": False},
        {"clamping_length": 0.040, "direction": "y", "measured_hz": 1250.0, "q05_hz": 1300.0, "q50_hz": 1312.5,
         "q95_hz": 1320.0, "used_in_fit": False},
        {"clamping_length": 0.030, "direction": "x", "measured_hz": None, "q05_hz": 1.0, "q50_hz": 1.0,
         "q95_hz": 1.0, "used_in_fit": False},
    ]
    t = transfer_errors(entries)
    assert t["fit_error_pct"] == {"0.025": pytest.approx(0.05)}
    assert t["transfer_error_pct"] == {"0.04": pytest.approx(0.5 * (8.0 + 5.0))}
    assert t["rows"][1]["error_q05_pct"] == pytest.approx(-100 / 12) and t["rows"][1]["measured_in_90"] is False
    assert t["rows"][3]["error_q50_pct"] is None
