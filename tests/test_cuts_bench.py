"""Cut outcomes from the bench's truth (synthetic/cuts.py, synthesize --cuts) and the next-cut ranking (#23)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main as cli
from bayes_rcsa.cuts.next_cut import (best_safe_mrr, candidate_grid, map_uncertainty, p_stable_matrix,
                                      parse_next_cut_target, rank_next_cuts)
from bayes_rcsa.errors import SetupError
from bayes_rcsa.stability import CuttingConditions, mean_directional_matrix, zoa_lobes
from bayes_rcsa.stability.tests_io import read_cutting_tests
from bayes_rcsa.synthetic import default_bench_config
from bayes_rcsa.synthetic.cuts import (CutPlan, cuts_truth_document, generate_cuts, label_cuts,
                                       quadrature_directional_matrix, root_depth_limit, true_cut_frfs,
                                       true_depth_limit, write_cuts)

PLAN = CutPlan(n_cuts=12, clamping_length=0.030, depth_range=(5e-6, 8e-5), frequency_step=2.0)


@pytest.fixture(scope="module")
def bench():
    cfg = default_bench_config()
    return cfg, generate_cuts(cfg, PLAN, np.random.default_rng(3))


def test_outcomes_follow_the_true_limit(bench):
    cfg, cuts = bench
    lim = true_depth_limit(cfg, PLAN, cuts.speed_rpm)
    np.testing.assert_allclose(cuts.true_limit_at_cuts, lim, rtol=1e-12)
    assert np.array_equal(cuts.stable, cuts.depth_m < lim)  # no label noise: exact labels
    assert 0 < cuts.stable.sum() < cuts.stable.size  # the default box straddles the boundary
    # just below / above the true limit at the same speeds
    below, _ = label_cuts(0.98 * lim, lim, 0.0, np.random.default_rng(0))
    above, _ = label_cuts(1.02 * lim, lim, 0.0, np.random.default_rng(0))
    assert below.all() and not above.any()


def test_wrong_coefficients_move_the_truth_as_zoa_predicts(bench):
    cfg, cuts = bench
    # ZOA: H0 is linear in (K_t, K_r), so scaling both by (1 + e) scales every limit by 1 / (1 + e)
    other = CutPlan(**{**PLAN.__dict__, "kt_error": -0.2, "kr_error": -0.2})
    lim = true_depth_limit(cfg, other, cuts.map_speed_rpm)
    finite = np.isfinite(lim)
    np.testing.assert_allclose(lim[finite], cuts.map_limit_m[finite] * 1.2 / 0.8, rtol=1e-9)


def test_truth_map(bench):
    _, cuts = bench
    assert cuts.map_stable.shape == (50, 50)
    assert np.array_equal(cuts.map_stable, cuts.map_depth_m[None, :] < cuts.map_limit_m[:, None])
    assert 0.05 < cuts.map_stable.mean() < 0.95  # the map shows both regions


def test_own_zoa_agrees_with_the_project_zoa():
    cfg = default_bench_config()
    cut = CuttingConditions(kt=PLAN.kt_true, kr=PLAN.kr_true, flutes=4, radial_immersion=0.95, milling="down",
                            feed="y")
    e, x = PLAN.angles
    h0 = quadrature_directional_matrix(PLAN.kt_true, PLAN.kr_true, 4, e, x, "y")
    # trapezoidal rule on 4001 angles against the closed form: error ~ (pi/4000)^2
    np.testing.assert_allclose(h0, mean_directional_matrix(cut), rtol=1e-6, atol=1e-6 * np.abs(h0).max())
    f = np.arange(600.0, 1400.0, 1.0)
    gx, gy = true_cut_frfs(cfg, 0.030, f)
    speeds = np.linspace(6000, 20000, 30)
    mine = root_depth_limit(gx, gy, f, h0, 4, speeds)
    ref = zoa_lobes(gx, gy, f, cut, speeds).depth_limit_m
    assert np.array_equal(np.isfinite(mine), np.isfinite(ref))
    # different algorithms (roots in frequency vs. lobe envelope in speed) on a 1 Hz grid: linear interpolation
    # error of either, measured 8e-4 at most
    np.testing.assert_allclose(mine[np.isfinite(ref)], ref[np.isfinite(ref)], rtol=5e-3)


def test_label_noise_is_a_probit_in_the_log_depth_ratio():
    lim = np.full(4000, 1e-4)
    rng = np.random.default_rng(1)
    at, p = label_cuts(lim, lim, 0.1, rng)
    assert np.allclose(p, 0.5)
    assert 0.45 < 1 - at.mean() < 0.55  # binomial(4000, 0.5): 5 sigma is 0.04
    far, p_far = label_cuts(0.5 * lim, lim, 0.1, rng)  # ln 0.5 / 0.1 = -6.9 sigma
    assert far.all() and p_far.max() < 1e-10


def test_csv_and_truth_files(bench, tmp_path):
    _, cuts = bench
    csv_path, truth_path = write_cuts(cuts, tmp_path, seed=3)
    speed, depth, stable = read_cutting_tests(csv_path)
    np.testing.assert_array_equal(speed, cuts.speed_rpm)
    np.testing.assert_array_equal(depth, cuts.depth_m)
    np.testing.assert_array_equal(stable, cuts.stable)
    doc = json.loads(truth_path.read_text())
    assert doc["kt_true"] == pytest.approx(1.2 * doc["kt_assumed"])
    assert np.array_equal(np.array(doc["map"]["stable"], dtype=bool), cuts.map_stable)
    assert doc == json.loads(json.dumps(cuts_truth_document(cuts, 3)))


def test_synthesize_cuts_cli(tmp_path, capsys):
    out = tmp_path / "c"
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[campaign]\nclamping_lengths = [0.030]\ndirections = ['x', 'y']\n")
    assert cli(["synthesize", str(cfg), "--out", str(tmp_path / "bad"), "--cuts", "3", "--cut-depths", "1:4"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "millimetres" in err[0]
    assert not (tmp_path / "bad").exists()  # no partial output
    assert cli(["synthesize", str(cfg), "--out", str(tmp_path / "bad"), "--cuts", "3", "--artifact"]) == 2
    assert "--artifact" in capsys.readouterr().err and not (tmp_path / "bad").exists()
    assert cli(["synthesize", str(cfg), "--out", str(out), "--cuts", "4", "--cut-depths", "5e-6:8e-5"]) == 0
    speed, depth, stable = read_cutting_tests(out / "cuts.csv")
    assert speed.size == 4 and (out / "cuts_truth.json").is_file() and (out / "setup.toml").is_file()
    # the default truth is the project's SDM on the true FRFs, not the ZOA the cut likelihood uses
    assert json.loads((out / "cuts_truth.json").read_text())["method"].startswith("sdm")


def test_sdm_truth_and_the_benchs_own_zoa_label_the_same_cuts(bench):
    """Two methods on the same noise-free FRFs: SDM (time-varying directional matrix) and the bench's ZOA
    (tooth-pass average) agree where ZOA is good (immersion 0.95, four flutes): limits within 15 % (SDM finds
    a few narrow flip-lobe dips ZOA cannot) and the same label for almost every map cell."""
    from bayes_rcsa.cuts.truth import SDM_TRUTH, sdm_true_limit

    cfg, zoa = bench
    sdm = generate_cuts(cfg, PLAN, np.random.default_rng(3), true_limit=sdm_true_limit(PLAN), truth_method=SDM_TRUTH)
    assert sdm.truth_method == SDM_TRUTH and zoa.truth_method.startswith("zoa")
    np.testing.assert_array_equal(sdm.speed_rpm, zoa.speed_rpm)  # the same cuts, labelled twice
    finite = np.isfinite(zoa.map_limit_m) & np.isfinite(sdm.map_limit_m)
    ratio = sdm.map_limit_m[finite] / zoa.map_limit_m[finite]
    assert np.median(np.abs(ratio - 1)) < 0.02 and np.all(np.abs(ratio - 1) < 0.15), ratio
    assert np.mean(sdm.map_stable == zoa.map_stable) > 0.97


# ------------------------------------------------------------------ next cut --
def _toy(n_draws=400, seed=0):
    """Draws of a flat limit a_lim,d = c / K_t,d (K_t lognormal 30 %), a map and candidate cuts."""
    rng = np.random.default_rng(seed)
    kt = np.exp(rng.normal(0.0, 0.3, n_draws))
    base = np.array([1.0, 2.0, 1.5])  # limit at three speeds for K_t = 1 (mm-like units in m)
    speeds = np.array([1000.0, 2000.0, 3000.0])
    cs, ca = candidate_grid((1000.0, 3000.0), (0.05, 4.0), 3, 12)
    cand_lim = base[np.searchsorted(speeds, cs)][None, :] / kt[:, None]
    map_depth = np.linspace(0.05, 4.0, 40)
    return kt, speeds, cs, ca, cand_lim, map_depth, base[None, :] / kt[:, None]


def test_next_cut_exact_expectation_and_uninformative_cut():
    kt, speeds, cs, ca, cl, md, ml = _toy()
    r = rank_next_cuts(parse_next_cut_target("map"), cs, ca, cl, speeds, md, ml, boundary_width=0.05)
    by = {(c.speed_rpm, c.depth_m): c for c in r.candidates}
    # brute force for one candidate: enumerate the two outcomes
    i = 17
    p = p_stable_matrix(ca[i:i + 1], cl[:, i:i + 1], 0.05)[:, 0]
    ind = (md[None, None, :] < ml[:, :, None]).reshape(len(kt), -1)
    w = np.full(len(kt), 1 / len(kt))
    ps = w @ p
    u = ps * map_uncertainty((w * p) @ ind / ps) + (1 - ps) * map_uncertainty((w * (1 - p)) @ ind / (1 - ps))
    assert by[(cs[i], ca[i])].expected == pytest.approx(u, rel=1e-12)
    # a cut far below every draw's limit teaches nothing; the best cut sits near the median limit
    shallow = by[(cs[0], ca[0])]
    assert shallow.p_chatter < 1e-6 and abs(shallow.gain) < 1e-6
    best = r.best
    assert best.gain > 0.05
    med = np.median(ml[:, np.searchsorted(speeds, best.speed_rpm)])
    assert 0.5 * med < best.depth_m < 2.0 * med


def test_next_cut_respects_the_risk_budget():
    kt, speeds, cs, ca, cl, md, ml = _toy()
    free = rank_next_cuts(parse_next_cut_target("map"), cs, ca, cl, speeds, md, ml, boundary_width=0.05)
    budget = 0.1
    r = rank_next_cuts(parse_next_cut_target("map"), cs, ca, cl, speeds, md, ml, boundary_width=0.05,
                       risk_budget=budget)
    assert free.best.p_chatter > budget  # without a budget the most informative cut is a coin toss
    assert r.best.p_chatter <= budget and r.best.gain > 0
    assert all(c.p_chatter <= budget for c in r.candidates if c.allowed)
    assert all(not c.allowed for c in r.candidates if c.p_chatter > budget + 1e-12)
    none = rank_next_cuts(parse_next_cut_target("map"), cs, ca + 10.0, cl, speeds, md, ml, risk_budget=0.01)
    assert none.best is None and any("risk budget" in w for w in none.warnings)


def test_next_cut_depth_and_mrr_targets():
    kt, speeds, cs, ca, cl, md, ml = _toy()
    d = rank_next_cuts(parse_next_cut_target("depth@2000"), cs, ca, cl, speeds, md, ml, boundary_width=0.05,
                       target_limits_m=ml[:, 1])
    # the limit at 2000 rpm is what a cut at 2000 rpm measures directly; elsewhere it is learnt through K_t only,
    # which here is the same information: the best gain is positive and the current width is the prior's
    assert d.best.gain > 0
    assert d.current == pytest.approx(np.quantile(ml[:, 1], 0.95) - np.quantile(ml[:, 1], 0.05), rel=0.05)
    m = rank_next_cuts(parse_next_cut_target("mrr@0.9"), cs, ca, cl, speeds, md, ml, boundary_width=0.05)
    p_now = np.mean(md[None, None, :] < ml[:, :, None], axis=0).ravel()
    assert m.current == pytest.approx(best_safe_mrr(p_now, (speeds[:, None] * md[None, :]).ravel(), 0.9))
    assert m.best.gain > 0
    with pytest.raises(SetupError):
        parse_next_cut_target("mrr@1.5")


# ------------------------------------------------------- design --next-cut (CLI) --
from test_cuts_cli import world  # noqa: E402,F401  (the stand-in posterior and cuts of the update tests)

NEXT = ["--next-cut", "--clamping-length", "0.03", "--kt", "600e6±30%", "--kr", "180e6", "--flutes", "4",
        "--radial-immersion", "0.5", "--draws", "60", "--particles", "2", "--speeds", "7000:17000:6"]


def test_design_next_cut_cli(world, tmp_path, capsys):  # noqa: F811
    setup, post = str(world / "data" / "setup.toml"), str(world / "posterior.nc")
    out = tmp_path / "nc"
    argv = ["design", setup, "--posterior", post, *NEXT, "--depths", "5e-6:3e-4:8", "--cuts", str(world / "cuts.csv"),
            "--risk-budget", "0.3", "--out", str(out)]
    assert cli(argv) == 0
    doc = json.loads((out / "design.json").read_text())
    assert (out / "design.png").is_file() and "warnings" in doc and doc["inputs"]["n_cuts_so_far"] == 6
    assert doc["best"] is not None and doc["best"]["p_chatter"] <= 0.3
    assert all(c["p_chatter"] <= 0.3 + 1e-12 for c in doc["candidates"] if c["allowed"])
    assert len(doc["candidates"]) == 6 * 8 and np.shape(doc["map"]["p_stable"]) == (50, 50)
    capsys.readouterr()
    for bad, word in ((["--depths", "1:4"], "metres"), (["--depths", "5e-6:3e-4", "--speeds", "5000:90000"], "band"),
                      (["--depths", "5e-6:3e-4", "--risk-budget", "2"], "risk-budget")):
        assert cli(["design", setup, "--posterior", post, *NEXT, *bad, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0], err
        assert not (tmp_path / "bad").exists()


# ------------------------------------- cut sequences: map error and designed vs random (reduced acceptance) --
# A stand-in for benchmarks/cuts.py's races (docs/stability.md, "Cutting tests: benchmark"): the "posterior" is
# 400 draws of a lobed limit curve, uncertain in the mode (2 %, what the hammer test leaves) and in K_t (the ±30 %
# prior); the truth's K_t is 20 % off the assumed value.  Unlike _toy() (K_t only, a flat limit per speed), the
# boundary has pockets the cuts must find in speed as well as depth.  Weights come from the package's probit
# (outcome_log_likelihood, default width and label error) and normalise_log_weights; the designed cuts from
# rank_next_cuts (map target) on the current weights; outcomes from the truth (label_cuts, no noise).
RACE_SEEDS = (0, 1, 2)  # even seeds: truth cuts 20 % harder (K_t x 1.2); odd: 20 % softer (x 0.8)


def _lobes(speed, mode, kt):
    """(D, S) limits: floor 0.5 / K_t with pockets up to 2 / K_t where speed / mode is near an integer."""
    return (0.5 + 1.5 * np.clip(np.cos(2 * np.pi * speed[None, :] / mode[:, None]), 0, None) ** 4) / kt[:, None]


def _race_world(seed, n_draws=400, mode_sd=0.02):
    rng = np.random.default_rng(seed)
    mode = np.exp(rng.normal(0.0, mode_sd, n_draws))
    kt = np.exp(rng.normal(0.0, 0.3, n_draws))
    truth = (np.exp(rng.normal(0.0, 0.02, 1)), np.array([1.2 if seed % 2 == 0 else 0.8]))
    ms, md = np.linspace(1.0, 3.0, 40), np.linspace(0.05, 2.5, 40)
    cs, ca = candidate_grid((1.0, 3.0), (0.05, 2.5), 15, 10)
    return {"cs": cs, "ca": ca, "ms": ms, "md": md, "cand_lim": _lobes(cs, mode, kt), "map_lim": _lobes(ms, mode, kt),
            "true_cand": _lobes(cs, *truth)[0], "truth_map": md[None, :] < _lobes(ms, *truth)[0][:, None],
            "hammer_lim": _lobes(ms, mode, np.ones(n_draws))}  # hammer only: the assumed K_t


def _map_error(limits, weights, world):
    p = np.einsum("n,nsa->sa", weights, world["md"][None, None, :] < limits[:, :, None])
    return float(np.mean(np.abs(p - world["truth_map"])))


def _cut_sequence(world, strategy, rng, n_cuts):
    """Map error after each of ``n_cuts`` cuts made one at a time (``next``: rank_next_cuts; else uniform)."""
    from bayes_rcsa.cuts.likelihood import outcome_log_likelihood
    from bayes_rcsa.cuts.update import normalise_log_weights

    ll = np.zeros(world["cand_lim"].shape[0])
    errors = []
    for _ in range(n_cuts):
        if strategy == "next":
            r = rank_next_cuts(parse_next_cut_target("map"), world["cs"], world["ca"], world["cand_lim"],
                               world["ms"], world["md"], world["map_lim"], normalise_log_weights(ll))
            b = r.best or r.candidates[0]  # no positive gain left: the top-ranked cut, as benchmarks/cuts.py
            i = int(np.flatnonzero((world["cs"] == b.speed_rpm) & (world["ca"] == b.depth_m))[0])
        else:
            i = int(rng.integers(world["cs"].size))
        stable, _ = label_cuts(world["ca"][i:i + 1], world["true_cand"][i:i + 1], 0.0, rng)
        ll = ll + outcome_log_likelihood(world["ca"][i], world["cand_lim"][:, i], ~stable[0])
        errors.append(_map_error(world["map_lim"], normalise_log_weights(ll), world))
    return np.array(errors)


@pytest.fixture(scope="module")
def races():
    out = {}
    for seed in RACE_SEEDS:
        w = _race_world(seed)
        n = w["hammer_lim"].shape[0]
        out[seed] = {"hammer": _map_error(w["hammer_lim"], np.full(n, 1 / n), w),
                     "prior": _map_error(w["map_lim"], np.full(n, 1 / n), w),
                     "next": _cut_sequence(w, "next", np.random.default_rng([seed, 1]), 10),
                     "random": _cut_sequence(w, "random", np.random.default_rng([seed, 1]), 20)}
    return out


def _cuts_to(errors, target):
    """Cuts until the map error is <= target; len + 1 when never reached."""
    hit = np.flatnonzero(errors <= target)
    return int(hit[0]) + 1 if hit.size else errors.size + 1


def test_ten_designed_cuts_halve_the_map_error(races):
    for seed, r in races.items():
        # the ±30 % K_t prior alone widens the boundary: worse than the hammer test at the assumed K_t, so
        # the halving below is the cuts' work (without the re-weighting the error stays at r["prior"])
        assert r["prior"] > r["hammer"] > 0.05, (seed, r["hammer"], r["prior"])
        # measured ratios 0.17-0.34 over dev seeds 0-9 (0.25, 0.27, 0.17 here): 0.5 is the acceptance item
        # and leaves a wide margin; asserted for every seed
        assert r["next"][-1] <= 0.5 * r["hammer"], (seed, r["next"][-1], r["hammer"])


def test_designed_cuts_reach_the_map_error_sooner_than_random(races):
    designed = [_cuts_to(r["next"], 0.5 * r["hammer"]) for r in races.values()]
    random = [_cuts_to(r["random"], 0.5 * r["hammer"]) for r in races.values()]
    # dev seeds 0-9: designed cuts reach half the hammer-only error in 4-6 cuts, random cuts from the same
    # candidate grid in 15-20 or not within 20 (most land deep in the chatter region).  Designed <= 8 in every
    # seed fails if rank_next_cuts proposed a random candidate (random reached it within 8 in none of 10; with
    # the ranking swapped for a random candidate this test failed in 100 of 100 replicates);
    # "fewer in >= 2 of 3" is the reduced acceptance item (4 of 5 campaigns in the benchmark)
    assert max(designed) <= 8, designed
    assert sum(d < r for d, r in zip(designed, random)) >= 2, (designed, random)


def test_the_hammer_prior_needs_fewer_cuts_than_a_generic_modal_prior(races):
    """Reduced 'against the anchor': the same designed race from a generic modal prior (mode frequency spread
    20 %, as with no hammer test; the Cornelius/Schmitz setting) against the hammer-test prior (2 %), to the
    same map error (half the hammer-only error).  The truth is the same draw of the same world (same seed)."""
    hammer, generic = [], []
    for seed, r in races.items():
        w = _race_world(seed, mode_sd=0.2)
        errors = _cut_sequence(w, "next", np.random.default_rng([seed, 1]), 20)
        target = 0.5 * r["hammer"]
        hammer.append(_cuts_to(r["next"], target))
        generic.append(_cuts_to(errors, target))
    # the benchmark's anchor reached that error within 20 cuts in 1 of 5 campaigns (the hammer prior: 3 cuts);
    # here fewer cuts from the hammer prior in every seed
    assert all(h < g for h, g in zip(hammer, generic)), (hammer, generic)
