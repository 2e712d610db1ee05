"""SDM on many FRF draws: the surrogate (12 exact draws, the rest ZOA x their ratio) against every draw exact.

Run: ``python benchmarks/sdm_surrogate.py [--speeds 120] [--draws 500] [--immersions 0.95,0.3,0.1] [--seed 6100]``

The bundled 30 mm measured files (coherence, 5 averages) give ``--draws`` realisations of their random error
(the default ``bayes-rcsa lobes`` path); the same draws go through ``lobes_from_frf_draws(method="sdm")`` with the
surrogate (default) and with ``exact=True``, at ``--speeds`` speeds over 5000-30000 rpm, for each radial immersion
(4 flutes, K_t 790 MPa, K_r 230 MPa, down milling, feed along Y).  Printed per immersion: CPU time of both and
their ratio, the surrogate's leave-one-out error (or that it fell back to exact), the largest difference of the
P(stable) maps on the exact run's grid, the relative shift of the P = 0.95 and P = 0.5 contours (the draws' 5 %
and 50 % points per speed: median and largest over speeds) next to the exact run's own Monte Carlo error of its
5 % point (bootstrap over the draws, median over speeds), and both recommendations.  Where the draws' limits
cluster within a fraction of a per cent, a contour shift far below the Monte Carlo error still moves many draws
across one grid depth: the largest map difference is then large while the contours agree (read the shifts).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=120)
    ap.add_argument("--draws", type=int, default=500)
    ap.add_argument("--immersions", default="0.95,0.3,0.1")
    ap.add_argument("--seed", type=int, default=6100)
    args = ap.parse_args()

    from bayes_rcsa.data import example_dir
    from bayes_rcsa.stability.cutting import CuttingConditions
    from bayes_rcsa.stability.measured import draw_measured_frf, read_measured_direction
    from bayes_rcsa.stability.probabilistic import lobes_from_frf_draws

    ex = example_dir()
    dx = read_measured_direction(str(ex / "tip_x_30mm.csv"), None, "--measured-x")
    dy = read_measured_direction(str(ex / "tip_y_30mm.csv"), None, "--measured-y")
    rng = np.random.default_rng(args.seed)
    gx, gy = draw_measured_frf(dx, args.draws, rng), draw_measured_frf(dy, args.draws, rng)
    f = dx.frequency_hz
    speeds = np.linspace(5000, 30000, args.speeds)
    print(f"{args.draws} realisations of the bundled 30 mm files, {args.speeds} speeds, seed {args.seed}")
    print("| immersion | surrogate CPU | exact CPU | ratio | LOO error q95 / max | max abs dP | P=0.95 contour shift "
          "median / max | P=0.5 contour shift median / max | MC error of the 5 % point | recommendation surrogate | "
          "recommendation exact |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for imm in (float(v) for v in args.immersions.split(",")):
        cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=imm, milling="down", feed="y")
        runs, cpu = {}, {}
        for exact in (False, True):
            t = time.process_time()
            runs[exact] = lobes_from_frf_draws(gx, gy, f, cut, speeds, method="sdm", exact=exact)
            cpu[exact] = time.process_time() - t
        a, b = runs[False], runs[True]
        sur = a.method_info.get("surrogate")
        loo = (f"{100 * sur['loo_relative_error']['q95']:.2f} % / {100 * sur['loo_relative_error']['max']:.1f} %"
               if sur else "fell back to exact")
        dp = float(np.max(np.abs(_p_on(a.depth_limit_m, b.depth_m) - b.p_stable)))
        shifts = []
        for q in (0.05, 0.5):
            qa, qb = np.quantile(a.depth_limit_m, q, axis=0), np.quantile(b.depth_limit_m, q, axis=0)
            ok = np.isfinite(qa) & np.isfinite(qb) & (qb > 0)
            rel = np.abs(qa[ok] - qb[ok]) / qb[ok]
            shifts.append(f"{100 * np.median(rel):.2f} % / {100 * rel.max():.2f} %")
        boot = np.random.default_rng(args.seed + 1).integers(0, b.depth_limit_m.shape[0], (200, b.depth_limit_m.shape[0]))
        q05 = np.quantile(b.depth_limit_m[boot], 0.05, axis=1)  # (200, n_speed)
        mc = np.nanmedian(np.std(q05, axis=0) / np.quantile(b.depth_limit_m, 0.05, axis=0))
        rec = [f"{r.recommended.spindle_speed_rpm:.0f} rpm, {1e3 * r.recommended.depth_m:.3f} mm" for r in (a, b)]
        print(f"| {imm:g} | {cpu[False]:.1f} s | {cpu[True]:.1f} s | {cpu[True] / cpu[False]:.1f}x | {loo} | {dp:.3f} | "
              f"{shifts[0]} | {shifts[1]} | {100 * mc:.2f} % | {rec[0]} | {rec[1]} |", flush=True)


def _p_on(limits, depths):
    from bayes_rcsa.stability.probabilistic import probability_map

    return probability_map(np.sort(np.atleast_2d(limits), axis=0), depths)


if __name__ == "__main__":
    main()
