"""The tool-library population model (#20): joint prior, stage 2 against the joint model, ESS, outliers.

Cheap stand-ins: stage-1 "posteriors" are Gaussian draws from a known likelihood (so the joint model can
be sampled exactly), one or two pooled coordinates, few setups.  The statistical campaigns on the
finite-element bench are in benchmarks/library.py and docs/library.md.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.stats import kstest, multivariate_normal, norm

from bayes_rcsa.errors import SetupError
from bayes_rcsa.inference.diagnostics import chain_diagnostics
from bayes_rcsa.library.joint import gaussian_log_likelihood, sample_joint
from bayes_rcsa.library.outliers import (ADEQUACY_WEIGHT, adequacy_p_value, adequacy_rows, combine, draw_statistics,
                                         flag_outliers, loo_p_values, refit_warnings,
                                         shift_direction)
from bayes_rcsa.library.population import Hyperprior, covariate
from bayes_rcsa.library.predictive import Population, predictive_draws, predictive_prior
from bayes_rcsa.library.hierarchy import Group, fit_hyper
from bayes_rcsa.library.stage2 import SetupDraws, Stage2Settings, fit_population, surrogate
from bayes_rcsa.params.priors import JointMember, JointNormal, PriorSet, Uniform, prior_from_spec

NAMES2 = ("k_xf", "g_xf")
BOX2 = np.array([[4.0, 10.0], [0.0, 1.5]])
WIDE = np.array([[-50.0, 50.0], [-50.0, 50.0]])


_LAW = {"k_xf": (7.0, 1.5), "k_thetaM": (5.5, 2.0), "g_xf": (0.6, 0.0)}  # mean at 10 mm, slope per ln d


def _setups(rng, diameters, types, shift=None, n_draws=1500, names=NAMES2, box=WIDE, spread=0.06, c_scale=1.0):
    """Stage-1 stand-ins: a population law per setup, a Gaussian likelihood around it, draws of that likelihood.

    ``shift = (i, dz)`` moves setup i's stiffness coordinates by dz (log10).  Returns the setups and
    their exact likelihoods (m, C)."""
    d = len(names)
    out, exact = [], []
    base = np.array([[0.02, 0.004], [0.004, 0.01]])
    for i, (dia, t) in enumerate(zip(diameters, types)):
        x = np.log(dia / 0.01)
        z = np.array([_LAW[n][0] + _LAW[n][1] * x for n in names]) + spread * rng.standard_normal(d)
        if shift is not None and i == shift[0]:
            z += np.array([shift[1] if n.startswith("k_") else 0.0 for n in names])
        C = base[:d, :d] * rng.uniform(0.5, 1.5) * c_scale
        m = z + np.linalg.cholesky(C) @ rng.standard_normal(d)
        draws = m + rng.standard_normal((n_draws, d)) @ np.linalg.cholesky(C).T
        out.append(SetupDraws(f"s{i}", t, dia, draws, np.zeros(d), np.zeros((d, d)), box))
        exact.append((m, C))
    return out, exact


# -- the joint prior of params -------------------------------------------------------------------------


def test_joint_normal_prior_is_the_multivariate_normal_and_round_trips_through_its_description():
    g = JointNormal.from_arrays(NAMES2, [7.0, 0.4], [[0.04, 0.01], [0.01, 0.02]], ["log10", "linear"],
                                [None, 0.0], [None, 1.5])
    ps = PriorSet({"k_xf": g.member("k_xf"), "c_xf": Uniform(0.0, 2.0), "g_xf": g.member("g_xf")})
    rng = np.random.default_rng(0)
    u = ps.sample(rng, 4000)
    assert np.all(u[:, 2] >= 0)  # the growth factor's box
    inside = u[:3]
    lp = ps.ln_prob(inside)
    ref = multivariate_normal([7.0, 0.4], [[0.04, 0.01], [0.01, 0.02]]).logpdf(inside[:, [0, 2]]) - np.log(2.0)
    # the same density divided by the mass the box keeps, P(g >= 0) = Phi(0.4 / sqrt(0.02)); the mass is a
    # Monte Carlo estimate of 20 000 draws (standard error ~3e-4 on a mass of 0.9977)
    mass = norm.cdf(0.4 / np.sqrt(0.02))
    diff = lp - ref
    assert np.ptp(diff) < 1e-9 and abs(diff[0] + np.log(mass)) < 2e-3
    assert np.isneginf(ps.ln_prob(np.array([[7.0, 1.0, -0.1]]))[0])
    # the correlation of the group is sampled (independent marginals would give ~0)
    assert np.corrcoef(u[:, 0], u[:, 2])[0, 1] > 0.25
    # log10 coordinate of the stiffness
    assert float(g.member("k_xf").to_physical(7.0)) == pytest.approx(1e7)
    back = prior_from_spec(json.loads(json.dumps(g.member("g_xf").describe())), "x")
    assert isinstance(back, JointMember) and back == g.member("g_xf")
    with pytest.raises(SetupError, match="all its parameters"):
        PriorSet({"k_xf": g.member("k_xf")})


# -- stage 2 against the joint model ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def four_combinations():
    """Two holder types of two combinations each, fitted by stage 2 with its default settings (seed 11)."""
    rng = np.random.default_rng(11)
    names = NAMES2[:1]
    hyper = Hyperprior.from_box(names, BOX2[:1], 1.5)
    dia = np.array([0.006, 0.013, 0.009, 0.018])
    types = [0, 0, 1, 1]
    x = covariate(dia)
    exact = []
    for i in range(4):
        z = 7.0 + 0.2 * types[i] + 1.5 * x[i] + 0.15 * rng.standard_normal(1)
        C = np.array([[0.02]]) * rng.uniform(0.5, 1.5)
        exact.append((z + np.sqrt(C[0]) * rng.standard_normal(1), C))
    groups = [Group(f"T{t}", tuple(f"s{i}" for i in range(4) if types[i] == t), x[[i for i in range(4) if types[i] == t]],
                    np.array([exact[i][0] for i in range(4) if types[i] == t]),
                    np.array([exact[i][1] for i in range(4) if types[i] == t])) for t in (0, 1)]
    fit = fit_hyper(groups, hyper, rng, Stage2Settings())
    return hyper, types, x, exact, fit, rng


def test_stage2_stops_converged_by_default_and_reports_no_more_than_the_arviz_bulk_ess(four_combinations):
    # The old rule (walkers x steps / max tau >= 400 and 10 tau) stopped this case after 250 steps with a reported
    # ESS of 1,246 against an ArviZ bulk ESS of 351 and R-hat 1.19.  Now: stage 1's rule, and the ESS of the draws
    # that are kept, recomputed here from them (walker by walker, as ArviZ chains)
    _, _, _, _, fit, _ = four_combinations
    settings = Stage2Settings()
    chain = np.swapaxes(fit.theta.reshape(fit.n_walkers, -1, fit.theta.shape[1]), 0, 1)
    dg = chain_diagnostics(chain)
    assert fit.ess <= np.min(dg["ess_bulk"]), (fit.ess, dg)
    assert fit.ess >= 0.9 * settings.ess_target
    np.testing.assert_array_equal(fit.rhat, dg["rhat"])
    if fit.converged:
        assert np.all(dg["rhat"] < settings.rhat_max), dg
        assert fit.n_steps > settings.tau_factor * np.max(fit.tau)
        assert not any("unconverged" in w for w in fit.warnings)
    else:
        assert any("unconverged" in w and "R-hat" in w and "bulk ESS" in w and "autocorrelation time" in w
                   for w in fit.warnings), fit.warnings
    # every type is a view of the one coupled chain
    assert all(t.quality is fit.quality and t.ess == fit.ess for t in fit.types.values())
    # and a chain stopped by its cap says so, with the numbers
    short = fit_hyper(fit.groups, four_combinations[0], np.random.default_rng(1), Stage2Settings(n_burn=50,
                                                                                                 max_steps=100))
    assert not short.converged and short.n_steps == 100
    warn = next(w for w in short.warnings if "unconverged" in w)
    assert f"R-hat {np.max(short.rhat):.3f}" in warn and f"bulk ESS {np.min(short.quality.ess_bulk):.0f}" in warn, warn
    # a chain too short to measure its own tau has no ESS (issue #42: stage 2's first 500 steps measured tau 47-72
    # where long chains measure 153-369, an ESS overstated ~5x): unknown, not the bulk ESS ArviZ computes from it
    assert fit.quality.tau_measured and math.isfinite(fit.ess) and fit.quality.summary()["ess"] == fit.ess
    assert short.n_steps <= 50 * np.max(short.tau) and not short.quality.tau_measured
    assert np.min(short.quality.ess_bulk) > 0 and math.isnan(short.ess)
    row = short.quality.summary()
    assert row["ess"] is None and row["tau_measured"] is False and "not measured" in row["ess_reason"]
    assert "ESS unknown (chain shorter than 50 autocorrelation times)" in warn, warn


def test_two_stage_hyperparameters_match_joint_emcee_on_four_combinations(four_combinations):
    # two holder types of two combinations each: the types share the slope's and the spread's hyperparameters,
    # so stage 2 is one coupled fit; the joint sampler integrates nothing out.  Stage 2 runs with its default
    # settings (converged by stage 1's rule: ~2,000 steps, bulk ESS ~3,900)
    hyper, types, x, exact, fit, rng = four_combinations
    joint = sample_joint([gaussian_log_likelihood(m, C) for m, C in exact], types, x, hyper, rng, n_steps=8000,
                         n_burn=2000, n_walkers=48)
    for t in range(2):
        two, ref = fit.types[f"T{t}"].flat, joint["types"][t]
        for j, label in enumerate(("a", "b", "sigma")):
            qj = np.quantile(ref[:, j], [0.05, 0.5, 0.95])
            q2 = np.quantile(two[:, j], [0.05, 0.5, 0.95])
            sd = np.std(ref[:, j])
            # acceptance: medians within 0.2 posterior sd; 90 % ends within 10 % (of the joint interval's width,
            # since b's interval straddles 0 and a relative error of its ends is meaningless).  The spread's
            # upper end sits in a long tail that one ensemble of 48 x 8000 joint steps pins only to ~15 % of the
            # width (a few walkers' excursions move it), so it gets 20 % here; benchmarks/library_scale.py joint
            # pools four long independent runs, and tests/test_library_joint.py shows the two targets are one
            # distribution (docs/library.md, "Stage 2").
            tol = 0.2 if label == "sigma" else 0.1
            assert abs(q2[1] - qj[1]) < 0.2 * sd, (t, label, q2, qj)
            assert np.all(np.abs(q2[[0, 2]] - qj[[0, 2]]) < tol * (qj[2] - qj[0])), (t, label, q2, qj)
    qj, q2 = np.quantile(joint["tau_b"][:, 0], [0.05, 0.5, 0.95]), np.quantile(fit.tau_b[:, 0], [0.05, 0.5, 0.95])
    assert abs(q2[1] - qj[1]) < 0.2 * np.std(joint["tau_b"][:, 0]), (q2, qj)


def test_surrogate_divides_out_a_normal_stage1_prior():
    rng = np.random.default_rng(2)
    L, P0 = np.array([7.0]), np.array([[1 / 0.3**2]])
    C = np.array([[0.1**2]])
    # posterior of a N(7.2, 0.1^2) likelihood under a N(7, 0.3^2) prior
    post_var = 1 / (1 / 0.1**2 + 1 / 0.3**2)
    post_mean = post_var * (7.2 / 0.1**2 + 7.0 / 0.3**2)
    z = post_mean + np.sqrt(post_var) * rng.standard_normal((40000, 1))
    m, Cs, _ = surrogate(SetupDraws("s", "T", 0.01, z, L, P0, WIDE[:1]))
    assert m[0] == pytest.approx(7.2, abs=0.01) and Cs[0, 0] == pytest.approx(C[0, 0], rel=0.05)
    with pytest.raises(SetupError, match="not narrower than its stage-1 prior"):
        surrogate(SetupDraws("s", "T", 0.01, 7 + 0.5 * rng.standard_normal((4000, 1)), L, P0, WIDE[:1]))


# -- per-setup ESS and refusal, outliers ----------------------------------------------------------------


#: Short stage-2 chains for the tests of what is computed from the draws (per-setup ESS, refusals, the predictive, the
#: outlier statistics, pooling), not of the chain's convergence.  Stage 2's default rule (50 autocorrelation times,
#: tau stable to 5 %, R-hat < 1.02) needs 2,000-10,000 steps on these stand-ins (tau 35-190 steps; 9,000-10,000 for
#: the three types below with 24 walkers, 13 fits of ~14 s each); a step cap keeps each fit at the cost the old ESS
#: rule had (200-400 steps), and each says in its warnings that it stopped unconverged.  Here 200 steps after 100 of
#: burn-in (was 500 after 200; ~25 % less work in the fits below): on the clean library with the fixture's generator
#: and seeds 70-72 the smallest per-setup ESS is 684-720 (asked: >= 100; 704-747 with the longer chain), the HSK
#: predictive's median 0.033 decade from 7 (asked: < 0.1; 0.031-0.034) and its sd 0.090-0.096 (asked: 0.04-0.5;
#: 0.089-0.098); the broad setup's importance ESS is 3.6-6.1 on seeds 6 (the test's) and 60-62 (refused below 30;
#: 3.7-6.3).
_SHORT = Stage2Settings(n_burn=100, ess_target=200, max_steps=200)


@pytest.fixture(scope="module")
def clean_fit():
    """Eight setups in two holder types.  As on the bench, each setup's own data pin its law down much more
    tightly (sd ~0.01 decade) than the laws scatter between combinations (0.06 decade)."""
    rng = np.random.default_rng(5)
    dia = np.array([0.006, 0.008, 0.010, 0.012, 0.014, 0.016, 0.018, 0.020])
    setups, _ = _setups(rng, dia, ["ER32", "HSK"] * 4, n_draws=800, box=BOX2, c_scale=0.01)
    hyper = Hyperprior.from_box(NAMES2, BOX2, 1.5)
    res = fit_population(setups, hyper, rng, _SHORT)
    return setups, hyper, res


def test_per_setup_ess_is_reported_and_a_degenerate_reweighting_refused(clean_fit):
    setups, hyper, res = clean_fit
    rows = {r["name"]: r for r in res.setups}
    # well-determined setups: the population hardly re-weights their narrow draws
    assert all(r["refused"] is None and r["ess"] >= 100 for r in rows.values()), rows
    assert all(r["k_xf_pooled"][0] <= r["k_xf_pooled"][1] <= r["k_xf_pooled"][2] for r in rows.values())
    # a setup whose data say almost nothing (draws over 1 decade and the whole growth range) against a
    # population ~0.06 decade wide: few of its draws lie where the pooled posterior is; refused with the reason
    rng = np.random.default_rng(6)
    bad = SetupDraws("bad", "ER32", 0.012, np.column_stack([7.3 + 1.0 * rng.standard_normal(500),
                                                            rng.uniform(0.0, 1.5, 500)]),
                     np.zeros(2), np.zeros((2, 2)), BOX2)
    er32 = [s for s in setups if s.holder_type == "ER32"]
    res2 = fit_population(er32 + [bad], hyper, rng, _SHORT)
    row = next(r for r in res2.setups if r["name"] == "bad")
    assert row["refused"] is not None and "importance ESS" in row["refused"] and "k_xf_pooled" not in row, row
    assert any("setup bad" in w for w in res2.warnings)
    # its growth draws fill the stage-1 box (contraction ~0): named as barely identified, once, with the setup; its
    # stiffness (sd 1 decade in a 6-decade box: contraction 0.67) and every well-determined setup are not
    weak = [w for w in res2.warnings if "barely identified" in w]
    assert len(weak) == 1 and weak[0].startswith("coordinate g_xf:") and "1 of 5 setups (bad:" in weak[0], weak
    assert not any("barely identified" in w for w in res.warnings)


#: Three holder types shaped like the bench's (docs/library.md): mean at 10 mm and slope of (k_xf, k_thetaM) in
#: log10 per e-fold, and each type's own spread between combinations (decades): the spreads differ by ~2x.
_TYPES = {"ER32": ([6.45, 5.95], [0.87, 1.30], 0.065), "shrink_fit": ([6.65, 6.18], [0.78, 1.22], 0.035),
          "hydraulic": ([6.56, 6.08], [0.96, 1.39], 0.043)}
_BOX_K = np.array([[4.0, 10.0], [2.0, 9.0]])
_CHEAP = Stage2Settings(n_burn=100, ess_target=150, chunk=100, n_walkers=24, max_steps=400)  # see _SHORT
#: The leave-one-out refits of the softer-contact test: _CHEAP with a 200-step cap, half its steps and half the test's
#: cost.  Each refit starts from the full library's draws and none converges within either cap; on the test's
#: generator (seed 23) and seeds 200-203, 400 steps gave ER32_1 a combined p of 3e-10 to 3e-6 and the clean ones
#: 0.096 at least, 200 steps 9e-10 to 3e-6 and 0.11 at least (flagged below 0.0042; the test asks > 0.01), and a
#: median shift of -9.6 to -11.1 (asked: < -2).  (A 100-step cap lets ER32_1's p rise to 3e-4 on one of them.)
_REFIT = dataclasses.replace(_CHEAP, max_steps=200)


def _three_types(seed, softer=None):
    """Four combinations per type; each setup's own data pin its stiffnesses to ~0.004 / 0.02 decade (as the
    bench's three-length identify fits do), much tighter than the spreads.  ``softer`` = index of a combination
    whose contact is 3x softer (both stiffnesses) than its population's."""
    rng = np.random.default_rng(seed)
    out, i = [], 0
    for t, (a, b, s) in _TYPES.items():
        for dia in rng.choice([0.006, 0.008, 0.010, 0.012, 0.016, 0.020], 4, replace=False):
            z = np.array(a) + np.array(b) * np.log(dia / 0.01) + s * rng.standard_normal(2)
            if i == softer:
                z -= np.log10(3.0)
            sd = np.array([0.004, 0.02]) * rng.uniform(0.5, 1.5)
            m = z + sd * rng.standard_normal(2)
            out.append(SetupDraws(f"{t}_{i}", t, float(dia), m + sd * rng.standard_normal((600, 2)), np.zeros(2),
                                  np.zeros((2, 2)), _BOX_K))
            i += 1
    return out


