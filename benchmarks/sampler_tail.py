"""The right tail of a weakly identified contact stiffness: identify's emcee moves against two independent references.

Run: ``OMP_NUM_THREADS=1 python benchmarks/sampler_tail.py [--seed 5001] [--setup ER32_d16_1]``
(about 3 min on the 2-core machine).

The setup is one combination of the tool-library bench (``benchmarks/library.py``: library seed 5001, four
combinations per holder type; a 16-mm tool in an ER32 collet, taps at 25, 35 and 45 mm).  Its rotational
contact stiffness ``k_thetaM`` is identified only from below: a stiffer joint changes the FRF less and less,
so the posterior has a long right tail.  The script

1. identifies it with ``bayes-rcsa identify`` (the default sampler: emcee with differential-evolution and
   snooker moves), with long chains (``--max-steps 20000 --ess-min 10000``);
2. samples the same log posterior by importance sampling from a multivariate t (3 degrees of freedom, twice
   the draws' covariance), which needs no mixing;
3. runs emcee again from the identify draws with three move sets (the default differential evolution, the
   stretch move, and a Gaussian random walk with the draws' covariance), 48 walkers, 20,000 steps;

and prints the 1/5/50/95/99/99.9 % quantiles of ``k_thetaM`` (its sampling coordinate) from each.  A sampler
that agrees with importance sampling in the bulk but not in the tail under-samples the tail; its R-hat and
autocorrelation times, computed from the bulk, do not show it.
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
    ap.add_argument("--steps", type=int, default=20000)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_library(generate_library(library_spec(4), seed=a.seed), root / "lib")
        setup_file = root / "lib" / a.setup / "setup.toml"
        out = root / "fit"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "bayes_rcsa", "identify", str(setup_file), "--out", str(out), "--quiet",
                        "--method", "multi", "--seed", "9101", "--walkers", "24", "--max-steps", "20000",
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
    ik = names.index("k_thetaM")
    rows = [("identify (DE + snooker, 24 walkers)", np.quantile(th[:, ik], QUANTILES), "")]
    rng = np.random.default_rng(7)
    prop = stats.multivariate_t(loc=th.mean(0), shape=2.0 * np.cov(th, rowvar=False), df=3, seed=rng)
    x = prop.rvs(400_000)
    lw = np.concatenate([lp(x[i:i + 4000]) for i in range(0, x.shape[0], 4000)]) - prop.logpdf(x)
    lw[~np.isfinite(lw)] = -np.inf
    w = np.exp(lw - lw.max())
    rows.append(("importance sampling, multivariate t", weighted_quantiles(x[:, ik], w),
                 f"ESS {w.sum() ** 2 / np.sum(w * w):.0f} of {x.shape[0]}"))
    cov = np.cov(th, rowvar=False)
    for label, moves in (("emcee DE + snooker (default moves)", [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]),
                         ("emcee stretch", emcee.moves.StretchMove()),
                         ("emcee Gaussian random walk", emcee.moves.GaussianMove(cov * 2.38 ** 2 / th.shape[1]))):
        s = emcee.EnsembleSampler(48, th.shape[1], lp, vectorize=True, moves=moves)
        t0 = time.perf_counter()
        s.run_mcmc(th[rng.integers(0, th.shape[0], 48)], a.steps, progress=False)
        ch = s.get_chain(discard=a.steps // 5)
        tau = s.get_autocorr_time(discard=a.steps // 5, quiet=True)[ik]
        rows.append((label, np.quantile(ch[:, :, ik].ravel(), QUANTILES),
                     f"{a.steps} steps, {time.perf_counter() - t0:.0f} s, tau(k_thetaM) {tau:.0f}"))
    print("\n| sampler | " + " | ".join(f"{100 * q:g} %" for q in QUANTILES) + " | notes |")
    print("|---|" + "---|" * len(QUANTILES) + "---|")
    for label, q, note in rows:
        print(f"| {label} | " + " | ".join(f"{v:.3f}" for v in q) + f" | {note} |")


if __name__ == "__main__":
    main()
