"""Spindle-identification benchmark on the synthetic artifact (3801 lines, one direction).

Prints median times of several runs and, for the inverse coupling, the
ratio to a naive implementation measured in the same run: Namazi's
equations solved line by line as a nonlinear system (``scipy.optimize.root``
on the six real unknowns of h, l = n, p, started from the previous line's
solution) instead of the closed-form, vectorised linear solve.

The end-to-end case is the command a user runs: ``bayes-rcsa spindle
ARTIFACT --samples 50`` on the synthetic artifact tests (both directions,
budget 60 s), timed in a subprocess for the current tree and for the tree
before issue 13 (commit ``OLD_COMMIT``, exported with ``git archive``), with
the largest relative difference of their bootstrap samples (the speed-up must
not change results).  The current tree runs with the default two worker
processes and with ``--workers 1`` (whose samples must be identical).  The
CPU times include the worker processes.  ``--skip-old`` leaves the old run out.
Run: ``python benchmarks/spindle.py [--samples 50] [--skip-old]``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import root  # noqa: E402

from bayes_rcsa.spindle import identify_direction, load_artifact  # noqa: E402
from bayes_rcsa.spindle.inverse import forward_artifact, inverse_exact  # noqa: E402
from bayes_rcsa.spindle.substructure import artifact_receptances  # noqa: E402
from bayes_rcsa.synthetic import default_bench_config  # noqa: E402
from bayes_rcsa.synthetic.artifact import default_bench_artifact, generate_artifact_tests, write_artifact_tests  # noqa: E402


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def naive_inverse(ar, measured: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Namazi's equations as a nonlinear root-finding problem, one line at a time."""
    n = measured.shape[0]
    out = np.empty((n, 2, 2), dtype=complex)
    x = np.concatenate([start.real, start.imag])
    scale = np.abs(start)

    for i in range(n):
        sub = type(ar)(ar.omega[i : i + 1], ar.matrix[i : i + 1])  # one line

        def residual(v, i=i, sub=sub):
            e = (v[:3] + 1j * v[3:]) * scale
            s = np.array([[[e[0], e[1]], [e[1], e[2]]]])
            g = forward_artifact(s, sub)[0] - measured[i]
            g = g / np.abs(measured[i])
            return np.concatenate([g.real, g.imag])

        sol = root(residual, x / np.concatenate([scale, scale]), method="hybr")
        v = sol.x * np.concatenate([scale, scale])
        x = v
        e = v[:3] + 1j * v[3:]
        out[i] = [[e[0], e[1]], [e[1], e[2]]]
    return out


OLD_COMMIT = "0b81963"
ROOT = Path(__file__).resolve().parent.parent


def cli_run(tree: Path, artifact: Path, out: Path, samples: int, extra=()) -> tuple[float, float]:
    """Wall and CPU time (this process's children: the command and its workers) of ``bayes-rcsa spindle``
    run from source ``tree`` in a fresh interpreter."""
    import resource

    env = dict(os.environ, PYTHONPATH=str(tree))
    t0 = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "bayes_rcsa", "spindle", str(artifact), "--out", str(out),
                    "--samples", str(samples), "--no-plots", "--quiet", *extra], cwd=out.parent, env=env,
                   check=True, capture_output=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.perf_counter() - t0, (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)