@pytest.fixture(scope="module")
def three_types():
    hyper = Hyperprior.from_box(("k_xf", "k_thetaM"), _BOX_K, 1.5)
    setups = _three_types(21)
    return hyper, setups, fit_population(setups, hyper, np.random.default_rng(22), _CHEAP)


def test_a_contact_three_times_softer_is_flagged_with_four_combinations_per_type(three_types):
    # the #20 acceptance at the size that failed before the types were pooled: three types of four, one
    # combination of the type with the widest spread (an ER32 collet) clamped badly, both stiffnesses 3x
    # softer: flagged, and none of the eleven clean ones (the false-flag rate of whole clean libraries is
    # the benchmark's: 0/10, docs/library.md)
    hyper, _, _ = three_types
    rng = np.random.default_rng(23)
    setups = _three_types(21, softer=1)
    fit = fit_population(setups, hyper, rng, _CHEAP)
    p_rows = loo_p_values(fit.fit, hyper, rng, settings=_REFIT, n_draws=300)
    rows, _ = flag_outliers(p_rows, len(setups))
    assert all(r["method"] == "exact" for r in rows)
    assert {r["name"] for r in rows if r["outlier"]} == {"ER32_1"}, rows
    # seen as what it is: a softer contact, the shift statistic stronger than the omnibus distance
    bad = next(r for r in rows if r["name"] == "ER32_1")
    assert bad["shift_median"] < -2 and bad["p_shift"] < bad["p_omnibus"], bad
    # the importance-sampling check of large types (no refits; here forced) sees the same combination
    imp, _ = flag_outliers(loo_p_values(fit.fit, hyper, rng, exact_max=0), len(setups))
    assert all(r["method"] == "importance" for r in imp)
    # each exact refit says whether it met its rule; capped at 200 steps here, those that did not are named in one
    # warning (they used to be dropped), and the importance rows have no refit to judge
    assert all(isinstance(r["refit_converged"], bool) and 0 < r["refit_steps"] <= 200 for r in rows)
    assert all(r["refit_converged"] is None and r["refit_rhat_max"] is None for r in imp)
    unconverged = [r["name"] for r in rows if not r["refit_converged"]]
    warn = refit_warnings(p_rows)
    assert unconverged and len(warn) == 1 and "step cap (200 steps) unconverged" in warn[0]
    assert all(name in warn[0] for name in unconverged) and refit_warnings(imp) == []
    assert {r["name"] for r in imp if r["outlier"]} == {"ER32_1"}, imp
    # the clean ones are not near the threshold either (Bonferroni 0.05 / 12 = 0.0042)
    assert min(r["p_value"] for r in rows if r["name"] != "ER32_1") > 0.01, rows
    # with the model-adequacy component: a setup whose contact agrees with its type but whose own hammer tests the
    # model does not reproduce is flagged for that, and says so; the softer one still for its contact; a skipped
    # component (no stage-1 summary) leaves the contact check as it was
    contact = {r["name"]: r["p_value"] for r in p_rows}
    adq = {r["name"]: {"p_adequacy": 0.6, "residual_correlation_lines": 1.0, "adequacy_skipped": None} for r in rows}
    adq["hydraulic_9"] = {"p_adequacy": 5e-5, "residual_correlation_lines": 7.6, "adequacy_skipped": None}
    adq["shrink_fit_5"] = {"p_adequacy": None, "residual_correlation_lines": None, "adequacy_skipped": "no summary"}
    both, warns = flag_outliers(p_rows, len(setups), adequacy=adq)
    by = {r["name"]: r for r in both}
    assert {n for n, r in by.items() if r["outlier"]} == {"ER32_1", "hydraulic_9"}, both
    assert by["hydraulic_9"]["outlier_reason"].startswith("its own hammer tests are not reproduced by the model: "
                                                          "hidden effect or bad measurement"), by["hydraulic_9"]
    assert "contact disagrees" not in by["hydraulic_9"]["outlier_reason"]
    assert "residuals correlated over 7.6 lines (> 2)" in by["hydraulic_9"]["outlier_reason"]  # discrepancy's rule 1
    assert by["ER32_1"]["outlier_reason"].startswith("its contact disagrees with its holder type's population")
    assert "softer" in by["ER32_1"]["outlier_reason"] and "not reproduced" not in by["ER32_1"]["outlier_reason"]
    assert by["shrink_fit_5"]["p_value"] == by["shrink_fit_5"]["p_contact"]  # two components: as before
    assert any(w.startswith("setup hydraulic_9: outlier") and "not reproduced" in w for w in warns)
    # the contact statistics' own combination is kept beside the overall p-value
    assert all(by[n]["p_contact"] == contact[n] for n in contact), (by, contact)
    assert all(r["p_value"] == combine(r["p_shift"], r["p_omnibus"], r["p_adequacy"]) for r in both)


