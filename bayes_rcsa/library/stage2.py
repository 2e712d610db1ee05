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

and the hyperparameters of all holder types are sampled together
(:mod:`.hierarchy`: slopes and spreads partially pooled across types, the
linear hyperparameters integrated out in closed form; one emcee vectorised
over walkers and setups, whose cost grows linearly with the number of
setups).

Where the library is small enough and the weights are sound, the hyperparameter draws are then re-weighted to
the exact two-stage target, in which each setup's stage-1 draws (its stage-1 box included) are its likelihood,
and resampled to an equally weighted set (:mod:`.exact`, option ``exact``); otherwise the surrogate result is
kept and ``Stage2Result.exact`` says why.  The resampled set is worth the chain's ESS times the weights' ESS
fraction; where that falls below the ESS target, the chain is run once more, longer (its ESS target scaled by
the inverse fraction, within the same step cap), and re-weighted again (``Stage2Result.exact["rerun"]``).

The surrogate is then checked setup by setup: the stage-1 draws are
importance re-weighted to the setup's pooled posterior (weights = population
density averaged over hyperparameter draws / stage-1 prior density).  The
effective sample size of those weights is reported; where it falls below
``ess_min`` the pooled estimate of that setup is refused with the reason
(the pooled posterior lies where the stage-1 draws are too few).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConvergenceError, SetupError
from ..stats.weights import MIN_ESS, effective_sample_size, normalise_log_weights
from .exact import reweight_exact
from .hierarchy import Group, HyperFit, Stage2Settings, TypeFit, _factor, _forward, fit_hyper
from .population import Hyperprior

__all__ = ["SetupDraws", "Stage2Settings", "TypeFit", "Stage2Result", "surrogate", "weakly_identified", "WEAK_CONTRACTION",
           "fit_population", "pooled_weights",
           "ESS_MIN"]

#: Smallest importance ESS of a setup's re-weighted stage-1 draws for its pooled estimate to be reported (the
#: package's least ESS of a weighted estimate, :data:`bayes_rcsa.stats.weights.MIN_ESS`).
ESS_MIN = MIN_ESS


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


#: A pooled coordinate whose stage-1 posterior keeps more than this fraction of its flat stage-1 prior's variance
#: (the box's width^2 / 12) is barely identified by that setup's taps: a posterior contraction below 1/2
#: (Betancourt 2018, "Calibrating model-based inferences and decisions").
WEAK_CONTRACTION = 0.5


def weakly_identified(s: SetupDraws) -> list[int]:
    """Coordinates (column indices) of ``s`` that its taps barely identify.

    Only coordinates with a flat stage-1 prior on a finite box are judged: the contraction
    ``1 - var(draws) / (width^2 / 12)`` below :data:`WEAK_CONTRACTION`.  Such a posterior is mostly the box, and
    a Gaussian fitted to its draws claims a finite variance the likelihood does not have (docs/library.md).
    """
    width = s.box[:, 1] - s.box[:, 0]
    flat = (np.diag(np.atleast_2d(s.prior_precision)) == 0) & np.isfinite(width) & (width > 0)
    prior_var = np.where(flat, width, 1.0) ** 2 / 12.0
    contraction = 1.0 - np.var(s.z, axis=0) / prior_var
    return [int(j) for j in np.flatnonzero(flat & (contraction < WEAK_CONTRACTION))]


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
    """
    L, logdet = _factor(Ct, s2)
    w = _forward(L, r)
    return sum(v * v for v in w), logdet


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
    return z, normalise_log_weights(np.where(np.isfinite(ln_w), ln_w, -np.inf), refuse=False)


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
    fit : HyperFit, the coupled posterior (sampler draws, groups) the types are views of
    exact : dict, the exact two-stage re-weighting (:func:`.exact.reweight_exact`): ``used``, ``reason``,
        ``weight_ess``, ``pairs`` (its cost), ...
    """

    names: tuple
    hyper: Hyperprior
    types: dict
    setups: list
    warnings: list
    fit: HyperFit | None = None
    exact: dict | None = None


