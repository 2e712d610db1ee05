"""Benchmark of lobes from measured FRFs with their random error (issue 22).

Run: ``OMP_NUM_THREADS=1 python benchmarks/lobes_measured.py [--campaigns 20] [--posterior P] [--skip-e2e]``

1. **Coverage on the bench.**  ``--campaigns`` synthetic campaigns (seeds 1000, 1001, ...; each seed also
   draws the clamping length from 25/30/35/40 mm and scales the true contact stiffness k_xf by U(0.8, 1.2)),
   written with ``[campaign] repeats = 3`` (three hits per direction, coherence, ``# averages = 5``).  The
   truth's depth limit is the ZOA limit of the noise-free FRFs
   (:func:`bayes_rcsa.synthetic.true_tool_point_frf`); the lobes come from the noisy files (paper case b: 4
   flutes, 95 % immersion, down milling, feed Y, 5000-30000 rpm, 400 speeds, 300 realisations).  Reported:
   the pooled share of speeds at which the truth lies inside the 90 % band [q05, q95] for

   - the coherence model (hit 1 with its coherence and averages),
   - the repeats model (hits 1-3),
   - the deterministic mode (hit 1 alone; its "band" is the single limit),

   with a 95 % interval from a block bootstrap over campaigns (the speeds of one campaign share its noise,
   so they are not independent) and a Clopper-Pearson interval at the bootstrap's effective sample size.
2. **Robust point.**  The recommendation at P(stable) >= 0.95 (coherence model) is checked against the truth
   at the point and over its whole checked neighbourhood (speed window x depth up to depth_checked, 41
   speeds); Clopper-Pearson interval of the count; the depth (and removal rate) it costs against the
   recommendation at P(stable) >= 0.5.
3. **Repeats vs coherence.**  The ratio of the hits' scatter to the coherence-derived error per campaign,
   and for mismatched "repeats" (hit 1 of campaign i with hits 2-3 of campaign i + 1, another clamping
   length or contact) the ratio and how often the command's warning (factor 3) fires.
4. **Cost.**  300 FRF draws x 400 speeds, ZOA: measured mode (reading, drawing, lobes, recommendation)
   against posterior mode (posterior-predictive FRFs of the bundled example at 30 mm, lobes,
   recommendation); median of ``--runs`` runs; budget 2x.
5. **End to end.**  ``bayes-rcsa lobes --measured-x/-y`` on the bundled 30 mm files at
   ``--speeds 5000:30000:25001`` (deterministic: ``--deterministic`` in the current tree, which reads the
   files' ``# averages = 5``; the tree before issue 22 ignores that header), as a subprocess, current tree and
   the tree before issue 22 (commit ``BEFORE``, exported with ``git archive``): median wall and CPU time of ``--runs`` runs, and
   the ratio to the peer time ``--peer-seconds`` (acornel5's AltintasSLD in Octave, 3.2-3.4 s as quoted in
   issue 22; not re-measured here unless given).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import beta

from bayes_rcsa.model.assembly import Configuration
from bayes_rcsa.stability import CuttingConditions, lobes_from_frf_draws
from bayes_rcsa.stability.posterior_frf import measured_frf_draws
from bayes_rcsa.stability.zoa import zoa_lobes
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, true_tool_point_frf, write_campaign

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "bayes_rcsa" / "data" / "example"
BEFORE = "54bae8c"  # the tree before issue 22's lobes changes
CASE_B = dict(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.95, milling="down", feed="y")
SPEEDS = np.linspace(5000.0, 30000.0, 400)
DRAWS = 300
LENGTHS = (0.025, 0.030, 0.035, 0.040)


def clopper_pearson(k: float, n: float, conf: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval for k successes in n trials (k, n may be effective, non-integer)."""
    a = (1 - conf) / 2
    lo = 0.0 if k <= 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k >= n else float(beta.ppf(1 - a, k + 1, n - k))
    return lo, hi


