"""Stage 2: the hierarchical posterior of a tool library from stored stage-1 draws.

Method (docs/library.md, "Stage 2"): every stage-1 posterior (a setup's
``identify`` fit under the broad common prior) is replaced by a Gaussian
*likelihood surrogate* in the population coordinates: the draws' mean and
covariance, divided by the stage-1 prior (flat in these coordinates for the
default log-uniform stiffness and uniform growth priors; a normal or
log-normal stage-1 prior is divided out exactly).  With the population
``z_s ~ N(a_t + b_t x_s, diag sigma_t^2)`` the setups' latent laws then
integrate out in closed form,

    m_s ~ N(a_t + b_t x_s, C_s + diag sigma_t^2),

and the hyperparameters ``(a_t, b_t, sigma_t)`` of each holder type are
sampled with emcee, vectorised over walkers and setups.  Holder types share
no hyperparameter, so each type is an independent fit (the cost grows
linearly with the number of setups).

The surrogate is then checked setup by setup: the stage-1 draws are
importance re-weighted to the setup's pooled posterior (weights = population
density averaged over hyperparameter draws / stage-1 prior density).  The
effective sample size of those weights is reported; where it falls below
``ess_min`` the pooled estimate of that setup is refused with the reason
(the pooled posterior lies where the stage-1 draws are too few).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConvergenceError, SetupError
from .population import Hyperprior

__all__ = ["SetupDraws", "Stage2Settings", "TypeFit", "Stage2Result", "surrogate", "fit_population", "fit_type", "marginal_ln_like",
           "pooled_weights", "ESS_MIN"]

#: Smallest importance ESS of a setup's re-weighted stage-1 draws for its pooled estimate to be reported.
ESS_MIN = 30.0


@dataclass(frozen=True)
class SetupDraws:
    """Stage-1 posterior of one combination in the population coordinates.

    Attributes
    ----------
    name : str
    holder_type : str
    diameter : float, m, shank diameter
    z : (n, d) draws in the population coordinates
    prior_mean, prior_precision : (d,), (d, d)
        Gaussian part of the stage-1 prior in these coordinates (zero
        precision for a flat coordinate).
    box : (d, 2) support of the stage-1 prior
    """

    name: str
    holder_type: str
    diameter: float
    z: np.ndarray
    prior_mean: np.ndarray
    prior_precision: np.ndarray
    box: np.ndarray

    def ln_prior(self, z: np.ndarray) -> np.ndarray:
        """Stage-1 prior log density of (..., d) up to a constant (-inf outside the box)."""
        r = z - self.prior_mean
        lp = -0.5 * np.einsum("...i,ij,...j->...", r, self.prior_precision, r)
        inside = np.all((z >= self.box[:, 0]) & (z <= self.box[:, 1]), axis=-1)
        return np.where(inside, lp, -np.inf)


def surrogate(s: SetupDraws) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Gaussian likelihood surrogate ``(m, C, notes)`` of a stage-1 posterior.

    Raises
    ------
    SetupError
        Too few draws, or a stage-1 posterior that is not narrower than its
        Gaussian prior (the data carry no information to divide out).
    """
    n, d = s.z.shape
    if n < 4 * d + 4 or not np.all(np.isfinite(s.z)):
        raise SetupError(f"setup {s.name}: {n} stage-1 draws (finite: {bool(np.all(np.isfinite(s.z)))}); expected at "
                         f"least {4 * d + 4} finite draws")
    mean = s.z.mean(axis=0)
    cov = np.atleast_2d(np.cov(s.z, rowvar=False))
    cov += np.eye(d) * 1e-12 * np.maximum(np.diag(cov), 1e-300)
    post_prec = np.linalg.inv(cov)
    prec = post_prec - s.prior_precision
    try:
        np.linalg.cholesky(prec)
    except np.linalg.LinAlgError:
        raise SetupError(f"setup {s.name}: its stage-1 posterior is not narrower than its stage-1 prior; the data "
                         "carry no information on the contact to pool") from None
    C = np.linalg.inv(prec)
    m = C @ (post_prec @ mean - s.prior_precision @ s.prior_mean)
    notes = []
    width = s.box[:, 1] - s.box[:, 0]
    edge = np.mean((s.z - s.box[:, 0] < 0.01 * width) | (s.box[:, 1] - s.z < 0.01 * width), axis=0)
    for j in np.flatnonzero(edge > 0.2):
        notes.append(f"setup {s.name}: {edge[j]:.0%} of its stage-1 draws of coordinate {j} lie at the edge of the "
                     "stage-1 prior; the Gaussian surrogate understates that side")
    return m, 0.5 * (C + C.T), notes


