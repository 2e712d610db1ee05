"""The coupled stage-2 posterior of all holder types: spreads and slopes pooled across types (model version 2).

Per holder type ``t`` the setups' Gaussian likelihood surrogates ``N(m_s, C_s)``
(:func:`.stage2.surrogate`) give, with the law integrated out,

    m_s ~ N(a_t + b_t x_s, V_s),   V_s = C_s + diag(sigma_t^2),   b_t = b0 + tau_b * delta_t.

Given the spreads ``sigma`` (all types) and the slopes' spread ``tau_b`` the
model is linear-Gaussian in ``beta = (a_1..a_T, delta_1..delta_T, b0)``
(``2 d T + d`` numbers, prior normal), so ``beta`` is integrated out in
closed form: with the per-type sums ``S_p = sum_s x_s^p V_s^-1`` and ``g_p =
sum_s x_s^p V_s^-1 m_s`` the posterior precision of ``beta`` is ``P = P0 +
F(S, tau_b)`` and the marginal likelihood a ratio of Gaussian normalisers.
emcee samples only ``theta = (ln sigma_tj, tau_b,j)`` (``d (T + 1)``
dimensions, the types coupled through ``b0`` and the spreads' hyperprior,
:meth:`.population.Hyperprior.ln_prob_log_sigma`), vectorised over walkers
and setups; ``beta`` is then drawn from its conditional normal for every kept
draw, which gives each type's ``(a_t, b_t, sigma_t)`` draws.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from ..inference.diagnostics import chain_diagnostics
from ..inference.sampler import SamplerSettings, run_ensemble
from .defaults import STAGE2_MAX_STEPS
from .population import Hyperprior

__all__ = ["Group", "HyperFit", "TypeFit", "ChainQuality", "HyperPosterior", "Stage2Settings", "fit_hyper",
           "log_posterior", "beta_posterior", "predictive_of_setup", "RHAT_MAX"]

#: Kept hyperparameter draws (evenly thinned) for which ``beta`` is drawn: at most 8000, and fewer (down to 2000)
#: for large libraries, where each draw costs a pass over all setups.
MAX_KEPT = 8000
MIN_KEPT = 2000

#: Default R-hat bound of stage 2 (stage 1 uses 1.01).  R-hat over the walkers of a converged ensemble is not
#: 1 + noise but about 1 + 0.8 tau / N (N kept steps per walker, whatever the number of walkers): measured on the
#: four-combination case of tests/test_library.py (96 walkers, seeds 21-23, one 12,000-step run each) it was
#: 1.021-1.025 at N = 40 tau, 1.016-1.020 at 50 tau, 1.010-1.014 at 75 tau and 1.008-1.009 at 95 tau.  So 1.02
#: asks the same chain length as the rule's 50 autocorrelation times, and R-hat keeps its job here: catching an
#: underestimated tau or walkers that have not mixed (1.15-1.22 at the 250 steps the old ESS rule stopped at);
#: 1.01 would ask ~90 tau per walker, a bulk ESS ~20 x the target of 400, for no better estimate.
RHAT_MAX = 1.02


def _factor(Ct: np.ndarray, s2: np.ndarray):
    """Cholesky factors of ``V = C_s + diag(s2_w)`` for every walker w and setup s, element by element.

    Parameters
    ----------
    Ct : (d, d, n) surrogate covariances, setup axis last
    s2 : (W, d) population variances per walker, or (W, d, n) per walker and setup

    Returns
    -------
    L : nested list, ``L[i][j]`` (W, n) for j <= i
    logdet : (W, n) ln det V; NaN where V is not positive definite

    Notes
    -----
    Each element is one array over (walkers, setups) and V is never formed:
    for thousands of 6x6 matrices this is several times faster than LAPACK's
    per-matrix calls.
    """
    d = Ct.shape[0]
    L = [[None] * d for _ in range(d)]
    logdet = 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(d):
            acc = Ct[j, j][None, :] + (s2[:, j] if s2.ndim == 3 else s2[:, j][:, None])
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
    return L, logdet


def _forward(L, r):
    """``L^-1 r`` for the factors of :func:`_factor`; r (d, W, n) -> list of d arrays (W, n)."""
    d = len(L)
    w = [None] * d
    with np.errstate(invalid="ignore", divide="ignore"):
        for i in range(d):
            acc = r[i]
            for k in range(i):
                acc = acc - L[i][k] * w[k]
            w[i] = acc / L[i][i]
    return w


@dataclass(frozen=True)
class Group:
    """The surrogates of one holder type, laid out for the vectorised sums (setup axis last).

    Attributes
    ----------
    holder_type : str
    names : tuple of str, (n,) setups
    x : (n,) covariate ln(d / 10 mm)
    m : (n, d) surrogate means; C : (n, d, d) surrogate covariances
    """

    holder_type: str
    names: tuple
    x: np.ndarray
    m: np.ndarray
    C: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "x", np.asarray(self.x, dtype=float))
        object.__setattr__(self, "m", np.asarray(self.m, dtype=float))
        object.__setattr__(self, "C", np.asarray(self.C, dtype=float))
        object.__setattr__(self, "mT", np.ascontiguousarray(self.m.T))
        object.__setattr__(self, "Ct", np.ascontiguousarray(np.moveaxis(self.C, 0, -1)))

    def without(self, i: int) -> "Group":
        keep = np.arange(len(self.names)) != i
        return Group(self.holder_type, tuple(n for k, n in enumerate(self.names) if keep[k]), self.x[keep],
                     self.m[keep], self.C[keep])


class _Layout:
    """The surrogates of all holder types laid out once for :func:`_linear_system` (what does not depend on the
    sampled hyperparameters).

    The setups of all types sit side by side (setup axis last), so that the element-by-element Cholesky
    factors, forward substitutions and inverse factors are one pass over every setup instead of one per type; the
    per-type sums and the assembly of ``P`` repeat the arithmetic of one type at a time, operation for operation,
    so the numbers are those of the per-type computation bit for bit (tests/test_library_fastpaths.py).
    ``S1`` and ``S2`` enter both off-diagonal blocks untransposed, as the per-type computation had them.

    Parameters
    ----------
    groups : sequence of Group, one per holder type
    hyper : Hyperprior
    """

    def __init__(self, groups, hyper: Hyperprior) -> None:
        groups = tuple(groups)
        T, d = len(groups), hyper.ndim
        K = 2 * d * T + d
        self.T, self.d, self.K = T, d, K
        n = [len(g.names) for g in groups]
        self.edges = np.concatenate([[0], np.cumsum(n)]).astype(int)
        self.type_of = np.repeat(np.arange(T), n)  # (N,) holder type of each setup
        self.mT = np.concatenate([g.mT for g in groups], axis=1)  # (d, N)
        self.Ct = np.concatenate([g.Ct for g in groups], axis=2)  # (d, d, N)
        self.x = np.concatenate([g.x for g in groups])
        # every type with the same number of setups: the per-type sums are one batched product over a view
        self.equal = len(set(n)) == 1
        self.const = np.array([k * d * math.log(2 * math.pi) for k in n])
        self.mu0 = np.concatenate([np.tile(hyper.a_mean, T), np.zeros(T * d), np.zeros(d)])
        self.p0 = np.concatenate([np.tile(hyper.a_sd ** -2, T), np.ones(T * d), hyper.b_sd ** -2])
        self.p0mu0 = self.p0 * self.mu0
        # the prior's terms of the log marginal likelihood (log_posterior)
        self.prior_quad = 0.5 * float(np.sum(self.p0 * self.mu0 * self.mu0))
        self.prior_logdet = 0.5 * float(np.sum(np.log(self.p0)))
        # flat indices into P (K * K) of the blocks each type writes alone, in the order of the stacked values of
        # _linear_system: (a, a), (a, delta), (delta, a), (a, b0), (b0, a), (delta, delta), (delta, b0), (b0, delta)
        j = np.arange(d)
        blocks = []
        for t in range(T):
            ia, idl, ib = t * d + j, T * d + t * d + j, 2 * d * T + j
            blocks.append([(ia, ia), (ia, idl), (idl, ia), (ia, ib), (ib, ia), (idl, idl), (idl, ib), (ib, idl)])
        self.flat = np.array([[[(r[:, None] * K + c[None, :]).ravel() for r, c in bt] for bt in blocks]]).reshape(-1)
        # entries of P that hold a prior precision in the blocks above: P starts as diag(p0) there
        self.ia_diag = (np.arange(T * d) * (K + 1))
        self.idl_diag = ((T * d + np.arange(T * d)) * (K + 1))
        self.ib = slice(2 * d * T, K)
        for v in (self.edges, self.type_of, self.mT, self.Ct, self.x, self.const, self.mu0, self.p0, self.p0mu0,
                  self.flat):
            v.setflags(write=False)  # handed out to every call (mu0, p0 to the caller): never written


def _gram(Ct: np.ndarray, mT: np.ndarray, x: np.ndarray, s2: np.ndarray, edges, equal: bool = False):
    """The Gram matrices of the setups between consecutive ``edges``, and ``ln det V`` (W, n) of every setup.

    Parameters
    ----------
    Ct : (d, d, n) surrogate covariances; mT : (d, n) means; x : (n,) covariate (setup axis last)
    s2 : (W, d) population variances, or (W, d, n) per setup
    edges : sequence of int, the setups ``edges[k]:edges[k + 1]`` form group k
    equal : bool, every group has the same number of setups (then one batched product over a view of A; its
        matrices, strides and hence products are those of the group-by-group copies)

    Returns
    -------
    G : (W, groups, 2d + 1, 2d + 1), one Gram matrix per group: with ``A[w, s, k] = (row k of L^-1, x_s * row k of L^-1,
        y_k)`` and ``V^-1 = sum_k Linv[k]^T Linv[k]``, ``G = A^T A`` over (setups of the group, k) holds every
        sum at once: ``S_p = sum_s x^p V^-1`` (p = 0, 1, 2), ``g_p = sum_s x^p V^-1 m`` (p = 0, 1) and
        ``q = sum_s m^T V^-1 m``
    logdet : (W, n)
    """
    d, n = mT.shape
    W = s2.shape[0]
    L, logdet = _factor(Ct, s2)
    y = _forward(L, np.broadcast_to(mT[:, None, :], (d, W, n)))
    A = _rows(L, y, x)
    if equal:
        Ag = A.reshape(W, len(edges) - 1, -1, 2 * d + 1)
        return np.swapaxes(Ag, 2, 3) @ Ag, logdet
    G = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        # a contiguous copy per group: the same product, in the same memory layout, as a group's own array
        Ag = np.ascontiguousarray(A[:, lo:hi]).reshape(W, (hi - lo) * d, 2 * d + 1)
        G.append(np.swapaxes(Ag, 1, 2) @ Ag)  # (W, 2d + 1, 2d + 1)
    return np.stack(G, axis=1), logdet


def _rows(L, y, x: np.ndarray) -> np.ndarray:
    """``A[w, s, k] = (row k of L^-1, x_s * row k of L^-1, y_k)`` (W, n, d, 2d + 1) of the factors of
    :func:`_factor`, ``y = L^-1 m`` (:func:`_forward`) and the covariate x (n,)."""
    d = len(L)
    W, n = y[0].shape
    A = np.zeros((W, n, d, 2 * d + 1))
    xs = x[None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        Linv = [[None] * d for _ in range(d)]
        for i in range(d):
            Linv[i][i] = 1.0 / L[i][i]
            for j in range(i):
                acc = L[i][j] * Linv[j][j]
                for k in range(j + 1, i):
                    acc = acc + L[i][k] * Linv[k][j]
                Linv[i][j] = -acc * Linv[i][i]
            for j in range(i + 1):
                A[:, :, i, j] = Linv[i][j]
                A[:, :, i, d + j] = Linv[i][j] * xs
            A[:, :, i, 2 * d] = y[i]
    return A


def _split(theta: np.ndarray, T: int, d: int):
    """(W, T, d) ln sigma and (W, d) tau_b of sampler coordinates (W, d (T + 1))."""
    return theta[:, :T * d].reshape(-1, T, d), theta[:, T * d:]


def _linear_system(theta: np.ndarray, groups, hyper: Hyperprior, layout: _Layout | None = None):
    """Posterior precision ``P`` (W, K, K), right-hand side ``r`` (W, K) of ``beta`` and the rest of the log
    marginal likelihood (W,), with ``K = 2 d T + d``; also the prior parts ``(mu0, p0)``.

    ``layout`` (a :class:`_Layout` of ``groups`` and ``hyper``) saves laying the surrogates out on every call."""
    lay = _Layout(groups, hyper) if layout is None else layout
    T, d, K = lay.T, lay.d, lay.K
    u, tau_b = _split(theta, T, d)
    W = theta.shape[0]
    # (W, d, N) variances of every setup: exp of the same numbers as one type at a time
    s2 = np.exp(2.0 * u).transpose(0, 2, 1)[:, :, lay.type_of]
    G, logdet = _gram(lay.Ct, lay.mT, lay.x, s2, lay.edges, lay.equal)  # (W, T, 2d + 1, 2d + 1), (W, N)
    S0, S1, S2 = G[:, :, :d, :d], G[:, :, :d, d:2 * d], G[:, :, d:2 * d, d:2 * d]
    g0, g1, q = G[:, :, :d, 2 * d], G[:, :, d:2 * d, 2 * d], G[:, :, 2 * d, 2 * d]
    D = tau_b[:, None, None, :]  # column scaling by tau_b
    Dr = tau_b[:, None, :, None]  # row scaling
    S1D = S1 * D
    # every block a type writes alone (in the order of layout.flat), then the shared (b0, b0) block type by type
    # (W, T, 8 d, d): the blocks stacked along rows, each (d, d) row-major
    vals = np.concatenate([S0, S1D, S1D.transpose(0, 1, 3, 2), S1, S1, S2 * D * Dr, S2 * Dr, S2 * D], axis=2)
    P = np.zeros((W, K * K))
    P[:, lay.flat] = vals.reshape(W, -1)
    P[:, lay.ia_diag] += lay.p0[:T * d]
    P[:, lay.idl_diag] += lay.p0[T * d:2 * T * d]
    P = P.reshape(W, K, K)
    ib = lay.ib
    Pbb = np.broadcast_to(np.diag(lay.p0[ib]), (W, d, d))
    r = np.broadcast_to(lay.p0mu0, (W, K)).copy()
    r[:, :T * d] += g0.reshape(W, T * d)
    r[:, T * d:2 * T * d] += (tau_b[:, None, :] * g1).reshape(W, T * d)
    if lay.equal:  # (W, T) sums over each type's setups, as np.sum of each type's own (W, n) array adds them
        ld = np.sum(logdet.reshape(W, T, -1), axis=2)
    else:
        ld = np.stack([np.sum(logdet[:, lay.edges[t]:lay.edges[t + 1]], axis=1) for t in range(T)], axis=1)
    h = 0.5 * (q + ld + lay.const)
    rest = np.zeros(W)
    for t in range(T):  # the shared sums in the order of the per-type computation
        Pbb = Pbb + S2[:, t]
        r[:, ib] += g1[:, t]
        rest = rest - h[:, t]
    P[:, ib, ib] = Pbb
    return P, r, rest, lay.mu0, lay.p0


def _chol(P: np.ndarray):
    """Batched Cholesky; ``ok`` (W,) marks the walkers whose ``P`` is finite and positive definite."""
    ok = np.all(np.isfinite(P), axis=(1, 2))
    if np.all(ok):
        try:  # the common case: every walker's P factors (each matrix is factored on its own either way)
            return np.linalg.cholesky(P), ok
        except np.linalg.LinAlgError:
            pass
    Lp = np.zeros_like(P)
    Lp[:, np.arange(P.shape[1]), np.arange(P.shape[1])] = 1.0
    if np.any(ok):
        try:
            Lp[ok] = np.linalg.cholesky(P[ok])
        except np.linalg.LinAlgError:
            for w in np.flatnonzero(ok):
                try:
                    Lp[w] = np.linalg.cholesky(P[w])
                except np.linalg.LinAlgError:
                    ok[w] = False
    return Lp, ok


def log_posterior(theta: np.ndarray, groups, hyper: Hyperprior, layout: _Layout | None = None) -> np.ndarray:
    """Log posterior (W,) of the sampler coordinates ``(ln sigma_tj, tau_b,j)`` (W, d (T + 1)), beta integrated out.

    ``layout``: the groups laid out beforehand (:class:`HyperPosterior` does it once for all its calls)."""
    T, d = len(groups), hyper.ndim
    u, tau_b = _split(theta, T, d)
    lp = hyper.ln_prob_log_sigma(u) + hyper.ln_prob_tau_b(tau_b)
    ok = np.isfinite(lp) & np.all(np.abs(u) < 50, axis=(1, 2))  # exp(2u) stays finite
    every = bool(np.all(ok))
    if not every and not np.any(ok):
        return np.full(theta.shape[0], -np.inf)
    lay = _Layout(groups, hyper) if layout is None else layout
    P, r, rest, _, _ = _linear_system(theta if every else theta[ok], groups, hyper, lay)
    Lp, good = _chol(P)
    v = np.linalg.solve(Lp, r[..., None])[..., 0] if Lp.shape[0] else r
    diag = np.diagonal(Lp, axis1=1, axis2=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        ll = rest - lay.prior_quad + 0.5 * np.sum(v * v, axis=1) + lay.prior_logdet - np.sum(np.log(diag), axis=1)
    ll = np.where(good & np.isfinite(ll), ll, -np.inf)
    if every:
        return lp + ll
    out = np.full(theta.shape[0], -np.inf)
    out[ok] = lp[ok] + ll
    return out


def beta_posterior(theta: np.ndarray, groups, hyper: Hyperprior, layout: _Layout | None = None):
    """Conditional normal of ``beta`` given sampler coordinates: mean (W, K) and Cholesky factor of its precision."""
    P, r, _, _, _ = _linear_system(theta, groups, hyper, layout)
    Lp, _ = _chol(P)
    mean = np.linalg.solve(np.swapaxes(Lp, 1, 2), np.linalg.solve(Lp, r[..., None]))[..., 0]
    return mean, Lp


def _type_draws(theta: np.ndarray, groups, hyper: Hyperprior, rng: np.random.Generator) -> list[np.ndarray]:
    """Per type (H, 3d) draws of (a_t, b_t, sigma_t), one per row of ``theta`` (H, d (T + 1))."""
    T, d = len(groups), hyper.ndim
    out = [[] for _ in range(T)]
    layout = _Layout(groups, hyper)
    for lo in range(0, theta.shape[0], 1000):  # bounded memory: K x K per draw
        th = theta[lo:lo + 1000]
        mean, Lp = beta_posterior(th, groups, hyper, layout)
        eps = rng.standard_normal(mean.shape)
        beta = mean + np.linalg.solve(np.swapaxes(Lp, 1, 2), eps[..., None])[..., 0]
        u, tau_b = _split(th, T, d)
        b0 = beta[:, 2 * d * T:]
        for t in range(T):
            a = beta[:, t * d:(t + 1) * d]
            b = b0 + tau_b * beta[:, T * d + t * d:T * d + (t + 1) * d]
            out[t].append(np.concatenate([a, b, np.exp(u[:, t, :])], axis=1))
    return [np.concatenate(v) for v in out]


def predictive_of_setup(theta: np.ndarray, groups, hyper: Hyperprior, t: int, m: np.ndarray, C: np.ndarray,
                        x: float) -> tuple[np.ndarray, np.ndarray]:
    """The population predictive of a setup's surrogate mean ``m`` (type ``t``, covariance ``C``) given each row of
    ``theta``, with ``beta`` integrated out (its conditional normal from ``groups``).

    Returns
    -------
    res : (H, d) residual ``m - E[m]``
    V : (H, d, d) predictive covariance ``C + diag(sigma_t^2) + Var(a_t + b_t x)``
    """
    T, d = len(groups), hyper.ndim
    mean, Lp = beta_posterior(theta, groups, hyper)
    u, tau_b = _split(theta, T, d)
    H, K = mean.shape
    X = np.zeros((H, d, K))  # design row of the setup: a_t + (b0 + tau_b delta_t) x
    j = np.arange(d)
    X[:, j, t * d + j] = 1.0
    X[:, j, T * d + t * d + j] = tau_b * x
    X[:, j, 2 * d * T + j] = x
    mu = np.einsum("hjk,hk->hj", X, mean)
    Z = np.linalg.solve(Lp, np.swapaxes(X, 1, 2))  # (H, K, d): X P^-1 X^T = Z^T Z
    V = np.swapaxes(Z, 1, 2) @ Z + C[None] + np.eye(d)[None] * np.exp(2.0 * u[:, t, :])[:, None, :]
    return m[None, :] - mu, V


@dataclass(frozen=True)
class Stage2Settings:
    """How long stage 2 samples: the convergence rule of stage 1 (:mod:`bayes_rcsa.inference.sampler`).

    After ``n_burn`` discarded steps from the start, the chain runs until it is longer than ``tau_factor`` times
    the largest integrated autocorrelation time ``tau``, every ``tau`` changed by less than ``tau_rtol`` since the
    previous check, and, after discarding ``ceil(3 max tau)`` more steps, the rank-normalised split R-hat over the
    walkers is below ``rhat_max`` and the bulk ESS at least ``ess_target`` for every sampled hyperparameter; or
    until ``max_steps`` (a warning).

    Attributes
    ----------
    n_burn : int, steps discarded after the start (at the posterior mode, or at the draws of ``start_from``)
    ess_target : float, required ArviZ bulk ESS of every sampled hyperparameter (draws)
    chunk : int, steps between convergence checks (spaced out to >= 10 % of the chain as it grows,
        :func:`bayes_rcsa.inference.sampler.check_schedule`)
    max_steps : int, steps after ``n_burn`` at most; stopping there unconverged is a warning
    n_walkers : int or None
        Default ``max(2 x ndim + 2, min(96, 16000 / n_setups))``: a call's
        cost grows with walkers x setups, so a large library gets few
        walkers, a small one (where the Python overhead dominates) many.
    tau_factor : float, required chain length in autocorrelation times (stage 1's 50)
    tau_rtol : float, required relative stability of ``tau`` between two checks (stage 1's 5 %)
    rhat_max : float, required R-hat of every sampled hyperparameter (see :data:`RHAT_MAX`)
    """

    n_burn: int = 400
    ess_target: float = 400.0
    chunk: int = 250
    max_steps: int = STAGE2_MAX_STEPS
    n_walkers: int | None = None
    tau_factor: float = 50.0
    tau_rtol: float = 0.05
    rhat_max: float = RHAT_MAX

    def sampler_settings(self, n_walkers: int) -> SamplerSettings:
        """The stopping rule as stage 1's :class:`~bayes_rcsa.inference.sampler.SamplerSettings` (no progress line)."""
        return SamplerSettings(n_walkers=n_walkers, max_steps=self.max_steps, check_every=self.chunk,
                               tau_factor=self.tau_factor, tau_rtol=self.tau_rtol, rhat_max=self.rhat_max,
                               ess_min=self.ess_target, progress=False)


@dataclass(frozen=True)
class ChainQuality:
    """How far stage 2's coupled chain can be trusted (one object shared by a :class:`HyperFit` and its types).

    Attributes
    ----------
    n_walkers : int
    n_steps : int, steps after ``n_burn`` (at most ``Stage2Settings.max_steps``)
    burn : int, steps of those discarded as well, ``ceil(3 max tau)``
    tau : (ndim,) integrated autocorrelation times of the sampled hyperparameters (steps)
    rhat, ess_bulk, ess_tail : (ndim,) rank-normalised split R-hat over the walkers, bulk and tail ESS (draws)
        of the kept draws (``HyperFit.theta``: after ``burn``, evenly thinned, one ArviZ chain per walker); NaN
        where there are fewer than 4 per walker
    n_draws : int, kept draws (the chain evenly thinned to at most :data:`MAX_KEPT`)
    converged : bool, the rule of :class:`Stage2Settings` was met before ``max_steps``
    reason : str, why the chain stopped
    tau_factor : float, the chain length in autocorrelation times below which ``tau`` (and so any ESS) is not
        measured (``Stage2Settings.tau_factor``)
    """

    n_walkers: int
    n_steps: int
    burn: int
    tau: np.ndarray
    rhat: np.ndarray
    ess_bulk: np.ndarray
    ess_tail: np.ndarray
    n_draws: int
    converged: bool
    reason: str
    tau_factor: float = 50.0

    @property
    def tau_measured(self) -> bool:
        """Whether the chain is long enough to measure its own autocorrelation time: longer than ``tau_factor``
        times the largest ``tau`` (the first rule of :mod:`bayes_rcsa.inference.sampler`'s convergence).  A
        shorter chain underestimates ``tau``: stage 2's 500-step chains measured 47-72 steps where chains of
        10,000+ steps measured 153-369 (issue #42)."""
        t = float(np.max(self.tau)) if np.size(self.tau) else math.nan
        return math.isfinite(t) and self.n_steps > self.tau_factor * t

    @property
    def ess(self) -> float:
        """Effective draws of the kept draws: their smallest ArviZ bulk ESS, at most their number; NaN (unknown)
        where the chain is too short to measure its own autocorrelation time (:attr:`tau_measured`) or the ESS could
        not be computed.

        The bulk ESS alone, as stage 1 reports it and as the stopping rule judges it.  The tau-based
        ``n_walkers (n_steps - burn) / max tau`` was above it in every run measured: 3.6-3.8x on the 250-step
        chains the old rule stopped at (which reported it), 10-20 % on converged ones (docs/library.md, "Stage
        2"); a minimum of the two would be the bulk ESS.  Neither is an ESS where ``tau`` itself is not measured:
        both then rest on an underestimated ``tau`` (about fivefold on stage 2's first 500 steps).
        """
        v = float(np.min(self.ess_bulk))
        return min(v, float(self.n_draws)) if (math.isfinite(v) and self.tau_measured) else math.nan

    @property
    def ess_text(self) -> str:
        """:attr:`ess` for messages: ``"1234"`` or ``"unknown (chain shorter than 50 autocorrelation times)"``."""
        e = self.ess
        return f"{e:.0f}" if math.isfinite(e) else (
            f"unknown (chain shorter than {self.tau_factor:g} autocorrelation times)" if not self.tau_measured
            else "unknown")

    def summary(self) -> dict:
        """JSON-ready numbers of the outputs (``library.json``, ``population.nc``): ``ess`` (:attr:`ess`), ``steps``,
        ``autocorrelation_steps`` (largest tau), ``rhat_max``, ``ess_bulk_min``, ``ess_tail_min`` (None where not
        computed), ``converged``."""
        def worst(v, f):
            return float(f(v)) if np.all(np.isfinite(v)) else None

        e = self.ess
        return {"ess": e if math.isfinite(e) else None, "ess_reason": None if math.isfinite(e) else (
                    f"not measured: the chain of {int(self.n_steps)} steps is not longer than {self.tau_factor:g} "
                    "autocorrelation times" if not self.tau_measured else "could not be computed"),
                "tau_measured": self.tau_measured, "steps": int(self.n_steps),
                "autocorrelation_steps": worst(self.tau, np.max),
                "rhat_max": worst(self.rhat, np.max), "ess_bulk_min": worst(self.ess_bulk, np.min),
                "ess_tail_min": worst(self.ess_tail, np.min), "converged": bool(self.converged)}


def _of_quality(name: str, doc: str) -> property:
    """A read-only attribute of a fit that is ``fit.quality.<name>``."""
    return property(lambda self: getattr(self.quality, name), doc=doc)


class _ChainView:
    """The coupled chain's diagnostics (``self.quality``, a :class:`ChainQuality`) as attributes of a fit."""

    tau = _of_quality("tau", "(ndim,) integrated autocorrelation times (steps) of the coupled chain.")
    n_steps = _of_quality("n_steps", "Steps after the burn-in (:attr:`ChainQuality.n_steps`).")
    ess = _of_quality("ess", "Effective draws of the kept draws (:attr:`ChainQuality.ess`: at most their smallest "
                             "bulk ESS).")
    rhat = _of_quality("rhat", "(ndim,) R-hat over the walkers of the kept draws of the sampled hyperparameters.")
    converged = _of_quality("converged", "Whether the coupled chain met the rule of :class:`Stage2Settings` before "
                                         "``max_steps``.")


@dataclass
class TypeFit(_ChainView):
    """Stage-2 posterior of one holder type (a view of the coupled fit).

    Attributes
    ----------
    holder_type : str
    names : tuple of str, setups of this type
    x : (n,) covariate; m : (n, d); C : (n, d, d) surrogates
    chain : (n_walkers, n_keep, 3d) hyperparameter draws (a_t, b_t, sigma_t)
    quality : ChainQuality of the coupled chain (also ``tau``, ``n_steps``, ``ess``, ``rhat``, ``converged``)
    acceptance : float
    warnings : list of str
    """

    holder_type: str
    names: tuple
    x: np.ndarray
    m: np.ndarray
    C: np.ndarray
    chain: np.ndarray
    quality: ChainQuality
    acceptance: float
    warnings: list = field(default_factory=list)

    @property
    def flat(self) -> np.ndarray:
        """(n_walkers * n_keep, 3d) draws."""
        return self.chain.reshape(-1, self.chain.shape[-1])


@dataclass
class HyperFit(_ChainView):
    """The coupled stage-2 posterior.

    Attributes
    ----------
    groups : tuple of Group, one per holder type (sorted)
    theta : (H, d (T + 1)) kept sampler draws (ln sigma_tj, tau_b,j), evenly thinned
    types : dict holder type -> TypeFit (draws of a_t, b_t, sigma_t; row i of every type from theta[i])
    quality : ChainQuality (also ``tau``, ``n_steps``, ``ess``, ``rhat``, ``converged``)
    acceptance : float
    warnings : list of str
    """

    groups: tuple
    theta: np.ndarray
    types: dict
    quality: ChainQuality
    acceptance: float
    warnings: list

    @property
    def n_walkers(self) -> int:
        """Walkers of the coupled chain (``theta`` holds them one after the other)."""
        return self.quality.n_walkers

    @property
    def tau_b(self) -> np.ndarray:
        """(H, d) draws of the slopes' spread between types."""
        return self.theta[:, len(self.groups) * (self.theta.shape[1] // (len(self.groups) + 1)):]


class HyperPosterior:
    """:func:`log_posterior` of ``groups`` as a density for :func:`bayes_rcsa.inference.sampler.run_ensemble`.

    Parameters
    ----------
    groups : tuple of Group
    hyper : Hyperprior
    """

    def __init__(self, groups, hyper: Hyperprior) -> None:
        self.groups = tuple(groups)
        self.hyper = hyper
        self.ndim = hyper.ndim * (len(self.groups) + 1)
        self._layout = _Layout(self.groups, hyper)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """(W,) log posterior of (W, ndim) sampler coordinates."""
        return log_posterior(np.atleast_2d(theta), self.groups, self.hyper, self._layout)

    def check_inside(self, theta: np.ndarray, what: str = "walker start") -> None:
        """Raise :class:`SetupError` naming the first row of theta (n, ndim) outside the hyperprior's support
        (a negative ``tau_b``, or a log spread beyond +-50)."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.shape[1] != self.ndim:
            raise SetupError(f"{what}: {theta.shape[1]} coordinates, expected {self.ndim} (ln sigma per type and "
                             "coordinate, then tau_b per coordinate)")
        u, tau_b = _split(theta, len(self.groups), self.hyper.ndim)
        bad = ~(np.isfinite(self.hyper.ln_prob_tau_b(tau_b)) & np.all(np.abs(u) < 50, axis=(1, 2)))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise SetupError(f"{what} {i}: {theta[i].tolist()} lies outside the hyperprior's support")


def _start(groups, hyper: Hyperprior, rng, n_walkers) -> np.ndarray:
    """Walkers around the posterior mode (L-BFGS from a moment estimate; gradient by central differences,
    all 2 ndim + 1 points in one vectorised call)."""
    from scipy.optimize import minimize

    T, d = len(groups), hyper.ndim
    ndim = d * (T + 1)
    s_guess = np.exp(hyper.ls_mean)
    u0 = []
    for g in groups:
        if g.m.shape[0] > 2:  # residual spread about a straight line in x, less the stage-1 width
            X = np.column_stack([np.ones_like(g.x), g.x - g.x.mean()])
            res = g.m - X @ np.linalg.lstsq(X, g.m, rcond=None)[0]
            v = np.sum(res * res, axis=0) / (g.m.shape[0] - 2) - np.mean(np.diagonal(g.C, axis1=1, axis2=2), axis=0)
            s = np.sqrt(np.maximum(v, (0.05 * s_guess) ** 2))
        else:
            s = s_guess
        u0.append(np.log(np.clip(s, 0.02 * s_guess, 20 * s_guess)))
    t0 = np.concatenate([np.concatenate(u0), 0.5 * hyper.tb_scale])
    h = 1e-5 * np.eye(ndim)
    layout = _Layout(groups, hyper)

    def f(t):
        v = -log_posterior(np.vstack([t, t + h, t - h]), groups, hyper, layout)
        if not np.all(np.isfinite(v)):
            return float(v[0]) if np.isfinite(v[0]) else 1e300, np.zeros(ndim)
        return float(v[0]), (v[1:ndim + 1] - v[ndim + 1:]) / 2e-5

    bounds = [(-30.0, 10.0)] * (T * d) + [(1e-3 * v, None) for v in hyper.tb_scale]
    res = minimize(f, t0, jac=True, method="L-BFGS-B", bounds=bounds, options={"maxiter": 500})
    t = res.x if np.isfinite(res.fun) and res.fun <= f(t0)[0] else t0
    scale = np.concatenate([np.full(T * d, 0.05), 0.05 * hyper.tb_scale])
    start = t + scale * rng.standard_normal((n_walkers, ndim))
    start[:, T * d:] = np.abs(start[:, T * d:])
    lp = log_posterior(start, groups, hyper, layout)
    start[~np.isfinite(lp)] = t
    return start


def _start_from_draws(target: HyperPosterior, draws: np.ndarray, rng: np.random.Generator,
                      n_walkers: int) -> np.ndarray | None:
    """Walker starts at ``n_walkers`` distinct rows of ``draws`` (H, ndim) with a finite log posterior; None if
    there are fewer.

    A thinned chain repeats rows where a walker stood still, and an exactly re-weighted fit (:mod:`.exact`) is a
    resample full of copies.  Copies are useless walkers (the stretch move from a walker towards its copy proposes
    the same point), and too few distinct rows would fail the sampler's check that the walkers span the space.
    """
    rows = np.unique(np.asarray(draws, dtype=float), axis=0)
    if rows.shape[0] < n_walkers:
        return None
    rows = rows[rng.permutation(rows.shape[0])]
    # the first 4 n_walkers shuffled rows are enough candidates: the nearby posterior rarely puts one outside
    cand = rows[:4 * n_walkers]
    cand = cand[np.isfinite(target(cand))]
    return cand[:n_walkers] if cand.shape[0] >= n_walkers else None


def fit_hyper(groups, hyper: Hyperprior, rng: np.random.Generator, settings: Stage2Settings = Stage2Settings(),
              start_from: np.ndarray | None = None, type_draws: bool = True) -> HyperFit:
    """Sample the coupled hyperparameters of all holder types (emcee's stretch move, vectorised over walkers and
    setups) until converged by stage 1's rule (:class:`Stage2Settings`), with stage 1's run loop
    (:func:`bayes_rcsa.inference.sampler.run_ensemble`).

    Parameters
    ----------
    groups : sequence of Group, one per holder type
    hyper : Hyperprior
    rng : numpy Generator
    settings : Stage2Settings
    start_from : (H, d (T + 1)) or None
        Draws of a nearby posterior (e.g. the full library's for a leave-one-out refit): the walkers start
        at distinct randomly chosen rows instead of around the mode found by L-BFGS (which is used where
        there are fewer distinct rows with a finite density than walkers).
    type_draws : bool
        Draw each type's ``(a_t, b_t, sigma_t)`` (``types`` of the result); a leave-one-out refit needs only
        the sampler draws.

    Returns
    -------
    HyperFit
        Its ``warnings`` name the R-hat, bulk ESS and autocorrelation time where the chain stopped at
        ``settings.max_steps`` unconverged.
    """
    import emcee

    groups = tuple(groups)
    target = HyperPosterior(groups, hyper)
    T, d, ndim = len(groups), hyper.ndim, target.ndim
    n_setups = sum(len(g.names) for g in groups)
    n_walkers = settings.n_walkers or max(2 * ndim + 2, min(96, 16000 // max(1, n_setups)))
    n_walkers += n_walkers % 2
    start = None
    if start_from is not None and start_from.ndim == 2 and start_from.shape[1] == ndim:
        start = _start_from_draws(target, start_from, rng, n_walkers)
    if start is None:
        start = _start(groups, hyper, rng, n_walkers)
    moves = [(emcee.moves.StretchMove(), 1.0)]
    if settings.n_burn > 0:
        # one check at the end only, which cannot stop it (no previous tau to be stable against)
        burn_in = run_ensemble(target, SamplerSettings(max_steps=settings.n_burn, check_every=settings.n_burn,
                                                       progress=False), initial=start, rng=rng, moves=moves)
        start = burn_in.chain[-1]
    run = run_ensemble(target, settings.sampler_settings(n_walkers), initial=start, rng=rng,
                       diagnose=chain_diagnostics, moves=moves)
    n_keep = int(np.clip(2e6 / n_setups, MIN_KEPT, MAX_KEPT))
    chain = run.chain[run.burn:]  # (steps, walkers, ndim)
    step = max(1, int(math.ceil(chain.shape[0] * chain.shape[1] / n_keep)))
    kept = np.swapaxes(chain[::step], 0, 1)  # (walkers, kept steps, ndim): theta walker by walker
    theta = kept.reshape(-1, ndim)
    # reported: the diagnostics of the draws kept (what every output uses), not those of the chain the rule judged,
    # thinned by half the smallest tau: on short chains that thinning gives a 10-35 % higher bulk ESS and a lower
    # R-hat than the kept draws or the whole chain (within 4 % at the default settings; docs/library.md)
    diag = chain_diagnostics(np.swapaxes(kept, 0, 1))
    quality = ChainQuality(n_walkers, run.n_steps, run.burn, np.asarray(run.tau), diag["rhat"], diag["ess_bulk"],
                           diag["ess_tail"], theta.shape[0], run.converged, run.reason, settings.tau_factor)
    warns = []
    if not run.converged:
        warns.append(f"stage 2 stopped at max_steps = {settings.max_steps} unconverged: R-hat "
                     f"{np.max(diag['rhat']):.3f} (required < {settings.rhat_max:g}), bulk ESS "
                     f"{np.min(diag['ess_bulk']):.0f} (required >= {settings.ess_target:g}), autocorrelation time "
                     f"{np.max(run.tau):.0f} steps (required < 1/{settings.tau_factor:g} of the chain); the "
                     f"hyperparameter intervals are approximate (ESS {quality.ess_text}; a larger max_steps helps: "
                     "'bayes-rcsa library --max-steps')")
    draws = _type_draws(theta, groups, hyper, rng) if type_draws else [np.zeros((theta.shape[0], 0))] * T
    acc = float(np.mean(run.acceptance_fraction))
    types = {}
    for g, dr in zip(groups, draws):
        tw = []
        if len(g.names) < 3:
            tw.append(f"holder type {g.holder_type}: {len(g.names)} combination(s); its mean and slope lean on the "
                      "other types and the hyperprior (a weak fit)")
        types[g.holder_type] = TypeFit(g.holder_type, g.names, g.x, g.m, g.C,
                                       dr.reshape(kept.shape[0], kept.shape[1], -1), quality, acc, tw)
        warns += tw
    return HyperFit(groups, theta, types, quality, acc, warns)
