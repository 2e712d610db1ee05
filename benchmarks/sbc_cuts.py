"""Simulation-based calibration of the cut update on the bundled example (issue #42 item 1; docs/calibration.md).

The update's prior is real: the bundled example's identified posterior (two lengths, importance-sampled,
``--draws`` of its draws), its ZOA inverse limits at sixteen cuts at 30 mm (4 flutes, half immersion; speeds
6,000-20,000 rpm, each at the median limit of the draws, so that both outcomes occur), the coefficient prior
of ``--kt 790e6±30% --kr 230e6±30%`` (three ratio nodes) and a boundary width log-uniform on [0.05, 0.3].
Each replicate draws a truth from that prior, simulates the sixteen outcomes, re-weights
(:func:`bayes_rcsa.cuts.update.importance_update`, the command's defaults) and ranks the truth's
``log10 k_xf``, ``log10 k_thetaM``, ``ln K_t``, ``ln K_r`` and ``ln w`` among 99 updated draws
(:mod:`bayes_rcsa.cuts.sbc`).  Printed: the uniformity test per quantity (ECDF, Holm at family-wise 0.01), the
smallest effective sample size, and the time; written: ``<out>/cuts_update.json`` and ``.png``.

Run:  python benchmarks/sbc_cuts.py [--replicates 200] [--seed 20261130] [--draws 1000] [--out docs/sbc]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from _bench_setup import print_sbc_verdicts

SPEEDS = np.linspace(6000.0, 20000.0, 16)
CLAMPING_LENGTH = 0.030
N_RANKED = 99


def template(n_draws: int, seed: int, work: Path):
    """Inverse limits (n_nodes, n_draws, n_cuts), the cuts' depths, the draws' ranked values and the priors."""
    import bayes_rcsa
    from bayes_rcsa.cuts.coefficients import CoefficientPrior
    from bayes_rcsa.cuts.data import cut_groups, prepare_cuts
    from bayes_rcsa.cuts.frf import posterior_dynamics
    from bayes_rcsa.cuts.likelihood import inverse_limits_at_cuts
    from bayes_rcsa.data import example_setup
    from bayes_rcsa.stability import CuttingConditions
    from bayes_rcsa.stability.tests_io import read_cut_table

    post = bayes_rcsa.identify(example_setup(), lengths=(0.025, 0.040), plots=False, seed=seed)
    post.save(work / "identify")
    table_path = work / "cuts.csv"
    table_path.write_text("spindle_speed_rpm,depth_m,outcome\n"
                          + "\n".join(f"{s:.0f},0.001,stable" for s in SPEEDS) + "\n")
    cutting = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.5)
    prior = CoefficientPrior.from_tolerances(790e6, 0.3, 230e6, 0.3, 3)
    from bayes_rcsa.io import load_setup

    setup = load_setup(example_setup(), load_data=False, load_spindle=False)
    cuts = prepare_cuts(read_cut_table(table_path), cutting, CLAMPING_LENGTH, setup.tools)
    dyn = posterior_dynamics(example_setup(), work / "identify" / "posterior.nc", cuts.setups(), n_draws,
                             np.random.default_rng(seed))
    inverse = inverse_limits_at_cuts(cut_groups(cuts, dyn.frfs, dyn.frequency_hz), cuts.n_cuts, prior)
    # each cut at the median limit of the draws at the prior's reference coefficients: outcomes uncertain
    with np.errstate(divide="ignore"):
        depth = np.median(1.0 / inverse[inverse.shape[0] // 2], axis=0)
    values = np.column_stack([np.log10(dyn.draws.values["k_xf"]), np.log10(dyn.draws.values["k_thetaM"])])
    return inverse, depth, values, prior


def main() -> None:
    from bayes_rcsa.cuts.likelihood import BoundaryWidth
    from bayes_rcsa.cuts.sbc import cuts_sbc_names, cuts_sbc_replicate
    from bayes_rcsa.inference.sbc_plots import sbc_plot
    from bayes_rcsa.stats.sbc import sbc_check

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--seed", type=int, default=20261130)
    ap.add_argument("--draws", type=int, default=1000, help="hammer draws of the update's prior")
    ap.add_argument("--out", type=Path, default=Path("docs/sbc"))
    a = ap.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        inverse, depth, values, prior = template(a.draws, a.seed, Path(tmp))
    t_template = time.perf_counter() - t0
    width = BoundaryWidth(0.05, 0.3)
    names = cuts_sbc_names(["log10_k_xf", "log10_k_thetaM"], width)
    rng = np.random.default_rng([a.seed, 1])
    t0 = time.perf_counter()
    rows = [cuts_sbc_replicate(inverse, depth, values, prior, width, rng, N_RANKED) for _ in range(a.replicates)]
    t_reps = time.perf_counter() - t0
    ranks = np.array([r.ranks for r in rows])
    check = sbc_check(ranks, N_RANKED, names, np.random.default_rng([a.seed, 7]))
    a.out.mkdir(parents=True, exist_ok=True)
    doc = {"config": "cuts_update", "seed": a.seed, "n_draws": N_RANKED, "parameter_names": names,
           "hammer_draws": int(inverse.shape[1]), "speeds_rpm": SPEEDS.tolist(), "depth_m": depth.tolist(),
           "replicates": [r.to_dict() for r in rows]}
    (a.out / "cuts_update.json").write_text(json.dumps(doc))
    sbc_plot(ranks, N_RANKED, names, a.out / "cuts_update.png", np.random.default_rng([a.seed, 7]),
             alpha=0.01 / len(names), title=f"SBC cut update: {len(rows)} replicates, L = {N_RANKED}",
             p_values=check.p_ecdf)
    ess = np.array([r.ess_draws for r in rows])
    chatter = np.array([r.n_chatter for r in rows])
    print(f"template (identify + ZOA inverse limits of {inverse.shape[1]} draws at {depth.size} cuts): "
          f"{t_template:.1f} s; {len(rows)} replicates: {t_reps:.1f} s ({t_reps / len(rows):.2f} s each)")
    print(f"chattering cuts per replicate: mean {chatter.mean():.2f} of {depth.size}; ESS of the draws: min "
          f"{ess.min():.0f}, median {np.median(ess):.0f}, below 50 in {int(np.sum(ess < 50))}")
    print_sbc_verdicts(names, check)


if __name__ == "__main__":
    main()
