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
``tip_mass_noise03``  as ``tip_mass`` with the noise scales' prior [1e-4, 0.3].
``statistical_discrepancy``  the discrepancy workflow's remainder model on one length (25 mm): ``[model] terms =
             ["statistical_discrepancy"]`` (the smooth multiplicative Chebyshev discrepancy, six coefficients
             Normal(0, 0.05), drawn from that prior and active in the simulation), noise prior [1e-4, 0.3]: k_xf,
             k_thetaM, discrepancy_{re,im}_{0,1,2}, sigma_0.  One length because with one fitted length the
             workflow adds this term alone (``law_shape_uncertainty`` needs two); tempering 1, not the
             workflow's ``1 / tau_r`` of its baseline fit (docs/calibration.md says why).

Negative control (``--fit-prior-sd-factor F``, F != 1): the truths are still drawn from the stated prior, but the
sampled posterior's prior of every ``discrepancy_*`` coefficient has sd ``F x 0.05`` (an extra log-likelihood term
adds ``ln N(c; 0, F sd) - ln N(c; 0, sd)``, :class:`PriorSdError`): the term's prior mis-specified by ``1/F`` in the
fit against the simulation.  Its files are ``<config>-<sampler>-priorsd<F>.*``.

Writes ``<out>/<config>.json`` (``<config>-auto.json`` for ``--sampler auto``) (ranks, truths, convergence and time of every replicate) and
``<out>/<config>.png`` (rank histograms and ECDF differences with their simultaneous bands); ``--table``
prints the Markdown table of docs/calibration.md from the JSON files present (of ``--config`` only when it is
given; a run prints and redraws only its own configuration's), and a run prints on stderr a summary of its sampler
paths (importance sampling accepted or the chain, time, Pareto k, chain length and an ESS estimate,
:func:`sampler_summary`).
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
    # the discrepancy workflow's remainder model at one fitted length (its only remainder term there), under the
    # realistic noise prior so that the known floor failure of the default one does not mask the term
    "statistical_discrepancy": {"lengths": (0.025,), "model": {"terms": ["statistical_discrepancy"]},
                                "noise_scale": (1e-4, 0.3)},
    # one model term under realistic noise, so that the noise-above-signal replicates of the default prior do not
    # mask what the term does (docs/calibration.md); last in the table so that the
    # others' seed indices stay
    "tip_mass_noise03": {"lengths": (0.025,), "model": {"terms": ["tip_mass"]}, "noise_scale": (1e-4, 0.3)},
}
N_DRAWS = 99  # posterior draws per replicate: ranks 0..99, 100 ECDF points
BAND = (500.0, 2500.0)  # Hz
LINE_STEP = 10  # every 10th line of the example's 2-Hz grid


class PriorSdError:
    """Negative control: an extra log-likelihood term that turns the ``discrepancy_*`` coefficients' stated prior
    Normal(0, sd) into Normal(0, ``factor`` sd) in the sampled posterior (the truths keep the stated prior)."""

    name = "prior_sd_error"

    def __init__(self, problem, factor: float):
        names = problem.parameters.names
        self.columns = [j for j, n in enumerate(names) if n.startswith("discrepancy_")]
        if not self.columns:
            raise SystemExit("--fit-prior-sd-factor: the configuration has no discrepancy coefficients")
        self.sd = np.array([problem.priors[names[j]].sigma for j in self.columns])
        self.factor = float(factor)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        c = np.atleast_2d(theta)[:, self.columns] / self.sd
        return -0.5 * (1.0 / self.factor**2 - 1.0) * np.sum(c * c, axis=1)  # constants cancel in the posterior


def template_problem(config: str, prior_sd_factor: float = 1.0):
    """The configuration's problem on the bundled example's measured FRFs (replaced by simulated ones later);
    ``prior_sd_factor != 1``: with the negative control's :class:`PriorSdError` term."""
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
    problem = build_problem(setup.model(), meas, setup.contact, options)
    if prior_sd_factor != 1.0:
        problem = problem.with_extra_terms(PriorSdError(problem, prior_sd_factor))
    return problem


def replicate_seed(config: str, seed: int, index: int) -> np.random.SeedSequence:
    """Replicate ``index`` of ``config`` under the run's base ``seed``: the key both drivers below use."""
    return np.random.SeedSequence([seed, list(CONFIGS).index(config), index])