def _quad_logdet(Ct: np.ndarray, s2: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(r^T V^-1 r, ln det V)`` with ``V = C_s + diag(s2_w)`` for every walker w and setup s.

    Parameters
    ----------
    Ct : (d, d, n) surrogate covariances, setup axis last
    s2 : (W, d) population variances per walker
    r : (d, W, n) residuals

    Returns
    -------
    (W, n), (W, n); NaN where V is not positive definite

    Notes
    -----
    The Cholesky factor is written out element by element, each element one
    array over (walkers, setups) and V never formed: for thousands of 6x6
    matrices this is several times faster than LAPACK's per-matrix calls.
    """
    d = Ct.shape[0]
    L = [[None] * d for _ in range(d)]
    with np.errstate(invalid="ignore", divide="ignore"):
        logdet = 0.0
        for j in range(d):
            acc = Ct[j, j][None, :] + s2[:, j][:, None]
            for k in range(j):
                acc = acc - L[j][k] * L[j][k]
            L[j][j] = np.sqrt(acc)
            logdet = logdet + np.log(acc)
            inv = 1.0 / L[j][j]
            for i in range(j + 1, d):
                acc = Ct[i, j][None, :]
                for k in range(j):
                    acc = acc - L[i][k] * L[j][k]
                L[i][j] = acc * inv
        q = 0.0
        w = [None] * d
        for i in range(d):
            acc = r[i]
            for k in range(i):
                acc = acc - L[i][k] * w[k]
            w[i] = acc / L[i][i]
            q = q + w[i] * w[i]
    return q, logdet


def marginal_ln_like(theta: np.ndarray, m: np.ndarray, C: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Per-setup log marginal likelihood of hyperparameters.

    Parameters
    ----------
    theta : (W, 3d) hyperparameters (a, b, sigma)
    m : (n, d) surrogate means
    C : (n, d, d) surrogate covariances
    x : (n,) covariate

    Returns
    -------
    (W, n)
    """
    return _marginal(theta, _Surrogates(m, C, x))


@dataclass(frozen=True)
class _Surrogates:
    """A type's surrogates laid out for :func:`_quad_logdet` (setup axis last, contiguous)."""

    m: np.ndarray
    C: np.ndarray
    x: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "mT", np.ascontiguousarray(np.asarray(self.m, float).T))
        object.__setattr__(self, "Ct", np.ascontiguousarray(np.moveaxis(np.asarray(self.C, float), 0, -1)))
        object.__setattr__(self, "x_mean", float(np.mean(self.x)))


def _marginal(theta: np.ndarray, sur: _Surrogates) -> np.ndarray:
    d = sur.mT.shape[0]
    a, b, s = theta[:, :d], theta[:, d:2 * d], theta[:, 2 * d:]
    r = sur.mT[:, None, :] - a.T[:, :, None] - b.T[:, :, None] * sur.x[None, None, :]  # (d, W, n)
    q, logdet = _quad_logdet(sur.Ct, s * s, r)
    out = -0.5 * (q + logdet + d * math.log(2 * math.pi))
    return np.where(np.isfinite(out), out, -np.inf)


@dataclass
class TypeFit:
    """Stage-2 posterior of one holder type.

    Attributes
    ----------
    holder_type : str
    names : tuple of str, setups of this type
    x : (n,) covariate; m : (n, d); C : (n, d, d) surrogates
    chain : (n_walkers, n_keep, 3d) hyperparameter draws (a, b, sigma)
    tau : (3d,) integrated autocorrelation times (steps)
    acceptance : float
    warnings : list of str
    """

    holder_type: str
    names: tuple
    x: np.ndarray
    m: np.ndarray
    C: np.ndarray
    chain: np.ndarray
    tau: np.ndarray
    acceptance: float
    warnings: list = field(default_factory=list)

    @property
    def flat(self) -> np.ndarray:
        """(n_walkers * n_keep, 3d) draws."""
        return self.chain.reshape(-1, self.chain.shape[-1])

    @property
    def ess(self) -> float:
        """Smallest effective sample size over the hyperparameters."""
        n = self.chain.shape[0] * self.chain.shape[1]
        return float(n / np.max(self.tau))


