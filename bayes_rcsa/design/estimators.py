"""Expected posterior width of a target after a candidate test: two estimators.

Importance re-weighting (nested Monte Carlo, :func:`importance_widths`)
-----------------------------------------------------------------------
For ``m = 1..M`` a "true" draw ``theta_m`` is taken from the current draws,
the candidate measurement is simulated as ``y_m = H(theta_m; c) + e`` with
the likelihood's noise model (circular complex Gaussian, variance
``s^2 (|H|^2 + floor2)`` per line), and all *other* draws are weighted by
``p(y_m | theta_n)^beta``.  The weighted 90 % width of the target (5 % to
95 % weighted quantiles) is the width the posterior would have after that
measurement; its average over ``m`` is the expected width, and
``std_m / sqrt(M)`` its Monte Carlo error.  The true draw itself is left out
of its own weights (it would otherwise receive an outsized weight and make
the posterior look narrower than it is when the effective sample size is
small).  The effective sample size ``ESS_m = 1 / sum w^2`` of every set of
weights is reported; when its median falls below :data:`ESS_MIN` the
re-weighted draws are too few to represent the new posterior (they
"collapse") and the Laplace estimator below is used instead.

Laplace / Fisher approximation (:func:`laplace_widths`)
-------------------------------------------------------
In the draws' sampling coordinates ``u`` (log stiffness, growth factors,
term parameters), the current posterior is approximated by a Gaussian with
the draws' covariance ``S``; the candidate adds the Fisher information
``F_m = 2 beta Re(J^H W J)`` at ``theta_m`` (``J = dH/du`` on the candidate
lines by central differences, ``W = 1 / (s^2 v)``), and the target varies
linearly with gradient ``g_m``.  Then ``width_m = 2 z_0.95 sqrt(g^T (S^-1 +
F_m)^-1 g)``, averaged over ``m``.  Cheap and free of weight collapse, but
blind to non-Gaussian posteriors (a bounded growth prior, a ridge).

Both are vectorised over draws and lines; the only Python loops run over
the components of a lobes target (speeds) and over parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..stats.weights import MIN_ESS, effective_sample_size, normalise_log_weights

__all__ = ["ESS_MIN", "Z90", "NoiseLevel", "WidthEstimate", "weighted_widths", "unweighted_width",
           "simulate_measurements", "log_likelihoods", "importance_widths", "finite_difference_jacobian",
           "laplace_widths"]

#: Median importance-weight ESS below which the re-weighting is declared collapsed (the package's least ESS of a
#: weighted estimate, :data:`bayes_rcsa.stats.weights.MIN_ESS`).
ESS_MIN = MIN_ESS
#: z of the 95 % quantile of the standard normal: a 90 % central interval is 2 * Z90 standard deviations wide.
Z90 = 1.6448536269514722


@dataclass(frozen=True)
class NoiseLevel:
    """Noise of a simulated candidate measurement (the likelihood's model and level).

    Attributes
    ----------
    scale : float
        s, relative noise scale (the fit's sigma_j).
    floor : float
        eps, noise floor relative to the largest ``|H|`` in the band.
    tempering : float
        beta in (0, 1], the power the fit raised the likelihood to.
    """

    scale: float
    floor: float
    tempering: float


@dataclass(frozen=True)
class WidthEstimate:
    """Expected 90 % width of the target after one candidate test.

    Attributes
    ----------
    expected_width : float
        Mean over the simulated measurements (target unit).
    mc_error : float
        Standard error of that mean (``std / sqrt(M)``).
    widths : (M,) float
        Width after each simulated measurement.
    method : {"importance", "laplace"}
    ess_median, ess_min : float or None
        Importance-weight effective sample sizes (importance only).
    collapsed : bool
        Median ESS below :data:`ESS_MIN`.
    """

    expected_width: float
    mc_error: float
    widths: np.ndarray
    method: str
    ess_median: float | None = None
    ess_min: float | None = None
    collapsed: bool = False

    @property
    def width_range(self) -> tuple[float, float]:
        """5 % and 95 % quantiles of the width over the simulated measurements: the spread of the width a
        real test may leave (beyond ``mc_error``, which is the error of the *mean*)."""
        lo, hi = np.quantile(self.widths, [0.05, 0.95])
        return float(lo), float(hi)

    @property
    def prediction_interval(self) -> tuple[float, float]:
        """2.5 % and 97.5 % quantiles of the width over the simulated measurements: the stated 95 % interval
        of the width that one real test will leave."""
        lo, hi = np.quantile(self.widths, [0.025, 0.975])
        return float(lo), float(hi)


def _mean_and_error(widths: np.ndarray) -> tuple[float, float]:
    w = np.asarray(widths, dtype=float)
    err = float(np.std(w, ddof=1) / np.sqrt(w.size)) if w.size > 1 else float("nan")
    return float(np.mean(w)), err


def unweighted_width(values: np.ndarray) -> float:
    """Mean over components of the 5 %-95 % width of ``values`` (n, K), NaNs ignored per component."""
    v = np.asarray(values, dtype=float)
    q = np.nanquantile(v, [0.05, 0.95], axis=0)
    return float(np.mean(q[1] - q[0]))


def weighted_widths(values: np.ndarray, weights: np.ndarray, levels=(0.05, 0.95)) -> np.ndarray:
    """Weighted 90 % widths: ``(M,)`` mean over components of ``q95 - q05``.

    Parameters
    ----------
    values : (N, K) target of every draw (finite)
    weights : (M, N) non-negative, rows summing to 1

    Notes
    -----
    Quantiles of the weighted empirical distribution with the midpoint
    rule: the sorted draw ``i`` sits at cumulative weight
    ``C_i - w_i / 2``; linear interpolation in between.  With equal weights
    this is Hazen's rule (close to :func:`numpy.quantile`).
    """
    values = np.asarray(values, dtype=float)
    weights = np.asarray(weights, dtype=float)
    m = weights.shape[0]
    out = np.zeros(m)
    rows = np.arange(m)
    for k in range(values.shape[1]):  # components of the target (speeds), not draws
        order = np.argsort(values[:, k], kind="stable")
        v = values[order, k]
        w = weights[:, order]
        pos = np.cumsum(w, axis=1) - 0.5 * w
        q = []
        for level in levels:
            i = np.clip(np.sum(pos < level, axis=1), 1, v.size - 1)
            p0, p1 = pos[rows, i - 1], pos[rows, i]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.clip(np.where(p1 > p0, (level - p0) / (p1 - p0), 0.0), 0.0, 1.0)
            q.append(v[i - 1] + t * (v[i] - v[i - 1]))
        out += q[1] - q[0]
    return out / values.shape[1]


def simulate_measurements(h_true: np.ndarray, noise: NoiseLevel, floor2: float, rng: np.random.Generator) -> np.ndarray:
    """Noisy measurements of noise-free FRFs ``h_true`` (M, L), circular complex Gaussian noise."""
    var = noise.scale**2 * (np.abs(h_true) ** 2 + floor2)
    e = rng.standard_normal(h_true.shape) + 1j * rng.standard_normal(h_true.shape)
    return h_true + np.sqrt(var / 2.0) * e


def log_likelihoods(y: np.ndarray, h: np.ndarray, noise: NoiseLevel, floor2: float) -> np.ndarray:
    """Tempered log-likelihood of every simulated measurement under every draw, (M, N).

    Parameters
    ----------
    y : (M, L) complex, simulated measurements
    h : (N, L) complex, FRFs of the draws on the same lines
    noise : NoiseLevel
    floor2 : float
        (m/N)^2, ``(eps max|H|)^2``, one value for all draws and
        measurements (from the current median FRF, so the quadratic form
        factorises into three matrix products).
    """
    var = noise.scale**2 * (np.abs(h) ** 2 + floor2)  # (N, L)
    w = 1.0 / var
    a = (np.abs(y) ** 2) @ w.T  # sum_l |y|^2 w
    b = np.real(y @ (np.conj(h) * w).T)  # sum_l Re(y conj h) w
    c = np.sum(np.abs(h) ** 2 * w, axis=1)  # sum_l |h|^2 w
    q = np.maximum(a - 2.0 * b + c[None, :], 0.0)
    logdet = np.sum(np.log(np.pi * var), axis=1)
    return noise.tempering * (-q - logdet[None, :])


def importance_widths(h: np.ndarray, target: np.ndarray, noise: NoiseLevel, floor2: float, n_truths: int,
                      rng: np.random.Generator) -> WidthEstimate:
    """Expected width by importance re-weighting of the draws (module docstring).

    Parameters
    ----------
    h : (N, L) complex, candidate FRF of every draw on the candidate's lines
    target : (N, K) finite target values of the draws
    noise : NoiseLevel
    floor2 : float, (m/N)^2
    n_truths : int
        M, simulated measurements (at most N).
    rng : numpy.random.Generator
    """
    n = h.shape[0]
    m = int(min(n_truths, n))
    idx = rng.choice(n, m, replace=False)
    y = simulate_measurements(h[idx], noise, floor2, rng)
    ll = log_likelihoods(y, h, noise, floor2)
    ll[np.arange(m), idx] = -np.inf  # leave the true draw out of its own posterior
    w = normalise_log_weights(ll, axis=1, refuse=False)
    ess = effective_sample_size(w, axis=1, normalised=True)
    widths = weighted_widths(target, w)
    mean, err = _mean_and_error(widths)
    med = float(np.median(ess))
    return WidthEstimate(mean, err, widths, "importance", med, float(np.min(ess)), med < ESS_MIN)


def finite_difference_jacobian(func: Callable[[np.ndarray], np.ndarray], u: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Central-difference derivative of a batched function.

    Parameters
    ----------
    func : callable
        ``(n_sets, p) -> (n_sets, ...)``, vectorised over sets.
    u : (M, p) points
    step : (p,) steps

    Returns
    -------
    (M, ..., p) derivatives; one call of ``func`` on ``2 p M`` sets.
    """
    m, p = u.shape
    eye = np.eye(p) * step[None, :]
    pts = np.concatenate([u[:, None, :] + eye[None], u[:, None, :] - eye[None]], axis=1).reshape(-1, p)
    out = np.asarray(func(pts))
    out = out.reshape((m, 2, p) + out.shape[1:])
    d = (out[:, 0] - out[:, 1]) / (2.0 * step.reshape((1, p) + (1,) * (out.ndim - 3)))
    return np.moveaxis(d, 1, -1)


def laplace_widths(jac_h: np.ndarray | Sequence[np.ndarray], grad_target: np.ndarray, covariance: np.ndarray,
                   line_weight: np.ndarray | Sequence[np.ndarray], tempering: float | Sequence[float],
                   centre: np.ndarray | None = None, bounds: np.ndarray | None = None,
                   rng: np.random.Generator | None = None, n_inner: int = 400) -> WidthEstimate:
    """Expected width by the Laplace / Fisher approximation (module docstring).

    Parameters
    ----------
    jac_h : (M, L, p) complex, or a sequence of them (several tests at once)
        dH/du of the candidate FRF at each true draw.
    grad_target : (M, K, p)
        dT/du of the target at each true draw.
    covariance : (p, p)
        Current posterior covariance of ``u`` (Gaussian approximation).
    line_weight : (M, L) or (L,), or a sequence matching ``jac_h``
        ``1 / (s^2 v)`` per line.
    tempering : float or sequence
        beta of each test.
    centre : (M, p), optional
        The true draws' coordinates ``u_m``; with ``bounds`` and ``rng``
        the Gaussian posterior is truncated to the prior's support.
    bounds : (p, 2), optional
        Support of each coordinate (e.g. ``[0, Q]`` of a growth factor).
    rng : numpy.random.Generator, optional
    n_inner : int
        Points per truncated Gaussian.

    Notes
    -----
    Truncation: per true draw, the posterior mean is the truth shifted by
    one draw of the posterior noise (the simulated data's scatter), ``n_inner``
    points of ``N(mean, Sigma_m)`` are kept inside ``bounds`` and the 90 %
    width of the linearised target is taken over them (the plain Gaussian
    width where fewer than 20 points stay inside).  A truth near a prior
    bound (e.g. growth close to Q) then gets the narrower, cut-off
    posterior a real fit finds.
    """
    if isinstance(jac_h, np.ndarray):
        jac_h, line_weight, tempering = [jac_h], [line_weight], [tempering]
    p = covariance.shape[0]
    prec = np.linalg.inv(covariance)
    fisher = np.zeros((grad_target.shape[0], p, p))
    for j, w, beta in zip(jac_h, line_weight, tempering):  # tests, not draws
        w = np.broadcast_to(np.asarray(w, dtype=float), j.shape[:2])
        fisher += 2.0 * beta * np.real(np.einsum("mlp,ml,mlq->mpq", np.conj(j), w, j))
    post = np.linalg.inv(prec[None] + fisher)
    post = 0.5 * (post + np.swapaxes(post, 1, 2))
    var = np.einsum("mkp,mpq,mkq->mk", grad_target, post, grad_target)
    gauss = 2.0 * Z90 * np.sqrt(np.maximum(var, 0.0))  # (M, K)
    if centre is not None and bounds is not None and rng is not None:
        chol = np.linalg.cholesky(post + 1e-300 * np.eye(p)[None])
        m = centre.shape[0]
        shift = np.einsum("mpq,mq->mp", chol, rng.standard_normal((m, p)))
        pts = (centre + shift)[:, None, :] + np.einsum("mpq,mnq->mnp", chol, rng.standard_normal((m, n_inner, p)))
        inside = np.all((pts >= bounds[:, 0]) & (pts <= bounds[:, 1]), axis=2)  # (M, n_inner)
        t = np.einsum("mkp,mnp->mkn", grad_target, pts - centre[:, None, :])
        t = np.where(inside[:, None, :], t, np.nan)
        enough = np.sum(inside, axis=1) >= 20  # else keep the plain Gaussian width
        if np.any(enough):
            q = np.nanquantile(t[enough], [0.05, 0.95], axis=2)
            gauss = gauss.copy()
            gauss[enough] = q[1] - q[0]
    widths = np.mean(gauss, axis=1)
    mean, err = _mean_and_error(widths)
    return WidthEstimate(mean, err, widths, "laplace")


def laplace_current_width(grad_target: np.ndarray, covariance: np.ndarray) -> float:
    """Width of the Gaussian approximation before any new test (mean over draws and components)."""
    var = np.einsum("mkp,pq,mkq->mk", grad_target, covariance, grad_target)
    return float(np.mean(2.0 * Z90 * np.sqrt(np.maximum(var, 0.0))))


def sampling_coordinates(parameters, values: Mapping[str, np.ndarray], names: Sequence[str]) -> np.ndarray:
    """(n, p) sampling coordinates of the named sampled parameters."""
    pri = parameters.priors
    return np.column_stack([np.asarray(pri[n].to_sampling(np.asarray(values[n], dtype=float)), dtype=float)
                            for n in names])


def with_sampling_coordinates(parameters, values: Mapping[str, np.ndarray], names: Sequence[str], u: np.ndarray,
                              base_index: np.ndarray) -> dict[str, np.ndarray]:
    """Values of the draws ``base_index`` with the named parameters replaced by coordinates ``u`` (n, p)."""
    pri = parameters.priors
    out = {k: np.asarray(v)[base_index] for k, v in values.items()}
    for j, n in enumerate(names):
        out[n] = np.asarray(pri[n].to_physical(u[:, j]), dtype=float)
    return out


__all__ += ["laplace_current_width", "sampling_coordinates", "with_sampling_coordinates"]