def run_replicate(args) -> dict:
    """One SBC replicate ``(config, seed, index, sampler, prior_sd_factor)``
    (:func:`bayes_rcsa.inference.sbc.sbc_replicate`)."""
    from bayes_rcsa.inference.sampler import SamplerSettings
    from bayes_rcsa.inference.sbc import sbc_replicate

    config, seed, index, sampler, factor = args
    ss = replicate_seed(config, seed, index)
    row = sbc_replicate(_template(config, factor), ss, SamplerSettings(progress=False), N_DRAWS,
                        sampler=sampler).to_dict()
    return {"index": index, **row}


_TEMPLATES: dict = {}


def _versions() -> dict:
    """The versions a run used (a fixed-seed replicate can change with a library's release)."""
    from importlib.metadata import version

    return {name: version(name) for name in ("bayes_rcsa", "numpy", "scipy", "emcee", "numba")}


def _template(config: str, prior_sd_factor: float = 1.0):
    key = (config, float(prior_sd_factor))
    if key not in _TEMPLATES:
        _TEMPLATES[key] = template_problem(config, prior_sd_factor)
    return _TEMPLATES[key]


def _stem(config: str, sampler: str, prior_sd_factor: float = 1.0) -> str:
    stem = config if sampler == "mcmc" else f"{config}-{sampler}"
    return stem if prior_sd_factor == 1.0 else f"{stem}-priorsd{prior_sd_factor:g}"


def run_config(config: str, replicates: int, seed: int, workers: int, out: Path, time_limit: float = math.inf,
               sampler: str = "auto", prior_sd_factor: float = 1.0, resume: bool = False) -> dict:
    """Run (or, ``resume``, complete) one configuration's replicates ``0 .. replicates - 1``.

    ``resume`` keeps the rows of an existing ``<stem>.json`` of the same configuration, sampler, seed base and
    prior factor and runs only the missing indices (each replicate's seeds depend on its index alone, so the
    result is the run that would have finished); the wall time adds up over the runs, and ``runs`` records
    each run's replicates, wall time and the versions of the libraries it ran with."""
    from bayes_rcsa.inference.diagnostics import chain_diagnostics

    names = list(_template(config, prior_sd_factor).parameters.names)
    # import ArviZ and compile its numba kernels once, before the workers fork (about 10 s each otherwise)
    chain_diagnostics(np.random.default_rng(0).standard_normal((50, 8, len(names))))
    path = out / f"{_stem(config, sampler, prior_sd_factor)}.json"
    rows, earlier_wall, runs = [], 0.0, []
    if resume and path.exists():
        old = json.loads(path.read_text())
        same = (old["config"], old["sampler"], old["seed"], old.get("fit_prior_sd_factor", 1.0)) == \
            (config, sampler, seed, prior_sd_factor)
        if not same:
            raise SystemExit(f"{path}: --resume needs the same configuration, sampler, seed and prior factor "
                             f"(file: {old['config']}, {old['sampler']}, {old['seed']})")
        rows = list(old["replicates"])
        earlier_wall = float(old["wall_time_s"])
        runs = old.get("runs") or [{"replicates": len(rows), "wall_time_s": earlier_wall, "workers": old["workers"]}]
    done_before = {r["index"] for r in rows}
    tasks = [(config, seed, r, sampler, prior_sd_factor) for r in range(replicates) if r not in done_before]
    t0 = time.perf_counter()
    this_run = {"replicates": 0, "wall_time_s": 0.0, "workers": workers, "versions": _versions()}

    def save() -> None:
        doc = {"config": config, "sampler": sampler, "seed": seed, "n_draws": N_DRAWS, "band_hz": list(BAND), "line_step": LINE_STEP,
               "fit_prior_sd_factor": prior_sd_factor,
               "parameter_names": names, "replicates": sorted(rows, key=lambda r: r["index"]),
               "wall_time_s": earlier_wall + time.perf_counter() - t0, "workers": workers,
               "replicates_requested": replicates,
               "runs": [*runs, {**this_run, "replicates": len(rows) - len(done_before),
                                "wall_time_s": time.perf_counter() - t0}]}
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


