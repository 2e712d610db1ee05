"""Simulation-based calibration of an identification problem: prior draw -> simulated campaign -> posterior -> ranks.

The statistics (ranks, ECDF bands, tests) are in :mod:`bayes_rcsa.stats.sbc`;
this module makes the replicates of a :class:`~.problem.Problem`:

* :func:`simulate_problem` replaces the problem's observations by FRFs simulated
  at a parameter vector from the problem's own forward model
  (:meth:`.likelihood.FRFLikelihood.model_frf`, i.e. :class:`bayes_rcsa.params.ForwardModel`)
  with the likelihood's own noise model (:mod:`.likelihood`): circular complex
  Gaussian residuals of variance ``s_j^2 (|H_model|^2 + (eps max_band |H|)^2) / gamma``
  with coherence ``gamma = 1``.  The likelihood takes the floor's ``max |H|`` from
  the measured band; the simulation from the model's (the generative model
  needs a floor before the data exist).  The floor is ``eps = 1 %`` of the band
  maximum and matters only near anti-resonances.
* :func:`sbc_replicate` draws the truth from ``problem.priors``, simulates,
  samples the posterior as identify does and ranks the truth among nearly
  independent draws.  ``sampler="mcmc"``: global optimum, walkers around it,
  :func:`.sampler.run_ensemble`, draws by :func:`nearly_independent_draws`;
  ``sampler="auto"`` (identify's default): importance sampling around the
  optimum (:func:`.importance.importance_posterior`, identify's acceptance rule
  and draw count), the chain only when it is refused; the draws are a random
  subset of the accepted equally weighted draws.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..errors import SetupError
from ..stats.sbc import sbc_ranks
from .likelihood import FRFLikelihood
from .problem import Problem
from .identify import MAX_DRAWS
from .sampler import ChainResult, SamplerSettings, find_optimum, initial_ensemble, run_ensemble

__all__ = ["simulate_problem", "nearly_independent_draws", "SbcReplicate", "ReplicateStreams", "replicate_streams",
           "sbc_replicate"]


def simulate_problem(problem: Problem, theta: np.ndarray, rng: np.random.Generator) -> Problem:
    """The problem with every observation replaced by one simulated at ``theta``.

    Parameters
    ----------
    problem : Problem
        Its band lines, parameter model and noise floor are kept; the observed values are replaced.
    theta : (ndim,) sampling coordinates
        Must include the noise scales ``sigma_j``.
    rng : numpy.random.Generator

    Returns
    -------
    Problem
        Untempered likelihood (beta = 1) sharing the forward-model cache of ``problem``.
    """
    lik = problem.likelihood
    theta = np.asarray(theta, dtype=float)[None, :]
    h = lik.model_frf(theta)[0]
    values = problem.parameters.values(theta)
    eps = lik.noise.floor
    observations = []
    for j, (obs, sl) in enumerate(zip(problem.observations, lik.stack.slices)):
        hj = h[sl]
        var = np.abs(hj) ** 2 + eps**2 * np.max(np.abs(hj)) ** 2  # (n_lines,) (m/N)^2
        s = float(values[problem.parameters.noise_names[j]][0])
        noise = (rng.standard_normal(hj.size) + 1j * rng.standard_normal(hj.size)) * np.sqrt(var / 2)
        observations.append(replace(obs, values=hj + s * noise, coherence=None))
    new = FRFLikelihood(problem.model, observations, problem.parameters, lik.noise, 1.0, stack=lik.stack)
    return replace(problem, observations=tuple(observations), likelihood=new)


def nearly_independent_draws(chain: ChainResult, n_draws: int, rng: np.random.Generator) -> np.ndarray:
    """``n_draws`` draws chosen at random from the post-burn-in chain thinned by ``ceil(max tau)``.

    Draws one autocorrelation time apart are nearly independent, which the
    uniformity of SBC ranks assumes (correlated draws make the ranks too
    dispersed even for a correct sampler).  If fewer remain, draws are chosen
    with replacement.

    Returns
    -------
    (n_draws, ndim) sampling coordinates
    """
    tau = np.asarray(chain.tau, dtype=float)
    spacing = max(1, math.ceil(float(np.max(tau)))) if np.all(np.isfinite(tau)) else 1
    kept = chain.chain[chain.burn :: spacing].reshape(-1, chain.chain.shape[-1])
    pick = rng.choice(kept.shape[0], n_draws, replace=kept.shape[0] < n_draws)
    return kept[pick]


@dataclass(frozen=True)
class SbcReplicate:
    """One SBC replicate.

    Attributes
    ----------
    truth : (ndim,) sampling coordinates drawn from the prior
    ranks : (ndim,) int in ``[0, n_draws]``
    converged : bool, the sampler's verdict
    steps : int, sampler steps run
    max_tau : float, steps (NaN for accepted importance sampling)
    time_s : float, wall time of the replicate
    sampler : str, what produced the draws: ``"mcmc"`` or ``"importance"``
    pareto_k : float, the importance weights' Pareto k (NaN when no importance sampling was tried)
    min_ess : float, effective sample size of the draws the truth was ranked among: the importance weights' Kish
        ESS, or the chain's smallest bulk ESS over the parameters (ArviZ, kept part; NaN when the chain was too short
        to compute it)
    """

    truth: np.ndarray
    ranks: np.ndarray
    converged: bool
    steps: int
    max_tau: float
    time_s: float
    sampler: str = "mcmc"
    pareto_k: float = math.nan
    min_ess: float = math.nan

    def to_dict(self) -> dict:
        return {"truth": self.truth.tolist(), "ranks": self.ranks.tolist(), "converged": self.converged,
                "steps": self.steps, "max_tau": None if math.isnan(self.max_tau) else self.max_tau,
                "time_s": self.time_s, "sampler": self.sampler,
                "pareto_k": None if math.isnan(self.pareto_k) else self.pareto_k,
                "min_ess": None if math.isnan(self.min_ess) else self.min_ess}


@dataclass(frozen=True)
class ReplicateStreams:
    """The independent random streams of one SBC replicate (:func:`replicate_streams`)."""

    truth: np.random.Generator
    noise: np.random.Generator
    init: np.random.Generator
    mcmc: np.random.Generator
    rank: np.random.Generator
    importance: np.random.Generator


def replicate_streams(seed_sequence: np.random.SeedSequence) -> ReplicateStreams:
    """Spawn one replicate's streams from ``seed_sequence``: the one layout every SBC driver uses.

    The truth, the noise, the walker start, emcee and the ranks took the first five children before importance
    sampling existed (so chain replicates kept their numbers); importance sampling takes the sixth.  A script
    that needs a replicate's truth or data without its sampler (``benchmarks/sbc.py --importance-only``) calls
    this to reach the same numbers.
    """
    return ReplicateStreams(*(np.random.default_rng(s) for s in seed_sequence.spawn(6)))


def sbc_replicate(problem: Problem, seed_sequence: np.random.SeedSequence, settings: SamplerSettings,
                  n_draws: int = 99, tempering: float = 1.0, sampler: str = "mcmc") -> SbcReplicate:
    """Truth from the prior, a simulated campaign, identify's sampler, the ranks of the truth.

    Parameters
    ----------
    problem : Problem
        Its priors, band lines and parameter model define the experiment.
    seed_sequence : numpy.random.SeedSequence
        Spawned into independent streams for the truth, the noise, the walker start, emcee and the ranks.
    settings : SamplerSettings
        Converge or fixed-steps mode.
    n_draws : int
        Posterior draws the truth is ranked among (L).
    tempering : float in (0, 1]
        The FRF likelihood's exponent in the *sampled* posterior (1: exact Bayes; anything else is a
        deliberately miscalibrated posterior, e.g. for a test that SBC detects it).
    sampler : {"mcmc", "auto"}
        ``"auto"``: importance sampling as identify's default does, the chain only when it is refused.
    """
    if sampler not in ("mcmc", "auto"):
        raise SetupError(f"sampler {sampler!r}: expected 'mcmc' or 'auto'")
    t0 = time.perf_counter()
    st = replicate_streams(seed_sequence)
    rng_truth, rng_noise, rng_init, rng_mcmc, rng_rank, rng_is = (st.truth, st.noise, st.init, st.mcmc, st.rank,
                                                                   st.importance)
    truth = problem.priors.sample(rng_truth, 1)[0]
    lp = simulate_problem(problem, truth, rng_noise).log_posterior(tempering)
    optimum = find_optimum(lp)
    k = math.nan
    if sampler == "auto":
        from .importance import importance_posterior

        imp = importance_posterior(lp, optimum.x, problem.priors.optimisation_bounds(), rng_is, MAX_DRAWS)
        k = float(imp.pareto_k)
        if imp.accepted:
            draws = imp.theta[rng_rank.choice(imp.theta.shape[0], n_draws, replace=False)]
            return SbcReplicate(truth, sbc_ranks(truth, draws, rng_rank), True, 0, math.nan,
                                time.perf_counter() - t0, "importance", k, float(imp.ess))
    walkers = initial_ensemble(lp, optimum.x, rng_init, settings.walkers(lp.ndim))
    from .diagnostics import chain_diagnostics

    chain = run_ensemble(lp, settings, initial=walkers, rng=rng_mcmc, diagnose=chain_diagnostics)
    draws = nearly_independent_draws(chain, n_draws, rng_rank)
    ess_bulk = np.asarray(chain.diagnostics.get("ess_bulk", ()), dtype=float)
    min_ess = float(np.min(ess_bulk)) if ess_bulk.size and np.all(np.isfinite(ess_bulk)) else math.nan
    return SbcReplicate(truth, sbc_ranks(truth, draws, rng_rank), bool(chain.converged), int(chain.steps_run),
                        float(np.max(chain.tau)), time.perf_counter() - t0, "mcmc", k, min_ess)