def block_bootstrap(inside: np.ndarray, valid: np.ndarray, rng, n_boot: int = 4000):
    """Pooled rate and its 95 % interval, resampling whole campaigns; also the effective sample size.

    inside, valid : (n_campaigns,) counts per campaign
    """
    rate = inside.sum() / valid.sum()
    idx = rng.integers(0, inside.size, (n_boot, inside.size))
    boot = inside[idx].sum(axis=1) / valid[idx].sum(axis=1)
    lo, hi = np.quantile(boot, [0.025, 0.975])
    var = float(np.var(boot))
    n_eff = rate * (1 - rate) / var if var > 0 else float(valid.sum())
    return float(rate), (float(lo), float(hi)), n_eff


def campaign(seed: int, tmp: Path):
    """Write campaign ``seed`` (3 hits per direction) and return (dir, config, clamping length)."""
    pick = np.random.default_rng(seed)
    cl = float(pick.choice(LENGTHS))
    factor = float(pick.uniform(0.8, 1.2))
    base = default_bench_config()
    cfg = default_bench_config(clamping_lengths=(cl,), repeats=3, seed=seed, k_xf=base.k_xf * factor)
    d = tmp / f"c{seed}"
    write_campaign(generate_campaign(cfg, np.random.default_rng(seed)), d, overwrite=True)
    return d, cfg, cl


def hits(d: Path, direction: str, cl: float, which=(1, 2, 3)) -> str:
    mm = round(cl * 1e3)
    return ",".join(str(d / f"tip_{direction}_{mm}mm_hit{k}.csv") for k in which)


