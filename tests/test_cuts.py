"""Cutting-test outcomes update the posterior (#23): likelihood, coefficient prior, re-weighting, recovery.

All on small stand-ins (analytic one-mode FRFs per direction, a few hundred lines, <= 200 draws), so the
whole file costs a few seconds.  The full recovery tables come from benchmarks/cuts.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from bayes_rcsa.cuts import (BoundaryWidth, CoefficientPrior, CutGroup, CutLikelihood, chatter_probability,
                             inverse_limits_at_cuts, outcome_log_likelihood)
from bayes_rcsa.cuts.data import check_supported, cut_groups, prepare_cuts
from bayes_rcsa.cuts.update import (UpdateSettings, effective_sample_size, importance_update, systematic_resample,
                                    weighted_quantile)
from bayes_rcsa.errors import ConvergenceError, DataError, SetupError
from bayes_rcsa.stability import CuttingConditions, zoa_lobes
from bayes_rcsa.stability.coefficients import limits_with_coefficients
from bayes_rcsa.stability.methods import STABILITY_METHODS, MethodOptions
from bayes_rcsa.stability.tests_io import read_cut_table, read_cutting_tests

F = np.linspace(500.0, 1600.0, 400)
GEOM = CuttingConditions(kt=600e6, kr=180e6, flutes=3, radial_immersion=0.5)


def mode_frf(k, fn, zeta=0.03):
    """(n_draws, n_freq) one-mode receptance (m/N) for stiffnesses k (n_draws,) N/m at fn Hz."""
    r = F[None, :] / fn
    return 1.0 / (np.asarray(k, dtype=float)[:, None] * (1 - r**2 + 2j * zeta * r))


def stand_in(n_draws, rng, spread=0.03):
    """X/Y FRF draws of a 'hammer posterior': stiffness known to ±spread."""
    k = 2e7 * np.exp(rng.normal(0, spread, n_draws))
    return mode_frf(k, 1000.0), mode_frf(1.1 * k, 1080.0)


# --------------------------------------------------------------------------- the likelihood term
def test_chatter_probability_is_a_monotone_probit_with_the_step_as_limit():
    depth = np.geomspace(0.2, 5.0, 41)
    p = chatter_probability(depth, 1.0, 0.1)
    assert np.all(np.diff(p) >= 0) and p[0] < 1e-9 and p[-1] > 1 - 1e-9  # far from the boundary: 0 and 1
    mid = (p > 1e-6) & (p < 1 - 1e-6)
    assert mid.sum() > 5 and np.all(np.diff(p[mid]) > 0)  # strictly increasing near the boundary
    assert chatter_probability(1.0, 1.0, 0.1) == pytest.approx(0.5)
    np.testing.assert_allclose(chatter_probability(1.1, 1.0, 0.1), ndtr(math.log(1.1) / 0.1))
    # w -> 0: the deterministic step, 0.5 on the boundary
    for w in (1e-3, 1e-6, 0.0):
        np.testing.assert_array_equal(np.round(chatter_probability([0.99, 1.01], 1.0, w), 6), [0.0, 1.0])
    assert chatter_probability(1.0, 1.0, 0.0) == 0.5
    assert chatter_probability(1e3, np.inf, 0.1) == 0.0  # no limit in the band: stable
    # the label error bounds both outcomes away from 0 and 1
    p = chatter_probability([1e-3, 1e3], 1.0, 0.1, 0.01)
    np.testing.assert_allclose(p, [0.01, 0.99], atol=1e-12)


def test_log_likelihood_is_the_log_of_the_outcome_probability_and_stays_finite():
    depth = np.array([0.5, 0.9, 1.0, 1.2, 3.0])
    for eps in (0.0, 0.01):
        p = chatter_probability(depth, 1.0, 0.15, eps)
        # atol: log1p(-p) of p ~ 1e-13 carries the rounding of p itself
        np.testing.assert_allclose(outcome_log_likelihood(depth, 1.0, np.ones(5, bool), 0.15, eps), np.log(p),
                                   rtol=1e-9, atol=1e-15)
        q = eps + (1 - 2 * eps) * ndtr(-np.log(depth) / 0.15)  # P(stable), without the cancellation of 1 - p
        np.testing.assert_allclose(outcome_log_likelihood(depth, 1.0, np.zeros(5, bool), 0.15, eps), np.log(q),
                                   rtol=1e-9, atol=1e-15)
    # 40 standard deviations on the wrong side: log_ndtr keeps it finite (an underflow would veto every draw)
    assert np.isfinite(outcome_log_likelihood(np.exp(4.0), 1.0, False, 0.1, 0.0))


def test_boundary_width_fixed_or_sampled():
    rng = np.random.default_rng(1)
    assert np.all(BoundaryWidth().sample(rng, 5) == 0.1)
    w = BoundaryWidth(0.05, 0.4).sample(rng, 2000)
    assert w.min() >= 0.05 and w.max() <= 0.4
    assert np.median(np.log(w)) == pytest.approx(0.5 * (math.log(0.05) + math.log(0.4)), abs=0.05)  # log-uniform
    with pytest.raises(SetupError):
        BoundaryWidth(-0.1, 0.1)


# --------------------------------------------------------------------------- coefficients
def test_coefficient_prior_level_and_ratio_nodes():
    pr = CoefficientPrior.from_tolerances(560e6, 0.3, 170e6, 0.2, nodes=5)
    assert pr.level_sd == pytest.approx(math.log(1.3)) and pr.ratio_sd == pytest.approx(math.log(1.2))
    d = pr.ratio_offsets
    np.testing.assert_allclose(d, -d[::-1], atol=1e-15)  # symmetric, median node = the stated ratio
    assert d[2] == 0 and np.std(d) < pr.ratio_sd  # midpoint quantiles: slightly narrower than the normal
    u, node = pr.sample(np.random.default_rng(2), 4000)
    kt, kr = pr.coefficients(u, node)
    assert np.median(kt) == pytest.approx(560e6, rel=0.02)
    assert np.std(np.log(kt)) == pytest.approx(math.log(1.3), rel=0.05)
    assert set(np.round(kr / kt / (170e6 / 560e6), 9)) == set(np.round(np.exp(d), 9))
    assert np.all(np.isfinite(pr.ln_prob(u, node))) and pr.ln_prob(0.0, 7) == -np.inf
    fixed = CoefficientPrior.from_tolerances(560e6, 0.0, 170e6, 0.0)
    assert not fixed.sampled and fixed.ratio_offsets.tolist() == [0.0]


def test_per_draw_coefficients_equal_one_method_call_per_draw():
    """The exact scaling a_lim(K_t, rho K_t) = a_lim(K_t0, rho K_t0) K_t0 / K_t, grouped by ratio."""
    rng = np.random.default_rng(3)
    gx, gy = stand_in(6, rng)
    kt = 600e6 * np.exp(rng.normal(0, 0.2, 6))
    kr = kt * np.array([0.3, 0.3, 0.5, 0.3, 0.5, 0.2])
    speeds = np.linspace(6000, 20000, 25)
    impl = STABILITY_METHODS.get("zoa")
    res = limits_with_coefficients(impl, gx, gy, F, GEOM, speeds, kt, kr, MethodOptions())
    for d in range(6):
        c = CuttingConditions(kt=kt[d], kr=kr[d], flutes=3, radial_immersion=0.5)
        direct = zoa_lobes(gx[d], gy[d], F, c, speeds).depth_limit_m
        np.testing.assert_allclose(res.depth_limit_m[d], direct, rtol=1e-10)
    np.testing.assert_allclose(res.limits_at(speeds[:4]), res.depth_limit_m[:, :4], rtol=1e-12)


# --------------------------------------------------------------------------- re-weighting
def _tiny_likelihood():
    inv = np.array([[[1 / 1.0, 1 / 2.0], [1 / 1.3, 1 / 2.4], [1 / 0.8, 1 / 1.7]]])  # (1 node, 3 draws, 2 cuts)
    return CutLikelihood(inv, depth_m=[1.1, 1.9], chatter=[True, False], label_error=0.0)


def test_importance_weights_agree_with_brute_force_integration():
    lik = _tiny_likelihood()
    prior = CoefficientPrior(600e6, 180e6, level_sd=0.2)
    width = BoundaryWidth(0.1, 0.1)
    # brute force: p(d, u | cuts) on a fine u grid
    u = np.linspace(-1.2, 1.2, 4001)
    post = np.array([np.exp(prior.ln_prob(u, 0) + lik(np.full(u.size, d), u, np.zeros(u.size, int),
                                                      np.full(u.size, 0.1))) for d in range(3)])
    p_draw = post.sum(axis=1) / post.sum()
    mean_u = float((post.sum(axis=0) * u).sum() / post.sum())
    res = importance_update(lik, prior, width, np.random.default_rng(4), UpdateSettings(20000, min_ess=1.0, n_out=3000))
    got = np.bincount(res.particle_draw, res.weights, 3)
    # 60000 particles: the Monte Carlo error of these weights is below 0.01 (binomial-like, ESS in the thousands)
    np.testing.assert_allclose(got, p_draw, atol=0.015)
    assert float(np.sum(res.weights * res.particle_u)) == pytest.approx(mean_u, abs=0.01)
    assert res.ess_draws == pytest.approx(1 / np.sum(p_draw**2), rel=0.05)
    # the resampled draws follow the weights
    assert np.bincount(res.draw, minlength=3) / res.draw.size == pytest.approx(got, abs=0.01)


def test_resampling_and_weighted_quantiles():
    rng = np.random.default_rng(5)
    w = np.array([0.1, 0.0, 0.6, 0.3])
    idx = systematic_resample(w, 1000, rng)
    np.testing.assert_allclose(np.bincount(idx, minlength=4) / 1000, w, atol=1e-3)  # systematic: error <= 1/n
    assert effective_sample_size(np.ones(10)) == pytest.approx(10)
    assert weighted_quantile([3.0, 1.0, np.inf], [0.2, 0.2, 0.6], [0.1, 0.5]).tolist() == [1.0, np.inf]


def test_ess_collapse_is_refused_with_the_reason():
    rng = np.random.default_rng(6)
    inv = 1.0 / np.exp(rng.normal(0, 0.3, (1, 200, 1)))  # 200 draws, limits ~ 1 ± 30 %
    # one cut that only the very deepest-limit draws allow, on a sharp boundary: a handful of draws carry it
    lik = CutLikelihood(inv, [2.2], [False], label_error=0.0)
    with pytest.raises(ConvergenceError, match="effective sample size .* below 50"):
        importance_update(lik, CoefficientPrior(600e6, 180e6), BoundaryWidth(0.01, 0.01), rng)
    res = importance_update(lik, CoefficientPrior(600e6, 180e6), BoundaryWidth(0.01, 0.01), rng,
                            UpdateSettings(min_ess=1.0))
    assert res.ess_draws < 50


# --------------------------------------------------------------------------- recovery (reduced acceptance)
def _campaign(seed, n_cuts=10, n_draws=150, bias=1.2):
    """Truth K_t 20 % above the assumed value; the cuts' outcomes from the true limit (no label noise)."""
    rng = np.random.default_rng(seed)
    gx, gy = stand_in(n_draws, rng)
    tx, ty = stand_in(1, rng)
    true = CuttingConditions(kt=600e6 * bias, kr=180e6 * bias, flutes=3, radial_immersion=0.5)
    speeds = np.sort(rng.uniform(6000, 20000, n_cuts))
    a_true = zoa_lobes(tx, ty, F, true, speeds).depth_limit_m[0]
    depth = a_true * np.exp(rng.uniform(-0.5, 0.5, n_cuts))  # cuts around the boundary, as a machinist probes it
    group = CutGroup(gx, gy, F, GEOM, np.arange(n_cuts), speeds)
    prior = CoefficientPrior.from_tolerances(600e6, 0.3, 180e6, 0.0)
    inv = inverse_limits_at_cuts([group], n_cuts, prior)
    lik = CutLikelihood(inv, depth, depth > a_true)
    return importance_update(lik, prior, BoundaryWidth(), rng, UpdateSettings(particles_per_draw=16)), 600e6 * bias