def test_combined_p_value_is_a_weighted_bonferroni_over_the_available_components():
    # contact statistics alone: 2 min(p_shift, p_omnibus), as before the adequacy component
    assert combine(0.01, 0.2) == pytest.approx(0.02) and combine(None, 0.2) == pytest.approx(0.2)
    # all three: p_k / w_k with the adequacy share ADEQUACY_WEIGHT and the rest split between the contact ones
    w = ADEQUACY_WEIGHT
    assert combine(0.01, 0.2, 0.5) == pytest.approx(0.01 / ((1 - w) / 2))
    assert combine(0.5, 0.5, 1e-4) == pytest.approx(1e-4 / w)
    assert combine(None, None, 0.003) == pytest.approx(0.003)  # the only one of its type: adequacy alone
    assert combine(None, None, None) is None and combine(0.9, 0.9, 0.9) == 1.0
    # the rule keeps the rate: independent uniform components, P(combined < a) <= a
    u = np.random.default_rng(40).uniform(size=(3, 20000))
    p = np.array([combine(*c) for c in u.T])
    for a in (0.05, 0.2):
        assert np.mean(p < a) <= a + 3 * math.sqrt(a * (1 - a) / p.size)


def test_adequacy_p_value_is_calibrated_for_white_residuals_and_tiny_for_a_smooth_misfit():
    # the null the component tests: the fit's normalised residuals white on its lines.  The statistic is the
    # residual correlation length identify reports; its p-value comes from simulating the same statistic, so
    # for white residuals it is uniform (up to ties at tau = 1, where it is 1: conservative)
    from bayes_rcsa.inference.likelihood import residual_correlation_length

    rng = np.random.default_rng(41)
    lines = (60, 70, 80)
    edges = np.cumsum((0,) + lines)
    slices = [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]
    z = rng.standard_normal((300, edges[-1])) + 1j * rng.standard_normal((300, edges[-1]))
    p = np.array([adequacy_p_value(residual_correlation_length(v, slices), lines, rng, 2000) for v in z])
    for a in (0.1, 0.3):  # rate <= a up to 3 binomial sd (a p-value of the wrong statistic or lines fails)
        assert np.mean(p <= a) <= a + 3 * math.sqrt(a * (1 - a) / p.size), (a, np.mean(p <= a))
    assert np.mean(p <= 0.3) > 0.15  # and not trivially 1: it has power to be small
    # a smooth misfit over ~15 lines (what a hidden tip mass leaves beside a resonance) on top of the noise
    f = np.arange(edges[-1])
    bump = 3.0 * np.exp(-0.5 * ((f - 100) / 10.0) ** 2) * (1 + 1j)
    tau = residual_correlation_length(z[0] + bump, slices)
    assert tau > 2 and adequacy_p_value(tau, lines, rng, 2000) == pytest.approx(1 / 2001)


