"""Simulation-based calibration (SBC) of identify's posterior: prior -> simulated campaign -> emcee -> ranks.

Run: ``OMP_NUM_THREADS=1 python3 benchmarks/sbc.py --config method2 --replicates 200 --workers 2``
(``--config all`` runs every configuration; ``--out docs/sbc``; ``--sampler mcmc`` the chain alone, ``auto``,
the default, identify's default: importance sampling, the chain only when it is refused).

For every replicate ``r`` (seed sequence ``[--seed, configuration index, r]``):

1. draw the parameter vector from the prior the setup states (``problem.priors.sample`` in sampling
   coordinates: log-uniform stiffnesses, uniform growth factors, log-uniform noise scales, the model term's
   priors);
2. simulate every used measurement from the project's own forward model (``FRFLikelihood.model_frf``, i.e.
   ``params.ForwardModel``) with the likelihood's own noise model: circular complex Gaussian residuals of
   variance ``sigma_j^2 (|H_model|^2 + (eps max|H|)^2)`` (coherence 1).  The likelihood takes its floor
   ``eps max|H|`` from the *measured* band maximum; the simulation takes it from the model's (the only
   difference between the generative and the fitted model: the floor is 1 % of the band maximum and matters
   only near anti-resonances);
3. identify as ``identify`` does with a fixed tempering of 1 (exact Bayes: with no model discrepancy the
   residuals are white, and ``"auto"`` tempering would estimate a correlation length from noise): global
   optimum, then (``--sampler auto``) importance sampling with identify's acceptance rule (Pareto k <= 0.7,
   ESS >= 1000), or (refused, or ``--sampler mcmc``) walkers around the optimum and
   :func:`bayes_rcsa.inference.sampler.run_ensemble` in converge mode with identify's default settings and
   moves (R-hat < 1.01, bulk ESS >= 400, chain > 50 tau);
4. rank every truth among ``L = 99`` draws taken at random from the accepted importance draws, or from the
   post-burn-in chain thinned by ``ceil(max tau)`` (nearly independent draws).

Geometry: the bundled example's setup (ER32 collet, 7.94 mm end mill, its spindle files and priors), x
direction, on a fixed band of 500-2500 Hz at 20 Hz spacing (101 lines per measurement; a fixed band keeps
the likelihood a function of the parameters only).

Configurations:

``method2``  Method II, two clamping lengths (25 and 40 mm): k_xf, k_thetaM, g_xf, g_thetaM, sigma_0, sigma_1.
``single``   one clamping length (25 mm): k_xf, k_thetaM, sigma_0.
``tip_mass`` one length (25 mm) with ``[model] terms = ["tip_mass"]``: k_xf, k_thetaM, tip_mass_kg,
             tip_mass_offset_m, sigma_0.
``single_noise03``, ``method2_noise03``  as ``single`` and ``method2`` with the noise scales' prior
             [1e-4, 0.3] (``[likelihood] noise_scale``) instead of the default [1e-4, 10].

Writes ``<out>/<config>.json`` (``<config>-auto.json`` for ``--sampler auto``) (ranks, truths, convergence and time of every replicate) and
``<out>/<config>.png`` (rank histograms and ECDF differences with their simultaneous bands); ``--table``
prints the Markdown table of docs/calibration.md from the JSON files present.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

CONFIGS = {
    "method2": {"lengths": (0.025, 0.04), "model": {}},
    "single": {"lengths": (0.025,), "model": {}},
    "tip_mass": {"lengths": (0.025,), "model": {"terms": ["tip_mass"]}},
    # the same experiments under a setup that states realistic noise ([likelihood] noise_scale = [1e-4, 0.3]):
    # the default prior reaches 10, where the noise floor taken from the measured band makes the likelihood no
    # longer the generative model (docs/calibration.md)
    "single_noise03": {"lengths": (0.025,), "model": {}, "noise_scale": (1e-4, 0.3)},
    "method2_noise03": {"lengths": (0.025, 0.04), "model": {}, "noise_scale": (1e-4, 0.3)},
}
N_DRAWS = 99  # posterior draws per replicate: ranks 0..99, 100 ECDF points
BAND = (500.0, 2500.0)  # Hz
LINE_STEP = 10  # every 10th line of the example's 2-Hz grid


def template_problem(config: str):
    """The configuration's problem on the bundled example's measured FRFs (replaced by simulated ones later)."""
    from bayes_rcsa.data import example_setup
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.model.receptance import FRF

    spec = CONFIGS[config]
    setup = load_setup(example_setup())
    meas = []
    for m in setup.measurements:
        if m.configuration.direction != "x":
            continue
        f = m.frf.frequency_hz
        idx = np.nonzero((f >= BAND[0]) & (f <= BAND[1]))[0][::LINE_STEP]
        meas.append((m.configuration, FRF(f[idx], m.frf.values[idx], None, m.frf.source)))
    options = IdentificationOptions(lengths=spec["lengths"], band=BAND, tempering=1.0, model=spec["model"],
                                    noise_scale=spec.get("noise_scale", IdentificationOptions.noise_scale))
    return build_problem(setup.model(), meas, setup.contact, options)


def run_replicate(args) -> dict:
    """One SBC replicate ``(config, seed, index)`` (:func:`bayes_rcsa.inference.sbc.sbc_replicate`)."""
    from bayes_rcsa.inference.sampler import SamplerSettings
    from bayes_rcsa.inference.sbc import sbc_replicate

    config, seed, index, sampler = args
    ss = np.random.SeedSequence([seed, list(CONFIGS).index(config), index])
    row = sbc_replicate(_template(config), ss, SamplerSettings(progress=False), N_DRAWS, sampler=sampler).to_dict()
    return {"index": index, **row}


_TEMPLATES: dict = {}


def _template(config: str):
    if config not in _TEMPLATES:
        _TEMPLATES[config] = template_problem(config)
    return _TEMPLATES[config]


def _stem(config: str, sampler: str) -> str:
    return config if sampler == "mcmc" else f"{config}-{sampler}"


def run_config(config: str, replicates: int, seed: int, workers: int, out: Path, time_limit: float = math.inf,
               sampler: str = "auto") -> dict:
    from bayes_rcsa.inference.diagnostics import chain_diagnostics

    names = list(_template(config).parameters.names)
    # import ArviZ and compile its numba kernels once, before the workers fork (about 10 s each otherwise)
    chain_diagnostics(np.random.default_rng(0).standard_normal((50, 8, len(names))))
    tasks = [(config, seed, r, sampler) for r in range(replicates)]
    t0 = time.perf_counter()
    rows = []
    path = out / f"{_stem(config, sampler)}.json"

    def save() -> None:
        doc = {"config": config, "sampler": sampler, "seed": seed, "n_draws": N_DRAWS, "band_hz": list(BAND), "line_step": LINE_STEP,
               "parameter_names": names, "replicates": sorted(rows, key=lambda r: r["index"]),
               "wall_time_s": time.perf_counter() - t0, "workers": workers,
               "replicates_requested": replicates}
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(doc, indent=1))
        tmp.replace(path)

    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from multiprocessing import get_context

    # at most `workers` replicates in flight; none started after the time limit (the count is reported)
    with ProcessPoolExecutor(workers, mp_context=get_context("fork")) as pool:
        pending, queue = set(), list(tasks)
        while queue or pending:
            while queue and len(pending) < workers and time.perf_counter() - t0 < time_limit:
                pending.add(pool.submit(run_replicate, queue.pop(0)))
            if not pending:
                break
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                rows.append(fut.result())
                if len(rows) % 10 == 0:
                    save()
                    print(f"{config}: {len(rows)}/{replicates} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    save()
    return json.loads(path.read_text())


def check_and_plot(doc: dict, out: Path, alpha: float = 0.01):
    """The SBC check of one configuration's JSON and its figure (``<out>/<config>.png``)."""
    from bayes_rcsa.inference.sbc_plots import sbc_plot
    from bayes_rcsa.stats.sbc import sbc_check

    ranks = np.array([r["ranks"] for r in doc["replicates"]])
    names = doc["parameter_names"]
    rng = np.random.default_rng([doc["seed"], 7])
    check = sbc_check(ranks, doc["n_draws"], names, rng, alpha=alpha)
    sampler = doc.get("sampler", "mcmc")
    sbc_plot(ranks, doc["n_draws"], names, out / f"{_stem(doc['config'], sampler)}.png", rng, alpha=alpha / len(names),
             title=f"SBC {doc['config']} ({sampler}): {ranks.shape[0]} replicates, L = {doc['n_draws']}",
             p_values=check.p_ecdf)
    return check


