"""Calibration of the identification's credible intervals on replicated synthetic campaigns.

For every replicate a new truth is drawn from the prior the setup states
(log-uniform k_xf(l_a) and k_thetaM(l_a), uniform growth g in [0, Q]; the
synthetic bench applies one g to both stiffnesses), a new campaign with new
noise is simulated by the bench's finite-element model (lumped contact, no
hidden effect, 2 % noise), and the contact is identified from the 25 and
40 mm measurements.  Coverage = fraction of replicates whose 50 % / 90 %
central interval contains the truth, for

* k_xf(l) at 25, 30, 35 and 40 mm (30 and 35 mm unmeasured), pooled, and
* the dominant natural frequency at the unmeasured 30 mm (the documented
  rule applied to the noise-free FE FRF and to every posterior draw, on the
  same frequency lines).

A calibrated method gives about 50 % and 90 %.  The binomial standard error
of a 90 % coverage over n replicates is sqrt(0.09 / n) (6.7 % for n = 20,
4.2 % for n = 50).

Run:  python benchmarks/calibration.py [--replicates 50] [--step 4] [--effect fluted_section]

With ``--effect`` the bench adds a hidden effect the setup does not know
about; the truth of k_xf is then the bench's contact, which the lumped
model can only approximate, so coverage measures how far the tempering
(effective number of lines) keeps the intervals honest under discrepancy.
(tests/test_inference_calibration.py runs a reduced version and asserts.)
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from bayes_rcsa.inference.identify import identify, posterior_stiffness, predict_frf
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.inference.sampler import SamplerSettings
from bayes_rcsa.io.setup import ContactSpec
from bayes_rcsa.model import Configuration, ToolPointModel
from bayes_rcsa.posterior import natural_frequency
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, true_contact, true_tool_point_frf

PRIOR_KX = (1.0e6, 4.0e6)  # N/m at l_a
PRIOR_KT = (1.5e5, 1.5e6)  # N m/rad at l_a
Q = 0.5
LENGTHS_K = (0.025, 0.030, 0.035, 0.040)
MEASURED = (0.025, 0.040)
UNMEASURED_F = 0.030


def replicate(seed: int, step_hz: float, settings: SamplerSettings, effects: dict | None = None,
              sampler: str = "auto") -> dict:
    """One campaign + identification; returns coverage indicators and timing."""
    rng = np.random.default_rng(seed)
    kx = 10 ** rng.uniform(*np.log10(PRIOR_KX))
    kt = 10 ** rng.uniform(*np.log10(PRIOR_KT))
    g = rng.uniform(0.0, Q)
    cfg = default_bench_config(
        directions=("x",), clamping_lengths=MEASURED, frequency_step=step_hz, k_xf=kx, k_thetaM=kt, growth=g,
        prior_k_xf=PRIOR_KX, prior_k_thetaM=PRIOR_KT, growth_bound=Q, clamping_range=(0.025, 0.040),
        hidden_effects=effects or {},
    )
    camp = generate_campaign(cfg, rng)
    c = camp.setup["contact"]
    contact = ContactSpec(tuple(c["translational_stiffness"]), tuple(c["rotational_stiffness"]), c["growth_bound"],
                          tuple(c["clamping_range"]), c["translational_damping"], c["rotational_damping"])
    model = ToolPointModel(cfg.holder, {"tool": cfg.tool}, camp.spindle)
    t0 = time.perf_counter()
    res = identify(build_problem(model, camp.measurements, contact, IdentificationOptions()), seed=seed, settings=settings,
                   sampler=sampler)
    wall = time.perf_counter() - t0
    kxd, _ = posterior_stiffness(res, LENGTHS_K)
    truth_k = np.array([true_contact(cfg, l)["k_xf"] for l in LENGTHS_K])
    f = cfg.frequency_hz
    cfg_u = Configuration(UNMEASURED_F, "x")
    truth_f = float(natural_frequency(f, true_tool_point_frf(cfg, cfg_u, f)))
    pred_f = natural_frequency(f, predict_frf(res, cfg_u, f, max_draws=1000, rng=np.random.default_rng(seed)))
    pred_f = pred_f[np.isfinite(pred_f)]

    def covered(draws, truth, p):
        lo, hi = np.quantile(draws, [(1 - p) / 2, (1 + p) / 2], axis=0)
        return (lo <= truth) & (truth <= hi)

    return {
        "k50": covered(kxd, truth_k, 0.5), "k90": covered(kxd, truth_k, 0.9),
        "f50": bool(covered(pred_f, truth_f, 0.5)), "f90": bool(covered(pred_f, truth_f, 0.9)),
        "converged": res.summary["converged"], "wall": wall, "tempering": res.tempering,
        "n_steps": res.summary["n_steps"], "sampler": res.summary["sampler"]["mode"],
    }


def summarise(rows: list[dict]) -> dict:
    k50 = np.concatenate([r["k50"] for r in rows])
    k90 = np.concatenate([r["k90"] for r in rows])
    return {
        "n": len(rows),
        "k_xf_cov50": float(np.mean(k50)), "k_xf_cov90": float(np.mean(k90)),
        "f_cov50": float(np.mean([r["f50"] for r in rows])), "f_cov90": float(np.mean([r["f90"] for r in rows])),
        "converged": float(np.mean([r["converged"] for r in rows])),
        "median_wall_s": float(np.median([r["wall"] for r in rows])),
        "median_tempering": float(np.median([r["tempering"] for r in rows])),
        "importance": float(np.mean([r["sampler"] == "importance" for r in rows])),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--replicates", type=int, default=50)
    ap.add_argument("--step", type=float, default=4.0, help="frequency line spacing of the campaigns, Hz")
    ap.add_argument("--first-seed", type=int, default=1000)
    ap.add_argument("--sampler", choices=("auto", "importance", "mcmc"), default="auto",
                    help="identify's sampler (default auto, identify's default)")
    ap.add_argument("--effect", default=None,
                    help="hidden effect of the bench (e.g. fluted_section) to test the tempering under model discrepancy")
    args = ap.parse_args()
    settings = SamplerSettings(progress=False)
    rows = []
    t0 = time.perf_counter()
    for i in range(args.replicates):
        rows.append(replicate(args.first_seed + i, args.step, settings, {args.effect: True} if args.effect else None,
                              args.sampler))
        r = rows[-1]
        how = r["sampler"] if r["n_steps"] is None else f"chain of {r['n_steps']} steps"
        print(f"replicate {i:3d}: k90 {r['k90'].astype(int)} f90 {int(r['f90'])} {how} "
              f"beta {r['tempering']:.2f} {r['wall']:.1f} s", flush=True)
    s = summarise(rows)
    se90 = math.sqrt(0.09 / s["n"])
    print()
    print(f"{'quantity':<34}{'50 % coverage':>15}{'90 % coverage':>15}")
    print(f"{'k_xf(l), 25/30/35/40 mm (pooled)':<34}{s['k_xf_cov50']:>15.3f}{s['k_xf_cov90']:>15.3f}")
    print(f"{'natural frequency at 30 mm':<34}{s['f_cov50']:>15.3f}{s['f_cov90']:>15.3f}")
    print(f"replicates {s['n']}, converged {100 * s['converged']:.0f} %, importance sampling accepted "
          f"{100 * s['importance']:.0f} %, binomial s.e. of a 90 % coverage {se90:.3f}")
    print(f"median wall time per replicate {s['median_wall_s']:.1f} s, total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
