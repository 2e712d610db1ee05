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
residual.  The mode count minimising the Bayesian information criterion

    BIC = n ln(RSS/n) + p ln n,   n = 2 n_freq,  p = 3 r + 1

is returned; the search stops at the first mode count whose BIC is worse
than the previous one.  The residual compliance is reported but not part of the modal
model (a massless spring has no place in the modal equations of motion).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..errors import ConvergenceError, DataError, ModelError

__all__ = ["ModalModel", "ModalFit", "fit_modal_model", "refit_modal_model"]


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


def _modes_and_jac(p: np.ndarray, f: np.ndarray):
    """Model G and dG/dp for p = [ln f_n, ln ζ, ln k] * r + [c]."""
    r_modes = (p.size - 1) // 3
    fn = np.exp(p[0 : 3 * r_modes : 3])
    ze = np.exp(p[1 : 3 * r_modes : 3])
    kk = np.exp(p[2 : 3 * r_modes : 3])
    r = f[:, None] / fn
    D = 1.0 - r**2 + 2j * ze * r
    H = 1.0 / (kk * D)
    G = H.sum(axis=1) + p[-1]
    J = np.empty((f.size, p.size), dtype=complex)
    HD = -H / D
    J[:, 0 : 3 * r_modes : 3] = HD * (2 * r**2 - 2j * ze * r)
    J[:, 1 : 3 * r_modes : 3] = HD * (2j * ze * r)
    J[:, 2 : 3 * r_modes : 3] = -H
    J[:, -1] = 1.0
    return G, J


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
    lo_bound, hi_bound = np.log(f[0] * 0.5), np.log(f[-1] * 2.0)

    params = np.array([0.0])  # residual compliance only (scaled units)
    fits: list[tuple[np.ndarray, float]] = []
    bics: list[float] = []
    for r in range(1, max_modes + 1):
        model, _ = _modes_and_jac(params, f)
        resid = np.abs(gs - model)
        i = int(np.argmax(resid))
        zeta0 = _half_power_zeta(f, resid, i)
        k0 = 1.0 / (2.0 * zeta0 * resid[i])  # scaled units: k * scale
        new = np.array([np.log(f[i]), np.log(zeta0), np.log(k0)])
        p0 = np.concatenate([params[:-1], new, params[-1:]])
        lb = np.tile([lo_bound, np.log(1e-4), -np.inf], r).tolist() + [-np.inf]
        ub = np.tile([hi_bound, np.log(0.5), np.inf], r).tolist() + [np.inf]
        p0 = np.clip(p0, np.array(lb) + 1e-9, np.array(ub) - 1e-9)  # start strictly inside the box

        sol = _least_squares_modes(f, gs, p0, lb, ub)
        rss = float(np.sum(sol.fun**2))
        bic = n_obs * np.log(max(rss, 1e-300) / n_obs) + (3 * r + 1) * np.log(n_obs)
        fits.append((sol.x, rss))
        bics.append(bic)
        params = sol.x
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

    The mode count of ``start`` is kept (no BIC search) and its modes and
    residual compliance are the start values of one nonlinear least-squares
    refinement, which costs a fraction of :func:`fit_modal_model`.  Meant for
    many draws of one posterior, whose FRFs differ by far less than the
    spacing of their modes; ``bic`` of the result holds the refined fit only.

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
    scale = float(np.sqrt(np.mean(np.abs(g) ** 2)))
    if not np.isfinite(scale) or scale == 0:
        raise DataError(f"{source}: FRF is zero or not finite")
    gs = g / scale
    m = start.model
    r = m.n_modes
    lo_f, hi_f = np.log(f[0] * 0.5), np.log(f[-1] * 2.0)
    p0 = np.empty(3 * r + 1)
    p0[0 : 3 * r : 3] = np.clip(np.log(m.natural_frequency_hz), lo_f + 1e-9, hi_f - 1e-9)
    p0[1 : 3 * r : 3] = np.clip(np.log(m.damping_ratio), np.log(1e-4) + 1e-9, np.log(0.5) - 1e-9)
    p0[2 : 3 * r : 3] = np.log(m.stiffness * scale)
    p0[-1] = start.residual_compliance / scale
    lb = np.tile([lo_f, np.log(1e-4), -np.inf], r).tolist() + [-np.inf]
    ub = np.tile([hi_f, np.log(0.5), np.inf], r).tolist() + [np.inf]

    sol = _least_squares_modes(f, gs, p0, lb, ub)
    p = sol.x
    rss = float(np.sum(sol.fun**2))
    n_obs = 2 * f.size
    fn = np.exp(p[0 : 3 * r : 3])
    ze = np.exp(p[1 : 3 * r : 3])
    kk = np.exp(p[2 : 3 * r : 3]) / scale
    if not np.all(np.isfinite(kk)):
        raise ConvergenceError(f"{source}: modal refit diverged")
    order = np.argsort(fn)
    bic = n_obs * np.log(max(rss, 1e-300) / n_obs) + (3 * r + 1) * np.log(n_obs)
    return ModalFit(model=ModalModel(fn[order], ze[order], kk[order]), residual_compliance=float(p[-1] * scale),
                    bic=np.array([bic]), rms_relative=float(np.sqrt(rss / f.size)))


def _least_squares_modes(f, gs, p0, lb, ub):
    """Bounded least squares of the scaled modal model against ``gs`` on the complex lines (re, im stacked)."""

    # A trial step of the optimiser may send ln k of a spurious mode (noisy FRFs) far enough for exp to overflow;
    # the residual is then not finite and the trust region shrinks (scipy's trf), so the overflow is expected.
    def fun(p):
        with np.errstate(over="ignore", invalid="ignore"):
            m, _ = _modes_and_jac(p, f)
        d = m - gs
        return np.concatenate([d.real, d.imag])

    def jac(p):
        with np.errstate(over="ignore", invalid="ignore"):
            _, J = _modes_and_jac(p, f)
        return np.concatenate([J.real, J.imag])

    return least_squares(fun, p0, jac=jac, bounds=(lb, ub), x_scale="jac", max_nfev=200)


def _checked_lines(frequency_hz, frf, source: str):
    """(f (n,) Hz, g (n,) complex m/N) after checking they are matching 1-D arrays of at least 8 lines."""
    f = np.asarray(frequency_hz, dtype=float)
    g = np.asarray(frf, dtype=complex)
    if f.ndim != 1 or g.shape != f.shape or f.size < 8:
        raise DataError(f"{source}: need matching 1-D frequency and FRF arrays with >= 8 lines")
    return f, g
