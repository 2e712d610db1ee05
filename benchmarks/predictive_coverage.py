"""Coverage of the posterior-predictive interval of a measured peak at held-out clamping lengths.

For every replicate a new truth is drawn from the prior the setup states
(as in benchmarks/calibration.py), the synthetic bench's finite-element
model simulates a noisy hammer-test campaign at 25, 30, 35 and 40 mm
(x direction), the contact is identified from the 25 and 40 mm tests only,
and ``bayes_rcsa.posterior.predict`` with the fit's noise model
(:class:`bayes_rcsa.posterior.predict.PredictiveNoise`) gives, per mode, the
90 % posterior-predictive interval of the peak frequency a new test would
show.  A case is covered when the natural frequency of the held-out NOISY
measurement (the same rule on the same lines) lies inside it.  The model's
own 90 % credible interval (noise-free natural frequency) is scored on the
same cases for contrast.

Cases: dominant mode at the held-out 30 and 35 mm of every replicate (two
cases per replicate; they share the posterior, so they are not
independent, and the Clopper-Pearson interval, which assumes they are, is
somewhat optimistic).

Run:  python benchmarks/predictive_coverage.py [--replicates 40] [--step 8]   (about 15-20 min)
(tests/test_report_predictive.py runs a reduced version and asserts.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.inference.sampler import SamplerSettings
from bayes_rcsa.io.setup import ContactSpec
from bayes_rcsa.model import ToolPointModel
from bayes_rcsa.posterior.draws import draws_from_result
from bayes_rcsa.posterior.predict import PredictionTarget, PredictiveNoise, predict
from bayes_rcsa.synthetic import default_bench_config, generate_campaign

PRIOR_KX = (1.0e6, 4.0e6)  # N/m at l_a
PRIOR_KT = (1.5e5, 1.5e6)  # N m/rad at l_a
Q = 0.5
FIT = (0.025, 0.040)
HELD_OUT = (0.030, 0.035)
NOISE_FLOOR = IdentificationOptions().noise_floor


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial confidence interval of a proportion ``k / n``."""
    from scipy.stats import beta

    a = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 1, n - k))
    return lo, hi


def replicate(seed: int, step_hz: float, settings: SamplerSettings, max_draws: int = 1000) -> list[dict]:
    """One campaign, a fit at 25 + 40 mm, and the held-out cases.

    Returns
    -------
    list of dict, one per held-out length:
        ``{"length", "measured_hz", "model": (q05, q95), "predictive": (q05, q95),
        "in_model", "in_predictive", "converged", "wall"}``
    """
    rng = np.random.default_rng(seed)
    kx = 10 ** rng.uniform(*np.log10(PRIOR_KX))
    kt = 10 ** rng.uniform(*np.log10(PRIOR_KT))
    g = rng.uniform(0.0, Q)
    cfg = default_bench_config(
        directions=("x",), clamping_lengths=FIT + HELD_OUT, frequency_step=step_hz, k_xf=kx, k_thetaM=kt, growth=g,
        prior_k_xf=PRIOR_KX, prior_k_thetaM=PRIOR_KT, growth_bound=Q, clamping_range=(0.025, 0.040),
    )
    camp = generate_campaign(cfg, rng)
    c = camp.setup["contact"]
    contact = ContactSpec(tuple(c["translational_stiffness"]), tuple(c["rotational_stiffness"]), c["growth_bound"],
                          tuple(c["clamping_range"]), c["translational_damping"], c["rotational_damping"])
    model = ToolPointModel(cfg.holder, {"tool": cfg.tool}, camp.spindle)
    fit = [(cf, frf) for cf, frf in camp.measurements if any(abs(cf.clamping_length - l) < 1e-9 for l in FIT)]
    t0 = time.perf_counter()
    res = identify(build_problem(model, fit, contact, IdentificationOptions()), seed=seed, settings=settings)
    draws = draws_from_result(res).subset(max_draws, np.random.default_rng(seed))
    noise = PredictiveNoise.from_draws(draws, NOISE_FLOOR, np.random.default_rng([seed, 1]))
    targets = [PredictionTarget(cf, frf.frequency_hz, frf, False) for cf, frf in camp.measurements
               if any(abs(cf.clamping_length - l) < 1e-9 for l in HELD_OUT)]
    pred = predict(draws, model, targets, influence=False, noise=noise)
    wall = time.perf_counter() - t0
    rows = []
    for m in pred.modes:
        if not m.dominant or m.measured_hz is None:
            continue
        q, p, f = m.natural_frequency_hz, m.predictive_peak_hz, m.measured_hz
        rows.append({"length": m.configuration.clamping_length, "measured_hz": f,
                     "model": (q["q05"], q["q95"]), "predictive": (p["q05"], p["q95"]),
                     "in_model": bool(q["q05"] <= f <= q["q95"]), "in_predictive": bool(p["q05"] <= f <= p["q95"]),
                     "converged": bool(res.summary["converged"]), "wall": wall})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--replicates", type=int, default=40)
    ap.add_argument("--step", type=float, default=8.0, help="frequency line spacing of the campaigns, Hz")
    ap.add_argument("--first-seed", type=int, default=3000)
    args = ap.parse_args()
    settings = SamplerSettings(progress=False)
    rows: list[dict] = []
    t0 = time.perf_counter()
    for i in range(args.replicates):
        new = replicate(args.first_seed + i, args.step, settings)
        rows += new
        for r in new:
            print(f"replicate {i:3d} {r['length'] * 1e3:4.0f} mm: measured {r['measured_hz']:8.2f} Hz  model 90 % "
                  f"[{r['model'][0]:8.2f}, {r['model'][1]:8.2f}] {'in ' if r['in_model'] else 'OUT'}  predictive 90 % "
                  f"[{r['predictive'][0]:8.2f}, {r['predictive'][1]:8.2f}] {'in ' if r['in_predictive'] else 'OUT'}"
                  f"  {r['wall']:.0f} s", flush=True)
    n = len(rows)
    print()
    print(f"{'interval (90 %)':<44}{'covered':>10}{'of':>5}{'rate':>8}   Clopper-Pearson 95 %")
    for key, label in (("in_predictive", "posterior-predictive peak of a new test"),
                       ("in_model", "model natural frequency (noise-free)")):
        k = sum(r[key] for r in rows)
        lo, hi = clopper_pearson(k, n)
        print(f"{label:<44}{k:>10d}{n:>5d}{k / n:>8.3f}   [{lo:.3f}, {hi:.3f}]")
    print(f"replicates {args.replicates}, converged {100 * np.mean([r['converged'] for r in rows]):.0f} %, "
          f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