def _uncentre(theta: np.ndarray, x_mean: float) -> np.ndarray:
    """(a, b, ln s) from the sampler's (a + b x_mean, b, ln s): a and b decorrelate when x is centred."""
    d = theta.shape[1] // 3
    out = theta.copy()
    out[:, :d] -= theta[:, d:2 * d] * x_mean
    return out


def _log_post(theta, hyper: Hyperprior, sur: "_Surrogates"):
    theta = _uncentre(theta, sur.x_mean)  # unit Jacobian
    lp = hyper.ln_prob(theta[:, :hyper.ndim], theta[:, hyper.ndim:2 * hyper.ndim], theta[:, 2 * hyper.ndim:])
    ok = np.isfinite(lp)
    out = np.full(theta.shape[0], -np.inf)
    if np.any(ok):
        out[ok] = lp[ok] + np.sum(_marginal(theta[ok], sur), axis=1)
    return out


def _start(hyper: Hyperprior, sur: "_Surrogates", rng, n_walkers) -> np.ndarray:
    """Walkers around the posterior mode (L-BFGS from a moment estimate; gradient by central differences,
    all 2 x 3d + 1 points in one vectorised call)."""
    from scipy.optimize import minimize

    d = hyper.ndim
    m = sur.m
    spread = np.std(m, axis=0) if m.shape[0] > 1 else 0.5 * hyper.s_scale
    s0 = np.clip(spread, 0.05 * hyper.s_scale, 2 * hyper.s_scale)
    t0 = np.concatenate([m.mean(axis=0), np.zeros(d), s0])  # centred: a + b mean(x) = mean(m)
    h = 1e-5 * np.eye(3 * d)

    def f(t):
        v = -_log_post(np.vstack([t, t + h, t - h]), hyper, sur)
        if not np.all(np.isfinite(v)):
            return float(v[0]) if np.isfinite(v[0]) else 1e300, np.zeros(3 * d)
        return float(v[0]), (v[1:3 * d + 1] - v[3 * d + 1:]) / 2e-5

    bounds = [(None, None)] * (2 * d) + [(1e-6 * v, None) for v in hyper.s_scale]
    res = minimize(f, t0, jac=True, method="L-BFGS-B", bounds=bounds, options={"maxiter": 500})
    t = res.x if np.isfinite(res.fun) and res.fun <= f(t0)[0] else t0
    scale = np.concatenate([0.05 * hyper.a_sd, 0.05 * hyper.b_sd, 0.05 * hyper.s_scale])
    start = t + scale * rng.standard_normal((n_walkers, 3 * d))
    start[:, 2 * d:] = np.abs(start[:, 2 * d:])
    lp = _log_post(start, hyper, sur)
    start[~np.isfinite(lp)] = t
    return start


@dataclass(frozen=True)
class Stage2Settings:
    """How long stage 2 samples each holder type.

    Attributes
    ----------
    n_burn : int, steps discarded after the start at the posterior mode
    ess_target : float, effective draws (walkers x kept steps / max autocorrelation time) to reach
    chunk : int, steps between checks of the ESS
    max_steps : int, kept steps at most; reaching it is a warning
    n_walkers : int or None
        Default ``max(2 x 3d + 2, min(96, 8000 / n_setups))``: a call's cost
        grows with walkers x setups, so a large type gets few walkers, a
        small one (where the Python overhead dominates) many.
    """

    n_burn: int = 400
    ess_target: float = 400.0
    chunk: int = 250
    max_steps: int = 10000
    n_walkers: int | None = None


