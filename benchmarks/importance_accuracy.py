"""Accuracy and fall-back rate of ``identify --sampler importance`` against a long MCMC reference.

For ``--campaigns`` campaigns of each bench (the project's FE bench ``bayes_rcsa.synthetic`` and the independent
rotor bench ``bayes_rcsa.synthetic.rotor``), each fitted on one clamping length (25 mm, method single) and on two
(25 and 40 mm, method multi), with the true contact drawn at random per campaign (seeds ``--seed-offset`` + i;
4200 + i made the first table in docs/identification.md):

* importance sampling (``sampler="importance"``; :mod:`bayes_rcsa.inference.importance`), recording whether it
  was accepted (else: fall-back) and its Pareto k, ESS and time;
* a long MCMC reference of the same posterior (``sampler="mcmc"``, emcee's stretch move -- not the default
  differential-evolution moves, which under-sample one-sided tails (issue #42) -- run until every bulk ESS >=
  ``--ref-ess``);
* for every sampled parameter and p in (0.05, 0.5, 0.95): the z-score of the importance quantile against the
  reference, computed in probability space so that no density estimate is needed:
  ``z = (F_is(q_ref) - p) / sqrt(p (1 - p) (1 / ESS_is + 1 / ESS_ref))``, where ``F_is`` is the importance
  draws' empirical CDF, ``q_ref`` the reference chain's p-quantile, ``ESS_is`` the weights' Kish ESS and
  ``ESS_ref`` ArviZ's quantile ESS of the chain at p.  Under agreement z is standard normal: |z| <= 1.96 for
  about 95 % of the comparisons and max |z| over a campaign's 3 x (4-8) comparisons a few.

Printed: a table per (bench, lengths) with the accepted fraction (fall-back rate), median k, median ESS, median
IS and reference times, the fraction of |z| <= 1.96 and <= 3, and the largest |z|.

Run:  OMP_NUM_THREADS=1 python benchmarks/importance_accuracy.py [--campaigns 20] [--ref-ess 2000]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
from bayes_rcsa.inference.sampler import SamplerSettings
from bayes_rcsa.io.setup import load_setup

PRIOR_KX = (1.0e6, 4.0e6)  # N/m at l_a (the calibration benchmark's)
PRIOR_KT = (1.5e5, 1.5e6)  # N m/rad at l_a
Q = 0.5
LAYOUTS = {"single 25 mm": ("single", (0.025,)), "multi 25+40 mm": ("multi", (0.025, 0.040))}
PROBS = (0.05, 0.5, 0.95)


def campaign(bench: str, seed: int, root: Path):
    """A campaign with a random true contact (x direction, 25 and 40 mm), written and read back as a setup."""
    rng = np.random.default_rng(seed)
    kx = 10 ** rng.uniform(*np.log10(PRIOR_KX))
    kt = 10 ** rng.uniform(*np.log10(PRIOR_KT))
    g = rng.uniform(0.0, Q)
    common = dict(directions=("x",), clamping_lengths=(0.025, 0.040), k_xf=kx, k_thetaM=kt, prior_k_xf=PRIOR_KX,
                  prior_k_thetaM=PRIOR_KT, growth_bound=Q, clamping_range=(0.025, 0.040))
    if bench == "fe":
        from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

        cfg = default_bench_config(**common, growth=g, frequency_step=1.0)
        camp, write = generate_campaign(cfg, rng), write_campaign
    else:
        from bayes_rcsa.synthetic.rotor import generate_rotor_campaign, rotor_bench_config, write_rotor_campaign

        cfg = rotor_bench_config(None, **common, growth=g, growth_thetaM=g, mesh_size=0.008, spindle_mesh_size=0.03,
                                 mode_cutoff_hz=30e3)
        camp, write = generate_rotor_campaign(cfg, rng), write_rotor_campaign
    return load_setup(write(camp, root / f"{bench}_{seed}", overwrite=True))


def z_scores(is_theta: np.ndarray, is_ess: float, chain: np.ndarray) -> np.ndarray:
    """(3, ndim) z-scores of the importance p-quantiles against the chain's (module docstring)."""
    import arviz as az

    z = np.empty((len(PROBS), is_theta.shape[1]))
    for j in range(is_theta.shape[1]):
        walkers = np.ascontiguousarray(chain[:, :, j].T)  # (chains, draws)
        for i, p in enumerate(PROBS):
            q_ref = np.quantile(walkers, p)
            ess_ref = float(az.ess(walkers, method="quantile", prob=p))
            f_is = float(np.mean(is_theta[:, j] <= q_ref))
            z[i, j] = (f_is - p) / np.sqrt(p * (1 - p) * (1 / is_ess + 1 / ess_ref))
    return z


