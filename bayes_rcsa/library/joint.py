"""The joint hierarchical posterior of a library, sampled directly with emcee: the check of stage 2.

Everything of the model of :mod:`.hierarchy` is sampled at once, explicitly
and non-centred: per type the mean ``a_t`` and slope deviation ``delta_t``,
the common slope ``b0``, the slopes' spread ``tau_b``, ``ln sigma0`` and the
spreads' spread ``tau_s`` with ``ln sigma_t = ln sigma0 + tau_s eta_t``, and
every setup's law ``z_s = a_t + (b0 + tau_b delta_t) x_s + sigma_t eps_s``
(``eta, eps ~ N(0, I)``; the non-centred form avoids the funnels of small
spreads).  Each setup contributes its own log-likelihood of ``z_s``, a
callable vectorised over walkers.  Nothing is integrated out here (stage 2
integrates ``a, delta, b0`` and ``ln sigma0`` in closed form and ``tau_s``
by quadrature), so the agreement of the two checks those steps too.  Cheap
for a handful of setups only (docs/library.md).
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


def sample_joint(log_likelihoods: Sequence[Callable[[np.ndarray], np.ndarray]], types: Sequence[int], x: np.ndarray,
                 hyper: Hyperprior, rng: np.random.Generator, n_steps: int = 6000, n_burn: int = 3000,
                 n_walkers: int = 64) -> dict:
    """Joint emcee of hyperparameters and setup laws of a library.

    Parameters
    ----------
    log_likelihoods : sequence of callables, (n,)
        ``f(z) -> (W,)`` for z (W, d) in the population coordinates.
    types : (n,) int, each setup's holder type index 0..T-1 (the order of the stage-2 groups)
    x : (n,) covariate ln(d / 10 mm)
    hyper : Hyperprior
    rng : numpy Generator
    n_steps, n_burn, n_walkers : int

    Returns
    -------
    dict: ``types`` list of (N, 3d) draws of (a_t, b_t, sigma_t) per type, ``tau_b`` (N, d)
    """
    import emcee

    d, n = hyper.ndim, len(log_likelihoods)
    types = np.asarray(types, dtype=int)
    T = int(types.max()) + 1
    x = np.asarray(x, dtype=float)
    # layout: a (T d), delta (T d), b0 (d), tau_b (d), ln sigma0 (d), tau_s (d), eta (T d), eps (n d)
    sizes = [T * d, T * d, d, d, d, d, T * d, n * d]
    edges = np.cumsum([0] + sizes)
    ndim = int(edges[-1])
    half = 0.5 * np.log(2.0 / np.pi)

    def parts(theta):
        p = [theta[:, edges[i]:edges[i + 1]] for i in range(len(sizes))]
        W = theta.shape[0]
        return (p[0].reshape(W, T, d), p[1].reshape(W, T, d), p[2], p[3], p[4], p[5], p[6].reshape(W, T, d),
                p[7].reshape(W, n, d))

    def values(theta):
        a, dl, b0, tb, ls0, ts, eta, eps = parts(theta)
        b = b0[:, None, :] + tb[:, None, :] * dl
        s = np.exp(ls0[:, None, :] + ts[:, None, :] * eta)
        return a, b, s, eps, tb, ts, ls0, dl, b0

    def log_post(theta):
        a, b, s, eps, tb, ts, ls0, dl, b0 = values(theta)
        lp = (-0.5 * np.sum(((a - hyper.a_mean) / hyper.a_sd) ** 2, axis=(1, 2))
              - 0.5 * np.sum(dl * dl, axis=(1, 2)) - 0.5 * np.sum((b0 / hyper.b_sd) ** 2, axis=1)
              + np.sum(half - np.log(hyper.tb_scale) - 0.5 * (tb / hyper.tb_scale) ** 2, axis=1)
              - 0.5 * np.sum(((ls0 - hyper.ls_mean) / hyper.ls_sd) ** 2, axis=1)
              + np.sum(half - np.log(hyper.ts_scale) - 0.5 * (ts / hyper.ts_scale) ** 2, axis=1)
              - 0.5 * np.sum(theta[:, edges[6]:] ** 2, axis=1))
        ok = np.all(tb >= 0, axis=1) & np.all(ts >= 0, axis=1) & np.all(np.abs(ls0) < 50, axis=1)
        z = a[:, types, :] + b[:, types, :] * x[None, :, None] + s[:, types, :] * eps
        for k, f in enumerate(log_likelihoods):
            lp = lp + np.where(ok, f(np.where(ok[:, None], z[:, k, :], 0.0)), 0.0)
        return np.where(ok, lp, -np.inf)

    # a long burn-in from prior draws keeps the check independent of stage 2's start
    start = np.empty((n_walkers, ndim))
    start[:, edges[0]:edges[1]] = (hyper.a_mean + hyper.a_sd * 0.1 * rng.standard_normal((n_walkers, T, d))).reshape(n_walkers, -1)
    start[:, edges[1]:edges[2]] = rng.standard_normal((n_walkers, T * d))
    start[:, edges[2]:edges[3]] = hyper.b_sd * 0.1 * rng.standard_normal((n_walkers, d))
    start[:, edges[3]:edges[4]] = np.abs(hyper.tb_scale * rng.standard_normal((n_walkers, d)))
    start[:, edges[4]:edges[5]] = hyper.ls_mean + 0.3 * rng.standard_normal((n_walkers, d))
    start[:, edges[5]:edges[6]] = np.abs(hyper.ts_scale * rng.standard_normal((n_walkers, d)))
    start[:, edges[6]:] = rng.standard_normal((n_walkers, ndim - edges[6]))
    sampler = emcee.EnsembleSampler(n_walkers, ndim, log_post, vectorize=True,
                                    moves=[(emcee.moves.StretchMove(), 1.0)])
    rstate = np.random.RandomState(int(rng.integers(0, 2**32 - 1))).get_state()
    state = sampler.run_mcmc(emcee.State(start, random_state=rstate), n_burn, progress=False)
    sampler.reset()
    sampler.run_mcmc(state, n_steps, progress=False)
    flat = sampler.get_chain(flat=True)
    a, b, s, _, tb, _, _, _, _ = values(flat)
    return {"types": [np.concatenate([a[:, t], b[:, t], s[:, t]], axis=1) for t in range(T)], "tau_b": tb}