def fit_type(holder_type: str, names, x, m, C, hyper: Hyperprior, rng: np.random.Generator,
             settings: Stage2Settings = Stage2Settings()) -> TypeFit:
    """Sample one holder type's hyperparameters (emcee, vectorised over walkers and setups).

    Parameters
    ----------
    holder_type : str
    names : sequence of str, (n,) setups
    x : (n,) covariate ln(d / 10 mm)
    m, C : (n, d), (n, d, d) likelihood surrogates
    hyper : Hyperprior
    rng : numpy Generator
    settings : Stage2Settings
    """
    import emcee

    ndim = 3 * hyper.ndim
    n_walkers = settings.n_walkers or max(2 * ndim + 2, min(96, 8000 // max(1, len(names))))
    n_walkers += n_walkers % 2
    sur = _Surrogates(m, C, np.asarray(x, dtype=float))
    start = _start(hyper, sur, rng, n_walkers)
    sampler = emcee.EnsembleSampler(n_walkers, ndim, _log_post, args=(hyper, sur), vectorize=True,
                                    moves=[(emcee.moves.StretchMove(), 1.0)])
    # emcee draws from a private RandomState: seed it from our generator (the global state is never touched)
    rstate = np.random.RandomState(int(rng.integers(0, 2**32 - 1))).get_state()
    state = sampler.run_mcmc(emcee.State(start, random_state=rstate), settings.n_burn, progress=False)
    sampler.reset()
    n_kept = 0
    while True:
        state = sampler.run_mcmc(state, settings.chunk, progress=False)
        n_kept += settings.chunk
        chain = np.swapaxes(sampler.get_chain(), 0, 1)  # (walkers, steps, ndim), centred coordinates
        tau = _autocorr(chain)
        ess = n_walkers * n_kept / np.max(tau)
        # the autocorrelation estimate itself needs a chain of >~10 tau to be trusted
        if (ess >= settings.ess_target and n_kept >= 10 * np.max(tau)) or n_kept >= settings.max_steps:
            break
    chain = _uncentre(chain.reshape(-1, ndim), sur.x_mean).reshape(chain.shape)
    warns = []
    if ess < settings.ess_target or n_kept < 10 * np.max(tau):
        warns.append(f"holder type {holder_type}: stage 2 stopped at {n_kept} steps with ESS {ess:.0f} (target "
                     f"{settings.ess_target:g}) and autocorrelation time {np.max(tau):.0f}; the hyperparameter "
                     "intervals are approximate")
    if len(names) < 3:
        warns.append(f"holder type {holder_type}: {len(names)} combination(s); its spread and diameter slope mostly "
                     "restate the hyperprior (a weak fit)")
    return TypeFit(holder_type, tuple(names), np.asarray(x, float), m, C, chain, np.asarray(tau),
                   float(np.mean(sampler.acceptance_fraction)), warns)


def _autocorr(chain: np.ndarray) -> np.ndarray:
    """Integrated autocorrelation time (steps) per parameter of (walkers, steps, ndim), quietly."""
    import logging

    import emcee

    log = logging.getLogger("emcee.autocorr")
    level = log.level
    log.setLevel(logging.ERROR)  # emcee logs a warning for short chains; ours goes into the outputs instead
    try:
        return np.asarray(emcee.autocorr.integrated_time(np.swapaxes(chain, 0, 1), quiet=True))
    finally:
        log.setLevel(level)


def pooled_weights(setup: SetupDraws, theta: np.ndarray, x: float, max_draws: int = 1000) -> tuple[np.ndarray, np.ndarray]:
    """Importance weights of a setup's stage-1 draws for its pooled (population-prior) posterior.

    Parameters
    ----------
    setup : SetupDraws
    theta : (H, 3d) hyperparameter draws (a subset)
    x : covariate of the setup
    max_draws : int
        Evenly thinned stage-1 draws used.

    Returns
    -------
    z : (n, d) the draws used
    w : (n,) normalised weights
    """
    z = setup.z[:: max(1, setup.z.shape[0] // max_draws)]
    d = z.shape[1]
    a, b, s = theta[:, :d], theta[:, d:2 * d], theta[:, 2 * d:]
    mu = a + b * x  # (H, d)
    r = (z[None, :, :] - mu[:, None, :]) / s[:, None, :]
    lp = -0.5 * np.sum(r * r, axis=-1) - np.sum(np.log(s), axis=-1)[:, None]  # (H, n)
    top = lp.max(axis=0)
    ln_pop = top + np.log(np.mean(np.exp(lp - top), axis=0))
    ln_w = ln_pop - setup.ln_prior(z)
    ln_w = np.where(np.isfinite(ln_w), ln_w, -np.inf)
    w = np.exp(ln_w - np.max(ln_w))
    return z, w / np.sum(w)


@dataclass
class Stage2Result:
    """Stage-2 posterior of a library: one :class:`TypeFit` per holder type, per-setup checks.

    Attributes
    ----------
    names : tuple of str, pooled coordinates
    hyper : Hyperprior
    types : dict holder type -> TypeFit
    setups : list of dict, per setup: name, holder_type, diameter_m, own/pooled q05/q50/q95 per coordinate,
        ess, refused (reason or None)
    warnings : list of str
    """

    names: tuple
    hyper: Hyperprior
    types: dict
    setups: list
    warnings: list


def fit_population(setups, hyper: Hyperprior, rng: np.random.Generator, settings: Stage2Settings = Stage2Settings(),
                   ess_min: float = ESS_MIN, n_weight_draws: int = 32) -> Stage2Result:
    """Stage 2 for a library: surrogates, one emcee fit per holder type, per-setup ESS and pooled estimates.

    Parameters
    ----------
    setups : sequence of SetupDraws (all with the coordinates ``hyper.names``)
    hyper : Hyperprior
    rng : numpy Generator
    settings : Stage2Settings
    ess_min : float, smallest importance ESS for a pooled estimate
    n_weight_draws : int, hyperparameter draws averaged in the importance weights

    Raises
    ------
    SetupError
        Fewer than two combinations in the whole library, or a setup whose
        surrogate cannot be built.
    """
    from .population import covariate

    setups = list(setups)
    if len(setups) < 2:
        raise SetupError(f"a library needs at least two combinations to estimate a population; got {len(setups)}")
    names = hyper.names
    warns: list[str] = []
    surr = {}
    for s in setups:
        m, C, notes = surrogate(s)
        surr[s.name] = (m, C)
        warns += notes
    types: dict[str, TypeFit] = {}
    for t in sorted({s.holder_type for s in setups}):
        group = [s for s in setups if s.holder_type == t]
        x = covariate([s.diameter for s in group], f"holder type {t}: shank diameter")
        m = np.array([surr[s.name][0] for s in group])
        C = np.array([surr[s.name][1] for s in group])
        fit = fit_type(t, [s.name for s in group], x, m, C, hyper, rng, settings)
        types[t] = fit
        warns += fit.warnings
    rows = []
    for s in setups:
        fit = types[s.holder_type]
        x = float(covariate(s.diameter, f"setup {s.name}: shank diameter"))
        flat = fit.flat
        sub = flat[rng.choice(flat.shape[0], size=min(n_weight_draws, flat.shape[0]), replace=False)]
        z, w = pooled_weights(s, sub, x)
        ess = float(1.0 / np.sum(w * w))
        row = {"name": s.name, "holder_type": s.holder_type, "diameter_m": s.diameter, "ess": ess,
               "n_draws": int(z.shape[0]), "refused": None}
        own = np.quantile(s.z, [0.05, 0.5, 0.95], axis=0)
        for j, n in enumerate(names):
            row[f"{n}_own"] = [float(v) for v in own[:, j]]
        if ess < ess_min:
            row["refused"] = (f"importance ESS {ess:.1f} of {z.shape[0]} stage-1 draws < {ess_min:g}: the pooled "
                              "posterior lies where the setup's broad-prior draws are few (a setup far from its "
                              "population, or too few stage-1 draws); its pooled estimate is not reported")
            warns.append(f"setup {s.name}: {row['refused']}")
        else:
            for j, n in enumerate(names):
                row[f"{n}_pooled"] = [float(v) for v in _weighted_quantiles(z[:, j], w, (0.05, 0.5, 0.95))]
        rows.append(row)
    return Stage2Result(tuple(names), hyper, types, rows, warns)


def _weighted_quantiles(v: np.ndarray, w: np.ndarray, q) -> np.ndarray:
    order = np.argsort(v)
    cw = np.cumsum(w[order])
    cw /= cw[-1]
    return np.interp(np.asarray(q), cw - 0.5 * w[order] / np.sum(w), v[order])


def check_converged(result: Stage2Result) -> None:
    """Raise :class:`ConvergenceError` if a type's stage-2 chain has fewer than 100 effective draws."""
    for t, fit in result.types.items():
        if fit.ess < 100:
            raise ConvergenceError(f"holder type {t}: stage-2 ESS {fit.ess:.0f} < 100; rerun with more steps")