def importance_acceptance(config: str, seed: int, replicates: int, max_log10_noise: float) -> dict:
    """Importance sampling alone on the replicates whose true ``log10 sigma_0`` is at most ``max_log10_noise``:
    the same truths, data, optimum and importance stream as :func:`run_replicate` (no chain, no ranks).  Prints
    one line per replicate and returns the counts (how often identify's default would fall back to the chain)."""
    from bayes_rcsa.inference.importance import importance_posterior
    from bayes_rcsa.inference.sampler import find_optimum
    from bayes_rcsa.inference.sbc import MAX_DRAWS, replicate_streams, simulate_problem

    problem = _template(config)
    j = problem.parameters.names.index("sigma_0")
    accepted, times, n = 0, [], 0
    for r in range(replicates):
        st = replicate_streams(replicate_seed(config, seed, r))
        truth = problem.priors.sample(st.truth, 1)[0]
        if truth[j] > max_log10_noise:
            continue
        lp = simulate_problem(problem, truth, st.noise).log_posterior(1.0)
        optimum = find_optimum(lp)
        t0 = time.perf_counter()
        imp = importance_posterior(lp, optimum.x, problem.priors.optimisation_bounds(), st.importance, MAX_DRAWS)
        times.append(time.perf_counter() - t0)
        n += 1
        accepted += bool(imp.accepted)
        print(f"{r}: log10 sigma_0 {truth[j]:.2f}, accepted {imp.accepted}, Pareto k {imp.pareto_k:.2f}, "
              f"ESS {imp.ess:.0f}, {times[-1]:.2f} s", file=sys.stderr)
    return {"replicates": n, "accepted": accepted, "median_s": float(np.median(times)) if times else math.nan}


def check_and_plot(doc: dict, out: Path, alpha: float = 0.01):
    """The SBC check of one configuration's JSON and its figure (``<out>/<config>.png``)."""
    from bayes_rcsa.inference.sbc_plots import sbc_plot
    from bayes_rcsa.stats.sbc import sbc_check

    ranks = np.array([r["ranks"] for r in doc["replicates"]])
    names = doc["parameter_names"]
    rng = np.random.default_rng([doc["seed"], 7])
    check = sbc_check(ranks, doc["n_draws"], names, rng, alpha=alpha)
    sampler = doc.get("sampler", "mcmc")
    factor = doc.get("fit_prior_sd_factor", 1.0)
    control = "" if factor == 1.0 else f", fitted prior sd x{factor:g}"
    sbc_plot(ranks, doc["n_draws"], names, out / f"{_stem(doc['config'], sampler, factor)}.png", rng,
             alpha=alpha / len(names),
             title=f"SBC {doc['config']} ({sampler}{control}): {ranks.shape[0]} replicates, L = {doc['n_draws']}",
             p_values=check.p_ecdf)
    return check


def _docs(out: Path, config: str, sampler: str) -> list[Path]:
    """The configuration's JSON files: the run itself, then its negative controls (``-priorsd<F>``)."""
    stem = _stem(config, sampler)
    main = [out / f"{stem}.json"] if (out / f"{stem}.json").exists() else []
    return main + sorted(out.glob(f"{stem}-priorsd*.json"))


