"""Modal models of tool-point receptances and their fit to (predicted or measured) FRFs.

A direct receptance is represented by real, mass-normalised modes with
viscous (proportional) damping, which is reciprocal and passive by
construction:

    G(ω) = Σ_r 1 / (k_r (1 - (ω/ω_r)^2 + 2 i ζ_r ω/ω_r))          (m/N)

(harmonic convention e^{+iωt}, so Im G <= 0).  Mode r is the single-degree
oscillator m_r ξ'' + c_r ξ' + k_r ξ = F with m_r = k_r/ω_r^2 and
c_r = 2 ζ_r sqrt(k_r m_r), all > 0; its unit-normalised shape at the tool tip
is 1/sqrt(m_r).

Fit
---
:func:`fit_modal_model` adds modes greedily: each new mode starts at the
largest peak of |G - model| with a half-power-bandwidth estimate of ζ and
k = 1/(2 ζ |peak|); then all modes (log f_n, log ζ, log k, so positivity
holds) and a real residual compliance (the static effect of modes above the
band) are refined together by nonlinear least squares on the complex
residual (a batched, projected Levenberg-Marquardt on the small normal
equations; ln k is bounded so that no mode's stiffness can run off).  The mode count minimising the Bayesian information criterion

    BIC = n ln(RSS/n) + p ln n,   n = 2 n_freq,  p = 3 r + 1

is returned; the search stops at the first mode count whose BIC is worse
than the previous one, or whose fit holds a mode inside the band with a
half-power bandwidth 2 ζ f_n below the line spacing (it fits a noise line,
not a resonance the lines resolve; that mode count is not used).  The residual compliance is reported but not part of the modal
model (a massless spring has no place in the modal equations of motion).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, DataError, ModelError

__all__ = ["ModalModel", "ModalFit", "fit_modal_model", "refit_modal_model", "refit_modal_models"]


@dataclass(frozen=True)
class ModalModel:
    """Real modes of one direct receptance.

    Attributes
    ----------
    natural_frequency_hz : (n_modes,) Hz, > 0
    damping_ratio : (n_modes,), in (0, 1)
    stiffness : (n_modes,) N/m, modal stiffness k_r > 0 (mass-normalised residue 1/m_r = ω_r^2/k_r)
    """

    natural_frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    stiffness: np.ndarray

    def __post_init__(self) -> None:
        f = np.atleast_1d(np.asarray(self.natural_frequency_hz, dtype=float))
        z = np.atleast_1d(np.asarray(self.damping_ratio, dtype=float))
        k = np.atleast_1d(np.asarray(self.stiffness, dtype=float))
        if not (f.ndim == 1 and f.shape == z.shape == k.shape and f.size >= 1):
            raise ModelError("modal model: natural_frequency_hz, damping_ratio and stiffness must be 1-D of equal length >= 1")
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(z)) and np.all(np.isfinite(k))):
            raise ModelError("modal model: parameters must be finite")
        if np.any(f <= 0) or np.any(k <= 0) or np.any(z <= 0) or np.any(z >= 1):
            raise ModelError("modal model: expected f_n > 0, k > 0 and 0 < zeta < 1 (passive, underdamped modes)")
        object.__setattr__(self, "natural_frequency_hz", f)
        object.__setattr__(self, "damping_ratio", z)
        object.__setattr__(self, "stiffness", k)

    @property
    def n_modes(self) -> int:
        return int(self.natural_frequency_hz.size)

    @property
    def omega(self) -> np.ndarray:
        """(n_modes,) rad/s"""
        return 2 * np.pi * self.natural_frequency_hz

    @property
    def mass(self) -> np.ndarray:
        """(n_modes,) kg, modal mass k/ω^2."""
        return self.stiffness / self.omega**2

    @property
    def damping(self) -> np.ndarray:
        """(n_modes,) N s/m, 2 ζ sqrt(k m)."""
        return 2 * self.damping_ratio * np.sqrt(self.stiffness * self.mass)

    def frf(self, frequency_hz) -> np.ndarray:
        """Receptance on ``frequency_hz``: (n_freq,) complex, m/N."""
        r = np.asarray(frequency_hz, dtype=float)[:, None] / self.natural_frequency_hz
        return np.sum(1.0 / (self.stiffness * (1.0 - r**2 + 2j * self.damping_ratio * r)), axis=-1)


@dataclass(frozen=True)
class ModalFit:
    """Result of :func:`fit_modal_model`.

    Attributes
    ----------
    model : ModalModel (modes sorted by frequency)
    residual_compliance : float, m/N (real constant fitted alongside, not in ``model``)
    bic : (n_tried,) BIC of the 1..n_tried-mode fits
    rms_relative : float, RMS |G - fit| / RMS |G| of the chosen fit
    """

    model: ModalModel
    residual_compliance: float
    bic: np.ndarray
    rms_relative: float


# Bounds of ln k in the scaled units of the fit (FRF divided by its RMS): a mode with k = 1e8 contributes at
# most 1/(2 ζ k) <= 5e-5 of the RMS (it has vanished), one with k = 1e-4 would give peaks 1e4 times the RMS
# (no FRF shows that).  Without them a spurious mode of a noisy FRF could send ln k off towards -1e18, where
# exp underflows to 0 and the model divides by zero.
_LN_K_BOUNDS = (np.log(1e-4), np.log(1e8))
_LN_ZETA_BOUNDS = (np.log(1e-4), np.log(0.5))
# Mean squared misfit per real observation (scaled units) below which fits count as equal in the BIC: ln f_n
# carries ~1e-15 relative error in double precision, which a peak's 1/ζ sensitivity lifts to ~1e-13 of the
# RMS, so a noise-free FRF is fitted to about 1e-12 at best and smaller differences are rounding, not modes.
_RSS_FLOOR = 1e-24


def _modes_and_jac(p: np.ndarray, f: np.ndarray, jac: bool = True):
    """Model G and dG/dp for p = [ln f_n, ln ζ, ln k] * r + [c], batched over leading axes.

    Parameters
    ----------
    p : (..., 3 r + 1) parameters (scaled units)
    f : (n_freq,) Hz
    jac : bool, also return the Jacobian

    Returns
    -------
    G : (..., n_freq) complex
    J : (..., n_freq, 3 r + 1) complex, or None
    """
    p = np.asarray(p, dtype=float)
    r_modes = (p.shape[-1] - 1) // 3
    fn = np.exp(p[..., None, 0 : 3 * r_modes : 3])  # (..., 1, r)
    ze = np.exp(p[..., None, 1 : 3 * r_modes : 3])
    kk = np.exp(p[..., None, 2 : 3 * r_modes : 3])
    r = f[:, None] / fn  # (..., n_freq, r)
    D = 1.0 - r**2 + 2j * ze * r  # Im D = 2 ζ r > 0: never zero inside the bounds
    H = 1.0 / (kk * D)
    G = H.sum(axis=-1) + p[..., -1:]
    if not jac:
        return G, None
    J = np.empty(G.shape + (p.shape[-1],), dtype=complex)
    HD = -H / D
    J[..., 0 : 3 * r_modes : 3] = HD * (2 * r**2 - 2j * ze * r)
    J[..., 1 : 3 * r_modes : 3] = HD * (2j * ze * r)
    J[..., 2 : 3 * r_modes : 3] = -H
    J[..., -1] = 1.0
    return G, J


def _bounds(f: np.ndarray, r: int):
    """Box (lb, ub) of (3 r + 1,) for [ln f_n, ln ζ, ln k] * r + [c]: f_n within half the lowest to twice the
    highest line, ζ in [1e-4, 0.5], ln k in :data:`_LN_K_BOUNDS`, c free (it enters linearly)."""
    lb = np.array([np.log(f[0] * 0.5), _LN_ZETA_BOUNDS[0], _LN_K_BOUNDS[0]] * r + [-np.inf])
    ub = np.array([np.log(f[-1] * 2.0), _LN_ZETA_BOUNDS[1], _LN_K_BOUNDS[1]] * r + [np.inf])
    return lb, ub


def _inside(p: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """``p`` moved strictly inside the box (finite bounds only)."""
    return np.clip(p, lb + 1e-9, ub - 1e-9)


def _unresolved(f: np.ndarray, p: np.ndarray) -> bool:
    """True when a mode inside the band has a half-power bandwidth 2 ζ f_n below the local line spacing.

    Such a mode changes one or two lines only: the FRF cannot tell it from noise on those lines (with
    noise proportional to |G|, as in a hammer test, the lines at a peak are the noisiest), and an unweighted
    BIC would otherwise keep adding ζ ~ 1e-4 spikes at the peaks of measured FRFs."""
    r = (p.size - 1) // 3
    fn = np.exp(p[0 : 3 * r : 3])
    ze = np.exp(p[1 : 3 * r : 3])
    inside = (fn >= f[0]) & (fn <= f[-1])
    spacing = np.interp(fn, f[1:], np.diff(f))
    return bool(np.any(inside & (2.0 * ze * fn < spacing)))


def _half_power_zeta(f: np.ndarray, mag: np.ndarray, i: int) -> float:
    """ζ from the half-power bandwidth around line i of |residual| (fallback 0.02)."""
    half = mag[i] / np.sqrt(2.0)
    lo = i
    while lo > 0 and mag[lo] > half:
        lo -= 1
    hi = i
    while hi < f.size - 1 and mag[hi] > half:
        hi += 1
    if lo == i or hi == i or mag[lo] > half or mag[hi] > half:
        return 0.02
    zeta = (f[hi] - f[lo]) / (2.0 * f[i])
    return float(min(max(zeta, 1e-3), 0.3))


def fit_modal_model(
    frequency_hz,
    frf,
    max_modes: int = 6,
    band: tuple[float, float] | None = None,
    source: str = "<frf>",
) -> ModalFit:
    """Fit real, passive modes to a direct receptance; mode count by BIC.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz, increasing
    frf : (n_freq,) complex, m/N
    max_modes : int
        Largest mode count tried.
    band : (f_lo, f_hi) Hz or None
        Restrict the fit to this band (default: all lines).
    source : str
        Name used in error messages.

    Returns
    -------
    ModalFit
    """
    f, g = _checked_lines(frequency_hz, frf, source)
    if band is not None:
        keep = (f >= band[0]) & (f <= band[1])
        f, g = f[keep], g[keep]
        if f.size < 8:
            raise DataError(f"{source}: fewer than 8 lines inside band {band} Hz")
    scale = float(np.sqrt(np.mean(np.abs(g) ** 2)))
    if not np.isfinite(scale) or scale == 0:
        raise DataError(f"{source}: FRF is zero or not finite")
    gs = g / scale
    n_obs = 2 * f.size

    params = np.array([0.0])  # residual compliance only (scaled units)
    fits: list[tuple[np.ndarray, float]] = []
    bics: list[float] = []
    for r in range(1, max_modes + 1):
        model, _ = _modes_and_jac(params, f, jac=False)
        resid = np.abs(gs - model)
        i = int(np.argmax(resid))
        zeta0 = _half_power_zeta(f, resid, i)
        k0 = 1.0 / (2.0 * zeta0 * max(resid[i], 1e-300))  # scaled units: k * scale
        new = np.array([np.log(f[i]), np.log(zeta0), np.log(k0)])
        lb, ub = _bounds(f, r)
        p0 = _inside(np.concatenate([params[:-1], new, params[-1:]]), lb, ub)  # start strictly inside the box

        x, rss_b = _levenberg_marquardt(f, gs[None], p0[None], lb, ub, max_iter=200)
        x, rss = x[0], float(rss_b[0])
        bic = n_obs * np.log(max(rss, _RSS_FLOOR * n_obs) / n_obs) + (3 * r + 1) * np.log(n_obs)
        if r > 1 and _unresolved(f, x):
            break  # a mode narrower than the line spacing fits a noise line, not the structure: r - 1 modes
        fits.append((x, rss))
        bics.append(bic)
        params = x
        if len(bics) >= 2 and bics[-1] > bics[-2]:
            break  # the criterion got worse: further modes would only fit noise
    best = int(np.argmin(bics))
    p, rss = fits[best]
    r = best + 1
    fn = np.exp(p[0 : 3 * r : 3])
    ze = np.exp(p[1 : 3 * r : 3])
    kk = np.exp(p[2 : 3 * r : 3]) / scale
    order = np.argsort(fn)
    if not np.all(np.isfinite(kk)):
        raise ConvergenceError(f"{source}: modal fit diverged")
    model = ModalModel(fn[order], ze[order], kk[order])
    rms_rel = float(np.sqrt(rss / f.size))  # gs has unit RMS
    return ModalFit(model=model, residual_compliance=float(p[-1] * scale), bic=np.asarray(bics), rms_relative=rms_rel)


def refit_modal_model(frequency_hz, frf, start: ModalFit, source: str = "<frf>") -> ModalFit:
    """Refine a modal fit of a similar receptance (e.g. the previous posterior draw) on ``frf``.

    One draw of :func:`refit_modal_models`: the mode count of ``start`` is kept (no BIC search) and its modes
    and residual compliance are the start values of one nonlinear least-squares refinement, which costs a
    fraction of :func:`fit_modal_model`; ``bic`` of the result holds the refined fit only.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz
    frf : (n_freq,) complex, m/N
    start : ModalFit
    source : str, name used in error messages

    Returns
    -------
    ModalFit
    """
    f, g = _checked_lines(frequency_hz, frf, source)
    return refit_modal_models(f, g[None], start, source=source)[0]


def refit_modal_models(frequency_hz, frfs, start: ModalFit, source: str = "<frf>", max_iter: int = 20,
                       chunk: int = 64) -> list[ModalFit]:
    """Refine one modal fit on many similar receptances at once (FRF draws around a nominal FRF).

    Every draw starts from ``start`` (e.g. the full :func:`fit_modal_model` of the draws' mean FRF) and keeps
    its mode count; the Levenberg-Marquardt iterations run on all draws together (batched normal equations of
    size 3 r + 1; no loop over draws or frequency lines).  Each step only lowers a draw's residual, so no draw
    ends worse than ``start``'s modes on it; ln k stays inside :data:`_LN_K_BOUNDS` (finite, positive
    stiffness whatever the FRF).

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz
    frfs : (n_draws, n_freq) complex, m/N
    start : ModalFit
    source : str, name used in error messages
    max_iter : int, Levenberg-Marquardt iterations at most (from a start near the optimum the well-determined
        modes settle in 3-5; the default 20 leaves only a poorly determined spurious mode, e.g. a ζ = 1e-4 spike
        on a noise line, still creeping: on the bundled example the RMS misfit is then within 0.05 % of the
        converged one)
    chunk : int, draws per batch (bounds the memory of the Jacobians: chunk x n_freq x (3 r + 1) complex)

    Returns
    -------
    list of ModalFit, one per draw (``bic`` holds the refined fit only)
    """
    f = np.asarray(frequency_hz, dtype=float)
    g = np.atleast_2d(np.asarray(frfs, dtype=complex))
    _checked_lines(f, g[0], source)
    if g.shape[1] != f.size:
        raise DataError(f"{source}: FRF draws have {g.shape[1]} lines, the frequency axis {f.size}")
    scale = np.sqrt(np.mean(np.abs(g) ** 2, axis=1))  # (n_draws,)
    if not (np.all(np.isfinite(scale)) and np.all(scale > 0)):
        raise DataError(f"{source}: an FRF draw is zero or not finite")
    gs = g / scale[:, None]
    m = start.model
    r = m.n_modes
    lb, ub = _bounds(f, r)
    p0 = np.empty((g.shape[0], 3 * r + 1))
    p0[:, 0 : 3 * r : 3] = np.log(m.natural_frequency_hz)
    p0[:, 1 : 3 * r : 3] = np.log(m.damping_ratio)
    p0[:, 2 : 3 * r : 3] = np.log(m.stiffness)[None, :] + np.log(scale)[:, None]
    p0[:, -1] = start.residual_compliance / scale
    p0 = _inside(p0, lb, ub)
    p = np.empty_like(p0)
    rss = np.empty(g.shape[0])
    n_obs = 2 * f.size
    # stop once a step lowers the misfit by less than 0.01 in chi^2 (RSS = n_obs sigma^2 at the optimum): the
    # parameters are then within a small fraction of their standard errors of the optimum, and the remaining
    # creep of modes at the edge of the box (spurious ζ = 1e-4 spikes) is not worth 5x the iterations
    rtol = 0.01 / n_obs
    for s in range(0, g.shape[0], chunk):  # memory bound only; each chunk is one batched solve
        p[s : s + chunk], rss[s : s + chunk] = _levenberg_marquardt(f, gs[s : s + chunk], p0[s : s + chunk], lb, ub,
                                                                    max_iter=max_iter, rtol=rtol)
    fn = np.exp(p[:, 0 : 3 * r : 3])
    ze = np.exp(p[:, 1 : 3 * r : 3])
    kk = np.exp(p[:, 2 : 3 * r : 3]) / scale[:, None]
    bic = n_obs * np.log(np.maximum(rss, _RSS_FLOOR * n_obs) / n_obs) + (3 * r + 1) * np.log(n_obs)
    order = np.argsort(fn, axis=1)
    take = np.take_along_axis
    return [ModalFit(model=ModalModel(take(fn, order, 1)[d], take(ze, order, 1)[d], take(kk, order, 1)[d]),
                     residual_compliance=float(p[d, -1] * scale[d]), bic=bic[d : d + 1],
                     rms_relative=float(np.sqrt(rss[d] / f.size))) for d in range(g.shape[0])]


def _levenberg_marquardt(f, gs, p0, lb, ub, max_iter: int, rtol: float = 1e-12):
    """Projected Levenberg-Marquardt of the scaled modal model against ``gs``, batched over rows.

    Parameters
    ----------
    f : (n_freq,) Hz
    gs : (n_batch, n_freq) complex, FRFs divided by their RMS
    p0 : (n_batch, 3 r + 1) start, inside [lb, ub]
    lb, ub : (3 r + 1,) bounds (steps are projected onto the box)
    max_iter : int
    rtol : float, a row stops when an accepted step lowers its RSS by less than this fraction

    Returns
    -------
    p : (n_batch, 3 r + 1), rss : (n_batch,) sum of squared real and imaginary residuals

    Notes
    -----
    The normal equations Re(J^H J) (size 3 r + 1) with Marquardt's diagonal scaling replace an SVD of the
    (2 n_freq, 3 r + 1) Jacobian: the parameters are logarithms of quantities of order one in scaled units, so
    squaring the condition number is harmless, and the batched solve costs microseconds per row.
    """
    p = np.array(p0, dtype=float)
    n_b, n_p = p.shape
    G, J = _modes_and_jac(p, f)
    res = G - gs
    rss = np.sum(res.real**2 + res.imag**2, axis=1)
    lam = np.full(n_b, 1e-3)
    active = np.ones(n_b, dtype=bool)
    eye = np.eye(n_p)
    for _ in range(max_iter):
        idx = np.nonzero(active)[0]
        if idx.size == 0:
            break
        # einsum's own loops, not BLAS: a threaded gemm per (n_freq, P) block spins its threads on a shared
        # machine and cost 5-10x the CPU time of the arithmetic here
        Jr, Ji = J[idx].real, J[idx].imag
        A = np.einsum("bnp,bnq->bpq", Jr, Jr) + np.einsum("bnp,bnq->bpq", Ji, Ji)  # Re(J^H J), (b, P, P)
        grad = np.einsum("bnp,bn->bp", Jr, res[idx].real) + np.einsum("bnp,bn->bp", Ji, res[idx].imag)
        d = np.diagonal(A, axis1=1, axis2=2)
        d = np.maximum(d, 1e-12 * d.max(axis=1, keepdims=True) + 1e-300)  # a column without effect still moves
        step = -np.linalg.solve(A + lam[idx, None, None] * d[:, :, None] * eye, grad[..., None])[..., 0]
        trial = np.clip(p[idx] + step, lb, ub)
        Gt, Jt = _modes_and_jac(trial, f)  # the Jacobian with the model: kept where the step is accepted
        rt = Gt - gs[idx]
        rss_t = np.sum(rt.real**2 + rt.imag**2, axis=1)
        better = rss_t < rss[idx]
        moved = np.max(np.abs(trial - p[idx]), axis=1)
        done = (better & (rss[idx] - rss_t <= rtol * rss[idx])) | (moved < 1e-13) | (lam[idx] > 1e12)
        acc = idx[better]
        p[acc] = trial[better]
        rss[acc] = rss_t[better]
        lam[acc] = np.maximum(lam[acc] / 3.0, 1e-12)
        lam[idx[~better]] *= 4.0
        active[idx[done]] = False
        res[acc] = rt[better]
        J[acc] = Jt[better]
    return p, rss


def _checked_lines(frequency_hz, frf, source: str):
    """(f (n,) Hz, g (n,) complex m/N) after checking they are matching 1-D arrays of at least 8 lines."""
    f = np.asarray(frequency_hz, dtype=float)
    g = np.asarray(frf, dtype=complex)
    if f.ndim != 1 or g.shape != f.shape or f.size < 8:
        raise DataError(f"{source}: need matching 1-D frequency and FRF arrays with >= 8 lines")
    return f, g
