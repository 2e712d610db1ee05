"""The default moves sample one-sided tails, and the default convergence report sees when they do not (issue #42).

emcee's DESnookerMove (up to 3.1.6) is not in detailed balance; the old default (DE 0.8 + that snooker 0.2)
under-sampled the long right tail of a weakly identified k_thetaM while R-hat, tau and ESS passed
(``benchmarks/sampler_tail.py``).  The default now uses :func:`bayes_rcsa.inference.sampler.snooker_move`.
"""

from __future__ import annotations

import emcee
import numpy as np
import pytest

from bayes_rcsa.inference.sampler import SamplerSettings, default_moves, run_ensemble, snooker_move

#: exact 95 % and 99 % points of a unit exponential
Q95, Q99 = -np.log(0.05), -np.log(0.01)


class _OneSided:
    """exp(-x_0) on x_0 > 0 times a standard normal in 3 more coordinates: a one-sided long tail in x_0."""

    ndim = 4

    def __call__(self, x):
        x = np.atleast_2d(x)
        return np.where(x[:, 0] > 0, -x[:, 0] - 0.5 * np.sum(x[:, 1:] ** 2, axis=1), -np.inf)

    def check_inside(self, x, what):
        assert np.all(x[:, 0] > 0), what


def _quantiles(moves, seed, n_steps=3000):
    rng = np.random.default_rng(seed)
    start = np.abs(rng.standard_normal((24, 4)))
    run = run_ensemble(_OneSided(), SamplerSettings(n_steps=n_steps, n_burn=500, progress=False), initial=start,
                       rng=rng, moves=moves)
    return np.quantile(run.chain[run.burn:, :, 0].ravel(), [0.95, 0.99])


def test_the_snooker_move_samples_a_one_sided_tail_where_emcees_does_not():
    # 24 walkers x 1,500-2,500 kept steps: the 95 % point's Monte Carlo error is about 0.07-0.09 (tau ~ 20
    # steps), the 99 % point's about 0.2-0.25
    ours = _quantiles([(snooker_move(), 1.0)], 1, n_steps=2000)
    assert ours[0] == pytest.approx(Q95, abs=0.25) and ours[1] == pytest.approx(Q99, abs=0.6), ours
    theirs = _quantiles([(emcee.moves.DESnookerMove(), 1.0)], 1, n_steps=1500)
    assert theirs[0] < Q95 - 0.6 and theirs[1] < Q99 - 1.0, theirs  # measured 1.85 and 2.95
    # the default moves (DE 0.8 + this snooker 0.2) too; the old default (emcee's snooker) measured 2.69 / 4.14
    new = _quantiles(default_moves(), 2)
    assert new[0] == pytest.approx(Q95, abs=0.25) and new[1] == pytest.approx(Q99, abs=0.6), new


#: independent identify runs of the tail case.  One 2,500-step run's 95 % point of log10 k_thetaM scatters by
#: about 0.05 (measured 6.796-6.893 over seeds 9101-9104), about the tail check's own 0.4-sd threshold (~0.09
#: here): a single run is flagged or not by its Monte Carlo luck (seed 9101: 0.52 sd after a library version
#: change moved its stream; 0.11-0.23 sd for the others).  Three pooled runs have a third of the variance.
TAIL_SEEDS = (9101, 9102, 9103)


@pytest.fixture(scope="module")
def tail_case(tmp_path_factory):
    """The benchmark's tail case: ER32_d16_1 of the library bench's seed-5001 library (its ER32 combinations are
    drawn first, so a one-combination library reproduces its data), identified with the default moves, three
    independent runs."""
    from bayes_rcsa.inference.identify import identify
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.synthetic.library import LibrarySpec, generate_library, write_library

    root = tmp_path_factory.mktemp("tail")
    write_library(generate_library(LibrarySpec(per_type=1, holder_types=("ER32",)), seed=5001), root / "lib")
    setup = load_setup(root / "lib" / "ER32_d16_1" / "setup.toml")
    problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(setup.extra, method="multi",
                                                                              lengths=None, band=None))
    # a fixed 2,500 steps each (converged by the rule at ~2,000-3,000; the verdicts, not the stopping rule, are
    # tested)
    results = [identify(problem, seed=seed, sampler="mcmc",
                        settings=SamplerSettings(n_walkers=24, n_steps=2500, check_every=250, progress=False))
               for seed in TAIL_SEEDS]
    return problem, results


def test_the_default_passes_the_tail_check_and_the_old_moves_undersample_the_tail(tail_case):
    from bayes_rcsa.inference.tail_check import importance_tail_check

    problem, results = tail_case
    names = list(problem.priors.names)
    lp = problem.log_posterior(results[0].tempering)
    new = importance_tail_check(lp, np.concatenate([r.flat_theta for r in results]), names,
                                np.random.default_rng([9101, 7]), n=40_000)
    # measured 0.13 sd pooled (0.11-0.52 sd for the single runs; threshold 0.4)
    assert new["verdict"] == "consistent", new["reason"]
    # the old default moves, as long a chain from each run's draws: their own diagnostics pass, and every run puts
    # the upper end of k_thetaM's 90 % interval below the importance estimate (measured 0.056-0.069 below; the
    # default's runs scatter around theirs, 0.016-0.08 above).  Whether the check's verdict flags a single old run
    # is not asserted: the old moves' shift, 0.27-0.55 sd over seven runs, straddles its 0.4-sd threshold.
    old_hi, new_hi = [], []
    for seed, result in zip(TAIL_SEEDS, results):
        theta = result.flat_theta
        rng = np.random.default_rng([3, seed])
        old = run_ensemble(lp, SamplerSettings(n_steps=result.summary["n_steps"], progress=False),
                           initial=theta[rng.choice(theta.shape[0], 24, replace=False)], rng=rng,
                           moves=[(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)])
        # (R-hat measured 1.003-1.017 at this length, below 1.01 with the benchmark's 20,000 steps)
        assert np.all(old.diagnostics["rhat"] < 1.02) and np.all(old.diagnostics["ess_bulk"] > 400), old.diagnostics
        draws = old.chain[old.burn::old.thin].reshape(-1, len(names))
        verdict = importance_tail_check(lp, draws, names, np.random.default_rng([9101, 7]), n=40_000)
        k = verdict["parameters"]["k_thetaM"]
        assert k["chain"][1] < k["importance"][1], (seed, k)
        old_hi.append(k["chain"][1])
        new_hi.append(float(np.quantile(theta[:, names.index("k_thetaM")], 0.95)))  # the check's chain end
    # pooled, the old moves' upper end lies below the default's by more than three of its Monte Carlo errors
    # (each mean of three has ~0.03; measured difference 0.12)
    assert np.mean(new_hi) - np.mean(old_hi) > 0.06, (new_hi, old_hi)