@pytest.fixture(scope="module")
def tip_mass_stage1(tmp_path_factory):
    """Two ER32 8 mm combinations of a development library (seed 3), hammer tests at 25 and 45 mm: one clean,
    one with the bench's hidden 2 g tip mass; each identified by the real ``identify`` (a short chain: the
    residual correlation is taken at the optimum, before sampling)."""
    from bayes_rcsa.batch.manifest import load_manifest
    from bayes_rcsa.cli.main import main as cli
    from bayes_rcsa.synthetic.library import LibrarySpec, Special, generate_library, write_library

    root = tmp_path_factory.mktemp("tip_mass")
    spec = LibrarySpec(holder_types=("ER32",), per_type=2, diameters=(0.008,), clamping_lengths=(0.025, 0.045),
                       specials=(Special(1, hidden_effects={"tip_mass": True}),),
                       identify={"walkers": 14, "max_steps": 10, "check_every": 10, "ess_min": 10, "seed": 0})
    write_library(generate_library(spec, seed=3), root / "lib")
    paths = {}
    for job in load_manifest(root / "lib" / "manifest.toml"):
        assert cli(job.argv("identify", root / "setups" / job.name) + ["--no-plots", "--quiet"]) == 0
        paths[job.name] = root / "setups" / job.name / "identify" / "summary.json"
    return root, paths