def table(out: Path, alpha: float = 0.01) -> str:
    lines = ["| configuration | sampler | parameter | replicates | ECDF p | Holm p | chi-square p (20 bins) "
             "| verdict at FWER 0.01 | importance accepted | not converged | median s / replicate | wall time |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for config in CONFIGS:
        for sampler in ("mcmc", "auto"):
            path = out / f"{_stem(config, sampler)}.json"
            if not path.exists():
                continue
            doc = json.loads(path.read_text())
            check = check_and_plot(doc, out, alpha)
            reps = doc["replicates"]
            nc = sum(not r["converged"] for r in reps)
            accepted = f"{sum(r.get('sampler') == 'importance' for r in reps)}/{len(reps)}" if sampler == "auto" else "-"
            med = float(np.median([r["time_s"] for r in reps]))
            for j, name in enumerate(check.names):
                lines.append(
                    f"| {config} | {sampler} | {name} | {check.n_replicates} | {check.p_ecdf[j]:.3f} | "
                    f"{check.p_holm[j]:.3f} | {check.p_chi2[j]:.3f} | {'pass' if check.passed[j] else '**fail**'} | "
                    f"{accepted} | {nc} | {med:.1f} | {doc['wall_time_s'] / 60:.0f} min ({doc['workers']} workers) |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="method2", choices=[*CONFIGS, "all"])
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--seed", type=int, default=20260421, help="base of every replicate's seed sequence")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("docs/sbc"))
    ap.add_argument("--time-limit", type=float, default=math.inf,
                    help="minutes per configuration after which no new replicate is started")
    ap.add_argument("--sampler", default="auto", choices=["auto", "mcmc"],
                    help="identify's default (importance sampling, the chain when refused) or the chain alone")
    ap.add_argument("--table", action="store_true", help="only print the table (and redraw the figures)")
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    a.out.mkdir(parents=True, exist_ok=True)
    if not a.table:
        for config in (CONFIGS if a.config == "all" else [a.config]):
            run_config(config, a.replicates, a.seed, a.workers, a.out, 60 * a.time_limit, a.sampler)
    print(table(a.out))


if __name__ == "__main__":
    main()
