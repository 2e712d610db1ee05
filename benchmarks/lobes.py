"""Benchmark of the stability-lobe solvers (run: ``python benchmarks/lobes.py [--posterior P] [--skip-old]``;
``--end-to-end [--peer-dir DIR]``: the command end to end against the peer, see benchmarks/lobes_peer.py).

Cases (acceptance budgets in brackets):

1. ZOA probabilistic lobes: 500 FRF draws x 400 spindle speeds, 1200
   frequency lines, 4 flutes, 70 % immersion (<= 10 s);
2. SDM stability map of one 2-mode x/y system (one mode per direction) on a
   200 x 100 speed-depth grid, 5000-30000 rpm, default discretisation (<= 20 s);
3. measured-FRF SDM on the bundled example (tip_x/y_30mm.csv, the demo's
   cutting case b: 4 flutes, 95 % immersion, feed y), 200 speeds (<= 20 s);
4. probabilistic SDM on the bundled example: 100 posterior-predictive draws
   at 30 mm x 200 speeds (<= 60 s).  The posterior comes from ``--posterior``
   or from a fresh ``bayes-rcsa identify`` of the example (timed separately).

Cases 3 and 4 are also run with the implementation before issue 13 (commit
``OLD_COMMIT``: full depth grid per draw, exact matrix exponentials per
depth, no compiled kernel), exported with ``git archive`` into a temporary
directory and run in a subprocess; the old probabilistic run is timed on
``--old-draws`` draws and scaled linearly (its per-draw loop is linear).
``--skip-old`` leaves them out (the old measured case alone takes minutes).

Each vectorised solver is timed over ``--runs`` runs (median).  The naive
per-point references implement the same methods with a Python loop per point:
ZOA with a 2 x 2 eigenvalue solve per frequency line and a scan of all lobe
segments per speed, SDM with scipy's ``expm`` per interval, dense products
of the d x d step matrices and ``numpy.linalg.eigvals`` per grid point.  They
are timed on a subset (draws; grid points at evenly spaced speeds) and
scaled linearly to the full problem, which the table states.  Both
references also check the vectorised results (last column).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from bayes_rcsa.stability import (
    CuttingConditions,
    ModalModel,
    default_intervals,
    lobes_from_frf_draws,
    mean_directional_matrix,
    sdm_stability_map,
)
from bayes_rcsa.stability.cutting import interval_directional_matrices

OLD_COMMIT = "0b81963"
ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "bayes_rcsa" / "data" / "example"
CASE_B = dict(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.95, milling="down", feed="y")
F = np.linspace(400.0, 3400.0, 1200)
CUT = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, milling="down", feed="y")
MX = ModalModel([1287.0], [0.02], [1.0e6])
MY = ModalModel([1340.0], [0.03], [1.3e6])


def draws(n, seed=0):
    rng = np.random.default_rng(seed)
    s = rng.normal(1.0, 0.03, n)
    z = rng.normal(1.0, 0.1, n)
    gx = np.array([ModalModel([1287 * a], [0.02 * b], [1.0e6 * a**2]).frf(F) for a, b in zip(s, z)])
    gy = np.array([ModalModel([1340 * a], [0.03 * b], [1.3e6 * a**2]).frf(F) for a, b in zip(s, z)])
    return gx, gy


# ---------------------------------------------------------------------------------------- naive ZOA
def naive_zoa(gx, gy, f, cutting, speeds):
    """Per-draw, per-line, per-speed loops of the same zero-order method (no vectorisation)."""
    h0 = mean_directional_matrix(cutting)
    N = cutting.flutes
    K = int(np.ceil(60 * f.max() / (N * speeds[0]))) + 1
    out = np.full((gx.shape[0], speeds.size), np.inf)
    for d in range(gx.shape[0]):
        pts = []  # (branch, lobe) -> list of (speed, depth) per line
        prev = None
        for j in range(f.size):
            mu = np.linalg.eigvals(h0 @ np.diag([gx[d, j], gy[d, j]]))
            if prev is not None and abs(mu[0] - prev[0]) + abs(mu[1] - prev[1]) > abs(mu[1] - prev[0]) + abs(mu[0] - prev[1]):
                mu = mu[::-1]
            prev = mu
            row = []
            for b in range(2):
                a = 0.5 / mu[b].real if mu[b].real > 0 else np.inf
                eps = np.pi + 2 * np.arctan(mu[b].imag / mu[b].real)
                row.append([(60 * 2 * np.pi * f[j] / (N * (eps + 2 * np.pi * k)), a) for k in range(K)])
            pts.append(row)
        for i, n in enumerate(speeds):
            best = np.inf
            for j in range(f.size - 1):
                for b in range(2):
                    for k in range(K):
                        (s0, a0), (s1, a1) = pts[j][b][k], pts[j + 1][b][k]
                        if np.isfinite(a0) and np.isfinite(a1) and min(s0, s1) <= n <= max(s0, s1) and s1 != s0:
                            best = min(best, a0 + (n - s0) / (s1 - s0) * (a1 - a0))
            out[d, i] = best
    return out


# ---------------------------------------------------------------------------------------- naive SDM
def naive_sdm_radius(mx, my, cutting, speed, depth, m):
    """Dense first-order SDM monodromy of one grid point and its spectral radius."""
    mass = np.array([mx.mass[0], my.mass[0]])
    k = np.array([mx.stiffness[0], my.stiffness[0]])
    c = np.array([mx.damping[0], my.damping[0]])
    N = cutting.flutes
    T = 60.0 / (N * speed)
    dt = T / m
    dphi = 2 * np.pi / (N * m)
    start = dphi * np.arange(m)
    H = interval_directional_matrices(cutting, start, start + dphi)
    d = 4 + 2 * m
    Phi = np.eye(d)
    for i in range(m):
        A = np.zeros((4, 4))
        A[:2, 2:] = np.eye(2)
        A[2:, :2] = -np.diag(k / mass) + depth * H[i] / mass[:, None]
        A[2:, 2:] = -np.diag(c / mass)
        B = np.zeros((4, 2))
        B[2:] = -depth * H[i] / mass[:, None]
        big = np.zeros((12, 12))
        big[:4, :4] = A
        big[:4, 4:8] = np.eye(4)
        big[4:8, 8:] = np.eye(4)
        E = expm(big * dt)
        P, G0, G1 = E[:4, :4], E[:4, 4:8], E[:4, 8:]
        D = np.zeros((d, d))
        D[:4, :4] = P
        D[:4, 4 + 2 * (m - 1) : 4 + 2 * m] = (G0 - G1 / dt) @ B  # q_{i-m}
        D[:4, 4 + 2 * (m - 2) : 4 + 2 * (m - 1)] = (G1 / dt) @ B  # q_{i-m+1}
        D[4:6, :2] = np.eye(2)
        D[6:, 4 : d - 2] = np.eye(d - 6)
        Phi = D @ Phi
    return np.max(np.abs(np.linalg.eigvals(Phi)))


CPU = {}  # case name -> (current CPU s, reference CPU s): the wall times on a shared machine vary with its load


def timed(fn, runs):
    times = []
    cpu = []
    result = None
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    timed.cpu = statistics.median(cpu)
    return statistics.median(times), result


# ---------------------------------------------------------------------------------------- example cases
_OLD_SCRIPT = """
import sys, time, numpy as np
from bayes_rcsa.stability import CuttingConditions, lobes_from_frf_draws
d = np.load(sys.argv[1])
cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.95, milling="down", feed="y")
t0, c0 = time.perf_counter(), time.process_time()
res = lobes_from_frf_draws(d["gx"], d["gy"], d["f"], cut, d["speeds"], method="sdm")
print(time.perf_counter() - t0, time.process_time() - c0)
np.save(sys.argv[2], res.depth_limit_m)
"""


def run_old(gx, gy, f, speeds, tmp: Path):
    """Time the pre-issue-13 probabilistic SDM on these draws in a subprocess; returns (seconds, limits)."""
    tree = tmp / "old"
    if not tree.exists():
        tree.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", OLD_COMMIT, "bayes_rcsa"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
    data = tmp / "draws.npz"
    np.savez(data, gx=gx, gy=gy, f=f, speeds=speeds)
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", _OLD_SCRIPT, str(data), str(tmp / "old_limits.npy")], cwd=tmp,
                         env=env, check=True, capture_output=True, text=True)
    wall, cpu = (float(v) for v in out.stdout.strip().splitlines()[-1].split())
    run_old.cpu = cpu
    return wall, np.load(tmp / "old_limits.npy")


def example_posterior(path, tmp: Path):
    """posterior.nc of the bundled example: ``path`` or a fresh identify run (returns path, seconds)."""
    if path is not None:
        return path, 0.0
    from bayes_rcsa.cli.main import main as cli

    t0 = time.perf_counter()
    status = cli(["identify", str(EXAMPLE / "setup.toml"), "--out", str(tmp / "identify"),
                  "--lengths", "0.025,0.040", "--seed", "0"])
    if status != 0:
        raise SystemExit("identify failed; pass --posterior")
    return str(tmp / "identify" / "posterior.nc"), time.perf_counter() - t0


def example_cases(args, rows):
    from bayes_rcsa.io.frf import read_frf
    from bayes_rcsa.stability.posterior_frf import common_frequency_grid, posterior_frf_draws

    cut = CuttingConditions(**CASE_B)
    speeds = np.linspace(5000, 30000, 200)
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        f, gx, gy = common_frequency_grid(read_frf(EXAMPLE / "tip_x_30mm.csv"), read_frf(EXAMPLE / "tip_y_30mm.csv"))
        lobes_from_frf_draws(gx, gy, f, cut, speeds[:4], method="sdm")  # load the compiled kernel once
        t_new, res = timed(lambda: lobes_from_frf_draws(gx, gy, f, cut, speeds, method="sdm"), args.runs)
        c_new, c_old = timed.cpu, float("nan")
        if args.skip_old:
            t_old, check = float("nan"), "old implementation skipped"
        else:
            t_old, old = run_old(gx[None], gy[None], f, speeds, tmp)
            c_old = run_old.cpu
            ok = np.isfinite(old[0])
            check = f"median |new/old - 1| {np.median(np.abs(res.depth_limit_m[0][ok] / old[0][ok] - 1)):.1e}"
        rows.append(("SDM measured FRFs, 200 speeds", t_new, t_old, "old: full run", 20.0, check))
        CPU["SDM measured FRFs, 200 speeds"] = (c_new, c_old)

        post, t_id = example_posterior(args.posterior, tmp)
        frf = posterior_frf_draws(EXAMPLE / "setup.toml", post, 0.030, 100, np.random.default_rng(0))
        t_new, res = timed(lambda: lobes_from_frf_draws(frf.frf_x, frf.frf_y, frf.frequency_hz, cut, speeds,
                                                        method="sdm"), 1)
        c_new, c_old = timed.cpu, float("nan")
        if args.skip_old:
            t_old, check = float("nan"), "old implementation skipped"
        else:
            k = args.old_draws
            t_sub, old = run_old(frf.frf_x[:k], frf.frf_y[:k], frf.frequency_hz, speeds, tmp)
            t_old = t_sub * frf.n_draws / k
            c_old = run_old.cpu * frf.n_draws / k
            ok = np.isfinite(old)
            check = f"median |new/old - 1| {np.median(np.abs(res.depth_limit_m[:k][ok] / old[ok] - 1)):.1e}"
        rows.append(("SDM 100 posterior draws x 200", t_new, t_old, f"old: {args.old_draws} draws, scaled", 60.0,
                     check + (f"; identify {t_id:.0f} s" if t_id else "")))
        CPU["SDM 100 posterior draws x 200"] = (c_new, c_old)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="runs of each vectorised solver (median reported)")
    ap.add_argument("--naive-draws", type=int, default=2, help="draws timed with the naive ZOA loop")
    ap.add_argument("--naive-points", type=int, default=20, help="grid points timed with the naive SDM loop")
    ap.add_argument("--posterior", help="posterior.nc of the bundled example (default: run identify)")
    ap.add_argument("--old-draws", type=int, default=2, help="draws timed with the pre-issue-13 implementation")
    ap.add_argument("--skip-old", action="store_true", help="do not run the pre-issue-13 implementation")
    ap.add_argument("--skip-naive", action="store_true", help="only the example cases (3 and 4)")
    ap.add_argument("--end-to-end", action="store_true",
                    help="only the end-to-end case of benchmarks/lobes_measured.py: deterministic 'lobes' on the "
                    "bundled 30 mm files at 25001 speeds, current tree and before issue 22, ratio to the peer")
    ap.add_argument("--peer-seconds", type=float, default=3.3, help="peer end-to-end time in s (with --end-to-end)")
    ap.add_argument("--peer-dir", help="with --end-to-end: directory holding the peer's AltintasSLD.m (default "
                    "$BAYES_RCSA_PEER_DIR); the peer then runs in octave-cli alternately with the project, >= 5 "
                    "runs each (benchmarks/lobes_peer.py); skipped with a message without it or octave-cli")
    args = ap.parse_args(argv)
    if args.end_to_end:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from lobes_peer import find_peer, run as peer_run

        peer_file, why = find_peer(args.peer_dir)
        if peer_file is not None:
            peer_run(args.peer_dir, max(args.runs, 5))
            return 0
        print(f"peer not run: {why}; using --peer-seconds {args.peer_seconds:g} (see benchmarks/lobes_peer.py)")
        from lobes_measured import end_to_end

        end_to_end(args, [])
        return 0

    rows = []
    if args.skip_naive:
        example_cases(args, rows)
        _print(args, rows)
        return 0
    # 1. ZOA probabilistic lobes
    gx, gy = draws(500)
    speeds = np.linspace(5000, 30000, 400)
    t_zoa, res = timed(lambda: lobes_from_frf_draws(gx, gy, F, CUT, speeds), args.runs)
    nd = args.naive_draws
    t0 = time.perf_counter()
    ref = naive_zoa(gx[:nd], gy[:nd], F, CUT, speeds)
    t_naive = (time.perf_counter() - t0) * 500 / nd
    err = float(np.max(np.abs(ref / res.depth_limit_m[:nd] - 1)))
    rows.append(("ZOA 500 draws x 400 speeds", t_zoa, t_naive, f"{nd} draws x {500 // nd}", 10.0, f"max rel diff {err:.1e}"))

    # 2. SDM map
    sp = np.linspace(5000, 30000, 200)
    dp = np.linspace(5e-6, 5e-4, 100)
    t_sdm, smap = timed(lambda: sdm_stability_map(MX, MY, CUT, sp, dp), args.runs)
    # naive sample: evenly spaced speeds (the cost grows with m, i.e. at low speed), random depths
    rng = np.random.default_rng(1)
    i_s = np.linspace(0, sp.size - 1, args.naive_points).round().astype(int)
    i_d = rng.integers(0, dp.size, args.naive_points)
    m_all = default_intervals(MX, MY, CUT, sp)
    t0 = time.perf_counter()
    rho = np.array([naive_sdm_radius(MX, MY, CUT, sp[i], dp[j], int(m_all[i])) for i, j in zip(i_s, i_d)])
    t_naive_sdm = (time.perf_counter() - t0) / args.naive_points * sp.size * dp.size
    err = float(np.max(np.abs(rho - smap.spectral_radius[i_s, i_d])))
    rows.append(("SDM 200 x 100 grid, 2 modes", t_sdm, t_naive_sdm, f"{args.naive_points} points x {sp.size * dp.size // args.naive_points}", 20.0, f"max |drho| {err:.1e} (naive = classic SDM; the difference is discretisation error)"))

    example_cases(args, rows)
    _print(args, rows)
    m = default_intervals(MX, MY, CUT, sp)
    print(f"SDM intervals per tooth period: {m.min()}-{m.max()} (rule max(30, 30 f_max T) on the ladder 30*2^(j/2))")
    return 0


def _print(args, rows):
    print(f"stability lobes benchmark (median of {args.runs} runs; naive loop / old implementation timed as stated)")
    print(f"{'case':30s} {'current s':>12s} {'ref. s':>10s} {'ratio':>9s} {'budget s':>9s} {'ok':>4s}  reference / check")
    for name, t, tn, sub, budget, check in rows:
        ok = "yes" if t <= budget else "NO"
        print(f"{name:30s} {t:12.2f} {tn:10.1f} {tn / t:9.0f} {budget:9.1f} {ok:>4s}  {sub}; {check}")
    for name, (c_new, c_old) in CPU.items():
        print(f"   CPU time, {name}: current {c_new:.1f} s, before issue 13 {c_old:.1f} s (ratio {c_old / c_new:.0f})")


if __name__ == "__main__":
    raise SystemExit(main())