def test_a_hidden_tip_mass_fails_the_adequacy_component_and_a_clean_combination_passes(tip_mass_stage1):
    _, paths = tip_mass_stage1
    clean, mass = sorted(paths)  # ER32_d8_1 clean, ER32_d8_2 with the tip mass
    rows, warns = adequacy_rows({**paths, "synthetic": None}, 4, np.random.default_rng(42))
    assert not warns
    # the contact law absorbs the mass at each length, but not its shape over the band: a smooth residual
    assert rows[mass]["residual_correlation_lines"] > 3, rows
    # below the component's share of a 4-combination library's threshold (the smallest p the simulations reach)
    assert rows[mass]["p_adequacy"] < ADEQUACY_WEIGHT * 0.05 / 4, rows
    assert rows[clean]["p_adequacy"] > 0.05 and rows[clean]["residual_correlation_lines"] < 1.5, rows
    # no hammer tests known (synthetic stage-1 draws): skipped with the reason recorded
    assert rows["synthetic"]["p_adequacy"] is None and "no stage-1 summary" in rows["synthetic"]["adequacy_skipped"]


def _bench_like_predictives(rng, H):
    """H predictive covariances shaped like the bench's (k_xf, k_thetaM, g_xf, g_thetaM): the setup's own stage-1
    sd 0.001 / 0.06-0.38 / 0.0015 / 0.27 (the rotational coordinates loosely pinned, g_thetaM not at all) plus a
    spread 0.035-0.065 / 0.1 / 0.06 / 0.1 and a random correlation of the stage-1 posterior."""
    sd = np.array([0.001, 0.2, 0.0015, 0.27]) * rng.uniform(0.3, 1.9, (H, 4))
    R = rng.standard_normal((H, 4, 6))
    R = R @ np.swapaxes(R, 1, 2)
    R = R / np.sqrt(np.einsum("hii,hjj->hij", R, R))  # a random correlation matrix per draw
    sig = np.array([0.05, 0.1, 0.06, 0.1]) * rng.uniform(0.7, 1.3, (H, 4))
    return sd[:, :, None] * R * sd[:, None, :] + np.eye(4) * (sig * sig)[:, None, :]


