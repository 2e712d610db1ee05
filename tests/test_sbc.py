"""Simulation-based calibration (issue #42): the rank statistics and a reduced SBC of identify's sampler.

(a) The machinery, without MCMC: ranks of truths among draws of an exact conjugate (normal-normal)
    posterior pass the family-wise 0.01 test; a posterior half as wide, or shifted by half a posterior sd,
    fails it with the same 200 replicates; the simultaneous ECDF band has its nominal coverage (a
    Clopper-Pearson interval of the simulated coverage contains 1 - alpha) while the pointwise band at the
    same level does not.
(b) A reduced SBC of the project: one clamping length of the bundled example, k_xf and the noise scale
    and k_thetaM sampled (three decades each), 31 band lines, 20 replicates, L = 9, identify's
    optimum and walker start, run_ensemble in fixed-steps mode (8 walkers, 240 steps).  With the exact
    posterior the ranks pass; with the likelihood tempered by 0.05 (a posterior about 4.5 times too wide where the data dominate,
    the kind of error a wrong tempering or noise model makes) the same truths and data fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import beta as beta_dist

from bayes_rcsa.stats.sbc import (chi_square_pvalue, ecdf_difference, ecdf_pvalue, ecdf_statistic, holm, sbc_check,
                                  sbc_ranks, simultaneous_band)


# -- (a) the machinery ------------------------------------------------------------------------------------------


def _conjugate_ranks(rng, n_rep: int, n_draws: int, scale: float = 1.0, shift: float = 0.0) -> np.ndarray:
    """Ranks of three independent normal-normal problems (prior N(0, tau0^2), n obs of sd sigma).

    The "posterior" sampled is N(m + shift * s, (scale * s)^2) around the exact N(m, s^2).
    """
    tau0 = np.array([1.0, 3.0, 0.3])
    sigma = np.array([1.0, 0.5, 2.0])
    n_obs = np.array([1, 5, 20])
    mu = rng.standard_normal((n_rep, 3)) * tau0
    ybar = mu + rng.standard_normal((n_rep, 3)) * sigma / np.sqrt(n_obs)
    prec = 1 / tau0**2 + n_obs / sigma**2
    m = (n_obs / sigma**2) * ybar / prec
    s = 1 / np.sqrt(prec)
    draws = m[:, None, :] + s * (shift + scale * rng.standard_normal((n_rep, n_draws, 3)))
    return sbc_ranks(mu, draws, rng)


def test_exact_conjugate_posterior_passes_and_broken_ones_fail():
    rng = np.random.default_rng(20260421)
    names = ["a", "b", "c"]
    ok = sbc_check(_conjugate_ranks(rng, 200, 99), 99, names, rng, alpha=0.01, n_sim=5000)
    assert ok.all_passed, ok
    assert np.all(ok.p_ecdf > 0.01)
    narrow = sbc_check(_conjugate_ranks(rng, 200, 99, scale=0.5), 99, names, rng, alpha=0.01, n_sim=5000)
    assert not np.any(narrow.passed), narrow.p_holm
    shifted = sbc_check(_conjugate_ranks(rng, 200, 99, shift=0.5), 99, names, rng, alpha=0.01, n_sim=5000)
    assert not np.any(shifted.passed), shifted.p_holm
    wide = sbc_check(_conjugate_ranks(rng, 200, 99, scale=2.0), 99, names, rng, alpha=0.01, n_sim=5000)
    assert not np.any(wide.passed), wide.p_holm


def test_ties_are_broken_uniformly_and_shapes_checked():
    rng = np.random.default_rng(3)
    # every draw equals the truth: the rank is uniform on 0..L
    r = sbc_ranks(np.zeros((4000, 1)), np.zeros((4000, 9, 1)), rng)
    counts = np.bincount(r[:, 0], minlength=10)
    assert counts.size == 10 and chi_square_pvalue(r, 9, 10)[0] > 0.001 and counts.min() > 300
    assert sbc_ranks(np.array([0.5]), np.array([[0.1], [0.2], [0.9]]), rng).tolist() == [2]
    with pytest.raises(Exception, match="do not match"):
        sbc_ranks(np.zeros(2), np.zeros((5, 3)), rng)


def _clopper_pearson(k: int, n: int, level: float) -> tuple[float, float]:
    a = 1 - level
    lo = beta_dist.ppf(a / 2, k, n - k + 1) if k > 0 else 0.0
    hi = beta_dist.ppf(1 - a / 2, k + 1, n - k) if k < n else 1.0
    return lo, hi


@pytest.mark.parametrize("n_ranks,n_draws,n_points,alpha", [(100, 99, 100, 0.05), (200, 99, 50, 0.01)])
def test_simultaneous_band_has_nominal_coverage(n_ranks, n_draws, n_points, alpha):
    """Exact uniform ranks lie wholly inside the band with probability 1 - alpha.

    2000 independent rank sets give the coverage to about +-0.005 (alpha = 0.05); the 99.9 % Clopper-Pearson
    interval must contain 1 - alpha.  The band's own alpha quantile comes from 20,000 simulations (a relative
    error of about 5 % in alpha) and the statistic is discrete (which can only raise the coverage), so the
    upper end is allowed alpha / 4 more.  The pointwise band at level alpha covers far less (about 0.5 here),
    which the test also checks: it would catch a band that forgot to adjust its level.
    """
    rng = np.random.default_rng([n_ranks, n_points])
    band = simultaneous_band(n_ranks, n_points, alpha, rng)
    assert band.gamma < alpha / 3  # the adjusted pointwise level is much smaller than alpha
    m = 2000
    ranks = rng.integers(0, n_draws + 1, size=(n_ranks, m))
    _, diff = ecdf_difference(ranks, n_draws, n_points)
    inside = band.contains(diff)
    # the band and the statistic agree: inside iff the smallest pointwise tail probability is >= gamma
    assert np.array_equal(inside, ecdf_statistic(ranks, n_draws, n_points) >= band.gamma)
    lo, hi = _clopper_pearson(int(inside.sum()), m, 0.999)
    assert lo <= 1 - alpha <= hi + alpha / 4, (inside.mean(), lo, hi)
    pointwise = type(band)(band.z, *_pointwise(n_ranks, n_points, alpha), alpha, alpha, n_ranks)
    assert pointwise.contains(diff).mean() < 1 - 3 * alpha


def _pointwise(n, k, alpha):
    from scipy.stats import binom

    z = np.arange(1, k) / k
    lo, hi = binom.ppf(alpha / 2, n, z), binom.isf(alpha / 2, n, z)
    return lo / n - z, hi / n - z


def test_ecdf_pvalue_is_uniform_under_the_null_and_holm_is_step_down():
    rng = np.random.default_rng(11)
    ranks = rng.integers(0, 20, size=(60, 400))
    p = ecdf_pvalue(ranks, 19, rng, n_points=20, n_sim=5000)
    assert p.shape == (400,)
    # the share of p-values at or below 0.05 and 0.2: binomial(400, q) within 3.3 sd
    for q in (0.05, 0.2):
        assert abs(np.mean(p <= q) - q) < 3.3 * np.sqrt(q * (1 - q) / 400)
    reject, adjusted = holm([0.001, 0.04, 0.03, 0.5], 0.05)
    assert np.allclose(adjusted, [0.004, 0.09, 0.09, 0.5])
    assert reject.tolist() == [True, False, False, False]


# -- (b) a reduced SBC of the project's sampler ---------------------------------------------------------------


N_REPLICATES = 20
N_DRAWS = 9


@pytest.fixture(scope="module")
def reduced_problem():
    return _reduced_problem()


def _reduced_problem():
    from bayes_rcsa.data import example_setup
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.model.receptance import FRF

    setup = load_setup(example_setup())
    m = next(m for m in setup.measurements if m.configuration.direction == "x" and m.configuration.clamping_length == 0.025)
    f = m.frf.frequency_hz
    idx = np.nonzero((f >= 700.0) & (f <= 1000.0))[0][::5]  # 31 lines around the first mode
    frf = FRF(f[idx], m.frf.values[idx], None, m.frf.source)
    options = IdentificationOptions(band=(700.0, 1000.0), tempering=1.0, priors={"k_xf": [1e5, 1e8], "k_thetaM": [1e4, 1e7]},
                                    noise_scale=(0.01, 0.1))
    problem = build_problem(setup.model(), [(m.configuration, frf)], setup.contact, options)
    assert problem.parameters.names == ("k_xf", "k_thetaM", "sigma_0")
    return problem


def _reduced_sbc(problem, tempering: float, sampler: str = "mcmc", replicates: int = N_REPLICATES):
    from bayes_rcsa.inference.sampler import SamplerSettings
    from bayes_rcsa.inference.sbc import sbc_replicate

    settings = SamplerSettings(n_walkers=8, n_steps=240, n_burn=80, check_every=120, progress=False)
    reps = [sbc_replicate(problem, np.random.SeedSequence([4242, r]), settings, N_DRAWS, tempering, sampler)
            for r in range(replicates)]
    return np.array([r.ranks for r in reps]), [r.sampler for r in reps], reps


@pytest.mark.slow
def test_reduced_sbc_passes_for_the_sampler_and_fails_for_a_tempered_posterior(reduced_problem):
    rng = np.random.default_rng(5)
    names = list(reduced_problem.parameters.names)
    exact = sbc_check(_reduced_sbc(reduced_problem, 1.0)[0], N_DRAWS, names, rng, alpha=0.01)
    assert exact.all_passed, (exact.p_ecdf, exact.p_chi2)
    # a likelihood tempered by 0.03 (1/0.03 times too wide).  The tempered posterior tends to the prior as the
    # tempering goes to 0, and a prior passes SBC, so a stronger break is not easier to see; the power is in the
    # replicates: at 20, 0.01 was detected on sigma_0 alone (ECDF p 0.030, not significant after Holm) once a
    # library update (scipy 1.16 -> 1.17) moved the random path.  Measured with these seeds: 0.01 at 40
    # replicates p = 0.0002, 0.03 at 20/30/40/60 replicates p = 0.0011 / 0.0003 / <1e-4 / <1e-4 (sigma_0)
    broken = sbc_check(_reduced_sbc(reduced_problem, 0.03, replicates=40)[0], N_DRAWS, names, rng, alpha=0.01)
    assert not broken.all_passed, (broken.p_ecdf, broken.p_chi2)


@pytest.mark.slow
def test_reduced_sbc_of_the_default_importance_sampler_passes(reduced_problem):
    """identify's default (``auto``: importance sampling, the chain only when refused) on the same reduced problem
    passes SBC.  Nearly every replicate must have been importance sampled (36 of 40 with these seeds on
    2026-11-30, the other four refused with Pareto k 0.84-1.25; the fall-back to the chain is part of the
    default), or this would test the chain again.  That the check fails for a
    miscalibrated posterior is shown above (a tempered likelihood): the check does not depend on the sampler, and a
    tempered posterior importance-sampled needs 20 replicates at tempering 0.01, half of them falling back to the
    chain (8 s), to be told apart."""
    rng = np.random.default_rng(6)
    names = list(reduced_problem.parameters.names)
    ranks, used, reps = _reduced_sbc(reduced_problem, 1.0, "auto", 40)
    # at least 80 %: the count sat exactly on a threshold of 36 (it was 39 when the test was written; a library
    # release or a sampler change moves a few replicates across k = 0.7), and 32 of 40 still make this a test of
    # importance sampling, not of the chain
    assert used.count("importance") >= 32, used
    # each replicate records the ESS of the draws it ranked: the weights' (accepted at >= 1000), the chain's bulk ESS
    assert all(r.min_ess >= 1000 for r in reps if r.sampler == "importance")
    assert all(np.isfinite(r.min_ess) and r.min_ess > 0 for r in reps), [r.min_ess for r in reps]
    assert all(r.to_dict()["min_ess"] == r.min_ess for r in reps)
    # a script that needs a replicate's truth without its sampler (benchmarks/sbc.py --importance-only) reaches
    # the same truth through the one stream layout
    from bayes_rcsa.inference.sbc import replicate_streams

    for r, rep in enumerate(reps[:3]):
        truth = reduced_problem.priors.sample(replicate_streams(np.random.SeedSequence([4242, r])).truth, 1)[0]
        np.testing.assert_array_equal(truth, rep.truth)
    exact = sbc_check(ranks, N_DRAWS, names, rng, alpha=0.01)
    assert exact.all_passed, (exact.p_ecdf, exact.p_chi2)


def test_sbc_replicate_refuses_an_unknown_sampler(reduced_problem):
    from bayes_rcsa.errors import SetupError
    from bayes_rcsa.inference.sampler import SamplerSettings
    from bayes_rcsa.inference.sbc import sbc_replicate

    with pytest.raises(SetupError, match="'mcmc' or 'auto'"):
        sbc_replicate(reduced_problem, np.random.SeedSequence(1), SamplerSettings(), 9, 1.0, "nuts")
