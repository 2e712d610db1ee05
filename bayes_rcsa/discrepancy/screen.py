"""Rank candidate terms cheaply: a score (Lagrange-multiplier) test at the baseline fit.

For a candidate term with parameters ``phi`` (baseline ``phi_0``, at which the
model *is* the baseline), the baseline fit ``theta*`` is a fit of the
extended model with ``phi = phi_0``.  Rao's score test asks whether the
likelihood would rise if ``phi`` left its baseline, without refitting:

* ``z``: whitened residuals at the baseline fit (real and imaginary parts);
* ``J_N``: their sensitivity to the nuisance (contact, growth)
  coordinates, ``J_A`` to the term's coordinates, both by forward
  differences through the parameter model's forward model;
* ``Q = I - J_N (J_N^T J_N)^-1 J_N^T`` projects out what the contact
  parameters could already absorb;
* the score statistic on the tempered likelihood (``beta`` the baseline's)::

      S = 2 beta (J_A^T Q z)^T (J_A^T Q J_A)^-1 (J_A^T Q z)

  which is asymptotically chi-square with ``dim phi`` degrees of freedom
  when the term is absent and the lines are independent after tempering.

Parameters that have no effect at the baseline (the frequency of a
resonator of zero mass, the lever of a zero rotation) cannot be tested
there (Davies' problem): they are set on a grid over their prior (fine
in the first such parameter, coarse in the others) and the largest
statistic over the grid is used (``S_max``; its reference distribution is wider than chi-square, which only matters for ranking
when the statistics are close).  A term whose single active parameter has
its baseline on a prior bound is tested one-sided: a step out of the
support scores zero.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..inference.problem import Problem
from .fit import ModelFit, model_floor, whitened_residuals

__all__ = ["ScoreResult", "embed_baseline", "score_test"]

_FINE = 120  # grid points of the first inactive parameter (25 Hz over a 3 kHz file: within a resonance half-width)
_COARSE_Q = (0.15, 0.5, 0.85)  # prior quantiles of the others
_CHUNK = 256  # parameter sets per batched model evaluation of the switch path (memory: sets x lines)
_N_STARTS = 3  # best grid points handed to the refit as starting points


@dataclass(frozen=True)
class ScoreResult:
    """Score test of one candidate.

    Attributes
    ----------
    effect : str
    statistic : float
        Tempered score statistic S (max over the grid of inactive parameters).
    dof : int
        Number of parameters tested (active at the baseline).
    p_value : float
        chi-square(dof) survival probability of ``statistic`` (indicative).
    start : (ndim,) sampling coordinates
        One Gauss-Newton step from the baseline in the term's direction: a
        starting point for the refit.
    starts : tuple of (ndim,)
        The same from the best few grid points of the inactive parameters, best first.
    """

    effect: str
    statistic: float
    dof: int
    p_value: float
    start: np.ndarray
    starts: tuple = ()


def embed_baseline(baseline: ModelFit, problem: Problem) -> np.ndarray:
    """The baseline MAP in the sampling coordinates of ``problem`` (terms at their baseline values)."""
    pm = problem.parameters
    theta = np.zeros(pm.ndim)
    bounds = problem.priors.optimisation_bounds()
    for j, name in enumerate(pm.names):
        prior = problem.priors[name]
        # the base fit's own values, its terms' included (a second round starts from the named model)
        if name in baseline.values:
            value = baseline.values[name]
        else:
            value = pm[name].baseline
        with np.errstate(divide="ignore"):
            u = float(prior.to_sampling(value))
        lo, hi = bounds[j]
        if not np.isfinite(u):  # a log prior cannot hold a baseline of 0: start at its lower bound
            u = lo
        theta[j] = min(max(u, lo), hi)
    return theta


def score_test(baseline: ModelFit, problem: Problem, effect: str) -> ScoreResult:
    """Score statistic of adding ``effect`` (whose term is in ``problem``) to the baseline."""
    from scipy.stats import chi2

    pm = problem.parameters
    names = pm.names
    beta = baseline.tempering
    theta0 = embed_baseline(baseline, problem)
    floor = model_floor(problem, theta0)  # held at the baseline: every score is a derivative there
    bounds = np.array(problem.priors.optimisation_bounds(), dtype=float)
    width = bounds[:, 1] - bounds[:, 0]
    term_cols = [j for j, n in enumerate(names) if pm[n].term == effect]
    nuis_cols = [j for j, n in enumerate(names) if pm[n].term is None and pm[n].role != "noise"]

    def steps(theta, cols, rel):
        h = rel * width[cols]
        return np.where(theta[cols] + h > bounds[cols, 1], -h, h)  # inwards on an upper bound

    def jac(theta, cols, rel):
        h = steps(theta, cols, rel)
        pts = np.repeat(theta[None], len(cols) + 1, axis=0)
        for k, j in enumerate(cols):
            pts[k + 1, j] += h[k]
        z = whitened_residuals(problem, pts, floor)
        return z[0], ((z[1:] - z[0]) / h[:, None]).T

    z0, jn = jac(theta0, nuis_cols, 1e-6)
    # orthonormal basis of what the nuisance parameters can absorb
    qn, _ = np.linalg.qr(jn)
    project = lambda a: a - qn @ (qn.T @ a)  # noqa: E731
    zq = project(z0)
    # term coordinates: 1e-3 of the prior width, so a parameter on a bound is probed just inside it
    _, jt = jac(theta0, term_cols, 1e-3)
    norms = np.linalg.norm(jt, axis=0)
    active = [c for c, nrm in zip(term_cols, norms) if nrm > 1e-9 * max(norms.max(), 1e-300)]
    inactive = [c for c in term_cols if c not in active]
    grid = [()]
    if inactive:
        # the first inactive parameter (e.g. a resonator's frequency) on a fine grid, since the
        # statistic is sharply peaked in it; the others on a coarse one
        axes = [(np.arange(_FINE) + 0.5) / _FINE] + [np.array(_COARSE_Q)] * (len(inactive) - 1)
        grid = list(itertools.product(*[bounds[c, 0] + q * width[c] for c, q in zip(inactive, axes)]))
    points = np.repeat(theta0[None], len(grid), axis=0)  # theta0 with the inactive parameters on the grid
    for i, g in enumerate(grid):
        points[i, inactive] = g
    switched = _switch_jacobians(problem, effect, theta0, points, active, inactive, lambda t: steps(t, active, 1e-3),
                                 floor)
    gridded = None
    if switched is None and inactive:
        h_t = 1e-3 * width[term_cols]
        h_t = np.where(points[:, term_cols] + h_t > bounds[term_cols, 1], -h_t, h_t)  # as steps(), at every point
        gridded = _grid_jacobians(problem, points, term_cols, h_t, floor)
    found = []
    for i, theta in enumerate(points):
        if switched is not None:
            ja = switched[i]
            act = active if np.linalg.norm(ja) > 0 else []
        elif inactive:
            ja = gridded[i]
            cols = [k for k, c in enumerate(term_cols) if np.linalg.norm(ja[:, k]) > 0]
            ja = ja[:, cols]
            act = [term_cols[k] for k in cols]
        else:
            ja = jt[:, [term_cols.index(c) for c in active]]
            act = active
        if ja.shape[1] == 0 or not act:
            continue
        jq = project(ja)
        u = jq.T @ zq
        m = jq.T @ jq
        step = -np.linalg.lstsq(m, u, rcond=None)[0]
        stat = float(2 * beta * u @ np.linalg.lstsq(m, u, rcond=None)[0])
        start = theta.copy()
        start[act] = np.clip(theta[act] + step, bounds[act, 0], bounds[act, 1])
        if len(act) == 1:
            c = act[0]
            on_lo = theta[c] <= bounds[c, 0] + 1e-12 * width[c]
            on_hi = theta[c] >= bounds[c, 1] - 1e-12 * width[c]
            if (on_lo and step[0] < 0) or (on_hi and step[0] > 0):
                stat = 0.0  # one-sided: the data want the term on the wrong side of its physical bound
        found.append((stat if np.isfinite(stat) else -np.inf, start, len(act)))
    found.sort(key=lambda t: -t[0])
    if not found:
        found = [(0.0, theta0, 1)]
    stat, start, dof = found[0]
    stat = max(stat, 0.0) if np.isfinite(stat) else 0.0
    starts = tuple(t[1] for t in found[:_N_STARTS])
    return ScoreResult(effect, stat, max(dof, 1), float(chi2.sf(stat, max(dof, 1))), start, starts)


def _grid_jacobians(problem: Problem, points: np.ndarray, cols: list[int], h: np.ndarray,
                    floor: np.ndarray | None = None) -> np.ndarray:
    """Forward-difference Jacobians in ``cols`` at every grid point, in batched model evaluations.

    One evaluation of ``_CHUNK`` sets instead of one small evaluation per point: a term without a switch (the
    fluted length of a tool declared as one cylinder) is differentiated at each of the grid's points.

    Parameters
    ----------
    points : (n_grid, ndim) sampling coordinates
    cols : the term's columns
    h : (n_grid, len(cols)) steps

    Returns
    -------
    (n_grid, 2 n_lines, len(cols))
    """
    n_grid, k = points.shape[0], len(cols)
    pts = np.repeat(points[:, None], k + 1, axis=1)  # (n_grid, k + 1, ndim): the point, then one step per column
    pts[:, 1 + np.arange(k), cols] += h
    flat = pts.reshape(-1, points.shape[1])
    z = np.concatenate([whitened_residuals(problem, flat[a:a + _CHUNK], floor)
                        for a in range(0, flat.shape[0], _CHUNK)])
    z = z.reshape(n_grid, k + 1, -1)
    return np.swapaxes((z[:, 1:] - z[:, :1]) / h[:, :, None], 1, 2)


def _switch_jacobians(problem: Problem, effect: str, theta0: np.ndarray, points: np.ndarray, active: list[int],
                      inactive: list[int], step, floor: np.ndarray | None = None) -> list[np.ndarray] | None:
    """The term Jacobian at every grid point when only the term's switch is active (else ``None``).

    A term that declares a ``switch`` (:attr:`~bayes_rcsa.params.terms.base.ModelTerm.switch`: a mass of 0)
    has, with the switch at its baseline, exactly no effect whatever its other parameters: at every grid
    point of those their forward-difference columns are exactly 0 and the model at the point is the
    baseline's.  So one baseline set and one set per grid point with the switch stepped give the same
    columns as differentiating in every term parameter at every point, with a fifth of the model
    evaluations for a four-parameter resonator.

    Parameters
    ----------
    points : (n_grid, ndim) sampling coordinates, ``theta0`` with the inactive parameters on the grid

    Returns
    -------
    list of (2 n_lines, 1) or None
    """
    from ..params.terms import get_term

    switch = get_term(effect).switch
    names = problem.parameters.names
    if not inactive or switch not in names or active != [names.index(switch)]:
        return None
    col = names.index(switch)
    prior = problem.priors[switch]
    with np.errstate(divide="ignore"):
        if theta0[col] != float(prior.to_sampling(problem.parameters[switch].baseline)):
            return None  # the term is already on (not a candidate's first screen)
    thetas = points.copy()
    h = float(step(theta0)[0])  # the step depends on the switch's own coordinate only, the same at every point
    thetas[:, col] += h
    out = []
    for a in range(0, len(thetas), _CHUNK):
        # the baseline set (switch at its baseline) evaluated with the chunk, on the same code path
        z = whitened_residuals(problem, np.vstack([theta0[None], thetas[a:a + _CHUNK]]), floor)
        out += [((z[j] - z[0]) / h)[:, None] for j in range(1, z.shape[0])]
    return out