def fit_population(setups, hyper: Hyperprior, rng: np.random.Generator, settings: Stage2Settings = Stage2Settings(),
                   ess_min: float = ESS_MIN, n_weight_draws: int = 32, exact="auto") -> Stage2Result:
    """Stage 2 for a library: surrogates, one coupled emcee fit of all holder types, per-setup ESS and pooled
    estimates.

    Parameters
    ----------
    setups : sequence of SetupDraws (all with the coordinates ``hyper.names``)
    hyper : Hyperprior
    rng : numpy Generator
    settings : Stage2Settings
    ess_min : float, smallest importance ESS for a pooled estimate
    n_weight_draws : int, hyperparameter draws averaged in the importance weights
    exact : ``"auto"``, True or False
        Re-weight the hyperparameter draws to the exact two-stage target and resample them
        (:func:`.exact.reweight_exact`): ``"auto"`` where the cost (setups x stage-1 draws x hyperparameter draws)
        is at most :data:`.exact.EXACT_MAX_PAIRS` and the weights are sound, True whatever the cost (if sound),
        False never.  Where it is requested but not sound the surrogate result is kept with a warning.

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
    weak: dict[int, list[str]] = {}
    for s in setups:
        m, C, notes = surrogate(s)
        surr[s.name] = (m, C)
        warns += notes
        for j in weakly_identified(s):
            weak.setdefault(j, []).append(s.name)
    for j, who in sorted(weak.items()):
        warns.append(f"coordinate {names[j]}: barely identified by the taps of {len(who)} of {len(setups)} setups "
                     f"({', '.join(who)}: stage-1 posterior variance more than {1 - WEAK_CONTRACTION:.0%} of the flat "
                     f"stage-1 prior's); their Gaussian surrogates claim more than those data carry, and the "
                     f"population of {names[j]} leans on the stage-1 box")
    groups = []
    for t in sorted({s.holder_type for s in setups}):
        group = [s for s in setups if s.holder_type == t]
        x = covariate([s.diameter for s in group], f"holder type {t}: shank diameter")
        groups.append(Group(t, tuple(s.name for s in group), x, np.array([surr[s.name][0] for s in group]),
                            np.array([surr[s.name][1] for s in group])))
    hfit = fit_hyper(groups, hyper, rng, settings)
    warns += hfit.warnings
    hfit, exact_info = _exact_step(hfit, groups, setups, hyper, rng, settings, exact)
    warns += [w for w in hfit.warnings if w not in warns]  # the longer chain's, where its draws are used
    if exact_info["sound"] is False:  # requested, judged and found unsound (not: switched off, or too costly)
        warns.append(f"stage 2: exact two-stage re-weighting not used: {exact_info['reason']}")
    elif exact_info["used"] and not (exact_info["effective_draws"] or 0.0) >= settings.ess_target:  # None: unknown
        # resampling keeps the draws' number, not their information: chain ESS x the weights' ESS fraction
        rerun = exact_info["rerun"]
        longer = ("" if rerun is None else f" after one longer chain ({rerun['n_steps']} steps, ESS target "
                  f"{rerun['ess_target']:.0f}, cap {settings.max_steps})")
        eff = exact_info["effective_draws"]
        warns.append(f"stage 2: the exact two-stage re-weighting leaves about {'an unknown number of' if eff is None else f'{eff:.0f}'} "
                     f"effective draws (chain ESS {hfit.quality.ess_text} x weight ESS fraction "
                     f"{exact_info['weight_ess_fraction']:.2f}){longer} < the ESS target {settings.ess_target:g}; "
                     "the interval ends carry that much more Monte Carlo error (a larger max_steps reduces it: "
                     "'bayes-rcsa library --max-steps')")
    types: dict[str, TypeFit] = hfit.types
    rows = []
    for s in setups:
        fit = types[s.holder_type]
        x = float(covariate(s.diameter, f"setup {s.name}: shank diameter"))
        flat = fit.flat
        sub = flat[rng.choice(flat.shape[0], size=min(n_weight_draws, flat.shape[0]), replace=False)]
        z, w = pooled_weights(s, sub, x)
        ess = effective_sample_size(w, normalised=True)
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
    return Stage2Result(tuple(names), hyper, types, rows, warns, hfit, exact_info)


#: Safety factor on the chain ESS asked of the longer stage-2 chain: the weights' ESS fraction of a new chain
#: scatters about the first one's (0.21 +- ~0.02 on the bench's 12-combination libraries).
RERUN_MARGIN = 1.25


def _exact_step(hfit: HyperFit, groups, setups, hyper: Hyperprior, rng: np.random.Generator,
                settings: Stage2Settings, exact) -> tuple[HyperFit, dict]:
    """The exact re-weighting (:func:`.exact.reweight_exact`), with at most one longer chain where it falls short.

    Resampling keeps the number of draws, not their information: the re-weighted set is worth about the chain's
    ESS x the weights' ESS fraction.  Where that is below ``settings.ess_target`` and the chain stopped before
    ``settings.max_steps``, the chain is run again (once), started from the first chain's draws, to an ESS target
    scaled by ``RERUN_MARGIN / fraction`` within the same step cap, and re-weighted again.  If the second
    re-weighting is not sound, the first (sound) one is kept.

    Returns
    -------
    fit : HyperFit, the one whose draws the result uses
    info : dict of :func:`.exact.reweight_exact` plus ``rerun``: None (not needed or not possible) or a dict
        ``ess_target``, ``n_steps``, ``chain_ess`` of the longer chain, ``used`` (its re-weighting replaced the
        first), ``first_effective_draws``, ``first_weight_ess_fraction``, ``first_chain_ess``, ``first_n_steps``
    """
    fit, info = reweight_exact(hfit, setups, rng, exact)
    info["rerun"] = None
    if not info["used"] or hfit.n_steps >= settings.max_steps:
        return fit, info
    if info["effective_draws"] is not None and info["effective_draws"] >= settings.ess_target:  # None: unknown
        return fit, info
    target = RERUN_MARGIN * settings.ess_target / info["weight_ess_fraction"]
    longer = fit_hyper(groups, hyper, rng, dataclasses.replace(settings, ess_target=target), start_from=hfit.theta)
    fit2, info2 = reweight_exact(longer, setups, rng, exact)
    rerun = {"ess_target": float(target), "n_steps": int(longer.n_steps), "chain_ess": _known(longer.ess),
             "used": bool(info2["used"]), "first_effective_draws": info["effective_draws"],
             "first_weight_ess_fraction": info["weight_ess_fraction"], "first_chain_ess": _known(hfit.ess),
             "first_n_steps": int(hfit.n_steps)}
    if not info2["used"]:  # keep the first, sound, re-weighting
        info["rerun"] = rerun
        return fit, info
    info2["rerun"] = rerun
    return fit2, info2


def _known(ess: float) -> float | None:
    """An ESS for the outputs: None where unknown (NaN: the chain too short to measure its tau)."""
    return float(ess) if math.isfinite(ess) else None


def _weighted_quantiles(v: np.ndarray, w: np.ndarray, q) -> np.ndarray:
    order = np.argsort(v)
    cw = np.cumsum(w[order])
    cw /= cw[-1]
    return np.interp(np.asarray(q), cw - 0.5 * w[order] / np.sum(w), v[order])


def check_converged(result: Stage2Result) -> None:
    """Raise :class:`ConvergenceError` if the stage-2 chain has fewer than 100 effective draws."""
    if result.fit is not None and not result.fit.ess >= 100:  # NaN: the chain too short to measure its ESS
        raise ConvergenceError(f"stage-2 ESS {result.fit.quality.ess_text} < 100; rerun with more steps")
