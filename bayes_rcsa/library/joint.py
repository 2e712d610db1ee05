"""The joint hierarchical posterior of a library, sampled directly with emcee: the check of stage 2.

Everything of the model of :mod:`.hierarchy` is sampled at once: per type the
mean ``a_t`` and slope deviation ``delta_t``, the common slope ``b0``, the
slopes' spread ``tau_b``, ``ln sigma0`` and the spreads' spread ``tau_s``
with ``ln sigma_t = ln sigma0 + tau_s eta_t`` (non-centred), and every
setup's law ``z_s``, either non-centred, ``z_s = a_t + (b0 + tau_b delta_t)
x_s + sigma_t eps_s`` (``eps ~ N(0, I)``; no funnel where the spreads are
small, the bulk of this posterior), or centred, ``z_s`` itself with density
``N(a_t + b_t x_s, sigma_t^2)`` (no funnel where a spread is large against
the setup's likelihood width: the upper tail).  Each setup contributes its
own log-likelihood of ``z_s``, a callable vectorised over walkers.  Nothing
is integrated out here (stage 2 integrates ``a, delta, b0`` and ``ln
sigma0`` in closed form and ``tau_s`` by quadrature), so the agreement of the
two checks those steps too.

A test oracle must say how far it can be trusted: the far tail of a spread
is visited by few walkers at a time (a few excursions move the 95 % end of a
single ensemble by 5-15 % of the interval's width, docs/library.md), so the
sampler runs ``n_runs`` independent ensembles from over-dispersed prior
starts and returns each run's draws with the pooled ones; the between-run
spread of a statistic is its Monte Carlo error (:func:`run_spread`).  Cheap
for a handful of setups only (docs/library.md).

Where a setup's likelihood is far narrower than the population spread (real
identify fits pin the stiffness to ~1e-3 decades) the stretch move mixes too
slowly and under-samples small spreads, even with exactly Gaussian
likelihoods: the sampler is a valid reference for the stand-ins of the
benchmark, not there (docs/library.md, "With real identify posteriors").
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from .population import Hyperprior

__all__ = ["JointModel", "sample_joint", "gaussian_log_likelihood", "pool_runs", "run_spread"]


def gaussian_log_likelihood(m: np.ndarray, C: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``z -> ln N(m; z, C)`` for z (W, d): a setup whose likelihood is exactly Gaussian (the test's stand-in)."""
    P = np.linalg.inv(C)
    _, logdet = np.linalg.slogdet(C)
    const = -0.5 * (logdet + len(m) * np.log(2 * np.pi))

    def f(z: np.ndarray) -> np.ndarray:
        r = z - m
        return const - 0.5 * np.einsum("wi,ij,wj->w", r, P, r)

    return f


