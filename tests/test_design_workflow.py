"""Acceptance tests of ``bayes-rcsa design`` (issue #15) on a synthetic bench campaign.

One campaign (tests/test_design_support.py: independent FE bench, truth drawn
from the setup's prior, no hidden effect) with measurements at 25, 27, 35
and 40 mm; two fits: 25 mm only, and 25 + 40 mm.  The replicated version
(five seeds, timing) is benchmarks/design.py.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.design import NoiseLevel, design_from_draws, parse_candidates, parse_target
from bayes_rcsa.design.targets import TargetEvaluator
from bayes_rcsa.design.workflow import WORTH_IT_FRACTION, noise_level
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.posterior import draws_from_result, load_posterior
from bayes_rcsa.posterior.growth_prior import feasible_growth_law, with_growth_prior

from test_design_support import campaign, fit

SEED = 1  # the seed whose realised width benchmarks/design.py reports (see docs/design.md)
TARGET = "frequency@0.035"


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """The campaign and the 25-mm-only fit (the non-slow tests need only these)."""
    tmp = tmp_path_factory.mktemp("design")
    _, setup_path = campaign(SEED, tmp / "campaign")
    _, post25 = fit(setup_path, (0.025,), tmp / "fit25", SEED)
    return {"setup": setup_path, "post25": post25, "tmp": tmp}


@pytest.fixture(scope="module")
def bench2540(bench):
    """The 25 + 40 mm fit of the same campaign (the realised width, and the 'not worth it' case)."""
    res2540, post2540 = fit(bench["setup"], (0.025, 0.040), bench["tmp"] / "fit2540", SEED)
    return {**bench, "post2540": post2540, "res2540": res2540}


def _design(capsys, args):
    rc = main(["design", *map(str, args)])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.slow
def test_far_length_preferred_and_realised_width_within_prediction(bench2540, capsys):
    bench = bench2540
    out = bench["tmp"] / "d25"
    rc, stdout, err = _design(capsys, [bench["setup"], "--posterior", bench["post25"], "--candidates", "0.027,0.040",
                                      "--target", TARGET, "--out", out, "--seed", 3])
    assert rc == 0, err
    doc = json.loads((out / "design.json").read_text())
    assert (out / "design.png").is_file()
    assert doc["target"] == TARGET and doc["unit"] == "Hz"
    widths = [c["expected_width"] for c in doc["candidates"]]
    assert widths == sorted(widths)  # best first
    assert doc["best"]["clamping_length"] == pytest.approx(0.040)
    c40, c27 = doc["candidates"]
    # far beats near by more than both Monte Carlo errors together (measured: ~0.26 vs ~2.3 Hz)
    assert c27["expected_width"] - c40["expected_width"] > 3 * np.hypot(c27["mc_error"], c40["mc_error"])
    # a 25-mm-only posterior transfers to 35 mm with the growth law's prior uncertainty: tens of Hz
    assert doc["current_width"] > 20 * c40["expected_width"]
    assert doc["worth_it"] is True and "measure x 40 mm" in doc["verdict"]
    # realised: the campaign holds the 40-mm measurement; the 25+40 mm fit's 90 % width at 35 mm
    setup = load_setup(bench["setup"])
    d = draws_from_result(bench["res2540"])
    t = TargetEvaluator(parse_target(TARGET), d.parameters, setup.model(), setup, "x", "tool", None, d.values)(d.values)
    t = t[np.isfinite(t[:, 0]), 0]
    realised = float(np.quantile(t, 0.95) - np.quantile(t, 0.05))
    lo, hi = c40["width_interval_95"]
    # the realised width is itself a Monte Carlo estimate (docs/design.md: ~5-7 % sampling error): like with like,
    # the stated interval is compared with it up to two of its standard errors.  se of a quantile q_p from an
    # effective sample of n: sqrt(p (1 - p) / n) / f(q_p), the density f from the empirical quantile function's
    # slope over p +- 0.02.  (Measured after scipy 1.16 -> 1.17 moved the fit's random path: realised 0.2498
    # against the interval's upper end 0.2486; two standard errors here 0.0115, 4.6 %.)
    ess = min(v["ess_bulk"] for v in bench["res2540"].summary["parameters"].values())
    ess = min(float(ess), t.size) if ess is not None and np.isfinite(ess) else float(t.size)

    def se(p):
        slope = (np.quantile(t, p + 0.02) - np.quantile(t, p - 0.02)) / 0.04
        return np.sqrt(p * (1 - p) / ess) * slope

    tol = 2.0 * float(np.hypot(se(0.05), se(0.95)))
    assert tol < 0.1 * realised, (tol, realised, ess)  # the allowance stays a small correction
    assert lo - tol <= realised <= hi + tol, (realised, lo, hi, tol)


@pytest.mark.slow
def test_third_length_not_worth_it_after_25_and_40(bench2540, capsys):
    bench = bench2540
    out = bench["tmp"] / "d2540"
    rc, stdout, err = _design(capsys, [bench["setup"], "--posterior", bench["post2540"], "--candidates",
                                      "0.027,0.030,0.035", "--target", TARGET, "--out", out, "--json"])
    assert rc == 0, err
    doc = json.loads((out / "design.json").read_text())
    assert doc["worth_it"] is False
    assert doc["relative_gain"] < WORTH_IT_FRACTION
    assert "not worth it" in json.loads(stdout)["verdict"]  # --json: one object on stdout
    assert "not worth it" in err  # the one human line on stderr


def test_importance_and_laplace_agree_when_weights_do_not_collapse(bench):
    """One case where the importance weights keep a large ESS: both estimators must agree.

    Five times the fit's noise keeps the median ESS near 100 of 1500 draws
    for the 27-mm candidate; measured 6.7 (importance) vs 7.1 Hz (Laplace).
    Tolerance 20 %: the growth prior is uniform, the Laplace approximation
    Gaussian, and each carries a few % Monte Carlo error.
    """
    setup = load_setup(bench["setup"])
    rng = np.random.default_rng(0)
    draws = with_growth_prior(load_posterior(bench["post25"], setup).subset(1500, rng), feasible_growth_law(setup), rng)
    base = noise_level(draws, 0.01, 1.0)
    noise = NoiseLevel(5 * base.scale, base.floor, 1.0)
    cands = parse_candidates("0.027", setup, feasible_growth_law(setup))
    r = design_from_draws(setup, draws, parse_target(TARGET), cands, noise, np.random.default_rng(1), 120, "auto")
    c = r.candidates[0]
    assert not c.importance.collapsed and c.importance.ess_median > 50
    assert c.estimate.method == "importance"
    assert c.laplace.expected_width == pytest.approx(c.importance.expected_width, rel=0.2)


def test_no_data_mode_plans_the_two_extreme_lengths(bench, capsys):
    out = bench["tmp"] / "plan"
    rc, stdout, err = _design(capsys, [bench["setup"], "--out", out, "--truths", 40, "--candidates",
                                      "0.025,0.030,0.035,0.040", "--no-plots"])
    assert rc == 0, err
    doc = json.loads((out / "design.json").read_text())
    assert doc["mode"] == "prior"
    assert doc["best"]["clamping_lengths"] == pytest.approx([0.025, 0.040])
    assert len(doc["candidates"]) == 6  # every pair of four lengths
    assert doc["candidates"][0]["expected_width"] < doc["current_width"]


@pytest.mark.parametrize("args, needle", [
    (["--candidates", "0.027,0.045", "--target", TARGET], "outside the feasible clamping range"),
    (["--candidates", "tool:nope@0.030", "--target", TARGET], "unknown tool"),
    (["--candidates", "0.027", "--target", "frequency@0.050"], "outside the feasible clamping range"),
    (["--candidates", "0.027", "--target", "freq@0.030"], "--target"),
    (["--candidates", "0.027,abc", "--target", TARGET], "--candidates"),
    (["--candidates", "0.027", "--target", "lobes@0.030:8000:16000"], "lobes target needs"),
    (["--candidates", "dir:z@0.030", "--target", TARGET], "direction"),
])
def test_bad_input_one_line_exit_2_nothing_written(bench, capsys, tmp_path, args, needle):
    out = tmp_path / "out"
    rc, stdout, err = _design(capsys, [bench["setup"], "--posterior", bench["post25"], *args, "--out", out])
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in err
    assert not out.exists()