def coverage_cases(args, rows: list, rng):
    cut = CuttingConditions(**CASE_B)
    per = {"coherence": [], "repeats": [], "deterministic": []}
    robust = []
    ratios, mismatch = [], []
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        camps = [campaign(1000 + i, tmp) for i in range(args.campaigns + 1)]  # one extra for the mismatch pairs
        for i, (d, cfg, cl) in enumerate(camps[:-1]):
            f = cfg.frequency_hz
            tx = true_tool_point_frf(cfg, Configuration(cl, "x", "tool"), f)
            ty = true_tool_point_frf(cfg, Configuration(cl, "y", "tool"), f)
            truth = zoa_lobes(tx, ty, f, cut, SPEEDS).depth_limit_m
            ok = np.isfinite(truth)
            seed_rng = np.random.default_rng(1000 + i)
            for mode, (sx, sy, n) in {
                "coherence": (hits(d, "x", cl, (1,)), hits(d, "y", cl, (1,)), None),
                "repeats": (hits(d, "x", cl), hits(d, "y", cl), None),
                "deterministic": (hits(d, "x", cl, (1,)), hits(d, "y", cl, (1,)), "no-averages"),
            }.items():
                frf = measured_frf_draws(sx, sy, None, DRAWS, seed_rng)
                gx, gy = (frf.frf_x, frf.frf_y) if n is None else (frf.measured[0].mean, frf.measured[1].mean)
                res = lobes_from_frf_draws(gx, gy, frf.frequency_hz, cut, SPEEDS, level=0.95)
                q05, q95 = res.quantiles[0.05], res.quantiles[0.95]
                inside = ok & (q05 <= truth) & (truth <= q95)
                per[mode].append((int(inside.sum()), int(ok.sum())))
                if mode == "repeats":
                    ratios.append(frf.measured[0].coherence_ratio)
                if mode == "coherence":
                    rec, med = res.recommended, res.median_recommended
                    at = zoa_lobes(tx, ty, f, cut, np.array([rec.spindle_speed_rpm])).depth_limit_m[0]
                    lo_n, hi_n = rec.speed_window_rpm
                    win = zoa_lobes(tx, ty, f, cut, np.linspace(lo_n, hi_n, 41)).depth_limit_m
                    robust.append({"point": bool(rec.depth_m < at), "neighbourhood": bool(rec.depth_checked_m < win.min()),
                                   "depth": rec.depth_m, "median_depth": med.depth_m,
                                   "mrr": rec.mrr_index, "median_mrr": med.mrr_index,
                                   "truth_margin": float(at / rec.depth_m - 1)})
            # mismatched "repeats": hit 1 of this campaign with hits 2-3 of the next one
            dn, _, cln = camps[i + 1]
            sx = f"{hits(d, 'x', cl, (1,))},{hits(dn, 'x', cln, (2, 3))}"
            mm = measured_frf_draws(sx, hits(d, "y", cl, (1,)), None, 2, seed_rng)
            mismatch.append((mm.measured[0].coherence_ratio, bool(mm.measured[0].notes), cl != cln))
    print(f"\n1. coverage of the truth's depth limit by the 90 % band ({args.campaigns} campaigns x {SPEEDS.size} "
          f"speeds, {DRAWS} realisations; 95 % intervals)")
    print(f"{'mode':15s} {'pooled':>8s} {'block bootstrap':>18s} {'n_eff':>7s} {'Clopper-Pearson (n_eff)':>25s} "
          f"{'campaign min-max':>17s}")
    for mode, counts in per.items():
        c = np.array(counts, dtype=float)
        rate, (lo, hi), n_eff = block_bootstrap(c[:, 0], c[:, 1], rng)
        cp = clopper_pearson(rate * n_eff, n_eff)
        each = c[:, 0] / c[:, 1]
        print(f"{mode:15s} {rate:8.3f} {f'[{lo:.3f}, {hi:.3f}]':>18s} {n_eff:7.0f} "
              f"{f'[{cp[0]:.3f}, {cp[1]:.3f}]':>25s} {f'{each.min():.2f}-{each.max():.2f}':>17s}")
        rows.append((f"coverage {mode}", rate, lo, hi))
    pt = sum(r["point"] for r in robust)
    nb = sum(r["neighbourhood"] for r in robust)
    n = len(robust)
    cost = np.array([1 - r["depth"] / r["median_depth"] for r in robust])
    mrr_cost = np.array([1 - r["mrr"] / r["median_mrr"] for r in robust])
    margin = np.array([r["truth_margin"] for r in robust])
    cpp, cpn = clopper_pearson(pt, n), clopper_pearson(nb, n)
    print(f"\n2. robust point at P(stable) >= 0.95 (coherence model): stable in the truth at the point {pt}/{n} "
          f"(CP [{cpp[0]:.2f}, {cpp[1]:.2f}]), over the whole checked neighbourhood {nb}/{n} "
          f"(CP [{cpn[0]:.2f}, {cpn[1]:.2f}])")
    print(f"   depth cost against P >= 0.5: median {100 * np.median(cost):.1f} % (range {100 * cost.min():.1f}-"
          f"{100 * cost.max():.1f} %); removal-rate cost median {100 * np.median(mrr_cost):.1f} %; truth's limit "
          f"above the point by median {100 * np.median(margin):.0f} % (min {100 * margin.min():.0f} %)")
    r = np.array(ratios, dtype=float)
    mr = np.array([m[0] for m in mismatch], dtype=float)
    fired = sum(m[1] for m in mismatch)
    other = [m for m in mismatch if m[2]]
    same = [m for m in mismatch if not m[2]]
    print(f"\n3. hits' scatter / coherence-derived error: same setup median {np.median(r):.2f} (range {r.min():.2f}-"
          f"{r.max():.2f}); mismatched hits median {np.median(mr):.1f} (range {mr.min():.1f}-{mr.max():.1f}), "
          f"warning (factor 3) fired in {fired}/{len(mismatch)}: {sum(m[1] for m in other)}/{len(other)} pairs of "
          f"another clamping length, {sum(m[1] for m in same)}/{len(same)} of the same length with another contact "
          f"stiffness (ratios {', '.join(f'{m[0]:.1f}' for m in same)})")
    return per, robust


