"""Performance of ``identify`` (multi-length Bayesian method) on the synthetic bench.

Problem: two clamping lengths (25, 40 mm), about 800 band lines each,
6 sampled parameters (k_xf, k_thetaM at l_a, two growth factors, two noise
scales), run to R-hat < 1.01 and bulk ESS >= 1000 for every parameter.
Target: <= 60 s wall on the 2-core development machine.

Printed: median over ``--runs`` runs (different seeds) of the wall time,
log-posterior evaluations per second and minimum bulk ESS per second, and
two comparisons measured in the same process:

* vectorised vs naive likelihood: walker batches through the batched
  forward model (``vectorize=True``) against one parameter set per call
  (what ``emcee.EnsembleSampler(vectorize=False)`` would do);
* batched crash-safe checkpoint (bayes_rcsa.inference.checkpoint) against
  emcee's own HDFBackend, which opens and closes the file every step.

Both samplers side by side (``--sampler mcmc`` and ``--sampler importance``, issue #42): the in-process
runs above once per sampler, and ``--cold`` cold-process runs of the bundled example's two-length
identification (``python3 -m bayes_rcsa identify bayes_rcsa/data/example/setup.toml --lengths 0.025,0.040
--no-plots``), whose wall and CPU (user + sys) medians are printed with their ratio; the CPU time says what
the wall time would be on an idle machine when other jobs share the cores.

Run:  python benchmarks/identify.py [--runs 3] [--cold 3]
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

from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.inference.sampler import SamplerSettings
from bayes_rcsa.io.setup import ContactSpec
from bayes_rcsa.model import ToolPointModel
from bayes_rcsa.synthetic import default_bench_config, generate_campaign


def make_problem(step_hz: float = 0.45, ratio: float = 1.2):
    cfg = default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.040), frequency_step=step_hz,
                               frequency_start=500.0, frequency_stop=1800.0)
    camp = generate_campaign(cfg, np.random.default_rng(7))
    c = camp.setup["contact"]
    contact = ContactSpec(tuple(c["translational_stiffness"]), tuple(c["rotational_stiffness"]), c["growth_bound"],
                          tuple(c["clamping_range"]), c["translational_damping"], c["rotational_damping"])
    model = ToolPointModel(cfg.holder, {"tool": cfg.tool}, camp.spindle)
    return build_problem(model, camp.measurements, contact, IdentificationOptions(band_ratio=ratio))


def evals_per_second(fn, batch: np.ndarray, seconds: float = 2.0) -> float:
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        fn(batch)
        n += batch.shape[0]
    return n / (time.perf_counter() - t0)


def checkpoint_cost(n_walkers: int, ndim: int, steps: int = 300) -> tuple[float, float]:
    """Seconds per step: emcee HDFBackend (per-step open/close) vs the batched mirrored checkpoint."""
    import emcee

    from bayes_rcsa.inference.checkpoint import Checkpoint

    rng = np.random.default_rng(0)
    coords = rng.standard_normal((steps, n_walkers, ndim))
    lp = rng.standard_normal((steps, n_walkers))
    state_rs = np.random.RandomState(0).get_state()
    with tempfile.TemporaryDirectory() as d:
        be = emcee.backends.HDFBackend(str(Path(d) / "emcee.h5"))
        be.reset(n_walkers, ndim)
        be.grow(steps, None)
        t0 = time.perf_counter()
        for i in range(steps):
            be.save_step(emcee.State(coords[i], log_prob=lp[i], random_state=state_rs), np.ones(n_walkers, bool))
        t_emcee = (time.perf_counter() - t0) / steps
        ck = Checkpoint(Path(d) / "chain.h5")
        ck.create(n_walkers, ndim, {})
        t0 = time.perf_counter()
        for a in range(0, steps, 100):  # one batch per ~0.2 s of sampling at these step costs
            ck.append(coords[a : a + 100], lp[a : a + 100], np.ones(n_walkers), state_rs)
        t_ours = (time.perf_counter() - t0) / steps
    return t_emcee, t_ours


EXAMPLE = Path(__file__).resolve().parents[1] / "bayes_rcsa" / "data" / "example" / "setup.toml"


def cold_run(sampler: str, seed: int) -> tuple[float, float, dict]:
    """Wall and CPU seconds of one cold ``python3 -m bayes_rcsa identify`` of the bundled example, and its summary."""
    import json

    with tempfile.TemporaryDirectory() as d:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "bayes_rcsa", "identify", str(EXAMPLE), "--lengths", "0.025,0.040",
                        "--no-plots", "--quiet", "--seed", str(seed), "--sampler", sampler, "--out", d],
                       check=True, stdout=subprocess.DEVNULL, cwd=Path(__file__).resolve().parents[1],
                       env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        return wall, cpu, json.loads((Path(d) / "summary.json").read_text())


def side_by_side(problem, runs: int, cold: int) -> None:
    """Both samplers in one run: in-process on the synthetic bench, cold processes on the bundled example."""
    print()
    print(f"{'sampler side by side':<44}{'mcmc':>12}{'importance':>12}{'ratio':>8}")
    walls = {}
    for sampler in ("mcmc", "importance"):
        walls[sampler] = [identify(problem, seed=200 + r, sampler=sampler,
                                   settings=SamplerSettings(progress=False)).summary["timing"]["wall_time_s"]
                          for r in range(runs)]
    m, i = statistics.median(walls["mcmc"]), statistics.median(walls["importance"])
    print(f"{'in process, synthetic bench, median s':<44}{m:>12.2f}{i:>12.2f}{m / i:>8.1f}")
    if not cold:
        return
    res = {s: [cold_run(s, r) for r in range(cold)] for s in ("mcmc", "importance")}
    for j, label in ((0, "cold process, bundled example, wall s"), (1, "cold process, bundled example, CPU s")):
        m, i = (statistics.median(r[j] for r in res[s]) for s in ("mcmc", "importance"))
        print(f"{label:<44}{m:>12.2f}{i:>12.2f}{m / i:>8.1f}")
    modes = [r[2]["sampler"]["mode"] for r in res["importance"]]
    print(f"importance runs accepted: {modes.count('importance')}/{len(modes)}; "
          f"Pareto k {[round(r[2]['sampler']['pareto_k'] or float('nan'), 2) for r in res['importance']]}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cold", type=int, default=3, help="cold-process runs of the bundled example per sampler")
    args = ap.parse_args()
    problem = make_problem()
    lines = [o.n_lines for o in problem.observations]
    print(f"problem: {len(lines)} lengths, band lines {lines}, sampled parameters {list(problem.parameters.names)}")
    settings = SamplerSettings(ess_min=1000.0, progress=False)
    walls, eps, esss, conv = [], [], [], []
    for r in range(args.runs):
        res = identify(problem, seed=100 + r, settings=settings, sampler="mcmc")  # the chain's own figures
        s = res.summary
        min_ess = min(p["ess_bulk"] for p in s["parameters"].values())
        max_rhat = max(p["rhat"] for p in s["parameters"].values())
        walls.append(s["timing"]["wall_time_s"])
        eps.append(s["timing"]["evaluations_per_second"])
        esss.append(min_ess / s["timing"]["wall_time_s"])
        conv.append(s["converged"])
        print(f"run {r}: {s['timing']['wall_time_s']:.1f} s, {s['n_steps']} steps, converged {s['converged']}, "
              f"max R-hat {max_rhat:.4f}, min bulk ESS {min_ess:.0f}, tau_max {max(s['tau'].values()):.1f}")

    lp = problem.log_posterior()
    batch = problem.priors.sample(np.random.default_rng(1), 16)
    v_eps = evals_per_second(lp, batch)
    n_eps = evals_per_second(lambda b: [lp(row[None, :]) for row in b], batch)
    t_emcee, t_ours = checkpoint_cost(32, problem.parameters.ndim)

    print()
    print(f"{'quantity':<52}{'value':>14}{'ratio':>10}")
    print(f"{'wall time to R-hat<1.01, ESS>=1000 (median), s':<52}{statistics.median(walls):>14.1f}"
          f"{statistics.median(walls) / 60.0:>10.2f}  (of the 60 s target)")
    print(f"{'log-posterior evaluations / s in identify (median)':<52}{statistics.median(eps):>14.0f}")
    print(f"{'min bulk ESS / s (median)':<52}{statistics.median(esss):>14.1f}")
    print(f"{'vectorised evaluations / s (batches of 16)':<52}{v_eps:>14.0f}{v_eps / n_eps:>10.1f}")
    print(f"{'naive evaluations / s (one set per call)':<52}{n_eps:>14.0f}{1.0:>10.1f}")
    print(f"{'checkpoint cost per step, emcee HDFBackend, ms':<52}{1e3 * t_emcee:>14.3f}{t_emcee / t_ours:>10.1f}")
    print(f"{'checkpoint cost per step, batched + mirror, ms':<52}{1e3 * t_ours:>14.3f}{1.0:>10.1f}")
    print(f"all runs converged: {all(conv)}")
    side_by_side(problem, args.runs, args.cold)


if __name__ == "__main__":
    main()