def end_to_end(samples: int, skip_old: bool) -> None:
    cfg = default_bench_config()
    art = default_bench_artifact()
    tests = generate_artifact_tests(cfg, art, np.random.default_rng(1))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        artifact = Path(write_artifact_tests(tests, tmp / "artifact"))
        t_one, c_one = cli_run(ROOT, artifact, tmp / "one", samples, ("--workers", "1"))
        t_new, c_new = cli_run(ROOT, artifact, tmp / "new", samples)
        a1 = np.load(tmp / "one" / "spindle_samples.npz")
        a2 = np.load(tmp / "new" / "spindle_samples.npz")
        same = all(np.array_equal(a1[k], a2[k]) for k in a2.files if k != "metadata")
        print(f"{'bayes-rcsa spindle --workers 1, ' + str(samples) + ' samples':<58}{t_one:>10.1f} s "
              f"(CPU {c_one:.1f} s); samples {'identical' if same else 'DIFFERENT'} with --workers 2")
        line = (f"{'bayes-rcsa spindle, ' + str(samples) + ' samples (both directions, 2 workers)':<58}"
                f"{t_new:>10.1f} s (CPU {c_new:.1f} s)")
        if not skip_old:
            old_tree = tmp / "old"
            old_tree.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", OLD_COMMIT, "bayes_rcsa"], check=True,
                                     capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", str(old_tree)], input=archive, check=True)
            t_old, c_old = cli_run(old_tree, artifact, tmp / "old_out", samples)
            a = np.load(tmp / "new" / "spindle_samples.npz")
            b = np.load(tmp / "old_out" / "spindle_samples.npz")
            diff = max(float(np.max(np.abs(a[k] - b[k])) / np.max(np.abs(b[k]))) for k in b.files
                       if np.issubdtype(b[k].dtype, np.number) and b[k].size)
            line += (f"{t_old / t_new:>9.2f}x vs before issue 13 ({t_old:.1f} s, CPU {c_old:.1f} s); "
                     f"max rel. sample difference {diff:.1e}")
        print(line + "  (budget 60 s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=50)
    ap.add_argument("--skip-old", action="store_true")
    args = ap.parse_args()
    cfg = default_bench_config()
    art = default_bench_artifact()
    tests = generate_artifact_tests(cfg, art, np.random.default_rng(1), directions=("x",))
    with tempfile.TemporaryDirectory() as tmp:
        setup = load_artifact(write_artifact_tests(tests, f"{tmp}/artifact"))
        f = art.frequency_hz
        omega = 2 * np.pi * f
        m = setup.measurements["x"]
        measured = np.stack([m.h11.values, 0.5 * (m.h12.values + m.h21.values), m.h22.values], axis=-1)

        t_model = median_time(lambda: artifact_receptances(setup.artifact, omega), repeats=5)
        ar = artifact_receptances(setup.artifact, omega)
        t_closed = median_time(lambda: inverse_exact(ar, measured), repeats=7)
        exact = inverse_exact(ar, measured).block
        sub = slice(0, 400)  # the naive solver is slow: time 400 lines and scale up
        ar_sub = type(ar)(ar.omega[sub], ar.matrix[sub])
        start = np.array([exact[0, 0, 0], exact[0, 0, 1], exact[0, 1, 1]])
        t_naive_sub = median_time(lambda: naive_inverse(ar_sub, measured[sub], start), repeats=3)
        naive = naive_inverse(ar_sub, measured[sub], start)
        diff = float(np.max(np.abs(naive - exact[sub]) / np.abs(exact[sub])))
        t_naive = t_naive_sub * f.size / 400
        t_fit = median_time(lambda: identify_direction(setup, "x"), repeats=3)
        # 1 and 11 samples: the difference is 10 replicates, without the bootstrap start fits
        t_one = median_time(lambda: identify_direction(setup, "x", n_samples=1, rng=np.random.default_rng(0)),
                            repeats=1)
        t_boot = median_time(lambda: identify_direction(setup, "x", n_samples=11, rng=np.random.default_rng(0)),
                             repeats=1)

    print(f"Spindle identification, synthetic artifact, direction x, {f.size} lines")
    print(f"{'step':<58}{'median':>12}{'vs naive':>10}")
    print(f"{'artifact free-free receptances (flange + 2 points)':<58}{t_model * 1e3:>9.1f} ms")
    print(f"{'inverse coupling, closed form (vectorised)':<58}{t_closed * 1e3:>9.1f} ms{t_naive / t_closed:>9.0f}x")
    print(f"{'inverse coupling, naive per-line root finding (scaled)':<58}{t_naive * 1e3:>9.1f} ms{1:>9.0f}x")
    print(f"   max relative difference naive vs closed form (first 400 lines): {diff:.1e}")
    print(f"{'identify_direction (noise, inversion, smoothing, flags)':<58}{t_fit:>10.2f} s")
    per = (t_boot - t_one) / 10
    print(f"{'identify_direction with 11 bootstrap samples':<58}{t_boot:>10.2f} s")
    print(f"   -> bootstrap start fits about {t_one - t_fit - per:.2f} s, about {per:.2f} s per bootstrap sample")
    end_to_end(args.samples, args.skip_old)


if __name__ == "__main__":
    main()