def one(bench: str, seed: int, layout: str, root: Path, ref_ess: float) -> dict:
    import emcee

    method, lengths = LAYOUTS[layout]
    setup = campaign(bench, seed, root)
    problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(setup.extra, method=method,
                                                                               lengths=lengths))
    t0 = time.perf_counter()
    res = identify(problem, seed=seed, sampler="importance", settings=SamplerSettings(progress=False))
    t_is = time.perf_counter() - t0
    imp = res.importance
    row = {"accepted": bool(imp.accepted), "k": imp.pareto_k, "ess": imp.ess, "t_is": t_is, "z": None,
           "reason": imp.reason}
    if not imp.accepted:
        return row
    t0 = time.perf_counter()
    ref = identify(problem, seed=seed + 1, sampler="mcmc", moves=emcee.moves.StretchMove(),
                   settings=SamplerSettings(ess_min=ref_ess, max_steps=60000, progress=False))
    row["t_ref"] = time.perf_counter() - t0
    row["ref_converged"] = ref.summary["converged"]
    chain = ref.chain.chain[ref.chain.burn:]  # (steps, walkers, ndim)
    row["z"] = z_scores(imp.theta, imp.ess, chain)
    return row


def table(rows: list[dict]) -> str:
    acc = [r for r in rows if r["accepted"]]
    zs = np.concatenate([np.abs(r["z"]).ravel() for r in acc if r["z"] is not None]) if acc else np.array([])
    med = lambda key, rs: statistics.median(r[key] for r in rs) if rs else float("nan")  # noqa: E731
    return (f"{len(acc)}/{len(rows)} accepted ({100 * (1 - len(acc) / len(rows)):.0f} % fall-back) | "
            f"k {med('k', acc):.2f} | ESS {med('ess', acc):.0f} | IS {med('t_is', rows):.1f} s | "
            f"ref {med('t_ref', acc):.0f} s | |z|<=1.96 {np.mean(zs <= 1.96):.2f} | |z|<=3 {np.mean(zs <= 3):.3f} | "
            f"max |z| {zs.max() if zs.size else float('nan'):.2f} | n_z {zs.size}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--campaigns", type=int, default=20)
    ap.add_argument("--ref-ess", type=float, default=2000.0)
    ap.add_argument("--benches", default="fe,rotor")
    ap.add_argument("--seed-offset", type=int, default=4200,
                    help="campaign i uses seed OFFSET + i (4200: the first table of docs/identification.md)")
    args = ap.parse_args()
    t_all = time.perf_counter()
    results = {}
    with tempfile.TemporaryDirectory(prefix="importance_accuracy_") as tmp:
        for bench in args.benches.split(","):
            for layout in LAYOUTS:
                rows = []
                for i in range(args.campaigns):
                    r = one(bench, args.seed_offset + i, layout, Path(tmp), args.ref_ess)
                    rows.append(r)
                    zmax = "-" if r["z"] is None else f"{np.abs(r['z']).max():.2f}"
                    print(f"{bench} {layout} campaign {i}: accepted {r['accepted']} k {r['k']:.2f} ESS {r['ess']:.0f} "
                          f"IS {r['t_is']:.1f} s max|z| {zmax} {r['reason']}", flush=True)
                results[(bench, layout)] = rows
    print()
    print(f"campaigns per row: {args.campaigns}; reference: stretch-move emcee to bulk ESS >= {args.ref_ess:g}")
    for (bench, layout), rows in results.items():
        print(f"{bench:6s} {layout:15s} | {table(rows)}")
    print(f"total run time {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