def test_recovery_of_kt_from_ten_cuts_on_a_stand_in():
    covered, moved = 0, 0
    for seed in range(5):  # development seeds (the benchmark tables use seeds >= 5000)
        res, truth = _campaign(seed)
        lo, med, hi = np.quantile(res.kt, [0.05, 0.5, 0.95])
        covered += lo <= truth <= hi
        moved += abs(math.log(med / truth)) < abs(math.log(600e6 / truth))
        assert hi / lo < 1.6  # narrower than the prior's 90 % interval (1.3^3.29 = 2.37)
    # reduced version of the acceptance (>= 80 % of >= 20 campaigns): 4 of 5
    assert covered >= 4 and moved >= 4


# --------------------------------------------------------------------------- cut files and checks
def test_cut_file_optional_columns_and_old_files(tmp_path):
    old = tmp_path / "old.csv"
    old.write_text("# tests\nspindle_speed_rpm,depth_m,outcome\n9000,0.001,stable\n9500,0.002,Chatter\n")
    s, d, st = read_cutting_tests(old)
    assert st.tolist() == [True, False]
    t = read_cut_table(old)
    assert np.all(np.isnan(t.clamping_length_m)) and t.tool == (None, None) and t.line.tolist() == [3, 4]
    new = tmp_path / "new.csv"
    new.write_text("tool,feed_direction,depth_m,spindle_speed_rpm,outcome,clamping_length_m,radial_immersion\n"
                   "t1,y,0.001,9000,stable,0.03,0.25\n,,0.002,9500,chatter,,\n")
    t = read_cut_table(new)
    assert t.tool == ("t1", None) and t.feed_direction == ("y", None)
    assert t.clamping_length_m[0] == 0.03 and math.isnan(t.clamping_length_m[1]) and t.radial_immersion[0] == 0.25
    cuts = prepare_cuts(t, GEOM, 0.035, ["t1"])
    assert cuts.clamping_length_m.tolist() == [0.03, 0.035] and cuts.tool == ("t1", "t1")
    assert cuts.cutting[0].feed == "y" and cuts.cutting[0].radial_immersion == 0.25 and cuts.cutting[1] == GEOM
    bad = tmp_path / "bad.csv"
    for row, match in (("9000,0.001,wobbly", "outcome 'wobbly'"), ("9000,0.001,stable,z", "feed_direction")):
        bad.write_text("spindle_speed_rpm,depth_m,outcome" + (",feed_direction" if row.count(",") == 3 else "")
                       + "\n" + row + "\n")
        with pytest.raises(DataError, match=match):
            read_cut_table(bad)


