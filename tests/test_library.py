"""The tool-library population model (#20): joint prior, stage 2 against the joint model, ESS, outliers.

Cheap stand-ins: stage-1 "posteriors" are Gaussian draws from a known likelihood (so the joint model can
be sampled exactly), one or two pooled coordinates, few setups.  The statistical campaigns on the
finite-element bench are in benchmarks/library.py and docs/library.md.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from bayes_rcsa.errors import SetupError
from bayes_rcsa.library.joint import gaussian_log_likelihood, sample_joint
from bayes_rcsa.library.outliers import flag_outliers, loo_p_values
from bayes_rcsa.library.population import Hyperprior, covariate
from bayes_rcsa.library.predictive import Population, predictive_draws, predictive_prior
from bayes_rcsa.library.stage2 import SetupDraws, Stage2Settings, fit_population, fit_type, surrogate
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


def test_two_stage_hyperparameters_match_joint_emcee_on_four_combinations():
    rng = np.random.default_rng(11)
    names, box = NAMES2[:1], WIDE[:1]
    hyper = Hyperprior.from_box(names, BOX2[:1], 1.5)
    dia = np.array([0.006, 0.009, 0.013, 0.018])
    setups, exact = _setups(rng, dia, ["T"] * 4, names=names, box=box, spread=0.15)
    sur = [surrogate(s) for s in setups]
    x = covariate(dia)
    fit = fit_type("T", [s.name for s in setups], x, np.array([m for m, _, _ in sur]), np.array([C for _, C, _ in sur]),
                   hyper, rng, Stage2Settings(ess_target=3000))
    joint = sample_joint([gaussian_log_likelihood(m, C) for m, C in exact], x, hyper, rng, n_steps=3000,
                         n_burn=1500, n_walkers=48)
    two = fit.flat
    for j, label in enumerate(("a", "b", "sigma")):
        qj = np.quantile(joint[:, j], [0.05, 0.5, 0.95])
        q2 = np.quantile(two[:, j], [0.05, 0.5, 0.95])
        sd = np.std(joint[:, j])
        # acceptance: medians within 0.2 posterior sd; 90 % ends within 10 % (of the joint interval's width,
        # since b's interval straddles 0 and a relative error of its ends is meaningless)
        assert abs(q2[1] - qj[1]) < 0.2 * sd, (label, q2, qj)
        assert np.all(np.abs(q2[[0, 2]] - qj[[0, 2]]) < 0.1 * (qj[2] - qj[0])), (label, q2, qj)


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


@pytest.fixture(scope="module")
def clean_fit():
    """Eight setups in two holder types.  As on the bench, each setup's own data pin its law down much more
    tightly (sd ~0.01 decade) than the laws scatter between combinations (0.06 decade)."""
    rng = np.random.default_rng(5)
    dia = np.array([0.006, 0.008, 0.010, 0.012, 0.014, 0.016, 0.018, 0.020])
    setups, _ = _setups(rng, dia, ["ER32", "HSK"] * 4, n_draws=800, box=BOX2, c_scale=0.01)
    hyper = Hyperprior.from_box(NAMES2, BOX2, 1.5)
    res = fit_population(setups, hyper, rng, Stage2Settings(n_burn=200, ess_target=200))
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
    res2 = fit_population(er32 + [bad], hyper, rng, Stage2Settings(n_burn=200, ess_target=200))
    row = next(r for r in res2.setups if r["name"] == "bad")
    assert row["refused"] is not None and "importance ESS" in row["refused"] and "k_xf_pooled" not in row, row
    assert any("setup bad" in w for w in res2.warnings)


def test_a_contact_three_times_softer_is_flagged_and_its_clean_neighbours_are_not():
    # one holder type, five combinations; the third is clamped badly: both stiffnesses 3x softer
    names = ("k_xf", "k_thetaM")
    box = np.array([[4.0, 10.0], [2.0, 9.0]])
    hyper = Hyperprior.from_box(names, box, 1.5)
    rng = np.random.default_rng(9)
    dia = np.array([0.006, 0.009, 0.012, 0.016, 0.020])
    settings = Stage2Settings(n_burn=150, ess_target=150, chunk=150)
    flagged_runs = []
    for shift in ((2, -np.log10(3.0)), None):
        setups, _ = _setups(rng, dia, ["ER32"] * 5, shift=shift, n_draws=400, names=names, box=box, c_scale=0.01)
        res = fit_population(setups, hyper, rng, settings)
        rows, warns = flag_outliers(loo_p_values(res.types["ER32"], hyper, rng, settings=settings), len(setups))
        assert all(r["method"] == "exact" for r in rows)
        flagged_runs.append({r["name"] for r in rows if r["outlier"]})
    assert flagged_runs == [{"s2"}, set()], flagged_runs


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
