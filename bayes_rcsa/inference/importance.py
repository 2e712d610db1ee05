"""Exact posteriors by importance sampling from a heavy-tailed proposal around the optimum.

Where the posterior is unimodal and not far from Gaussian in the sampling coordinates -- the usual case of a
contact identified from a few well-measured FRFs -- independent draws from a proposal that covers it, weighted by
``posterior / proposal``, give the exact posterior without a chain: no burn-in, no autocorrelation, and every
log-posterior evaluation is one row of a large vectorised batch.  ``identify --sampler importance`` uses this
module and falls back to the emcee chain when the weights say the proposal does not cover the posterior.

The algorithm (:func:`importance_posterior`)
--------------------------------------------
1. **Laplace covariance** at the optimum (:func:`laplace_covariance`): the inverse finite-difference Hessian of
   ``-log p`` (:func:`.search.derivatives`), its eigenvalues bounded in prior-width-scaled coordinates so that no
   direction is wider than :data:`MAX_SD_OF_WIDTH` of its prior width (a flat direction, an optimum on a bound);
   a direction narrower than the finite-difference step is measured again with a step below its width.
2. **Pilot**: :data:`N_PILOT` draws from a multivariate t (:data:`DF` degrees of freedom) centred on the optimum,
   shape :data:`SCALE` times the Laplace covariance.
3. **Adaptation** (adaptive importance sampling, Cappé et al. 2004): a second t with the pilot's
   Pareto-smoothed weighted mean and covariance (when the pilot carries enough effective draws,
   :data:`bayes_rcsa.stats.weights.MIN_ESS_COVARIANCE`), which follows a skewed or bound-truncated posterior
   the curvature at the optimum cannot see; :data:`N_BATCH` draws from it, refitted again after every batch (at
   most :data:`MAX_REFITS` times) while the weights' ESS is below :data:`TARGET_ESS` or their Pareto k above 0.7
   (up to :data:`MAX_PROPOSALS` draws in all).
4. **Weights**: every draw is weighted against the *mixture* of both proposals in proportion to their draw
   counts (deterministic-mixture / balance-heuristic weights, Owen & Zhou 2000; Veach & Guibas 1995), so the
   pilot's draws are used too and the Laplace t stays in the proposal as a defensive component (Hesterberg
   1995): the weight of a draw can be large only where both proposals are small.  The weights are Pareto
   smoothed (PSIS, Vehtari et al. 2024).
5. **Acceptance** (:data:`ACCEPTANCE_RULE`): Pareto shape ``k <= 0.7``
   (:data:`bayes_rcsa.stats.weights.PARETO_K_MAX`) and Kish ESS of the smoothed weights ``>= 1000``
   (:data:`bayes_rcsa.stats.weights.MIN_ESS_INTERVAL_END`: a 5 % point then has a Monte Carlo error of about
   0.07 posterior sd).  Otherwise the result is refused with the reason, and identify runs the chain.
   Before any draw: refused when a relative noise scale at the optimum exceeds :data:`MAX_NOISE_SCALE` (1:
   noise above the signal on every line), where the posterior is a bent ridge of the two stiffnesses that a
   proposal around one end of it cannot be checked to cover (the weights it sees pass; docs/calibration.md).
6. **Resampling** to a fixed number of equally weighted draws by systematic resampling (Kitagawa 1996; unbiased,
   with a smaller variance than multinomial resampling: every draw of weight ``w`` appears ``floor(n w)`` or
   ``ceil(n w)`` times), in random order, so that every consumer of posterior draws (predict, lobes, design,
   update, report, the library) reads them exactly as it reads thinned chain draws.

Why a t with 4 degrees of freedom and shape 1.5 x Laplace: the proposal must have heavier tails than the
posterior for the weights to have a finite variance (Geweke 1989); a Gaussian proposal does not, and a
stiffness bounded by the data from one side only has a long one-sided tail.  Four degrees of freedom keep the
variance finite (``df > 2``) while wasting fewer draws in the far tails than the tail check's three; the
factor 1.5 on the shape makes the proposal's covariance ``1.5 * 4/2 = 3`` times the Laplace one, wide enough
for the skewed log-stiffness directions (the refit then narrows it where the posterior is narrower).  Chosen
on the bundled example and the benchmark campaigns (``benchmarks/importance_accuracy.py``,
docs/identification.md, "Exact posteriors by importance sampling").

What it cannot see: a second posterior mode far from the optimum that neither proposal reaches gives no large
weight and so no warning -- the same blind spot as a chain started at the optimum.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..stats.weights import (MIN_ESS_COVARIANCE, MIN_ESS_INTERVAL_END, MIN_ESS_PER_DIMENSION, PARETO_K_MAX,
                             effective_sample_size, importance_reliable, normalise_log_weights,
                             pareto_smoothed_log_weights)
from .search import derivatives, optimum_noise_scale

__all__ = ["ImportanceResult", "importance_posterior", "laplace_covariance", "systematic_resample", "optimum_noise_scale",
           "DF", "SCALE", "N_PILOT", "N_BATCH", "MAX_REFITS", "MAX_PROPOSALS", "TARGET_ESS", "MAX_SD_OF_WIDTH",
           "MAX_NOISE_SCALE", "ACCEPTANCE_RULE", "FD_STEP_OF_WIDTH", "FINE_STEP_OF_SD", "MIN_SD_OF_WIDTH"]

#: Degrees of freedom of the t proposals (finite variance of the weights needs heavier tails than the posterior).
DF = 4.0
#: Factor on the covariance of the t's shape matrix (Laplace covariance, then the pilot's weighted covariance).
SCALE = 1.5
#: Draws of the Laplace-t pilot.
N_PILOT = 2000
#: Draws per later batch, each from the latest t.
N_BATCH = 4000
#: Most refits of the t to the weighted draws (one new mixture component each).
MAX_REFITS = 3
#: Most proposal draws in all (log-posterior evaluations) before the result is judged as it is.
MAX_PROPOSALS = 50_000
#: Draws stop once the smoothed weights' ESS reaches this: twice the acceptance bound, so that the resampled
#: draws hold a few thousand distinct values and the accepted quantiles carry about 0.05 posterior sd of Monte
#: Carlo error at the 5 % and 95 % points.
TARGET_ESS = 2 * MIN_ESS_INTERVAL_END
#: Widest proposal standard deviation in a coordinate, as a fraction of its prior width: a uniform prior's own
#: sd is 0.29 of its width, so no posterior is wider; beyond this the Hessian is flat there, not informative.
MAX_SD_OF_WIDTH = 0.3
#: Finite-difference step of the Laplace Hessian, as a fraction of each prior width; also the narrowest proposal
#: sd unless a narrower direction is measured again (:func:`laplace_covariance`).
FD_STEP_OF_WIDTH = 1e-4
#: The second measurement's step as a fraction of the narrowest sd the first one found.
FINE_STEP_OF_SD = 0.3
#: Narrowest proposal sd (fraction of the prior width) after the second measurement: below it the finite
#: differences of a log posterior of order 1e3 lose their digits to round-off.
MIN_SD_OF_WIDTH = 1e-8
#: Largest relative noise scale (noise rms / model |H| on every line) at the optimum for which importance sampling is
#: tried.  Above it the noise exceeds the signal on every line: the data no longer resolve the resonance, and the
#: posterior is the prior's box cut by a bent ridge of the two stiffnesses (an L: a soft translational joint with
#: any rotational one, or a stiff one with a soft rotational joint) along which the noise scale trades with the
#: fit.  A unimodal t around one end of it gets Pareto k <= 0.7 from the weights it sees and never sees the other
#: end; simulation-based calibration of ``single`` under the default noise prior put every draw on one side of the
#: truth in such replicates (docs/calibration.md).  The chain, started at the optimum, walks the ridge.
MAX_NOISE_SCALE = 1.0
ACCEPTANCE_RULE = (f"importance sampling from multivariate t proposals ({DF:g} degrees of freedom) around the "
                   "posterior optimum (Laplace covariance, then refitted to a weighted pilot), deterministic-mixture "
                   f"Pareto-smoothed weights; accepted when the Pareto shape k <= {PARETO_K_MAX:g} and the weights' "
                   f"ESS >= {MIN_ESS_INTERVAL_END} (not tried when a noise scale at the optimum exceeds "
                   f"{MAX_NOISE_SCALE:g}); then systematically resampled to equally weighted draws")


@dataclass(frozen=True)
class ImportanceResult:
    """Outcome of :func:`importance_posterior`.

    Attributes
    ----------
    accepted : bool
        The weights passed :data:`ACCEPTANCE_RULE`.
    reason : str
        Why they did not ("" when accepted).
    theta : (n_draws, ndim) or None
        Equally weighted draws in sampling coordinates (systematically resampled), None when refused.
    log_prob : (n_draws,) or None
        The log posterior of each draw.
    pareto_k : float
        PSIS Pareto shape of the weights (NaN when too few draws had a finite posterior).
    ess : float
        Kish effective sample size of the smoothed weights.
    n_proposals : int
        Proposal draws (each one log-posterior evaluation when inside the prior).
    n_inside : int
        Draws with a finite log posterior.
    n_unique : int
        Distinct draws among ``theta``.
    wall_time : float
        Seconds.
    proposal : dict
        The proposals' degrees of freedom, shape factor, draws per component and whether the refit was used.
    """

    accepted: bool
    reason: str
    theta: np.ndarray | None
    log_prob: np.ndarray | None
    pareto_k: float
    ess: float
    n_proposals: int
    n_inside: int
    n_unique: int = 0
    wall_time: float = 0.0
    proposal: dict = field(default_factory=dict)

    def describe(self) -> dict:
        """JSON-ready diagnostics (summary.json's ``sampler`` block; its time is in ``timing``, with the run's)."""
        k = None if not math.isfinite(self.pareto_k) else float(self.pareto_k)
        return {"pareto_k": k, "ess": float(self.ess), "n_proposals": int(self.n_proposals),
                "n_inside_prior": int(self.n_inside), "n_unique_draws": int(self.n_unique),
                "proposal": dict(self.proposal), "rule": ACCEPTANCE_RULE}


class _T:
    """Multivariate t (location ``mu`` (d,), shape ``shape`` (d, d), ``df``): vectorised draws and log density."""

    def __init__(self, mu: np.ndarray, shape: np.ndarray, df: float):
        self.mu, self.df, self.d = np.asarray(mu, float), float(df), mu.size
        self.chol = np.linalg.cholesky(shape)
        self.log_det = 2.0 * float(np.sum(np.log(np.diag(self.chol))))
        d, v = self.d, self.df
        # math.lgamma, not scipy: importing this module (identify checks its options before loading the setup)
        # must not load scipy on the command line's error paths
        self.const = math.lgamma((v + d) / 2) - math.lgamma(v / 2) - 0.5 * d * math.log(v * math.pi) - 0.5 * self.log_det

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        z = rng.standard_normal((n, self.d)) @ self.chol.T
        return self.mu + z / np.sqrt(rng.chisquare(self.df, size=n) / self.df)[:, None]

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        from scipy.linalg import solve_triangular

        y = solve_triangular(self.chol, (x - self.mu).T, lower=True)
        return self.const - 0.5 * (self.df + self.d) * np.log1p(np.sum(y * y, axis=0) / self.df)


def laplace_covariance(log_post, x: np.ndarray, bounds) -> tuple[np.ndarray, str]:
    """Covariance (ndim, ndim) of the Laplace approximation of ``log_post`` at its optimum ``x``.

    The inverse finite-difference Hessian of ``-log_post`` (steps :data:`FD_STEP_OF_WIDTH` of each prior width,
    the point moved two steps inside the bounds), computed in coordinates scaled by the prior widths with its
    eigenvalues bounded so that every direction's sd lies in ``[FD_STEP_OF_WIDTH, MAX_SD_OF_WIDTH]`` prior widths:
    a negative or zero curvature (a flat direction, an optimum on a bound) then gives the widest proposal, not a
    failure.  When a direction is narrower than the step, every coordinate whose own curvature says so is
    measured again with a step of :data:`FINE_STEP_OF_SD` times its sd (the others keep theirs), and the lower
    bound becomes :data:`MIN_SD_OF_WIDTH`: the proposal follows the measured
    curvature of a very precisely identified coordinate instead of a floor tied to its prior's width.

    Parameters
    ----------
    log_post : callable, (n, ndim) -> (n,)
    x : (ndim,) sampling coordinates
    bounds : (ndim, 2) finite bounds of the sampling coordinates

    Returns
    -------
    cov : (ndim, ndim), note : str ("" or which directions were bounded)
    """
    lo, hi = np.asarray(bounds, dtype=float).T
    width = hi - lo

    def curvature(step_of_width):
        step = step_of_width * width
        _, _, h = derivatives(log_post, np.clip(x, lo + 2 * step, hi - 2 * step), step)
        if not np.all(np.isfinite(h)):
            h = np.where(np.isfinite(h), h, 0.0)
        hs = h * np.outer(width, width)  # Hessian in prior-width units
        return 0.5 * (hs + hs.T)

    hs = curvature(FD_STEP_OF_WIDTH)
    lam, vec = np.linalg.eigh(hs)
    lam_min, lam_max = MAX_SD_OF_WIDTH ** -2, FD_STEP_OF_WIDTH ** -2
    if lam.max() > lam_max:
        # A direction narrower than the step (a coefficient known to 1e-5 of its prior range at very low noise):
        # the floor tied to the prior's width made the proposal far too wide there and refused importance
        # sampling with Pareto k of 7-50 (docs/calibration.md).  Measured again per coordinate with the usual
        # finite-difference rule, step ~ 1/sqrt(curvature): a coordinate the data barely constrain keeps the
        # coarse step, whose curvature a small step would lose to round-off.
        diag = np.diag(hs)
        fine = np.full(x.size, FD_STEP_OF_WIDTH)
        steep = diag > lam_max
        fine[steep] = np.maximum(FINE_STEP_OF_SD / np.sqrt(diag[steep]), MIN_SD_OF_WIDTH)
        lam, vec = np.linalg.eigh(curvature(fine))
        lam_max = MIN_SD_OF_WIDTH ** -2
    clipped = int(np.sum((lam < lam_min) | (lam > lam_max)))
    lam = np.clip(lam, lam_min, lam_max)
    cov = (vec / lam) @ vec.T * np.outer(width, width)
    note = f"{clipped} of {x.size} curvature directions bounded" if clipped else ""
    return 0.5 * (cov + cov.T), note


def systematic_resample(weights: np.ndarray, size: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of ``size`` draws by systematic resampling of normalised ``weights`` (n,), in random order.

    One uniform offset ``u``; draw ``i`` is taken for every ``(j + u) / size`` inside its cumulative-weight
    interval, so it appears ``floor(size w_i)`` or ``ceil(size w_i)`` times (Kitagawa 1996).
    """
    c = np.cumsum(weights)
    c[-1] = 1.0
    idx = np.searchsorted(c, (np.arange(size) + rng.uniform()) / size, side="right")
    return rng.permutation(np.minimum(idx, weights.size - 1))