def test_cut_checks_name_depth_in_mm_speed_outside_band_and_unsupported_speed(tmp_path):
    f = tmp_path / "c.csv"
    f.write_text("spindle_speed_rpm,depth_m,outcome\n9000,2.5,stable\n")
    with pytest.raises(DataError, match=r"c.csv:2: depth_m 2.5 m is implausible .* was it 2.5 mm = 0.0025 m"):
        prepare_cuts(read_cut_table(f), GEOM, 0.03, ["t"])
    f.write_text("spindle_speed_rpm,depth_m,outcome\n9000,0.012,stable\n")
    with pytest.raises(DataError, match="deeper than the flute length"):
        prepare_cuts(read_cut_table(f), GEOM, 0.03, ["t"], flute_length=lambda name: 0.01)
    f.write_text("spindle_speed_rpm,depth_m,outcome\n9000,0.001,stable\n")
    with pytest.raises(SetupError, match="--clamping-length"):
        prepare_cuts(read_cut_table(f), GEOM, None, ["t"])
    gx, gy = stand_in(4, np.random.default_rng(7))
    f.write_text("spindle_speed_rpm,depth_m,outcome\n9000,0.001,stable\n40000,0.001,chatter\n")
    cuts = prepare_cuts(read_cut_table(f), GEOM, 0.03, ["t"])
    with pytest.raises(DataError, match=r"c.csv:3: spindle speed 40000 rpm is outside the speed range .* 2000 Hz"):
        cut_groups(cuts, {(0.03, "t"): (gx, gy)}, F)
    f.write_text("spindle_speed_rpm,depth_m,outcome\n9000,0.001,stable\n")
    cuts = prepare_cuts(read_cut_table(f), GEOM, 0.03, ["t"])
    inv = inverse_limits_at_cuts(cut_groups(cuts, {(0.03, "t"): (gx, gy)}, F), 1, CoefficientPrior(600e6, 180e6))
    check_supported(cuts, inv)  # a limit in the band: accepted
    with pytest.raises(DataError, match="no draw has a chatter frequency inside the band"):
        check_supported(cuts, np.zeros_like(inv))