def test_outlier_statistics_are_calibrated_under_the_predictive():
    # given the hyperparameters the predictive is normal and both statistics are exact: for residuals drawn
    # from it, p_shift and p_omnibus are uniform, and the combined p = 2 min(p_shift, p_omnibus) falls below a
    # threshold a at most at rate a (Bonferroni).  A wrong standardisation of the shift or the wrong degrees of
    # freedom of the distance would break the uniformity.
    rng = np.random.default_rng(31)
    H = 20000
    V = _bench_like_predictives(rng, H)
    r = np.einsum("hij,hj->hi", np.linalg.cholesky(V), rng.standard_normal((H, 4)))
    e = shift_direction(("k_xf", "k_thetaM", "g_xf", "g_thetaM"))
    st = draw_statistics(r, V, e)
    # KS at 20000 draws: a correct implementation passes the 1e-3 floor with probability 0.999; a shift whose sd
    # is 10 % off gives ~1e-35
    assert kstest(st["p_shift"], "uniform").pvalue > 1e-3
    assert kstest(st["p_omnibus"], "uniform").pvalue > 1e-3
    p = np.minimum(1.0, 2.0 * np.minimum(st["p_shift"], st["p_omnibus"]))
    for a in (0.05, 0.2):  # rate <= a, up to 3 binomial sd
        assert np.mean(p < a) <= a + 3 * math.sqrt(a * (1 - a) / H), (a, np.mean(p < a))


