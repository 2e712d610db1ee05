"""Synthetic-bench benchmark: a 4-clamping-length campaign with 1501 frequency lines.

Target (issue "synthetic impact-hammer campaigns"): generating the campaign
takes <= 20 s.  Prints median times of several runs and the ratio of the
banded solver (vectorised over frequency lines) to a naive pivoted dense
solve per frequency line, measured in the same run.
Run: ``python benchmarks/synthesize.py``.

BLAS is pinned to one thread (before numpy is imported) so that the naive
dense solve is not distorted by thread oversubscription on a shared machine;
the banded solver uses no BLAS threads anyway.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from bayes_rcsa.model import Configuration  # noqa: E402
from bayes_rcsa.synthetic import build_assembly, default_bench_config, generate_campaign  # noqa: E402
from bayes_rcsa.synthetic.fe import dense_receptance, receptance  # noqa: E402


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    cfg_x = default_bench_config(directions=("x",))
    cfg_xy = default_bench_config()
    n_lines = cfg_x.frequency_hz.size
    omega = 2 * np.pi * cfg_x.frequency_hz

    t_campaign = median_time(lambda: generate_campaign(cfg_x, np.random.default_rng(0)), repeats=5)
    t_campaign_xy = median_time(lambda: generate_campaign(cfg_xy, np.random.default_rng(0)), repeats=3)

    rows = []
    for label, cfg in (("lumped", cfg_x), ("distributed", default_bench_config(contact_model="distributed"))):
        model, tip = build_assembly(cfg, Configuration(0.025, "x"))
        t_band = median_time(lambda: receptance(model, omega, [tip], [tip]), repeats=5)
        t_dense = median_time(lambda: dense_receptance(model, omega, [tip], [tip]), repeats=3)
        a = receptance(model, omega, [tip], [tip])
        b = dense_receptance(model, omega, [tip], [tip])
        err = float(np.max(np.abs(a - b) / np.abs(b)))
        rows.append((label, model.n_dof, model.bandwidth, t_band, t_dense, err))

    print(f"Synthetic campaign: {len(cfg_x.clamping_lengths)} clamping lengths x {n_lines} lines")
    print(f"{'path':<52}{'median':>12}{'vs naive':>10}")
    naive_campaign = rows[0][4] * len(cfg_x.clamping_lengths)  # FE solves dominate; spindle export excluded
    print(f"{'generate_campaign, x only (4 FRFs + 1 spindle)':<52}{t_campaign:>10.2f} s"
          f"{naive_campaign / t_campaign:>9.1f}x")
    print(f"{'generate_campaign, x and y (8 FRFs + 2 spindles)':<52}{t_campaign_xy:>10.2f} s")
    for label, n, p, tb, td, err in rows:
        print(f"{f'assembly solve, {label}: banded ({n} DOF, p={p})':<52}{tb * 1e3:>9.1f} ms{td / tb:>9.1f}x")
        print(f"{f'assembly solve, {label}: naive dense per line':<52}{td * 1e3:>9.1f} ms{1:>9.1f}x")
        print(f"   max relative difference banded vs dense ({label}): {err:.1e}")
    print(f"naive campaign estimate (4 dense assembly solves): {naive_campaign:.2f} s")
    print(f"target: <= 20 s for the 4-length campaign -> {'met' if t_campaign <= 20 else 'NOT met'}")


if __name__ == "__main__":
    main()