def _evaluate(log_post, x: np.ndarray, batch: int) -> np.ndarray:
    return np.concatenate([np.asarray(log_post(x[a:a + batch]), dtype=float) for a in range(0, x.shape[0], batch)])


def _weights(lp: np.ndarray, x: np.ndarray, components: list, counts: list) -> tuple[np.ndarray, np.ndarray, float]:
    """Deterministic-mixture PSIS weights: (n,) normalised weights (0 outside the prior), mask of finite, k."""
    ok = np.isfinite(lp)
    n = float(sum(counts))
    logq = np.logaddexp.reduce(np.stack([math.log(c / n) + t.logpdf(x[ok])
                                         for t, c in zip(components, counts) if c > 0]), axis=0)
    w = np.zeros(x.shape[0])
    if ok.sum() < 2:
        return w, ok, math.nan
    lw, k = pareto_smoothed_log_weights(lp[ok] - logq)
    w[ok] = normalise_log_weights(lw, refuse=False)
    return w, ok, k


def _refit(x: np.ndarray, w: np.ndarray, d: int, scale: float):
    """Weighted mean and ``scale`` times the weighted covariance, or None when the weights carry too few draws."""
    if effective_sample_size(w[w > 0], normalised=True) < max(MIN_ESS_COVARIANCE, MIN_ESS_PER_DIMENSION * d):
        return None
    mu = w @ x
    cov = (w[:, None] * (x - mu)).T @ (x - mu)
    ev = np.linalg.eigvalsh(cov)
    if not (np.all(np.isfinite(cov)) and ev.min() > 1e-12 * ev.max()):
        return None
    return mu, scale * cov


