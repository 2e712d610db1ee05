"""The joint hierarchical posterior of one holder type, sampled directly with emcee: the check of stage 2.

Everything is sampled at once: the hyperparameters ``(a, b, sigma)`` and
every setup's law, non-centred, ``z_s = a + b x_s + sigma * eps_s`` with
``eps_s ~ N(0, I)`` (the non-centred form avoids the funnel of a small
spread).  Each setup contributes its own log-likelihood of ``z_s``, a
callable vectorised over walkers.  Cheap for a handful of setups only; the
two-stage result (:mod:`.stage2`) must agree with it (docs/library.md).
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from .population import Hyperprior

__all__ = ["sample_joint", "gaussian_log_likelihood"]


def gaussian_log_likelihood(m: np.ndarray, C: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``z -> ln N(m; z, C)`` for z (W, d): a setup whose likelihood is exactly Gaussian (the test's stand-in)."""
    P = np.linalg.inv(C)
    _, logdet = np.linalg.slogdet(C)
    const = -0.5 * (logdet + len(m) * np.log(2 * np.pi))

    def f(z: np.ndarray) -> np.ndarray:
        r = z - m
        return const - 0.5 * np.einsum("wi,ij,wj->w", r, P, r)

    return f


def sample_joint(log_likelihoods: Sequence[Callable[[np.ndarray], np.ndarray]], x: np.ndarray, hyper: Hyperprior,
                 rng: np.random.Generator, n_steps: int = 6000, n_burn: int = 3000,
                 n_walkers: int = 64) -> np.ndarray:
    """Joint emcee of hyperparameters and setup laws of one holder type.

    Parameters
    ----------
    log_likelihoods : sequence of callables, (n,)
        ``f(z) -> (W,)`` for z (W, d) in the population coordinates.
    x : (n,) covariate ln(d / 10 mm)
    hyper : Hyperprior
    rng : numpy Generator
    n_steps, n_burn, n_walkers : int

    Returns
    -------
    (n_walkers * n_steps, 3d) draws of (a, b, sigma)
    """
    import emcee

    d, n = hyper.ndim, len(log_likelihoods)
    x = np.asarray(x, dtype=float)
    ndim = 3 * d + n * d

    def log_post(theta):
        a, b, s = theta[:, :d], theta[:, d:2 * d], theta[:, 2 * d:3 * d]
        eps = theta[:, 3 * d:].reshape(-1, n, d)
        lp = hyper.ln_prob(a, b, s) - 0.5 * np.sum(eps * eps, axis=(1, 2))
        ok = np.isfinite(lp)
        z = a[:, None, :] + b[:, None, :] * x[None, :, None] + s[:, None, :] * eps
        for s, f in enumerate(log_likelihoods):
            lp = lp + np.where(ok, f(z[:, s, :]), 0.0)
        return np.where(ok, lp, -np.inf)

    start = np.concatenate([hyper.sample(rng, n_walkers), rng.standard_normal((n_walkers, n * d))], axis=1)
    # the hyperprior is broad: start the spreads small and the means near the data's centre is not needed;
    # a long burn-in from prior draws keeps the check independent of stage 2's start
    sampler = emcee.EnsembleSampler(n_walkers, ndim, log_post, vectorize=True,
                                    moves=[(emcee.moves.StretchMove(), 1.0)])
    rstate = np.random.RandomState(int(rng.integers(0, 2**32 - 1))).get_state()
    state = sampler.run_mcmc(emcee.State(start, random_state=rstate), n_burn, progress=False)
    sampler.reset()
    sampler.run_mcmc(state, n_steps, progress=False)
    return sampler.get_chain(flat=True)[:, :3 * d]