def table(out: Path, alpha: float = 0.01, configs=None) -> str:
    """The Markdown table of the JSON files of ``configs`` (default every configuration), redrawing their figures."""
    lines = ["| configuration | sampler | parameter | replicates | ECDF p | Holm p | chi-square p (20 bins) "
             "| verdict at FWER 0.01 | importance accepted | not converged | median s / replicate | wall time |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for config in (CONFIGS if configs is None else configs):
        for sampler in ("mcmc", "auto"):
            for path in _docs(out, config, sampler):
                doc = json.loads(path.read_text())
                check = check_and_plot(doc, out, alpha)
                reps = doc["replicates"]
                nc = sum(not r["converged"] for r in reps)
                n_imp = sum(r.get("sampler") == "importance" for r in reps)
                accepted = f"{n_imp}/{len(reps)}" if sampler == "auto" else "-"
                med = float(np.median([r["time_s"] for r in reps]))
                factor = doc.get("fit_prior_sd_factor", 1.0)
                label = config if factor == 1.0 else f"{config} (control: fitted prior sd x{factor:g})"
                for j, name in enumerate(check.names):
                    lines.append(
                        f"| {label} | {sampler} | {name} | {check.n_replicates} | {check.p_ecdf[j]:.3f} | "
                        f"{check.p_holm[j]:.3f} | {check.p_chi2[j]:.3f} | "
                        f"{'pass' if check.passed[j] else '**fail**'} | {accepted} | {nc} | {med:.1f} | "
                        f"{doc['wall_time_s'] / 60:.0f} min ({doc['workers']} workers) |")
    return "\n".join(lines)


def sampler_summary(doc: dict) -> str:
    """One line per sampler path of a JSON file: replicates, time, Pareto k, chain length and an ESS estimate.

    ``sbc_replicate`` does not record the ESS: an accepted importance sample has ESS >= 1,000 and a converged
    chain a bulk ESS >= 400 by identify's rules; for a chain the line also gives ``walkers (steps - burn) / max tau``
    (burn = min(3 max tau, steps / 2), the sampler's rule), the effective draws of its slowest coordinate.
    """
    from bayes_rcsa.inference.sampler import SamplerSettings

    reps = doc["replicates"]
    walkers = SamplerSettings(progress=False).walkers(len(doc["parameter_names"]))
    out = []
    imp = [r for r in reps if r.get("sampler") == "importance"]
    if imp:
        t = [r["time_s"] for r in imp]
        k = [r["pareto_k"] for r in imp]
        out.append(f"importance sampling: {len(imp)}/{len(reps)} replicates, median {np.median(t):.2f} s "
                   f"(max {max(t):.1f} s), Pareto k median {np.median(k):.2f} (max {max(k):.2f}), ESS >= 1000")
    ch = [r for r in reps if r.get("sampler", "mcmc") == "mcmc"]
    if ch:
        t = [r["time_s"] for r in ch]
        steps = np.array([r["steps"] for r in ch], dtype=float)
        tau = np.array([r["max_tau"] if r["max_tau"] is not None else np.nan for r in ch])
        recorded = [r.get("min_ess") for r in ch]
        if all(e is not None for e in recorded):  # the replicates' own bulk ESS (recorded since 2026-11-29)
            ess, ess_name = np.array(recorded, dtype=float), "bulk ESS"
        else:  # older files: estimated from the steps and tau
            ess, ess_name = walkers * (steps - np.minimum(3 * tau, steps / 2)) / tau, "ESS estimate"
        refused = [r["pareto_k"] for r in ch if r.get("pareto_k") is not None]
        out.append(f"chain: {len(ch)}/{len(reps)} replicates ({sum(r['converged'] for r in ch)} converged), median "
                   f"{np.median(t):.1f} s (max {max(t):.0f} s), steps median {np.median(steps):.0f}, max tau median "
                   f"{np.nanmedian(tau):.0f}, {ess_name} min {np.nanmin(ess):.0f} median {np.nanmedian(ess):.0f}"
                   + (f", refused importance Pareto k median {np.median(refused):.2f}" if refused else ""))
    t_all = [r["time_s"] for r in reps]
    out.append(f"all: {len(reps)} replicates, mean {np.mean(t_all):.1f} s, median {np.median(t_all):.1f} s per "
               f"replicate, wall {doc['wall_time_s'] / 60:.1f} min on {doc['workers']} workers")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default=None, choices=[*CONFIGS, "all"],
                    help="default: method2 for a run, every configuration for --table")
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--seed", type=int, default=20260421, help="base of every replicate's seed sequence")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("docs/sbc"))
    ap.add_argument("--time-limit", type=float, default=math.inf,
                    help="minutes per configuration after which no new replicate is started")
    ap.add_argument("--sampler", default="auto", choices=["auto", "mcmc"],
                    help="identify's default (importance sampling, the chain when refused) or the chain alone")
    ap.add_argument("--fit-prior-sd-factor", type=float, default=1.0,
                    help="negative control: the sampled posterior's prior sd of the discrepancy_* coefficients is "
                         "this factor times the stated one (which the truths are drawn from); 1: no control")
    ap.add_argument("--resume", action="store_true",
                    help="keep the replicates of the configuration's JSON file (same seed base) and run the missing "
                         "ones up to --replicates")
    ap.add_argument("--importance-only", type=float, default=None, metavar="LOG10_NOISE",
                    help="no SBC: importance sampling alone on the replicates whose true log10 sigma_0 <= LOG10_NOISE "
                         "(how often it is accepted); prints the counts")
    ap.add_argument("--table", action="store_true",
                    help="only print the table (and redraw the figures) of --config (default every configuration)")
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    a.out.mkdir(parents=True, exist_ok=True)
    configs = list(CONFIGS) if a.config in (None, "all") else [a.config]
    if a.importance_only is not None:
        for config in ["method2"] if a.config is None else configs:
            print(config, importance_acceptance(config, a.seed, a.replicates, a.importance_only))
        return
    if not a.table:
        configs = ["method2"] if a.config is None else configs
        for config in configs:
            doc = run_config(config, a.replicates, a.seed, a.workers, a.out, 60 * a.time_limit, a.sampler,
                             a.fit_prior_sd_factor, resume=a.resume)
            print(f"{config}:\n{sampler_summary(doc)}", file=sys.stderr)
    # only the figures of the configurations asked for are redrawn
    print(table(a.out, configs=configs))


if __name__ == "__main__":
    main()