def importance_posterior(log_post, x_map: np.ndarray, bounds, rng: np.random.Generator, size: int, *,
                         df: float = DF, scale: float = SCALE, n_pilot: int = N_PILOT, n_batch: int = N_BATCH,
                         max_proposals: int = MAX_PROPOSALS, target_ess: float = TARGET_ESS,
                         min_ess: float = MIN_ESS_INTERVAL_END, proposal_shrink: float = 1.0,
                         batch: int = 4000, max_noise_scale: float = MAX_NOISE_SCALE) -> ImportanceResult:
    """Importance-sample the posterior ``log_post`` around its optimum ``x_map`` (module docstring).

    Parameters
    ----------
    log_post : callable, (n, ndim) sampling coordinates -> (n,) log posterior (vectorised; -inf outside)
    x_map : (ndim,) the optimum (sampling coordinates)
    bounds : (ndim, 2) finite bounds of the sampling coordinates (the prior's optimisation bounds)
    rng : numpy.random.Generator
    size : int, equally weighted draws returned
    df, scale : the t proposals' degrees of freedom and covariance factor
    n_pilot, n_batch, max_proposals : draws of the Laplace pilot, per refitted batch, and at most in all
    target_ess : float, stop drawing once the weights' ESS reaches it
    min_ess : float, fewest effective draws accepted
    proposal_shrink : float
        Factor on the proposals' standard deviations (1: as designed).  Only for testing that a proposal too
        narrow for the posterior is refused (0.1 gives Pareto k far above 0.7).
    batch : int, rows per log-posterior call
    max_noise_scale : float
        Refused without a draw when a relative noise scale at ``x_map`` (:func:`optimum_noise_scale`) exceeds it
        (:data:`MAX_NOISE_SCALE`: noise above the signal); ``inf`` never refuses for that.

    Returns
    -------
    ImportanceResult
    """
    t0 = time.perf_counter()
    x_map = np.asarray(x_map, dtype=float)
    d = x_map.size
    noise = optimum_noise_scale(log_post, x_map)
    if noise > max_noise_scale:
        reason = (f"importance sampling refused: the noise scale at the optimum is {noise:.2g} > {max_noise_scale:g} "
                  "(noise above the signal): the posterior is a long bent ridge that a proposal around the optimum "
                  "does not cover")
        return ImportanceResult(False, reason, None, None, pareto_k=math.nan, ess=0.0, n_proposals=0, n_inside=0,
                                wall_time=time.perf_counter() - t0,
                                proposal={"df": df, "scale": scale, "noise_scale_at_optimum": noise})
    cov, note = laplace_covariance(log_post, x_map, bounds)
    shrink2 = float(proposal_shrink) ** 2
    components, counts = [_T(x_map, scale * shrink2 * cov, df)], [0]
    x, lp = np.empty((0, d)), np.empty(0)
    w, ok, k, ess, refits = np.zeros(0), np.zeros(0, bool), math.nan, 0.0, 0
    while sum(counts) < max_proposals:
        m = min(n_pilot if not x.size else n_batch, max_proposals - sum(counts))
        xn = components[-1].sample(rng, m)
        x, lp = np.vstack([x, xn]), np.concatenate([lp, _evaluate(log_post, xn, batch)])
        counts[-1] += m
        w, ok, k = _weights(lp, x, components, counts)
        ess = effective_sample_size(w, normalised=True) if ok.sum() >= 2 else 0.0
        if ess >= target_ess and k <= PARETO_K_MAX:
            break
        # adapt: the next batch comes from a t fitted to every weighted draw so far
        fit = _refit(x, w, d, scale * shrink2) if refits < MAX_REFITS and ok.sum() >= 2 else None
        if fit is not None:
            components.append(_T(fit[0], fit[1], df))
            counts.append(0)
            refits += 1
    n_inside = int(ok.sum())
    proposal = {"df": df, "scale": scale, "draws_per_component": [c for c in counts if c], "refits": refits,
                "laplace_note": note}
    if proposal_shrink != 1.0:
        proposal["proposal_shrink"] = float(proposal_shrink)
    common = dict(pareto_k=k, ess=ess, n_proposals=int(sum(counts)), n_inside=n_inside, proposal=proposal)
    if not importance_reliable(k, ess, min_ess):
        why = (f"Pareto shape k = {k:.2f} > {PARETO_K_MAX:g}" if not k <= PARETO_K_MAX
               else f"weights' ESS {ess:.0f} < {min_ess:g}")
        reason = (f"importance sampling refused: {why} after {sum(counts)} proposal draws ({n_inside} inside the "
                  "prior): the t proposal around the optimum does not cover the posterior")
        return ImportanceResult(False, reason, None, None, wall_time=time.perf_counter() - t0, **common)
    idx = systematic_resample(w, size, rng)
    return ImportanceResult(True, "", x[idx], lp[idx], n_unique=int(np.unique(idx).size),
                            wall_time=time.perf_counter() - t0, **common)
