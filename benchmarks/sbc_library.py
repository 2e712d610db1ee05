"""Simulation-based calibration of the tool library's stage 2 (issue #42 item 1; docs/calibration.md).

Two holder types of three combinations each (shank diameters 6, 10 and 16 mm), one pooled coordinate
(``log10 k_xf`` with the stage-1 box [4, 10] and growth bound 1.5: the library's default hyperprior), stage-1
surrogate variances 0.01-0.03 decade^2.  Each replicate draws the hyperparameters and the combinations' laws from
the hyperprior as docs/theory.md states the model, the surrogate means from their stage-1 posteriors, fits stage 2
with its default settings and ranks the truths of ``a_t``, ``b_t``, ``sigma_t`` of both types and ``tau_b``
among 99 kept draws (:mod:`bayes_rcsa.library.sbc`).  Printed: the uniformity test per quantity (ECDF, Holm at
family-wise 0.01), convergence and time; written: ``<out>/library_stage2.json`` and ``.png``.

Run:  python benchmarks/sbc_library.py [--replicates 200] [--seed 20261201] [--workers 2] [--out docs/sbc]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from _bench_setup import print_sbc_verdicts

DIAMETERS = np.array([0.006, 0.010, 0.016, 0.006, 0.010, 0.016])
TYPES = np.array([0, 0, 0, 1, 1, 1])
N_RANKED = 99


def _hyper():
    from bayes_rcsa.library.population import Hyperprior

    return Hyperprior.from_box(("k_xf",), np.array([[4.0, 10.0]]), 1.5)


def run_replicate(args) -> dict:
    from bayes_rcsa.library.population import covariate
    from bayes_rcsa.library.sbc import stage2_sbc_replicate

    seed, index = args
    rng = np.random.default_rng([seed, index])
    variances = rng.uniform(0.01, 0.03, TYPES.size)[:, None, None]
    t0 = time.perf_counter()
    row = stage2_sbc_replicate(_hyper(), TYPES, covariate(DIAMETERS), variances, rng, n_ranked=N_RANKED).to_dict()
    return {"index": index, "seconds": time.perf_counter() - t0, **row}


def main() -> None:
    from bayes_rcsa.inference.sbc_plots import sbc_plot
    from bayes_rcsa.library.sbc import stage2_sbc_names
    from bayes_rcsa.stats.sbc import sbc_check

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--seed", type=int, default=20261201)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("docs/sbc"))
    a = ap.parse_args()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as pool:
        rows = sorted(pool.map(run_replicate, [(a.seed, i) for i in range(a.replicates)]), key=lambda r: r["index"])
    wall = time.perf_counter() - t0
    names = stage2_sbc_names(_hyper(), 2)
    ranks = np.array([r["ranks"] for r in rows])
    check = sbc_check(ranks, N_RANKED, names, np.random.default_rng([a.seed, 7]))
    a.out.mkdir(parents=True, exist_ok=True)
    doc = {"config": "library_stage2", "seed": a.seed, "n_draws": N_RANKED, "parameter_names": names,
           "diameters_m": DIAMETERS.tolist(), "types": TYPES.tolist(), "replicates": rows}
    (a.out / "library_stage2.json").write_text(json.dumps(doc))
    sbc_plot(ranks, N_RANKED, names, a.out / "library_stage2.png", np.random.default_rng([a.seed, 7]),
             alpha=0.01 / len(names), title=f"SBC library stage 2: {len(rows)} replicates, L = {N_RANKED}",
             p_values=check.p_ecdf)
    conv = sum(r["converged"] for r in rows)
    secs = np.array([r["seconds"] for r in rows])
    print(f"{len(rows)} replicates in {wall:.0f} s on {a.workers} workers (median {np.median(secs):.1f} s each); "
          f"converged {conv}/{len(rows)}; ESS min {min(r['ess'] for r in rows):.0f}")
    print_sbc_verdicts(names, check)


if __name__ == "__main__":
    main()