class JointModel:
    """The joint log posterior of a library's hierarchical model, every quantity explicit.

    Sampler coordinates (W, ndim), in this order: ``a`` (T, d), ``delta`` (T, d), ``b0`` (d), ``tau_b`` (d),
    ``ln sigma0`` (d), ``tau_s`` (d), ``eta`` (T, d), per setup (n, d) either ``eps`` (non-centred) or ``z``
    (centred), and last each setup's nuisance parameters (``nuisance[s]`` of them, e.g. a real fit's noise
    scales); units those of the population coordinates (docs/theory.md, "Tool-library population").

    Parameters
    ----------
    log_likelihoods : sequence of callables, (n,)
        ``f(z) -> (W,)`` for z (W, d); with nuisance parameters ``f(z, v) -> (W,)``, v (W, nuisance[s]), the
        callable's value including their prior (and ``-inf`` outside the setup's support).
    types : (n,) int, holder type index 0..T-1 of each setup
    x : (n,) covariate ln(d / 10 mm)
    hyper : Hyperprior
    centred : bool, the setups' block is the laws ``z`` themselves (else their standardised deviations ``eps``)
    nuisance : (n,) int or None, nuisance parameters per setup (none by default)
    """

    def __init__(self, log_likelihoods, types, x, hyper: Hyperprior, centred: bool = False, nuisance=None) -> None:
        self.log_likelihoods = list(log_likelihoods)
        self.types = np.asarray(types, dtype=int)
        self.x = np.asarray(x, dtype=float)
        self.hyper = hyper
        self.centred = bool(centred)
        d, n, T = hyper.ndim, len(self.log_likelihoods), int(self.types.max()) + 1
        self.d, self.n, self.T = d, n, T
        self.nuisance = [0] * n if nuisance is None else [int(k) for k in nuisance]
        self.sizes = [T * d, T * d, d, d, d, d, T * d, n * d]
        self.edges = np.cumsum([0] + self.sizes)
        self.v_edges = int(self.edges[-1]) + np.cumsum([0] + self.nuisance)
        self.ndim = int(self.v_edges[-1])

    def pack(self, a, delta, b0, tau_b, ls0, tau_s, eta, last, nuisance=()) -> np.ndarray:
        """Sampler coordinates (W, ndim) of the blocks (each with a leading walker axis W; ``nuisance`` a list
        of (W, nuisance[s]) arrays of the setups that have some)."""
        W = np.shape(a)[0]
        return np.concatenate([np.reshape(v, (W, -1)) for v in (a, delta, b0, tau_b, ls0, tau_s, eta, last)]
                              + [np.reshape(v, (W, -1)) for v in nuisance], axis=1)

    def nuisance_of(self, theta: np.ndarray) -> list:
        """Per setup (W, nuisance[s]) nuisance parameters of (W, ndim) coordinates."""
        return [theta[:, self.v_edges[k]:self.v_edges[k + 1]] for k in range(self.n)]

    def blocks(self, theta: np.ndarray) -> list:
        """The eight blocks of :meth:`pack` of (W, ndim) coordinates."""
        W, e = theta.shape[0], self.edges
        shapes = [(self.T, self.d), (self.T, self.d), (self.d,), (self.d,), (self.d,), (self.d,), (self.T, self.d),
                  (self.n, self.d)]
        return [theta[:, e[i]:e[i + 1]].reshape((W,) + shapes[i]) for i in range(8)]

    def laws(self, theta: np.ndarray):
        """``(a, b, ln sigma)`` per type ((W, T, d) each) and the setups' laws ``z`` (W, n, d)."""
        a, dl, b0, tb, ls0, ts, eta, last = self.blocks(theta)
        b = b0[:, None, :] + tb[:, None, :] * dl
        ls = ls0[:, None, :] + ts[:, None, :] * eta
        if self.centred:
            z = last
        else:
            with np.errstate(over="ignore"):
                z = a[:, self.types, :] + b[:, self.types, :] * self.x[None, :, None] + np.exp(ls[:, self.types, :]) * last
        return a, b, ls, z

    def log_prob(self, theta: np.ndarray) -> np.ndarray:
        """Log joint posterior density (W,) of sampler coordinates (W, ndim), up to the evidence."""
        hyper, types = self.hyper, self.types
        a, dl, b0, tb, ls0, ts, eta, last = self.blocks(theta)
        half = 0.5 * np.log(2.0 / np.pi)
        lp = (-0.5 * np.sum(((a - hyper.a_mean) / hyper.a_sd) ** 2, axis=(1, 2))
              - 0.5 * np.sum(dl * dl, axis=(1, 2)) - 0.5 * np.sum((b0 / hyper.b_sd) ** 2, axis=1)
              + np.sum(half - np.log(hyper.tb_scale) - 0.5 * (tb / hyper.tb_scale) ** 2, axis=1)
              - 0.5 * np.sum(((ls0 - hyper.ls_mean) / hyper.ls_sd) ** 2, axis=1)
              + np.sum(half - np.log(hyper.ts_scale) - 0.5 * (ts / hyper.ts_scale) ** 2, axis=1)
              - 0.5 * np.sum(eta * eta, axis=(1, 2)))
        ls = ls0[:, None, :] + ts[:, None, :] * eta
        ok = (np.all(tb >= 0, axis=1) & np.all(ts >= 0, axis=1) & np.all(np.abs(ls) < 50, axis=(1, 2))
              & np.all(np.abs(ls0) < 50, axis=1))
        ls = np.where(ok[:, None, None], ls, 0.0)  # exp stays finite where the walker is refused anyway
        b = b0[:, None, :] + tb[:, None, :] * dl
        mu = a[:, types, :] + b[:, types, :] * self.x[None, :, None]
        s = np.exp(ls[:, types, :])
        if self.centred:  # z itself: its population density N(mu, s^2)
            z = last
            e = (z - mu) / s
            lp = lp - 0.5 * np.sum(e * e, axis=(1, 2)) - np.sum(np.log(s), axis=(1, 2))
        else:  # eps ~ N(0, 1), z = mu + s eps
            z = mu + s * last
            lp = lp - 0.5 * np.sum(last * last, axis=(1, 2))
        lp = lp - 0.5 * (self.n * self.d + self.d * self.T) * np.log(2 * np.pi)  # normal constants of eta, eps/z
        lp = lp - 0.5 * (2 * self.T * self.d + 2 * self.d) * np.log(2 * np.pi) - np.sum(np.log(hyper.a_sd)) * self.T \
            - np.sum(np.log(hyper.b_sd)) - self.d * np.log(hyper.ls_sd)  # of a, delta, b0, ln sigma0
        v = self.nuisance_of(theta)
        for k, f in enumerate(self.log_likelihoods):
            zk = np.where(ok[:, None], z[:, k, :], 0.0)
            lp = lp + np.where(ok, f(zk, v[k]) if self.nuisance[k] else f(zk), 0.0)
        return np.where(ok, lp, -np.inf)

    def start(self, rng: np.random.Generator, n_walkers: int, laws=None) -> np.ndarray:
        """Over-dispersed start (n_walkers, ndim): spreads, slopes and laws drawn from the prior, type means
        within a tenth of their prior width, so that independent runs start apart.

        ``laws`` (one (N_s, d + nuisance[s]) array per setup, e.g. its stage-1 draws) starts each setup's law
        and nuisance parameters at random rows instead: a real fit's likelihood is far narrower than the
        population and would take a prior start long to find."""
        hyper, T, d, n, W = self.hyper, self.T, self.d, self.n, n_walkers
        a0 = hyper.a_mean + hyper.a_sd * 0.1 * rng.standard_normal((W, T, d))
        dl0 = rng.standard_normal((W, T, d))
        b00 = hyper.b_sd * 0.1 * rng.standard_normal((W, d))
        tb0 = np.abs(hyper.tb_scale * rng.standard_normal((W, d)))
        ls00 = hyper.ls_mean + 0.3 * rng.standard_normal((W, d))
        ts0 = np.abs(hyper.ts_scale * rng.standard_normal((W, d)))
        eta0 = rng.standard_normal((W, T, d))
        last0 = rng.standard_normal((W, n, d))
        nu = [np.zeros((W, k)) for k in self.nuisance if k]
        if laws is not None:
            rows = [np.asarray(v)[rng.integers(0, len(v), W)] for v in laws]
            z0 = np.stack([r[:, :d] for r in rows], axis=1)
            nu = [r[:, d:] for r, k in zip(rows, self.nuisance) if k]
            if self.centred:
                last0 = z0
            else:
                b = b00[:, None, :] + tb0[:, None, :] * dl0
                mu = a0[:, self.types, :] + b[:, self.types, :] * self.x[None, :, None]
                last0 = (z0 - mu) / np.exp(ls00[:, None, :] + ts0[:, None, :] * eta0)[:, self.types, :]
        elif self.centred:
            # the same draws as laws: z = a + b x + sigma eps
            last0 = JointModel(self.log_likelihoods, self.types, self.x, hyper, False).laws(
                self.pack(a0, dl0, b00, tb0, ls00, ts0, eta0, last0))[3]
        return self.pack(a0, dl0, b00, tb0, ls00, ts0, eta0, last0, nu)


