"""The importance-sampling check of a chain's interval ends (inference/tail_check.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from bayes_rcsa.inference.tail_check import TOLERANCE_SD, importance_tail_check

COV = np.array([[1.0, 0.6], [0.6, 2.0]])
MEAN = np.array([3.0, -1.0])
TARGET = stats.multivariate_normal(MEAN, COV)


def lp(x):
    return TARGET.logpdf(x)


def test_exact_draws_are_consistent_and_the_ends_are_recovered():
    rng = np.random.default_rng(21)
    draws = TARGET.rvs(4000, random_state=rng)
    r = importance_tail_check(lp, draws, ["a", "b"], rng, n=40_000)
    assert r["verdict"] == "consistent" and r["pareto_k"] < 0.7 and r["ess"] > 5000
    # the importance estimate of each 95 % point is within 0.05 sd of the exact one (ESS > 5000: its Monte
    # Carlo error is about 0.02 sd)
    for j, name in enumerate(("a", "b")):
        exact = MEAN[j] + 1.6448536 * np.sqrt(COV[j, j])
        assert r["parameters"][name]["importance"][1] == pytest.approx(exact, abs=0.05 * np.sqrt(COV[j, j]))


def test_a_chain_that_missed_a_tail_is_caught_and_named():
    # the chain's draws of the same target without its upper 10 % in "a" (a sampler that never entered that
    # tail): its 95 % point of "a" is the target's 85.5 % point, 0.59 sd low; "b" is barely touched
    rng = np.random.default_rng(22)
    draws = TARGET.rvs(8000, random_state=rng)
    draws = draws[draws[:, 0] < np.quantile(draws[:, 0], 0.90)]
    r = importance_tail_check(lp, draws, ["a", "b"], rng, n=40_000)
    assert r["verdict"] == "disagrees" and "a:" in r["reason"] and "b:" not in r["reason"]
    assert r["parameters"]["a"]["shift_sd"] > TOLERANCE_SD >= r["parameters"]["b"]["shift_sd"]


def test_no_verdict_where_the_proposal_cannot_cover_the_posterior():
    # the posterior lives in a sliver the draws' t proposal almost never hits
    rng = np.random.default_rng(23)
    draws = TARGET.rvs(2000, random_state=rng)
    r = importance_tail_check(lambda x: np.where(np.abs(x[:, 0] - 3.0) < 1e-4, 0.0, -np.inf), draws, ["a", "b"], rng,
                              n=20_000)
    assert r["verdict"] == "unreliable" and "inside the prior" in r["reason"]


def test_identify_tail_check_is_on_by_default_and_part_of_the_reported_convergence(example, tmp_path):
    from bayes_rcsa.cli.main import main

    out = tmp_path / "fit"
    # the check of a chain (an accepted importance-sampling posterior, the default, is its own check)
    rc = main(["identify", str(example), "--lengths", "0.025,0.040", "--out", str(out), "--quiet", "--max-steps", "300",
               "--check-every", "100", "--walkers", "18", "--no-plots", "--sampler", "mcmc"])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    tc = s["tail_check"]
    assert tc["verdict"] in ("consistent", "disagrees", "unreliable") and np.isfinite(tc["pareto_k"])
    assert set(tc["parameters"]) == set(s["parameter_names"])
    assert f"within {TOLERANCE_SD} posterior sd" in tc["rule"] and "{" not in tc["rule"]  # the rule as applied
    # every warning printed also goes into the JSON output; only a disagreement is one (no verdict says nothing)
    assert any(w.startswith("tail check") for w in s["warnings"]) == (tc["verdict"] == "disagrees")
    # part of the reported convergence: a disagreement makes the run not converged, with the reason
    conv = s["convergence"]
    assert conv["tail_check"]["verdict"] == tc["verdict"] and conv["converged"] is s["converged"]
    assert s["converged"] == (conv["chain"]["converged"] and tc["verdict"] != "disagrees")
    assert ("tail check:" in conv["reason"]) == (tc["verdict"] == "disagrees")
    # on by default (with as many importance draws as the chain's evaluations, 2e4-1e5), off on request
    out2 = tmp_path / "fit2"
    assert main(["identify", str(example), "--lengths", "0.025,0.040", "--out", str(out2), "--quiet", "--max-steps",
                 "300", "--check-every", "100", "--walkers", "18", "--no-plots", "--no-tail-check", "--sampler",
                 "mcmc"]) == 0
    s2 = json.loads((out2 / "summary.json").read_text())
    assert "tail_check" not in s2 and s2["convergence"]["tail_check"]["verdict"] == "not run"
    assert s2["converged"] is s2["convergence"]["converged"] is s2["convergence"]["chain"]["converged"]
    assert tc["n"] == min(max(s["timing"]["log_posterior_evaluations"], 20_000), 100_000)
