"""MCMC fallback of the update when importance re-weighting collapses.

When the cuts leave too few effective hammer draws (:mod:`.update`), the
posterior is sampled directly with emcee over

    z = (θ in the sampling coordinates of the fit's physical parameters,
         u = log cutting-force level, v = ln w when the boundary width is sampled),

    log p(z) = log N(θ; μ, Σ)  +  log p(u)  +  log p(v)  +  log Σ_j P(cuts | θ, u, node j, w) / n_nodes,

where N(μ, Σ) is the hammer posterior approximated by a Gaussian in the
sampling coordinates (mean and covariance of its draws; the priors' supports
are enforced), and the discrete K_r/K_t node is summed out (each node is one
evaluation of the stability method on the walkers, which is vectorised).  The
hammer FRF data are not re-read: the Gaussian carries what the hammer test
taught, which is the approximation of this fallback (a strongly non-Gaussian
hammer posterior is smoothed).  Walkers start from the importance particles
with the largest weights.  After the run the node of every kept sample is
drawn from its conditional, and the per-cut summaries use leave-one-cut-out
importance weights of the samples (∝ 1 / P(cut c | sample)).

The chain is run by the package's one emcee driver
(:func:`bayes_rcsa.inference.sampler.run_ensemble`) in fixed-steps mode with
the stretch move: the first half of the steps is the burn-in, and its rule
says whether the run converged (the chain longer than :data:`TAU_FACTOR`
autocorrelation times, a burn-in of at least three, a stable tau, R-hat and
bulk ESS), reported in the info dict with tau, R-hat and bulk ESS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, SetupError
from ..inference.sampler import SamplerSettings, run_ensemble
from .likelihood import CutLikelihood, inverse_limits_at_cuts
from .update import UpdateResult, normalise_log_weights, per_cut_summary

__all__ = ["MCMCSettings", "mcmc_update", "TAU_FACTOR", "ESS_MIN"]

#: Required chain length in autocorrelation times: the former rule, kept steps (half) > 20 tau.
TAU_FACTOR = 40.0
#: Required bulk ESS of every parameter of the fallback's chain.
ESS_MIN = 100.0


@dataclass(frozen=True)
class MCMCSettings:
    """Walkers and steps of the fallback (half of the steps are burn-in)."""

    walkers: int = 32
    steps: int = 300

    def sampler_settings(self) -> SamplerSettings:
        """The driver's fixed-steps settings: ``steps`` steps, the first half burn-in, tau checked every quarter."""
        return SamplerSettings(n_walkers=self.walkers, n_steps=self.steps, n_burn=self.steps // 2,
                               check_every=max(1, self.steps // 4), tau_factor=TAU_FACTOR, ess_min=ESS_MIN,
                               move="stretch", progress=False)

    def __post_init__(self) -> None:
        if self.walkers < 8 or self.steps < 20:
            raise SetupError(f"MCMC fallback: walkers={self.walkers}, steps={self.steps}: expected >= 8 and >= 20")


class _Target:
    """Vectorised log density of the fallback (see the module docstring)."""

    def __init__(self, dyn, cuts, prior, width, label_error, method, options):
        from .data import cut_groups

        self.dyn, self.cuts, self.prior, self.width = dyn, cuts, prior, width
        self.label_error, self.method, self.options = label_error, method, options
        self._cut_groups = cut_groups
        pm = dyn.draws.parameters
        self.pm = pm
        self.names = list(pm.physical_names)
        self.priors = [pm.priors[n] for n in self.names]
        x = np.column_stack([np.asarray(p.to_sampling(dyn.draws.values[n]), dtype=float)
                             for n, p in zip(self.names, self.priors)])
        self.mean = x.mean(axis=0)
        cov = np.atleast_2d(np.cov(x, rowvar=False))
        cov += np.eye(len(self.names)) * (1e-10 + 1e-9 * np.trace(cov) / len(self.names))  # a degenerate direction
        self.chol = np.linalg.cholesky(cov)
        self.log_det = 2 * float(np.sum(np.log(np.diag(self.chol))))
        self.k = len(self.names)
        self.has_u = prior.level_sd > 0
        self.has_v = width.sampled
        self.ndim = self.k + self.has_u + self.has_v

    def split(self, z):
        z = np.atleast_2d(z)
        theta = z[:, : self.k]
        u = z[:, self.k] if self.has_u else np.zeros(z.shape[0])
        w = np.exp(z[:, self.k + self.has_u]) if self.has_v else np.full(z.shape[0], self.width.lo)
        return theta, u, w

    def check_inside(self, z, what: str) -> None:
        """Raise :class:`SetupError` naming the first row of z (n, ndim) outside the priors' supports."""
        theta, _, _ = self.split(z)
        for i, (n, p) in enumerate(zip(self.names, self.priors)):
            out = ~np.asarray(p.in_support(theta[:, i]), dtype=bool)
            if np.any(out):
                j = int(np.argmax(out))
                raise SetupError(f"MCMC fallback: {what} {j}: {n} outside its prior support {p.describe()}")

    def log_prior(self, z) -> np.ndarray:
        theta, u, w = self.split(z)
        ok = np.ones(theta.shape[0], dtype=bool)
        for i, p in enumerate(self.priors):
            ok &= np.asarray(p.in_support(theta[:, i]), dtype=bool)
        r = np.linalg.solve(self.chol, (theta - self.mean).T)
        lp = -0.5 * np.sum(r * r, axis=0) - 0.5 * self.log_det - 0.5 * self.k * math.log(2 * math.pi)
        lp = lp + self.prior.ln_prob(u, np.zeros(u.size, dtype=int)) + self.width.ln_prob(w)
        return np.where(ok, lp, -np.inf)

    def node_log_likelihood(self, z) -> tuple[np.ndarray, CutLikelihood]:
        """(n_nodes, n) log P(cuts | z, node j) and the likelihood object of these rows."""
        from ..posterior.draws import PosteriorDraws
        from .frf import frfs_of_draws

        theta, u, w = self.split(z)
        values = {n: np.asarray(p.to_physical(theta[:, i]), dtype=float) for i, (n, p) in
                  enumerate(zip(self.names, self.priors))}
        draws = PosteriorDraws(self.pm, values)
        frfs = frfs_of_draws(draws, self.dyn.model, self.dyn.caches)
        groups = self._cut_groups(self.cuts, frfs, self.dyn.frequency_hz)
        inv = inverse_limits_at_cuts(groups, self.cuts.n_cuts, self.prior, self.method, self.options)
        lik = CutLikelihood(inv, self.cuts.depth_m, self.cuts.chatter, self.label_error)
        idx = np.arange(theta.shape[0])
        per_node = np.array([lik(idx, u, np.full(idx.size, j), w) for j in range(inv.shape[0])])
        return per_node, lik

    def __call__(self, z) -> np.ndarray:
        z = np.atleast_2d(z)
        lp = self.log_prior(z)
        ok = np.isfinite(lp)
        if np.any(ok):
            per_node, _ = self.node_log_likelihood(z[ok])
            m = per_node.max(axis=0)
            ll = m + np.log(np.mean(np.exp(per_node - m), axis=0))
            lp[ok] += np.where(np.isfinite(ll), ll, -np.inf)
        return lp


def mcmc_update(dyn, cuts, prior, width, label_error, method, options, start: UpdateResult, rng,
                n_out: int, settings: MCMCSettings | None = None):
    """Sample the cut-updated posterior with emcee (the fallback of a collapsed re-weighting).

    Parameters
    ----------
    dyn : CutDynamics (hammer draws, model caches)
    cuts : CutSet
    prior, width, label_error, method, options : as the re-weighting
    start : UpdateResult of the collapsed re-weighting (start points, hammer-only particles)
    rng : numpy.random.Generator
    n_out : int, draws of the result
    settings : MCMCSettings

    Returns
    -------
    (PosteriorDraws of the samples, UpdateResult with ``draw = arange(n_out)`` into them, info dict with the
    acceptance fraction, autocorrelation times and the effective sample size)
    """
    from ..posterior.draws import PosteriorDraws

    s = settings or MCMCSettings()
    target = _Target(dyn, cuts, prior, width, label_error, method, options)
    if s.walkers < 2 * target.ndim + 2:  # emcee's stretch move needs more walkers than twice the dimension
        s = MCMCSettings(2 * target.ndim + 2, s.steps)
    # start: the walkers' positions from the heaviest importance particles (distinct draws), slightly jittered
    order = np.argsort(-start.weights)
    seen, rows = set(), []
    for p in order:
        d = int(start.particle_draw[p])
        if d not in seen:
            seen.add(d)
            rows.append(p)
        if len(rows) == s.walkers:
            break
    rows = np.array(rows + list(rng.choice(order[: max(len(rows), 1)], s.walkers - len(rows))), dtype=int)
    theta0 = np.column_stack([np.asarray(pr.to_sampling(dyn.draws.values[n][start.particle_draw[rows]]), dtype=float)
                              for n, pr in zip(target.names, target.priors)])
    cols = [theta0]
    if target.has_u:
        cols.append(start.particle_u[rows][:, None])
    if target.has_v:
        cols.append(np.log(start.particle_width[rows])[:, None])
    p0 = np.hstack(cols)
    p0 = p0 + 1e-4 * rng.standard_normal(p0.shape) * np.maximum(np.std(p0, axis=0), 1e-3)
    p0 = _finite_start(target, p0, rng)
    # emcee's proposals come from its private RandomState, seeded from ``rng`` (never numpy's global one)
    run = run_ensemble(target, s.sampler_settings(), initial=p0, rng=rng)
    burn = run.burn
    chain = run.chain[burn:]  # (steps - burn, walkers, ndim)
    tau = np.asarray(run.tau, dtype=float)
    flat = chain.reshape(-1, target.ndim)
    pick = rng.choice(flat.shape[0], n_out, replace=flat.shape[0] < n_out)
    z = flat[pick]
    theta, u, w = target.split(z)
    per_node, lik = target.node_log_likelihood(z)
    # the ratio node of every sample from its conditional (inverse CDF, vectorised over samples)
    prob = np.exp(per_node - per_node.max(axis=0))
    cdf = np.cumsum(prob / prob.sum(axis=0), axis=0)
    node = np.minimum(np.sum(rng.uniform(size=n_out)[None, :] > cdf, axis=0), per_node.shape[0] - 1)
    kt, kr = prior.coefficients(u, node)
    values = {n: np.asarray(p.to_physical(theta[:, i]), dtype=float) for i, (n, p) in
              enumerate(zip(target.names, target.priors))}
    draws = PosteriorDraws(target.pm, values, dyn.draws.method, dyn.draws.fit_lengths, "mcmc", "memory",
                           dyn.draws.notes)
    idx = np.arange(n_out)
    pw = lik.pointwise(idx, u, node, w)
    limits = lik.limits(idx, u, node)
    weights = np.full(n_out, 1.0 / n_out)
    loo = np.array([normalise_log_weights(-pw[:, c]) for c in range(pw.shape[1])])
    per_cut = per_cut_summary(lik, start.limits, start.particle_width, limits, weights, loo, w, kt)
    n_eff = float(flat.shape[0] / np.max(tau)) if np.all(np.isfinite(tau)) and np.max(tau) > 0 else float("nan")
    result = UpdateResult(idx, u, node, w, kt, kr, n_eff, n_eff, n_out, start.n_draws, float("nan"), per_cut,
                          start.prior_kt, start.prior_kr, weights, idx, limits, u, node, loo, w)
    diag = run.diagnostics or {}
    listed = lambda key: [None if not np.isfinite(v) else float(v) for v in diag[key]] if key in diag else None  # noqa: E731
    info = {"walkers": s.walkers, "steps": s.steps, "burn": burn,
            "acceptance_fraction": float(np.mean(run.acceptance_fraction)),
            "autocorrelation_time": [None if not np.isfinite(t) else float(t) for t in tau],
            "effective_samples": None if not np.isfinite(n_eff) else n_eff,
            "rhat": listed("rhat"), "ess_bulk": listed("ess_bulk"),
            "converged": bool(run.converged), "convergence": run.reason,
            "parameters": target.names + (["log_level"] if target.has_u else []) + (["ln_width"] if target.has_v else []),
            "hammer_prior": "Gaussian in the sampling coordinates of the hammer draws"}
    return draws, result, info


def _finite_start(target: _Target, p0: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``p0`` with every walker of non-finite density moved next to a random walker of finite density.

    Raises
    ------
    ConvergenceError
        If no walker has a finite density (the cuts contradict the hammer posterior).
    """
    ok = np.isfinite(target(p0))
    if not np.any(ok):
        raise ConvergenceError("MCMC fallback: no walker found a finite posterior density; the cuts contradict the "
                               "hammer posterior")
    if np.all(ok):
        return p0
    bad = np.flatnonzero(~ok)
    out = p0.copy()
    out[bad] = p0[rng.choice(np.flatnonzero(ok), bad.size)] \
        + 1e-4 * rng.standard_normal((bad.size, p0.shape[1])) * np.maximum(np.std(p0[ok], axis=0), 1e-3)
    return out