def test_a_softer_contact_is_seen_by_the_shift_statistic_where_the_omnibus_distance_dilutes_it():
    # the bench's 3x softer contact: both log stiffnesses 0.48 decade low, in a predictive whose spread (from a
    # leave-one-out posterior with a wide draw for the type's spread) is 0.2 decade in k_xf.  The loosely pinned
    # rotational coordinates add near-pure noise degrees of freedom to D; the shift statistic tests one
    # direction
    V = np.diag([0.2, 0.3, 0.06, 0.29]) ** 2
    r = np.array([-0.48, -0.48, 0.0, 0.0])
    st = draw_statistics(r[None], V[None], shift_direction(("k_xf", "k_thetaM", "g_xf", "g_thetaM")))
    assert st["t"][0] < -2.5  # softer
    assert st["p_shift"][0] < 0.3 * st["p_omnibus"][0], st
    # without a stiffness among the pooled coordinates only the omnibus statistic is left
    assert shift_direction(("g_xf", "c_xf")) is None


def test_pooled_zero_tap_predictive_is_narrower_than_one_type_alone_and_covers(three_types):
    # "unpooled": the same type fitted as a library of its own four combinations (its spread and slope from them
    # and the hyperprior only); pooled: with the other two types, which pin the spreads' and slopes' level
    hyper, setups, res = three_types
    rng = np.random.default_rng(24)
    alone = fit_population([s for s in setups if s.holder_type == "ER32"], hyper, rng, _CHEAP)
    growth, diam = (0.02, 0.045, 1.5), {"ER32": (0.006, 0.020)}
    pooled = Population(hyper.names, {"ER32": res.types["ER32"].flat}, _BOX_K, growth, diam)
    single = Population(hyper.names, {"ER32": alone.types["ER32"].flat}, _BOX_K, growth, diam)
    zp, _ = predictive_draws(pooled, "ER32", 0.012, rng, 4000)
    zs, _ = predictive_draws(single, "ER32", 0.012, rng, 4000)
    wp = np.diff(np.quantile(zp, [0.05, 0.95], axis=0), axis=0)[0]
    ws = np.diff(np.quantile(zs, [0.05, 0.95], axis=0), axis=0)[0]
    # narrower in both stiffnesses: k_xf by 37-38 % and k_thetaM by 17-20 % with converged chains (default settings,
    # bulk ESS > 4,000, three seeds); the chains here are short (_CHEAP: bulk ESS ~50), on which the ratio scatters
    # 0.55-0.68 and 0.68-0.93 over six seeds.  (This asked 20 % of k_thetaM too, which only the old rule's
    # unconverged chains gave, on some seeds: 0.74-1.04 over five.)
    assert wp[0] < 0.8 * ws[0] and wp[1] < 0.95 * ws[1], (wp, ws)
    # and it still covers: the type's true median law at 12 mm, and most of 40 new ER32 combinations drawn from
    # the type's true population.  One library's four ER32 combinations are themselves a small sample of the
    # spread (here their k_thetaM scatter is 0.038 decade against the true 0.065), so the coverage of one
    # library scatters around the nominal 90 % (the benchmark averages over libraries, docs/library.md); a
    # predictive that dropped the spread between combinations (hyperparameter uncertainty only) would cover
    # ~25 % of them, the 90 % interval of the true population 90 %
    a, b, s = _TYPES["ER32"]
    lo, hi = np.quantile(zp, [0.05, 0.95], axis=0)
    median = np.array(a) + np.array(b) * np.log(1.2)
    assert np.all((lo < median) & (median < hi)), (lo, median, hi)
    truth = median + s * np.random.default_rng(25).standard_normal((40, 2))
    covered = int(np.sum((truth >= lo) & (truth <= hi)))
    assert covered >= 52, (covered, lo, hi)  # of 80 (40 combinations x 2 stiffnesses), 65 %