# --------------------------------------------------------------------------- identify --cuts: the extra term
def test_extra_likelihood_terms_given_to_the_log_posterior_enter_it_untempered():
    from bayes_rcsa.inference.posterior import LogPosterior
    from bayes_rcsa.params import PriorSet, Uniform

    priors = PriorSet({"a": Uniform(0.0, 1.0)})
    frf = lambda th: -th[:, 0]  # noqa: E731  (stands in for the FRF likelihood)
    term = type("T", (), {"name": "t", "__call__": lambda self, th: 10 * th[:, 0]})()
    x = np.array([[0.5], [2.0]])  # the second row is outside the prior: never evaluated
    assert LogPosterior(priors, frf)(x)[0] == pytest.approx(-0.5)
    lp = LogPosterior(priors, frf, (term,))
    assert lp.extra_terms == (term,)
    assert lp(x)[0] == pytest.approx(-0.5 + 5.0) and lp(x)[1] == -np.inf
    assert lp.with_likelihood(lambda th: 0 * th[:, 0])(x)[0] == pytest.approx(5.0)  # tempering keeps the term
    assert LogPosterior(priors, frf)(x)[0] == pytest.approx(-0.5)  # nothing leaks into the next one


def test_cut_term_integrates_the_coefficients_out_and_draws_them_from_their_conditional():
    from bayes_rcsa.cuts.joint import CutTerm

    inv = np.array([[[1 / 1.0, 1 / 2.0], [1 / 1.3, 1 / 2.4]]])  # rows = the theta rows given below

    class Fixed(CutTerm):  # the stability part replaced by fixed limits: only the integral is under test
        def _likelihood(self, theta):
            rows = np.asarray(theta[:, 0], dtype=int)
            return CutLikelihood(inv[:, rows], [1.1, 1.9], [True, False], label_error=0.0)

    prior = CoefficientPrior(600e6, 180e6, level_sd=0.2)
    term = Fixed(None, None, None, F, None, prior, BoundaryWidth(), 0.0)
    u = np.linspace(-1.5, 1.5, 30001)
    for row in (0, 1):
        lik = CutLikelihood(inv[:, [row]], [1.1, 1.9], [True, False], label_error=0.0)
        ll = lik(np.zeros(u.size, int), u, np.zeros(u.size, int), np.full(u.size, 0.1))
        dens = np.exp(ll - 0.5 * (u / 0.2) ** 2) / (0.2 * math.sqrt(2 * math.pi))
        exact = math.log(np.trapezoid(dens, u))
        # 161 grid points over ±5 sd resolve a likelihood ~0.1 wide in u to well below 1e-3 in log
        assert term(np.array([[row]]))[0] == pytest.approx(exact, abs=1e-3)
    kt, kr, w = term.coefficient_draws(np.zeros((3000, 1)), np.random.default_rng(8))
    lik = CutLikelihood(inv[:, [0]], [1.1, 1.9], [True, False], label_error=0.0)
    post = np.exp(lik(np.zeros(u.size, int), u, np.zeros(u.size, int), np.full(u.size, 0.1)) - 0.5 * (u / 0.2) ** 2)
    mean_u = float(np.sum(post * u) / np.sum(post))
    # 3000 conditional draws of sd ~0.05: the mean is known to ~0.002; 64 candidates per draw add a small bias
    assert float(np.mean(np.log(kt / 600e6))) == pytest.approx(mean_u, abs=0.01)
    assert np.allclose(kr / kt, 0.3) and np.all(w == 0.1)
