"""The right tail of a weakly identified contact stiffness: emcee move sets against two independent references.

Run: ``OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/sampler_tail.py [--seed 5001] [--setup ER32_d16_1]
[--runs 4] [--steps 10000] [--walkers 32] [--moves 0,1]`` (about 20 min idle, 45 min on the shared 2-core machine).

The setup is one combination of the tool-library bench (``benchmarks/library.py``: library seed 5001, four
combinations per holder type; a 16-mm tool in an ER32 collet, taps at 25, 35 and 45 mm).  Its rotational
contact stiffness ``k_thetaM`` is identified only from below: a stiffer joint changes the FRF less and less,
so the posterior has a long right tail.  The script

1. identifies it with ``bayes-rcsa identify --sampler mcmc`` (the default moves), with long chains
   (``--max-steps 20000 --ess-min 10000``), and ``--runs`` times with identify's default sampler (importance
   sampling, the chain when refused; seeds 9201, ...);
2. samples the same log posterior by importance sampling from a multivariate t (3 degrees of freedom, twice
   the draws' covariance), which needs no mixing, in ``--is-batches`` independent batches of 100,000 draws;
3. runs emcee from the identify draws with each candidate move set (the old default: DE + emcee's
   DESnookerMove; the new default: DE + the corrected :func:`bayes_rcsa.inference.sampler.snooker_move`; DE
   alone; stretch; DE + stretch mixtures; and a Gaussian random walk with the draws' covariance as a
   reference), ``--runs`` independent runs each;

and prints the 1/5/50/95/99/99.9 % quantiles of ``k_thetaM`` (its sampling coordinate) from each, the mean over
runs (batches) with its Monte Carlo error (their standard deviation / sqrt(runs)).  A sampler that agrees with
importance sampling in the bulk but not in the tail under-samples the tail; its R-hat and autocorrelation times,
computed from the bulk, do not show it.  Results: docs/identification.md, "Sampler moves and the tails".
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import arviz as az
import emcee
import numpy as np
from scipy import stats

from bayes_rcsa.inference.sampler import default_moves, snooker_move
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.synthetic.library import generate_library, write_library

sys.path.insert(0, str(Path(__file__).resolve().parent))
from library import library_spec  # noqa: E402  (the library bench's own specification)

QUANTILES = (0.01, 0.05, 0.5, 0.95, 0.99, 0.999)


def weighted_quantiles(x: np.ndarray, w: np.ndarray, qs=QUANTILES) -> np.ndarray:
    o = np.argsort(x)
    cw = np.cumsum(w[o]) / np.sum(w)
    return np.array([x[o][min(np.searchsorted(cw, q), x.size - 1)] for q in qs])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=5001, help="library seed (the bench's second library)")
    ap.add_argument("--setup", default="ER32_d16_1")
    ap.add_argument("--steps", type=int, default=10000, help="steps of each candidate run")
    ap.add_argument("--runs", type=int, default=4, help="independent runs per candidate (their spread: MC error)")
    ap.add_argument("--walkers", type=int, default=32)
    ap.add_argument("--is-batches", type=int, default=4)
    ap.add_argument("--moves", default="", help="comma-separated indices of the candidates to run (default all)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_library(generate_library(library_spec(4), seed=a.seed), root / "lib")
        setup_file = root / "lib" / a.setup / "setup.toml"
        out = root / "fit"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "bayes_rcsa", "identify", str(setup_file), "--out", str(out), "--quiet",
                        "--method", "multi", "--sampler", "mcmc", "--seed", "9101", "--walkers", "24", "--max-steps", "20000",
                        "--ess-min", "10000", "--check-every", "500", "--no-plots"], check=True)
        print(f"identify: {time.perf_counter() - t0:.0f} s")
        setup = load_setup(setup_file)
        summary = json.loads((out / "summary.json").read_text())
        problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(
            setup.extra, method=summary["method"], lengths=None, band=None))
        lp = problem.log_posterior(summary["likelihood"]["tempering"])
        names = problem.priors.names
        post = az.from_netcdf(out / "posterior.nc")
        th = np.column_stack([np.asarray(problem.priors.priors[n].to_sampling(post.posterior[n].values.ravel()), float)
                              for n in names])
        # identify as a user runs it (its default sampler: importance sampling, the chain when refused), --runs
        # independent seeds: their spread is the Monte Carlo error of one run's quantiles
        auto_q, auto_used = [], []
        for r in range(a.runs):
            o = root / f"auto{r}"
            subprocess.run([sys.executable, "-m", "bayes_rcsa", "identify", str(setup_file), "--out", str(o), "--quiet",
                            "--method", "multi", "--seed", str(9201 + r), "--no-plots"], check=True)
            pa = az.from_netcdf(o / "posterior.nc")
            x = np.asarray(problem.priors.priors["k_thetaM"].to_sampling(pa.posterior["k_thetaM"].values.ravel()), float)
            auto_q.append(np.quantile(x, QUANTILES))
            auto_used.append(json.loads((o / "summary.json").read_text())["sampler"]["mode"])
    ik = names.index("k_thetaM")
    rows = [("identify (default moves, 24 walkers, --ess-min 10000)", np.quantile(th[:, ik], QUANTILES), None,
             f"{summary['n_steps']} steps")]
    auto_q = np.array(auto_q)
    rows.append(("identify, default sampler (auto)", auto_q.mean(0), auto_q.std(0, ddof=1) / np.sqrt(len(auto_q)),
                 f"{len(auto_q)} runs (seeds 9201+), sampler used: {', '.join(auto_used)}"))
    rng = np.random.default_rng(7)
    # reference 1: importance sampling, a.is_batches independent batches (their spread is the Monte Carlo error)
    prop = stats.multivariate_t(loc=th.mean(0), shape=2.0 * np.cov(th, rowvar=False), df=3, seed=rng)
    qb, ess = [], []
    for _ in range(a.is_batches):
        x = prop.rvs(100_000)
        lw = np.concatenate([lp(x[i:i + 4000]) for i in range(0, x.shape[0], 4000)]) - prop.logpdf(x)
        lw[~np.isfinite(lw)] = -np.inf
        w = np.exp(lw - lw.max())
        qb.append(weighted_quantiles(x[:, ik], w))
        ess.append(w.sum() ** 2 / np.sum(w * w))
    qb = np.array(qb)
    rows.append(("importance sampling, multivariate t", qb.mean(0), qb.std(0, ddof=1) / np.sqrt(len(qb)),
                 f"{len(qb)} x 100,000 draws, ESS {np.mean(ess):.0f} per batch"))
    cov = np.cov(th, rowvar=False)
    nd = th.shape[1]
    candidates = {
        "old default: DE 0.8 + emcee's DESnookerMove 0.2": lambda: [(emcee.moves.DEMove(), 0.8),
                                                                   (emcee.moves.DESnookerMove(), 0.2)],
        "new default: DE 0.8 + corrected snooker 0.2": lambda: default_moves("differential", 0.2),
        "DE alone": lambda: [(emcee.moves.DEMove(), 1.0)],
        "stretch": lambda: [(emcee.moves.StretchMove(), 1.0)],
        "DE 0.5 + stretch 0.5": lambda: [(emcee.moves.DEMove(), 0.5), (emcee.moves.StretchMove(), 0.5)],
        "DE 0.6 + corrected snooker 0.2 + stretch 0.2": lambda: [(emcee.moves.DEMove(), 0.6), (snooker_move(), 0.2),
                                                                  (emcee.moves.StretchMove(), 0.2)],
        "reference: Gaussian random walk (draws' covariance)":
            lambda: emcee.moves.GaussianMove(cov * 2.38 ** 2 / nd),
    }
    only = set(a.moves.split(",")) if a.moves else None
    for j, (label, make) in enumerate(candidates.items()):
        if only is not None and str(j) not in only:
            continue
        qs, taus, t0 = [], [], time.perf_counter()
        for r in range(a.runs):
            s = emcee.EnsembleSampler(a.walkers, nd, lp, vectorize=True, moves=make())
            start = th[rng.choice(th.shape[0], a.walkers, replace=False)]
            s.run_mcmc(emcee.State(start, random_state=np.random.RandomState(1000 * j + r).get_state()), a.steps,
                       progress=False)
            ch = s.get_chain(discard=a.steps // 5)
            qs.append(np.quantile(ch[:, :, ik].ravel(), QUANTILES))
            taus.append(s.get_autocorr_time(discard=a.steps // 5, quiet=True)[ik])
        qs = np.array(qs)
        rows.append((label, qs.mean(0), qs.std(0, ddof=1) / np.sqrt(a.runs),
                     f"{a.runs} x {a.walkers} walkers x {a.steps} steps, {(time.perf_counter() - t0) / a.runs:.0f} s "
                     f"per run, tau(k_thetaM) {np.mean(taus):.0f}"))
        print(f"{label}: " + " ".join(f"{v:.3f}" for v in qs.mean(0)), flush=True)
    print("\n| sampler | " + " | ".join(f"{100 * q:g} %" for q in QUANTILES) + " | notes |")
    print("|---|" + "---|" * len(QUANTILES) + "---|")
    for label, q, err, note in rows:
        cells = [f"{v:.3f}" if err is None else f"{v:.3f} ± {e:.3f}" for v, e in zip(q, q if err is None else err)]
        print(f"| {label} | " + " | ".join(cells) + f" | {note} |")

if __name__ == "__main__":
    main()