def cost_case(args, rows):
    from bayes_rcsa.stability.posterior_frf import posterior_frf_draws

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from lobes import example_posterior  # benchmarks/lobes.py: --posterior or a fresh identify run

    cut = CuttingConditions(**CASE_B)
    with tempfile.TemporaryDirectory() as tmpdir:
        post, t_id = example_posterior(args.posterior, Path(tmpdir))

        def measured():
            frf = measured_frf_draws(str(EXAMPLE / "tip_x_30mm.csv"), str(EXAMPLE / "tip_y_30mm.csv"), 5, DRAWS,
                                     np.random.default_rng(0))
            return lobes_from_frf_draws(frf.frf_x, frf.frf_y, frf.frequency_hz, cut, SPEEDS)

        def posterior():
            frf = posterior_frf_draws(EXAMPLE / "setup.toml", post, 0.030, DRAWS, np.random.default_rng(0))
            return lobes_from_frf_draws(frf.frf_x, frf.frf_y, frf.frequency_hz, cut, SPEEDS)

        measured()  # warm the imports of both paths
        posterior()
        tm = [_timed(measured) for _ in range(args.runs)]
        tp = [_timed(posterior) for _ in range(args.runs)]
    m, p = statistics.median(t[0] for t in tm), statistics.median(t[0] for t in tp)
    mc, pc = statistics.median(t[1] for t in tm), statistics.median(t[1] for t in tp)
    print(f"\n4. cost, {DRAWS} draws x {SPEEDS.size} speeds, ZOA (median of {args.runs}): measured {m:.2f} s "
          f"(CPU {mc:.2f}), posterior {p:.2f} s (CPU {pc:.2f}); ratio {m / p:.2f} (budget 2)"
          + (f"; identify for the posterior {t_id:.0f} s" if t_id else ""))
    rows.append(("cost measured/posterior", m / p, m, p))


def _timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def _cli_time(pythonpath, out: Path, extra=()):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    argv = [sys.executable, "-m", "bayes_rcsa", "lobes", "--measured-x", str(EXAMPLE / "tip_x_30mm.csv"),
            "--measured-y", str(EXAMPLE / "tip_y_30mm.csv"), "--flutes", "4", "--kt", "790e6", "--kr", "230e6",
            "--immersion", "0.95", "--milling", "down", "--feed", "y", "--speeds", "5000:30000:25001",
            *extra, "--out", str(out), "--force", "--quiet"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, env=env, check=True, capture_output=True, cwd=out.parent)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def end_to_end(args, rows):
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        old = tmp / "before"
        old.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", BEFORE, "bayes_rcsa"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        res = {}
        for name, path, extra in (("current", None, ["--deterministic"]), ("before issue 22", old, [])):
            _cli_time(path, tmp / "warm", extra)  # file-system cache and compiled caches
            runs = [_cli_time(path, tmp / f"o_{k}", extra) for k in range(args.runs)]
            res[name] = (statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs),
                         min(r[0] for r in runs))
    print(f"\n5. end to end, deterministic lobes on the bundled 30 mm files, 25001 speeds (median of {args.runs} "
          f"runs; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    for name, (w, c, best) in res.items():
        print(f"   {name:16s} wall {w:.2f} s (best {best:.2f}), CPU {c:.2f} s; peer {args.peer_seconds:g} s / wall = "
              f"{args.peer_seconds / w:.2f}x, / CPU = {args.peer_seconds / c:.2f}x")
    rows.append(("end to end current", res["current"][0], res["current"][1], res["before issue 22"][0]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaigns", type=int, default=20, help="synthetic campaigns (seeds 1000, 1001, ...)")
    ap.add_argument("--runs", type=int, default=3, help="timed runs (median reported)")
    ap.add_argument("--posterior", help="posterior.nc of the bundled example (default: run identify)")
    ap.add_argument("--peer-seconds", type=float, default=3.3,
                    help="peer (AltintasSLD, Octave) end-to-end time in s (default 3.3, issue 22's 3.2-3.4 s)")
    ap.add_argument("--skip-coverage", action="store_true")
    ap.add_argument("--skip-cost", action="store_true")
    ap.add_argument("--skip-e2e", action="store_true")
    args = ap.parse_args(argv)
    rows: list = []
    rng = np.random.default_rng(12345)
    t0 = time.perf_counter()
    if not args.skip_coverage:
        coverage_cases(args, rows, rng)
    if not args.skip_cost:
        cost_case(args, rows)
    if not args.skip_e2e:
        end_to_end(args, rows)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
