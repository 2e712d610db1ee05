"""Design benchmark (issue #15): five candidates, frequency target, replicated synthetic campaigns.

For each replicate (tests/test_design_support.py: bench campaign with a truth
drawn from the setup's prior, measurements at 25, 27, 35, 40 mm):

1. identify from 25 mm only;
2. ``design`` with five candidates (27, 30, 32.5, 35, 40 mm) for the target
   ``frequency@0.035`` -- timed (target of the issue: <= 60 s);
3. re-identify with 25 mm + the chosen length (the campaign holds it) and
   compare the realised 90 % width at 35 mm with the predicted one and its
   stated 95 % interval (2.5-97.5 % of the width over the simulated tests);
4. ``design`` from the 25 + 40 mm posterior with candidates 27, 30, 35 mm:
   the verdict "worth it" or not;

and, on more replicates, the coverage of the true dominant natural
frequency at 40 mm by the 90 % interval of the 25-mm-only posterior given
the growth prior (:mod:`bayes_rcsa.posterior.growth_prior`), with a
Clopper-Pearson 95 % interval.  Run: ``python benchmarks/design.py``.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import beta as beta_dist

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_design_support import campaign, fit  # noqa: E402

from bayes_rcsa.design import parse_candidates, parse_target, run_design  # noqa: E402
from bayes_rcsa.design.targets import TargetEvaluator  # noqa: E402
from bayes_rcsa.io.setup import load_setup  # noqa: E402
from bayes_rcsa.model import Configuration  # noqa: E402
from bayes_rcsa.model.natural_frequencies import natural_frequency  # noqa: E402
from bayes_rcsa.posterior import draws_from_result, predictive_frf  # noqa: E402
from bayes_rcsa.posterior.growth_prior import feasible_growth_law, with_growth_prior  # noqa: E402
from bayes_rcsa.synthetic import true_tool_point_frf  # noqa: E402

SEEDS = (1, 2, 3, 4, 5)
COVERAGE_SEEDS = tuple(range(100, 130))
CANDIDATES = "0.027,0.030,0.0325,0.035,0.040"
TARGET = "frequency@0.035"


def realised_width(res, setup, target) -> float:
    d = draws_from_result(res)
    ev = TargetEvaluator(target, d.parameters, setup.model(), setup, "x", "tool", None, d.values)
    t = ev(d.values)[:, 0]
    t = t[np.isfinite(t)]
    return float(np.quantile(t, 0.95) - np.quantile(t, 0.05))


def design_replicate(seed: int, tmp: Path) -> dict:
    _, setup_path = campaign(seed, tmp / f"c{seed}")
    setup = load_setup(setup_path)
    _, post25 = fit(setup_path, (0.025,), tmp / f"f25_{seed}", seed)
    target = parse_target(TARGET)
    feas = feasible_growth_law(setup)
    t0 = time.perf_counter()
    r = run_design(setup, post25, target, parse_candidates(CANDIDATES, setup, feas), seed=seed)
    t_design = time.perf_counter() - t0
    by_len = {round(c.candidate.clamping_length, 6): c for c in r.candidates}
    best = r.best
    res2, _ = fit(setup_path, (0.025, best.candidate.clamping_length), tmp / f"f2_{seed}", seed)
    real = realised_width(res2, setup, target)
    lo, hi = best.estimate.prediction_interval
    _, post2540 = fit(setup_path, (0.025, 0.040), tmp / f"f2540_{seed}", seed)
    r3 = run_design(setup, post2540, target, parse_candidates("0.027,0.030,0.035", setup, feas), seed=seed)
    return {
        "seed": seed, "time_s": t_design, "current": r.current_width,
        "w27": by_len[0.027].estimate.expected_width, "w40": by_len[0.04].estimate.expected_width,
        "best": best.candidate.clamping_length, "predicted": best.estimate.expected_width, "lo": lo, "hi": hi,
        "method": best.estimate.method, "realised": real, "inside": lo <= real <= hi,
        "current_2540": r3.current_width, "best_2540": r3.best.estimate.expected_width, "worth_2540": r3.worth_it(),
    }


def coverage_replicate(seed: int, tmp: Path) -> bool:
    cfg, setup_path = campaign(seed, tmp / f"c{seed}")
    setup = load_setup(setup_path)
    res, _ = fit(setup_path, (0.025,), tmp / f"f{seed}", seed)
    d = with_growth_prior(draws_from_result(res), feasible_growth_law(setup), np.random.default_rng(seed))
    c = Configuration(0.040, "x", "tool")
    f = cfg.frequency_hz
    truth = float(natural_frequency(f, true_tool_point_frf(cfg, c, f)))
    pred = natural_frequency(f, predictive_frf(d, setup.model(), c, f))
    pred = pred[np.isfinite(pred)]
    return bool(np.quantile(pred, 0.05) <= truth <= np.quantile(pred, 0.95))


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else beta_dist.ppf(a, k, n - k + 1)
    hi = 1.0 if k == n else beta_dist.ppf(1 - a, k + 1, n - k)
    return float(lo), float(hi)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows = [design_replicate(s, tmp) for s in SEEDS]
        print(f"design, target {TARGET}, candidates {CANDIDATES} (25-mm posterior)")
        print("seed  time_s  current_Hz  w27_Hz  w40_Hz  best_mm  predicted  [2.5%, 97.5%]      method      "
              "realised  inside  | 25+40: current  best  worth_it")
        for r in rows:
            print(f"{r['seed']:4d}  {r['time_s']:6.1f}  {r['current']:10.2f}  {r['w27']:6.3f}  {r['w40']:6.3f}  "
                  f"{1e3 * r['best']:7.1f}  {r['predicted']:9.3f}  [{r['lo']:.3f}, {r['hi']:.3f}]  {r['method']:10s}  "
                  f"{r['realised']:8.3f}  {str(r['inside']):6s}  |  {r['current_2540']:.3f}  {r['best_2540']:.3f}  "
                  f"{r['worth_2540']}")
        print(f"median design time {statistics.median(r['time_s'] for r in rows):.1f} s (target <= 60 s); "
              f"40 mm preferred over 27 mm in {sum(r['w40'] < r['w27'] for r in rows)}/{len(rows)}; realised width "
              f"inside the stated interval in {sum(r['inside'] for r in rows)}/{len(rows)}; "
              f"'not worth it' after 25+40 mm in {sum(not r['worth_2540'] for r in rows)}/{len(rows)}")
        hits = [coverage_replicate(s, tmp) for s in COVERAGE_SEEDS]
        k, n = sum(hits), len(hits)
        lo, hi = clopper_pearson(k, n)
        print(f"growth prior: 90 % intervals of the 40-mm natural frequency from 25-mm data cover the truth in "
              f"{k}/{n} = {k / n:.2f} replicates (Clopper-Pearson 95 %: [{lo:.2f}, {hi:.2f}])")


if __name__ == "__main__":
    main()