def _one_run(model: JointModel, rng, n_steps, n_burn, n_walkers, laws=None, thin=1) -> dict:
    """One emcee ensemble of the joint posterior from an over-dispersed start; see :func:`sample_joint`."""
    import emcee

    sampler = emcee.EnsembleSampler(n_walkers, model.ndim, model.log_prob, vectorize=True,
                                    moves=[(emcee.moves.StretchMove(), 1.0)])
    start = model.start(rng, n_walkers, laws)
    rstate = np.random.RandomState(int(rng.integers(0, 2**32 - 1))).get_state()
    state = sampler.run_mcmc(emcee.State(start, random_state=rstate), n_burn, progress=False)
    sampler.reset()
    sampler.run_mcmc(state, n_steps, thin_by=thin, progress=False)
    flat = sampler.get_chain(flat=True)  # step-major: n_steps x n_walkers rows
    a, b, ls, _ = model.laws(flat)
    s = np.exp(ls)
    return {"types": [np.concatenate([a[:, t], b[:, t], s[:, t]], axis=1) for t in range(model.T)],
            "tau_b": model.blocks(flat)[3],
            "acceptance": float(np.mean(sampler.acceptance_fraction)), "n_walkers": n_walkers}


def sample_joint(log_likelihoods: Sequence[Callable[[np.ndarray], np.ndarray]], types: Sequence[int], x: np.ndarray,
                 hyper: Hyperprior, rng: np.random.Generator, n_steps: int = 6000, n_burn: int = 3000,
                 n_walkers: int = 64, n_runs: int = 1, centred: bool = False, nuisance=None,
                 start_laws=None, thin: int = 1) -> dict:
    """Joint emcee of hyperparameters and setup laws of a library, in ``n_runs`` independent ensembles.

    Parameters
    ----------
    log_likelihoods : sequence of callables, (n,)
        ``f(z) -> (W,)`` for z (W, d) in the population coordinates.
    types : (n,) int, each setup's holder type index 0..T-1 (the order of the stage-2 groups)
    x : (n,) covariate ln(d / 10 mm)
    hyper : Hyperprior
    rng : numpy Generator
    n_steps, n_burn, n_walkers : int, per run (kept draws, burn-in steps, walkers)
    n_runs : int, independent ensembles (each from its own over-dispersed start)
    centred : bool, sample the setups' laws ``z_s`` themselves instead of their standardised deviations
    nuisance : (n,) int or None, nuisance parameters per setup (see :class:`JointModel`)
    start_laws : list of (N_s, d + nuisance[s]) arrays or None, rows to start the laws from (:meth:`JointModel.start`)
    thin : int, steps per kept draw (``n_steps x thin`` steps are run; bounds the memory of long chains)

    Returns
    -------
    dict: ``types`` list of (N, 3d) draws of (a_t, b_t, sigma_t) per type, ``tau_b`` (N, d), pooled over the
    runs (each run's draws in step-major emcee order, ``n_steps x n_walkers`` rows); ``runs`` the same per run,
    with its ``acceptance``
    """
    model = JointModel(log_likelihoods, types, x, hyper, centred, nuisance)
    return pool_runs([_one_run(model, rng, n_steps, n_burn, n_walkers, start_laws, thin) for _ in range(n_runs)])


def pool_runs(runs: Sequence[dict]) -> dict:
    """The pooled draws of independent runs (e.g. ``sample_joint(...)["runs"]`` of both parametrisations), in
    the layout of :func:`sample_joint`."""
    runs = list(runs)
    T = len(runs[0]["types"])
    return {"types": [np.concatenate([r["types"][t] for r in runs]) for t in range(T)],
            "tau_b": np.concatenate([r["tau_b"] for r in runs]), "runs": runs}


def run_spread(joint: dict, statistic: Callable[[dict], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A statistic of the pooled draws and its Monte Carlo standard error from the spread between the runs.

    Parameters
    ----------
    joint : dict of :func:`sample_joint` with ``n_runs >= 2``
    statistic : callable, a run's (or the pooled) dict -> array (e.g. quantiles of a hyperparameter)

    Returns
    -------
    value : the statistic of the pooled draws
    se : its standard error, ``sd between runs / sqrt(n_runs)``
    """
    per = np.array([statistic(r) for r in joint["runs"]])
    if per.shape[0] < 2:
        raise ValueError(f"run_spread needs at least two runs, got {per.shape[0]}")
    return np.asarray(statistic(joint)), per.std(axis=0, ddof=1) / np.sqrt(per.shape[0])