# -- the predictive of a new combination ------------------------------------------------------------------


def test_population_predictive_of_a_new_combination(clean_fit):
    setups, hyper, res = clean_fit
    pop = Population(NAMES2, {t: f.flat for t, f in res.types.items()}, BOX2, (0.02, 0.045, 1.5),
                     {"ER32": (0.006, 0.018), "HSK": (0.008, 0.020)})
    rng = np.random.default_rng(8)
    z, warns = predictive_draws(pop, "HSK", 0.010, rng, 4000)
    assert np.all((z >= BOX2[:, 0]) & (z <= BOX2[:, 1]))
    # the HSK setups scatter around 7 + 1.5 ln(d / 10 mm): the predictive at 10 mm is centred near 7, about
    # as wide as the scatter between combinations (0.06 decade) plus the hyperparameters' uncertainty
    assert abs(np.median(z[:, 0]) - 7.0) < 0.1 and 0.04 < np.std(z[:, 0]) < 0.5
    joint, _ = predictive_prior(pop, "HSK", 0.010, rng)
    assert joint.names == NAMES2 and joint.scales == ("log10", "linear") and joint.lo == (4.0, 0.0)
    _, warns = predictive_draws(pop, "HSK", 0.004, rng, 100)
    assert any("extrapolates" in w for w in warns)
    with pytest.raises(SetupError, match=r"'BT40' is not in the library's population \(known: \['ER32', 'HSK'\]\)"):
        predictive_draws(pop, "BT40", 0.010, rng, 10)
    with pytest.raises(SetupError, match="mixed units"):
        predictive_draws(pop, "HSK", 10.0, rng, 10)
