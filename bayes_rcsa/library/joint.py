"""The joint hierarchical posterior of a library, sampled directly: the check of stage 2.

Two samplers of the same model: emcee (:func:`sample_joint`, the stretch move on everything at once) and
Metropolis-within-Gibbs (:func:`sample_gibbs`, :class:`GibbsJoint`), the reference where real identify fits
pin the setups' laws (see the last paragraph).

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
identify fits pin the stiffness to ~3e-4 decades against a spread of ~0.06)
the stretch move mixes too slowly and over-states the spreads, even with
exactly Gaussian likelihoods (acceptance ~0.09): emcee is a valid reference
for the benchmark's stand-ins, not there.  The Gibbs sampler is: given the
laws, the means, slopes and common slope are drawn from their exact
conditional normal and the log spreads, ``tau_b`` and ``tau_s`` are
slice-sampled with the linear hyperparameters (resp. ``ln sigma0``)
integrated out, so the narrow laws never have to move together with the
hyperparameters; each law moves by random-walk Metropolis under its own
likelihood, shaped by its stage-1 covariance (docs/library.md, "With real
identify posteriors").  Independent chains run as one batch through each
likelihood; R-hat and ESS over the chains
(:func:`bayes_rcsa.inference.diagnostics.chain_diagnostics` of
``np.swapaxes(out["chains"], 0, 1)``: it takes steps first) say how far a
run can be trusted.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from .population import Hyperprior

__all__ = ["JointModel", "sample_joint", "gaussian_log_likelihood", "pool_runs", "run_spread", "GibbsJoint", "sample_gibbs",
           "slice_step"]


class _GaussianLogLikelihood:
    """``z -> ln N(m; z, C)`` for z (W, d), with its parts kept (``m`` (d,), ``P = C^-1`` (d, d), ``const``) so
    that :class:`JointModel` can evaluate all of its Gaussian setups in one batch (the same numbers)."""

    def __init__(self, m: np.ndarray, C: np.ndarray) -> None:
        self.m = m
        self.P = np.linalg.inv(C)
        _, logdet = np.linalg.slogdet(C)
        self.const = -0.5 * (logdet + len(m) * np.log(2 * np.pi))

    def __call__(self, z: np.ndarray) -> np.ndarray:
        r = z - self.m
        return self.const - 0.5 * np.einsum("wi,ij,wj->w", r, self.P, r)


def gaussian_log_likelihood(m: np.ndarray, C: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``z -> ln N(m; z, C)`` for z (W, d): a setup whose likelihood is exactly Gaussian (the test's stand-in)."""
    return _GaussianLogLikelihood(m, C)


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
        # the constants of log_prob, computed once (the same expressions, so the same numbers)
        half = 0.5 * np.log(2.0 / np.pi)
        self._c_tb, self._c_ts = half - np.log(hyper.tb_scale), half - np.log(hyper.ts_scale)
        self._c_normal = 0.5 * (n * d + d * T) * np.log(2 * np.pi)
        self._c_prior = (0.5 * (2 * T * d + 2 * d) * np.log(2 * np.pi), np.sum(np.log(hyper.a_sd)) * T,
                         np.sum(np.log(hyper.b_sd)), d * np.log(hyper.ls_sd))
        self._gaussian = None  # every setup exactly Gaussian, without nuisance: (m, P, const) stacked over setups
        if n and not any(self.nuisance) and all(isinstance(f, _GaussianLogLikelihood)
                                               and np.shape(f.m) == (d,) for f in self.log_likelihoods):
            self._gaussian = (np.stack([np.asarray(f.m, dtype=float) for f in self.log_likelihoods]),
                              np.stack([f.P for f in self.log_likelihoods]),
                              np.array([f.const for f in self.log_likelihoods]))

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

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """:meth:`log_prob` (the density protocol of :func:`bayes_rcsa.inference.sampler.run_ensemble`)."""
        return self.log_prob(theta)

    def check_inside(self, theta: np.ndarray, what: str) -> None:
        """Raise :class:`~bayes_rcsa.errors.SetupError` naming the first row of theta (W, ndim) of zero density."""
        from ..errors import SetupError

        bad = ~np.isfinite(self.log_prob(np.atleast_2d(theta)))
        if np.any(bad):
            raise SetupError(f"joint library model: {what} {int(np.argmax(bad))} has zero posterior density "
                             "(a negative spread, or outside a setup's support)")

    def log_prob(self, theta: np.ndarray) -> np.ndarray:
        """Log joint posterior density (W,) of sampler coordinates (W, ndim), up to the evidence."""
        hyper, types = self.hyper, self.types
        a, dl, b0, tb, ls0, ts, eta, last = self.blocks(theta)
        lp = (-0.5 * np.sum(((a - hyper.a_mean) / hyper.a_sd) ** 2, axis=(1, 2))
              - 0.5 * np.sum(dl * dl, axis=(1, 2)) - 0.5 * np.sum((b0 / hyper.b_sd) ** 2, axis=1)
              + np.sum(self._c_tb - 0.5 * (tb / hyper.tb_scale) ** 2, axis=1)
              - 0.5 * np.sum(((ls0 - hyper.ls_mean) / hyper.ls_sd) ** 2, axis=1)
              + np.sum(self._c_ts - 0.5 * (ts / hyper.ts_scale) ** 2, axis=1)
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
        lp = lp - self._c_normal  # normal constants of eta, eps/z
        c = self._c_prior  # of a, delta, b0, ln sigma0
        lp = lp - c[0] - c[1] - c[2] - c[3]
        if self._gaussian is not None:
            # every setup's _GaussianLogLikelihood in one batch (the same products and sums, setup by setup),
            # added to lp in the order of the setups
            m, P, const = self._gaussian
            r = np.where(ok[:, None, None], z, 0.0) - m
            ll = np.where(ok[:, None], const - 0.5 * np.einsum("wki,kij,wkj->wk", r, P, r), 0.0)
            for k in range(self.n):
                lp = lp + ll[:, k]
            return np.where(ok, lp, -np.inf)
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
    """One emcee ensemble of the joint posterior from an over-dispersed start; see :func:`sample_joint`.

    Run by the package's emcee driver (:func:`bayes_rcsa.inference.sampler.run_ensemble`) in fixed-steps mode:
    ``n_burn + n_steps x thin`` stretch-move steps, every ``thin``-th kept, the first ``n_burn`` steps burn-in;
    the driver's verdict on convergence, tau, R-hat and bulk ESS are returned with the draws.
    """
    from ..inference.sampler import SamplerSettings, run_ensemble

    start = model.start(rng, n_walkers, laws)
    total = n_burn + n_steps * thin
    settings = SamplerSettings(n_walkers=n_walkers, n_steps=total, n_burn=n_burn, store_every=thin,
                               check_every=max(1, total // 4), move="stretch", progress=False)
    run = run_ensemble(model, settings, initial=start, rng=rng)
    flat = run.chain[run.burn:].reshape(-1, model.ndim)  # step-major: n_steps x n_walkers rows
    a, b, ls, _ = model.laws(flat)
    s = np.exp(ls)
    diag = run.diagnostics or {}
    return {"types": [np.concatenate([a[:, t], b[:, t], s[:, t]], axis=1) for t in range(model.T)],
            "tau_b": model.blocks(flat)[3],
            "acceptance": float(np.mean(run.acceptance_fraction)), "n_walkers": n_walkers,
            "converged": run.converged, "convergence": run.reason, "tau_steps": run.tau * thin,
            "rhat": diag.get("rhat"), "ess_bulk": diag.get("ess_bulk")}


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
    with its ``acceptance`` (over all its steps), and the sampler driver's ``converged``, ``convergence`` (the
    reason), ``tau_steps``, ``rhat`` and ``ess_bulk`` (:func:`bayes_rcsa.inference.sampler.run_ensemble`,
    fixed-steps mode: ``n_burn`` steps of burn-in, checked against three autocorrelation times)
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


# ----------------------------------------------------------------------------------------------------------------
# Metropolis-within-Gibbs: the reference where real fits pin the laws (the funnel that stops the stretch move)
# ----------------------------------------------------------------------------------------------------------------


def slice_step(x0: np.ndarray, logf: Callable[[np.ndarray], np.ndarray], w: np.ndarray, rng: np.random.Generator,
               m: int = 32, max_shrink: int = 200) -> tuple[np.ndarray, int]:
    """One univariate slice-sampling update (stepping out and shrinkage, Neal 2003) of many independent targets.

    Parameters
    ----------
    x0 : (N...) current values, one per independent univariate target
    logf : callable, values of the shape of ``x0`` -> their log densities (elementwise, up to constants)
    w : (N...) or float, initial interval width (may depend on anything but ``x0``)
    rng : numpy Generator
    m : int, at most ``m`` widths of stepping out
    max_shrink : int, shrinkage steps at most; an element not accepted by then keeps ``x0`` (valid: the
        update is then the identity for it) and is counted

    Returns
    -------
    x1 : new values, the shape of ``x0``
    stuck : number of elements that kept ``x0`` after ``max_shrink`` shrinkages
    """
    x0 = np.asarray(x0, dtype=float)
    w = np.broadcast_to(np.asarray(w, dtype=float), x0.shape)
    ly = logf(x0) - rng.exponential(size=x0.shape)
    L = x0 - w * rng.uniform(size=x0.shape)
    R = L + w
    J = np.floor(m * rng.uniform(size=x0.shape))
    L = _step_out(L, -w, J, logf, ly)
    R = _step_out(R, w, (m - 1) - J, logf, ly)
    x1 = x0.copy()
    todo = np.ones(x0.shape, dtype=bool)
    for _ in range(max_shrink):
        xp = L + (R - L) * rng.uniform(size=x0.shape)
        ok = todo & (logf(np.where(todo, xp, x0)) > ly)
        x1 = np.where(ok, xp, x1)
        todo &= ~ok
        if not np.any(todo):
            break
        left = todo & (xp < x0)
        L = np.where(left, xp, L)
        R = np.where(todo & ~left, xp, R)
    return x1, int(np.sum(todo))


def _step_out(edge: np.ndarray, step: np.ndarray, budget: np.ndarray, logf, ly: np.ndarray) -> np.ndarray:
    """Move each interval end by ``step`` while it lies inside its slice (``logf > ly``), at most ``budget`` times."""
    while True:
        go = budget > 0
        if not np.any(go):
            return edge
        go &= logf(edge) > ly
        if not np.any(go):
            return edge
        edge = np.where(go, edge + step, edge)
        budget = np.where(go, budget - 1, 0)


def _cholesky(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched Cholesky factors of (..., k, k) and a mask (...) of the matrices that are not positive definite in
    floating point (their factor is the identity, the caller's density ``-inf``)."""
    try:
        return np.linalg.cholesky(A), np.zeros(A.shape[:-2], dtype=bool)
    except np.linalg.LinAlgError:
        L, bad = np.zeros_like(A), np.zeros(A.shape[:-2], dtype=bool)
        for i in np.ndindex(*A.shape[:-2]):
            try:
                L[i] = np.linalg.cholesky(A[i])
            except np.linalg.LinAlgError:
                L[i], bad[i] = np.eye(A.shape[-1]), True
        return L, bad


def _ln_half_normal(v: np.ndarray, scale) -> np.ndarray:
    return 0.5 * np.log(2.0 / np.pi) - np.log(scale) - 0.5 * (v / scale) ** 2


class GibbsJoint:
    """Metropolis-within-Gibbs for the joint model of :class:`JointModel` (centred laws and log spreads).

    State per chain: per type ``a`` (T, d), ``delta`` (T, d) and ``u = ln sigma`` (T, d); per coordinate
    ``b0``, ``tau_b``, ``ls0 = ln sigma0``, ``tau_s`` (d,); per setup the law ``z`` (n, d) and its nuisance
    parameters.  Given the laws, the hyperparameters of different coordinates are independent (the population
    is diagonal), so every hyperparameter update is vectorised over (chains, coordinates).  One iteration:

    1. each setup's law (and nuisance parameters): random-walk Metropolis under its own likelihood times the
       population density ``N(z; a_t + b_t x, sigma_t^2)``, proposal ``N(0, s^2 (S^-1 + diag sigma_t^-2)^-1)``
       with ``S`` the covariance of its stage-1 draws (the proposal depends on the spreads, which this step
       holds fixed, so it stays symmetric), the scale ``s`` adapted during burn-in only;
    2. per type ``u_t`` and then ``tau_b`` by slice sampling of their conditional with ``beta = (a, delta,
       b0)`` integrated out (per coordinate the laws are then one Gaussian vector ``N(X mu0, X V0 X^T + D)``,
       written out densely), then ``beta`` from its exact conditional normal (partially collapsed Gibbs: the
       collapsed steps come before the draw of what they integrate out, so the joint stays invariant);
    3. ``tau_s`` by slice sampling with ``ls0`` integrated out (``u_.j ~ N(ls_mean, tau_s^2 I + ls_sd^2
       1 1^T)``), then ``ls0`` from its exact conditional normal.

    ``tau_b`` and ``tau_s`` are sliced in their logarithms (with the Jacobian).  Nothing here calls stage 2's
    code; the conditionals are checked against :meth:`JointModel.log_prob` in tests/test_library_joint.py.

    Parameters
    ----------
    log_likelihoods, types, x, hyper, nuisance : as :class:`JointModel`
    proposal_cov : list of (d + nuisance[s], d + nuisance[s]) arrays, per setup the covariance of its
        stage-1 posterior (law then nuisance parameters)
    """

    def __init__(self, log_likelihoods, types, x, hyper: Hyperprior, proposal_cov, nuisance=None) -> None:
        self.lls = list(log_likelihoods)
        self.types = np.asarray(types, dtype=int)
        self.x = np.asarray(x, dtype=float)
        self.hyper = hyper
        self.n, self.d, self.T = len(self.lls), hyper.ndim, int(self.types.max()) + 1
        self.nuisance = [0] * self.n if nuisance is None else [int(k) for k in nuisance]
        self.S_inv = [np.linalg.inv(np.asarray(S, dtype=float)) for S in proposal_cov]
        d, T = self.d, self.T
        self.K = 2 * T + 1  # per coordinate: a_1..a_T, delta_1..delta_T, b0
        self.mu0 = np.concatenate([np.tile(hyper.a_mean[:, None], (1, T)), np.zeros((d, T)), np.zeros((d, 1))],
                                  axis=1)  # (d, K)
        self.var0 = np.concatenate([np.tile((hyper.a_sd ** 2)[:, None], (1, T)), np.ones((d, T)),
                                    (hyper.b_sd ** 2)[:, None]], axis=1)  # (d, K)
        self.scale = np.full(self.n, 2.38 / np.sqrt([d + k for k in self.nuisance]))

    # -- the linear-Gaussian part: beta = (a, delta, b0) per coordinate --------------------------------------
    def design(self, tau_b: np.ndarray) -> np.ndarray:
        """X (C, d, n, K): row s of coordinate j maps beta_j to ``a_t + (b0 + tau_b delta_t) x_s``."""
        C, n, T = tau_b.shape[0], self.n, self.T
        X = np.zeros((C, self.d, n, self.K))
        s = np.arange(n)
        X[:, :, s, self.types] = 1.0
        X[:, :, s, T + self.types] = tau_b[:, :, None] * self.x
        X[:, :, s, 2 * T] = self.x
        return X

    def collapsed(self, z: np.ndarray, u: np.ndarray, tau_b: np.ndarray) -> np.ndarray:
        """``ln p(z_.j | u_.j, tau_b,j)`` (C, d) with beta integrated out: ``N(X mu0, X V0 X^T + D)`` per coordinate.

        z (C, n, d) laws, u (C, T, d) log spreads, tau_b (C, d)."""
        X = self.design(tau_b)
        D = np.exp(2.0 * u[:, self.types, :])  # (C, n, d)
        Sig = np.einsum("cjnk,jk,cjmk->cjnm", X, self.var0, X)
        Sig[..., np.arange(self.n), np.arange(self.n)] += np.swapaxes(D, 1, 2)
        r = np.swapaxes(z, 1, 2) - np.einsum("cjnk,jk->cjn", X, self.mu0)
        L, bad = _cholesky(Sig)
        y = np.linalg.solve(L, r[..., None])[..., 0]
        logdet = 2.0 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
        return np.where(bad, -np.inf, -0.5 * (np.sum(y * y, axis=-1) + logdet + self.n * np.log(2 * np.pi)))

    def beta_conditional(self, z: np.ndarray, u: np.ndarray, tau_b: np.ndarray):
        """Conditional normal of beta given laws, spreads and tau_b: mean (C, d, K) and the Cholesky factor
        (C, d, K, K) of its precision ``diag(1 / V0) + X^T D^-1 X``."""
        X = self.design(tau_b)
        Dinv = np.exp(-2.0 * u[:, self.types, :])  # (C, n, d)
        P = np.einsum("cjnk,cnj,cjnl->cjkl", X, Dinv, X)
        P[..., np.arange(self.K), np.arange(self.K)] += 1.0 / self.var0
        h = self.mu0 / self.var0 + np.einsum("cjnk,cnj,cnj->cjk", X, Dinv, z)
        Lp = np.linalg.cholesky(P)
        mean = np.linalg.solve(np.swapaxes(Lp, -1, -2), np.linalg.solve(Lp, h[..., None]))[..., 0]
        return mean, Lp

    # -- the log spreads' level and spread ---------------------------------------------------------------------
    def ls_collapsed(self, u: np.ndarray, tau_s: np.ndarray) -> np.ndarray:
        """``ln HalfNormal(tau_s) + ln p(u_.j | tau_s)`` (C, d) with ``ls0`` integrated out: per coordinate
        ``u_.j ~ N(ls_mean_j 1, tau_s^2 I + ls_sd^2 1 1^T)``.

        Written with the deviations from the types' mean ``ubar`` (exact, and stable for tau_s -> 0, where the
        dense matrix is singular in floating point): the quadratic form is ``sum_t (u_t - ubar)^2 / tau_s^2 +
        T (ubar - ls_mean)^2 / (tau_s^2 + T ls_sd^2)``, the determinant ``tau_s^(2 (T - 1)) (tau_s^2 + T ls_sd^2)``."""
        T, h = self.T, self.hyper
        t2, c = tau_s ** 2, h.ls_sd ** 2
        ubar = np.mean(u, axis=1)
        with np.errstate(divide="ignore"):
            q = np.sum((u - ubar[:, None, :]) ** 2, axis=1) / t2 + T * (ubar - h.ls_mean) ** 2 / (t2 + T * c)
            logdet = (T - 1) * np.log(t2) + np.log(t2 + T * c)
        return _ln_half_normal(tau_s, h.ts_scale) - 0.5 * (q + logdet + T * np.log(2 * np.pi))

    def ls0_conditional(self, u: np.ndarray, tau_s: np.ndarray):
        """Mean and sd (C, d) of ``ls0`` given the log spreads u (C, T, d) and tau_s (C, d)."""
        h = self.hyper
        prec = 1.0 / h.ls_sd ** 2 + self.T / tau_s ** 2
        mean = (h.ls_mean / h.ls_sd ** 2 + np.sum(u, axis=1) / tau_s ** 2) / prec
        return mean, 1.0 / np.sqrt(prec)

    # -- the laws ----------------------------------------------------------------------------------------------
    def law_log_target(self, k: int, w: np.ndarray, mu: np.ndarray, sig: np.ndarray) -> np.ndarray:
        """Setup k's own log likelihood of w = (law, nuisance) (C, d + nuisance) plus its population density
        ``N(law; mu, sig^2)`` (mu, sig (C, d))."""
        z = w[:, :self.d]
        e = (z - mu) / sig
        pop = -0.5 * np.sum(e * e, axis=1)
        ok = np.isfinite(pop)
        zz = np.where(ok[:, None], z, mu)
        ll = self.lls[k](zz, w[:, self.d:]) if self.nuisance[k] else self.lls[k](zz)
        return np.where(ok, ll + pop, -np.inf)

    def law_steps(self, st: dict, rng: np.random.Generator, n_steps: int, adapt: float = 0.0) -> np.ndarray:
        """``n_steps`` random-walk Metropolis updates of every setup's law and nuisance parameters; returns the
        acceptance rate per setup (n,).  ``adapt > 0`` moves each setup's proposal scale toward an acceptance of
        0.3 (burn-in only)."""
        b = st["b0"][:, None, :] + st["tau_b"][:, None, :] * st["delta"]
        sig_t = np.exp(st["u"])
        acc = np.zeros(self.n)
        for k in range(self.n):
            t = self.types[k]
            mu = st["a"][:, t, :] + b[:, t, :] * self.x[k]
            sig = sig_t[:, t, :]
            D = self.d + self.nuisance[k]
            Q = np.broadcast_to(self.S_inv[k], (sig.shape[0], D, D)).copy()
            Q[:, np.arange(self.d), np.arange(self.d)] += sig ** -2
            LQ = np.linalg.cholesky(Q)  # proposal covariance scale^2 Q^-1 = scale^2 LQ^-T LQ^-1
            w = st["w"][k]
            lp = self.law_log_target(k, w, mu, sig)
            for _ in range(n_steps):
                step = np.linalg.solve(np.swapaxes(LQ, 1, 2), rng.standard_normal((w.shape[0], D, 1)))[..., 0]
                wp = w + self.scale[k] * step
                lpp = self.law_log_target(k, wp, mu, sig)
                ok = np.log(rng.uniform(size=lp.shape)) < lpp - lp
                w = np.where(ok[:, None], wp, w)
                lp = np.where(ok, lpp, lp)
                rate = float(np.mean(ok))
                acc[k] += rate / n_steps
                if adapt > 0:
                    self.scale[k] *= np.exp(adapt * (rate - 0.3))
            st["w"][k] = w
        st["z"] = np.stack([w[:, :self.d] for w in st["w"]], axis=1)
        return acc

    # -- one iteration -----------------------------------------------------------------------------------------
    def hyper_steps(self, st: dict, rng: np.random.Generator) -> int:
        """Steps 2 and 3 of the class docstring (every hyperparameter given the laws); returns the number of
        slice updates that kept their value after the shrinkage limit."""
        h, z, stuck = self.hyper, st["z"], 0
        for t in range(self.T):  # u_t given the other types' u, tau_b, ls0, tau_s; beta integrated out
            def f_u(v, t=t):
                u = st["u"].copy()
                u[:, t, :] = v
                e = (v - st["ls0"]) / st["tau_s"]
                with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                    out = -0.5 * e * e + self.collapsed(z, u, st["tau_b"])
                return np.where(np.abs(v) < 50, out, -np.inf)

            st["u"][:, t, :], k = slice_step(st["u"][:, t, :], f_u, np.minimum(1.0, 3.0 * st["tau_s"] + 0.05), rng)
            stuck += k

        def f_tb(y):
            tb = np.exp(np.minimum(y, 30.0))
            return np.where(y < 30, _ln_half_normal(tb, h.tb_scale) + y + self.collapsed(z, st["u"], tb), -np.inf)

        y, k = slice_step(np.log(st["tau_b"]), f_tb, 1.0, rng)
        st["tau_b"], stuck = np.exp(y), stuck + k
        mean, Lp = self.beta_conditional(z, st["u"], st["tau_b"])
        beta = mean + np.linalg.solve(np.swapaxes(Lp, -1, -2), rng.standard_normal(mean.shape)[..., None])[..., 0]
        T = self.T
        st["a"], st["delta"], st["b0"] = (np.swapaxes(beta[..., :T], 1, 2), np.swapaxes(beta[..., T:2 * T], 1, 2),
                                          beta[..., 2 * T])

        def f_ts(y):
            ts = np.exp(np.clip(y, -60.0, 30.0))
            return np.where((y > -60) & (y < 30), self.ls_collapsed(st["u"], ts) + y, -np.inf)

        y, k = slice_step(np.log(st["tau_s"]), f_ts, 1.0, rng)
        st["tau_s"], stuck = np.exp(y), stuck + k
        m, s = self.ls0_conditional(st["u"], st["tau_s"])
        st["ls0"] = m + s * rng.standard_normal(m.shape)
        return stuck

    def start(self, rng: np.random.Generator, n_chains: int, laws) -> dict:
        """Over-dispersed start: laws (and nuisance parameters) at random rows of ``laws`` (one (N_s, d +
        nuisance[s]) array per setup, e.g. its stage-1 draws), spreads and their hyperparameters from the
        prior; beta is drawn from its conditional by the first iteration."""
        h, C, T, d = self.hyper, n_chains, self.T, self.d
        w = [np.asarray(v, dtype=float)[rng.integers(0, len(v), C)] for v in laws]
        ls0 = h.ls_mean + h.ls_sd * rng.standard_normal((C, d))
        tau_s = np.abs(h.ts_scale * rng.standard_normal((C, d))) + 1e-3
        u = ls0[:, None, :] + tau_s[:, None, :] * rng.standard_normal((C, T, d))
        tau_b = np.abs(h.tb_scale * rng.standard_normal((C, d))) + 1e-3 * h.tb_scale
        st = {"w": w, "z": np.stack([v[:, :d] for v in w], axis=1), "u": u, "tau_b": tau_b, "ls0": ls0,
              "tau_s": tau_s}
        mean, Lp = self.beta_conditional(st["z"], u, tau_b)
        beta = mean + np.linalg.solve(np.swapaxes(Lp, -1, -2), rng.standard_normal(mean.shape)[..., None])[..., 0]
        st["a"], st["delta"], st["b0"] = (np.swapaxes(beta[..., :T], 1, 2), np.swapaxes(beta[..., T:2 * T], 1, 2),
                                          beta[..., 2 * T])
        return st

    def hyperparameters(self, st: dict) -> np.ndarray:
        """(C, T 3d + d) the compared hyperparameters of a state: per type (a_t, b_t, sigma_t), then tau_b."""
        b = st["b0"][:, None, :] + st["tau_b"][:, None, :] * st["delta"]
        per = np.concatenate([st["a"], b, np.exp(st["u"])], axis=2)  # (C, T, 3d)
        return np.concatenate([per.reshape(per.shape[0], -1), st["tau_b"]], axis=1)


def sample_gibbs(log_likelihoods: Sequence[Callable], types: Sequence[int], x: np.ndarray, hyper: Hyperprior,
                 rng: np.random.Generator, laws: Sequence[np.ndarray], n_iter: int = 4000, n_burn: int = 1000,
                 n_chains: int = 32, nuisance=None, law_steps: int = 4, thin: int = 1, n_groups: int = 4) -> dict:
    """The joint posterior by Metropolis-within-Gibbs (:class:`GibbsJoint`), ``n_chains`` independent chains
    advanced together (one likelihood call per setup and step for all chains).

    Parameters
    ----------
    log_likelihoods, types, x, hyper, nuisance : as :func:`sample_joint`
    rng : numpy Generator
    laws : list of (N_s, d + nuisance[s]) arrays, per setup its stage-1 draws (law then nuisance parameters):
        the chains start at random rows, and their covariance shapes the law proposal
    n_iter, n_burn : int, kept and burn-in iterations (the proposal scales adapt during burn-in only)
    n_chains : int, independent chains
    law_steps : int, Metropolis updates of every law per iteration
    thin : int, iterations per kept draw
    n_groups : int, the chains are split into this many groups, the ``runs`` of :func:`run_spread`

    Returns
    -------
    dict in the layout of :func:`sample_joint` (``types``, ``tau_b``, ``runs``; each run a group of chains) and
    ``chains`` (n_chains, n_kept, T 3d + d): per chain the hyperparameters (per type a, b, sigma; tau_b) for
    R-hat and ESS; ``law_acceptance`` (n,) per setup after burn-in; ``scale`` (n,) the adapted proposal scales;
    ``stuck`` slice updates that hit the shrinkage limit (0 expected)
    """
    laws = [np.asarray(v, dtype=float) for v in laws]
    g = GibbsJoint(log_likelihoods, types, x, hyper, [np.atleast_2d(np.cov(v, rowvar=False)) for v in laws],
                   nuisance)
    st = g.start(rng, n_chains, laws)
    stuck = 0
    for i in range(n_burn):
        g.law_steps(st, rng, law_steps, adapt=1.0 / np.sqrt(1.0 + i))
        stuck += g.hyper_steps(st, rng)
    kept, acc = [], np.zeros(g.n)
    for i in range(n_iter * thin):
        acc += g.law_steps(st, rng, law_steps) / (n_iter * thin)
        stuck += g.hyper_steps(st, rng)
        if (i + 1) % thin == 0:
            kept.append(g.hyperparameters(st))
    chains = np.stack(kept, axis=1)  # (C, N, p)
    T, d = g.T, g.d
    runs = []
    for grp in np.array_split(np.arange(n_chains), n_groups):
        flat = np.swapaxes(chains[grp], 0, 1).reshape(-1, chains.shape[2])  # iteration-major
        runs.append({"types": [flat[:, t * 3 * d:(t + 1) * 3 * d] for t in range(T)], "tau_b": flat[:, T * 3 * d:],
                     "acceptance": float(np.mean(acc)), "n_walkers": len(grp)})
    out = pool_runs(runs)
    out.update(chains=chains, law_acceptance=acc, scale=g.scale.copy(), stuck=stuck)
    return out

