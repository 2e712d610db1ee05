"""Modal smoothing of the identified flange receptance: a reciprocal, passive modal model.

Model
-----
A small mechanical system in mass-normalised modal coordinates, seen at the
flange::

    S(w) = Phi (Omega^2 - w^2 I + i w C)^-1 Phi^T  +  U  -  L / w^2

``Phi`` (2 x n, real) holds the undamped mode shapes at the flange
(displacement and rotation rows), ``Omega = diag(w_r)`` the undamped natural
frequencies, ``C = L_c L_c^T`` a full positive semi-definite damping matrix
(non-proportional damping: bearing dampers make the spindle's modes
complex, and a diagonal ``C`` -- real modes -- cannot follow the true
flange receptance near its antiresonances), and ``U``, ``L`` real symmetric
residual matrices of the modes above and below the band.

* **Reciprocal**: every term is symmetric, so l = n exactly.
* **Passive**: for a force vector f let y = Z^-1 Phi^T f with
  Z = Omega^2 - w^2 + i w C; then ``Im(f^H S f) = -w y^H C y <= 0`` (U and L
  are real), so the power ``-w Im(f^H S f) / 2`` absorbed at the flange is
  never negative, at every frequency, for every parameter value.

Fit
---
The model is first fitted to the line-by-line identified block with the
inverse of its noise covariance as weight: the residual of line f is
``W_f (S_model - S_raw)`` with ``W = sqrt(2) diag(1/sigma) K`` (``K``:
forward Jacobian of the coupling, :func:`.inverse.forward_jacobian`;
``sigma``: noise of the hammer tests).  Up to first order this equals the
misfit of the hammer tests predicted by coupling ``S_model`` to the
artifact, so lines where the inversion amplifies noise (near spindle
resonances and artifact antiresonances) get little weight, and no line is
discarded or clipped.  This space is nearly linear and the mode-count
search runs in it.  :func:`refine` with :class:`MeasurementData` then fits
the hammer tests themselves (``sqrt(2) (H_k(S_model) - H_k) / sigma_k``),
which is free of the second-order bias of inverting noisy data; it starts
from the first fit, so the strong nonlinearity of that space near sharp
artifact resonances does no harm.  Parameters are in scaled units
(w / w0, S = Lam S~ Lam) and refined by Levenberg-Marquardt with an
analytic Jacobian.

Mode count
----------
Modes are added greedily.  A new pole is the best point of a logarithmic
frequency grid (two start damping ratios) for a linear fit of real-mode
residues (a diagonal damping matrix) with the other poles held; then every
pole is polished by a small coordinate search, still with linear fits
only, so no pole can run away.  Two starts are refined for each mode count
(the polished poles, and the refined model of one mode fewer plus the new
pole) and the better is kept.  Natural frequencies stay within a factor 3
of the band and modal damping ratios in [1e-5, 2] through a smooth change
of variables.  The mode count minimises the Bayesian information criterion for Gaussian
residuals with unknown common scale::

    BIC(n) = N ln(chi2_n / N) + k_n ln N,     k_n = 3 n + n (n + 1) / 2 + 6

(N real residuals; per mode a frequency and two shape entries, the
damping matrix, and six residual coefficients).  The unknown scale keeps
the criterion from adding modes to absorb a misfit that the noise model
does not explain.  The search runs on every ``decimate``-th line (the
default keeps at most about 600), stops after two consecutive BIC
increases or at ``max_modes``, and the chosen model is finally refined on
all lines.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConvergenceError, ModelError
from .inverse import forward_artifact, forward_jacobian
from .substructure import ArtifactReceptances

__all__ = [
    "ModalModel", "FitData", "MeasurementData", "whitened_data", "block_entries", "ModalFit", "fit_modal_model",
    "fit_mode_count", "refine", "n_parameters", "passivity_margin", "is_passive", "is_reciprocal",
]

_PAIRS = ((0, 0), (0, 1), (1, 1))
# Relative tolerance of the refinement: with thousands of residuals a relative
# change of chi2 of 1e-6 is far below one unit of chi2 (statistically nil).
_TOL = 1e-6
# Absolute chi2 tolerance: one unit of chi2 is one standard deviation of a
# parameter, so 0.01 leaves every parameter within 0.1 sigma of the optimum.
_CHI2_TOL = 0.01
# Stop crawling along a flat, curved valley (near-degenerate mode pairs):
# three accepted steps gaining less than this chi2 each on average.
_CHI2_STALL = 0.1
# Evaluations allowed per refinement while searching the mode count (an
# approximate chi2 suffices to rank mode counts; the chosen model is then
# refined to convergence).
_SEARCH_NFEV = 100
# Lines used while searching the mode count (every k-th line).
_SEARCH_LINES = 600
# Problems with at least this many lines use the compiled loops (:mod:`._modal_kernel`); smaller ones the numpy
# reference.  Loading numba and the cached kernels costs about 1 s of CPU per process; the whole identification
# of 276 lines (two directions, three modes, two samples) takes under 1 s either way, so a spawned worker
# process on such data would only pay the load.  On 3801 lines the compiled loops cut it from 22 s to 9 s.
_COMPILED_LINES = 512


def n_parameters(n_modes: int) -> int:
    """Free parameters of the model with ``n_modes`` modes."""
    return 3 * n_modes + n_modes * (n_modes + 1) // 2 + 6


@dataclass(frozen=True)
class ModalModel:
    """A reciprocal, passive modal model of a 2x2 point receptance (see the module notes).

    Attributes
    ----------
    natural_frequency_hz : (n_modes,) Hz, undamped
    shapes : (2, n_modes)
        Mode shapes at the flange, mass-normalised: row 0 in sqrt(m/N) rad/s,
        row 1 in sqrt(rad/(N m)) rad/s.
    damping : (n_modes, n_modes) 1/s, symmetric positive semi-definite
    upper : (2, 2) the constant residual U (units of the block)
    lower : (2, 2) the mass-line residual L (block term ``-L / w^2``; units of the block times (rad/s)^2)
    """

    natural_frequency_hz: np.ndarray
    shapes: np.ndarray
    damping: np.ndarray
    upper: np.ndarray
    lower: np.ndarray

    @property
    def n_modes(self) -> int:
        return int(self.natural_frequency_hz.size)

    @property
    def damping_ratio(self) -> np.ndarray:
        """(n_modes,) modal damping ratios ``C_rr / (2 w_r)`` (diagonal part only)."""
        return np.diag(self.damping) / (4 * np.pi * self.natural_frequency_hz)

    def block(self, frequency_hz) -> np.ndarray:
        """The receptance block ``[[h, l], [n, p]]`` at ``frequency_hz``, shape (n_freq, 2, 2)."""
        w = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
        n = self.n_modes
        out = self.upper - self.lower / w[:, None, None] ** 2
        if n == 0:
            return out.astype(complex)
        wr2 = (2 * np.pi * self.natural_frequency_hz) ** 2
        z = np.diag(wr2)[None] - (w**2)[:, None, None] * np.eye(n) + 1j * w[:, None, None] * self.damping
        g = np.linalg.solve(z, np.broadcast_to(self.shapes.T, (w.size, n, 2)))
        s = self.shapes @ g
        # Phi Z^-1 Phi^T is symmetric; averaging with its transpose removes the
        # round-off of the solve so that l = n holds to the last bit
        return 0.5 * (s + np.swapaxes(s, -1, -2)) + out

    def as_dict(self) -> dict:
        return {
            "natural_frequency_hz": self.natural_frequency_hz.tolist(),
            "modal_damping_ratio": self.damping_ratio.tolist(),
            "shapes": self.shapes.tolist(),
            "damping_matrix": self.damping.tolist(),
            "upper_residual": self.upper.tolist(),
            "lower_residual": self.lower.tolist(),
        }


def passivity_margin(block: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of ``-Im(S)`` relative to its largest, per line, shape (n_freq,).

    Non-negative for a passive reciprocal block (round-off aside).  The
    symmetric part of ``S`` is used, so a non-reciprocal block is judged by
    its reciprocal part.
    """
    s = 0.5 * (block + np.swapaxes(block, -1, -2))
    ev = np.linalg.eigvalsh(-s.imag)
    top = np.max(np.abs(ev), axis=-1)
    return np.divide(ev[..., 0], top, out=np.zeros_like(top), where=top > 0)


def is_passive(block: np.ndarray, rtol: float = 1e-10) -> bool:
    """True if ``-Im S`` is positive semi-definite at every line (to ``rtol`` of its scale)."""
    return bool(np.all(passivity_margin(block) >= -rtol))


def is_reciprocal(block: np.ndarray, rtol: float = 1e-12) -> bool:
    """True if ``l = n`` at every line to ``rtol`` of the block's largest entry."""
    scale = np.max(np.abs(block))
    return bool(np.all(np.abs(block[..., 0, 1] - block[..., 1, 0]) <= rtol * scale))


@dataclass(frozen=True)
class FitData:
    """The line-by-line identified block and its noise model (what the modal fit compares with).

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz
    target : (n_freq, 3) complex
        Identified (h, l, p) entries, m/N, 1/N, rad/(N m).
    weight : (n_freq, 3, 3) complex
        Whitening map ``W = sqrt(2) diag(1 / sigma) K``: the real and imaginary
        parts of ``W (S_model - S_raw)`` are independent with unit variance.
    """

    frequency_hz: np.ndarray
    target: np.ndarray
    weight: np.ndarray

    def __post_init__(self) -> None:
        if not np.all(np.isfinite(self.weight)) or not np.all(np.isfinite(self.target)):
            raise ModelError("modal fit: non-finite identified receptance or weight")

    def with_target(self, target: np.ndarray) -> "FitData":
        return FitData(self.frequency_hz, target, self.weight)

    def subset(self, index) -> "FitData":
        return FitData(self.frequency_hz[index], self.target[index], self.weight[index])


def block_entries(block: np.ndarray) -> np.ndarray:
    """(h, (l + n)/2, p) of a block, shape (..., 3)."""
    return np.stack([block[..., 0, 0], 0.5 * (block[..., 0, 1] + block[..., 1, 0]), block[..., 1, 1]], -1)


def whitened_data(artifact: ArtifactReceptances, raw_block: np.ndarray, sigma: np.ndarray,
                  linearize_at: np.ndarray | None = None) -> FitData:
    """Build :class:`FitData` for the identified block ``raw_block``.

    Parameters
    ----------
    artifact : ArtifactReceptances
    raw_block : (n_freq, 2, 2) complex, line-by-line identified flange block
    sigma : (n_freq, 3) float, noise standard deviations of H11, H12 (combined), H22, m/N (> 0)
    linearize_at : (n_freq, 2, 2) complex, optional
        Block where the coupling is linearised (default ``raw_block``; a
        smoothed block gives less noisy weights).
    """
    sigma = np.asarray(sigma, dtype=float)
    if not np.all(sigma > 0):
        raise ModelError("modal fit: every noise standard deviation must be > 0 (give a noise floor or level)")
    at = raw_block if linearize_at is None else linearize_at
    k = forward_jacobian(artifact, at)
    # sqrt(2): circular complex noise of standard deviation sigma has real and
    # imaginary parts of variance sigma^2 / 2; the real residuals get unit variance.
    w = math.sqrt(2.0) * k / sigma[..., None]
    return FitData(np.asarray(artifact.omega) / (2 * np.pi), block_entries(raw_block), w)


class _Scaling:
    """Scaled units and parameter boxes.

    w~ = w / w0 and S = Lam S~ Lam with Lam = diag(lam_h, lam_p).  The
    natural frequencies stay within a factor 3 of the band and the modal
    damping ratios within [1e-5, 2]: both are mapped from unbounded
    parameters through ``centre + half_width * tanh(y)`` (on the logarithm),
    so the Levenberg-Marquardt steps can never leave the box.
    """

    def __init__(self, frequency_hz: np.ndarray, reference: np.ndarray):
        self.w0 = 2 * np.pi * float(np.sqrt(frequency_hz[0] * frequency_hz[-1]))
        lam_h = math.sqrt(float(np.median(np.abs(reference[:, 0]))))
        lam_p = math.sqrt(float(np.median(np.abs(reference[:, 2]))))
        if not (lam_h > 0 and lam_p > 0):
            raise ModelError("modal fit: the identified flange block is zero")
        self.lam = np.array([lam_h, lam_p])
        self.entry = np.array([lam_h**2, lam_h * lam_p, lam_p**2])  # physical factor of (h, l, p)
        w_lo = frequency_hz[0] / 3 * 2 * np.pi / self.w0
        w_hi = frequency_hz[-1] * 3 * 2 * np.pi / self.w0
        self.log_w = _Box(math.log(w_lo), math.log(w_hi))
        # diagonal of the Cholesky factor: C_rr = L_rr^2 = 2 zeta w_r
        self.log_d = _Box(0.5 * math.log(2 * 1e-5 * w_lo), 0.5 * math.log(2 * 2.0 * w_hi))

    def model(self, x: np.ndarray, n: int) -> ModalModel:
        lw, phi, lc, u, low = _unpack(x, n, self)[:5]
        lam2 = np.outer(self.lam, self.lam)
        return ModalModel(
            natural_frequency_hz=np.exp(lw) * self.w0 / (2 * np.pi),
            shapes=phi * self.lam[:, None] * self.w0,
            damping=(lc @ lc.T) * self.w0,
            upper=_sym(u) * lam2,
            lower=_sym(low) * lam2 * self.w0**2,
        )


class _Box:
    """``v = centre + half * tanh(y)``: an unbounded y for a value v in (lo, hi)."""

    def __init__(self, lo: float, hi: float):
        self.centre, self.half = 0.5 * (lo + hi), 0.5 * (hi - lo)

    def value(self, y):
        return self.centre + self.half * np.tanh(y)

    def slope(self, y):
        return self.half * (1.0 - np.tanh(y) ** 2)

    def inverse(self, v):
        t = (np.asarray(v, dtype=float) - self.centre) / self.half
        return np.arctanh(np.clip(t, -1 + 1e-12, 1 - 1e-12))  # a start on the edge moves just inside


def _sym(v) -> np.ndarray:
    return np.array([[v[0], v[1]], [v[1], v[2]]], dtype=float)


@functools.lru_cache(maxsize=32)
def _tril(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.tril_indices(n)``, read-only and made once per mode count (every evaluation needs them)."""
    j, k = np.tril_indices(n)
    j.flags.writeable = k.flags.writeable = False
    return j, k


def _unpack(x: np.ndarray, n: int, sc: _Scaling):
    """Parameters from x: log w_r (n, boxed), Phi (2, n), Cholesky factor of C (boxed log diagonal), U (3), L (3).

    Also returns d(log w)/dy (n,) and d(L_rr)/dy (n,) for the chain rule.
    """
    y = x[:n]
    lw = sc.log_w.value(y)
    phi = x[n : 3 * n].reshape(2, n)
    tri = _tril(n)
    k = 3 * n + tri[0].size
    lc = np.zeros((n, n))
    lc[tri] = x[3 * n : k]
    yd = np.diag(lc).copy()
    diag = np.exp(sc.log_d.value(yd))
    lc[np.diag_indices(n)] = diag
    return lw, phi, lc, x[k : k + 3], x[k + 3 : k + 6], sc.log_w.slope(y), diag * sc.log_d.slope(yd)


def _pack(lw, phi, lc, u, low, sc: _Scaling) -> np.ndarray:
    n = len(lw)
    tri = _tril(n)
    c = np.array(lc, dtype=float)
    c[np.diag_indices(n)] = sc.log_d.inverse(np.log(np.diag(c)))
    return np.concatenate([sc.log_w.inverse(lw), np.asarray(phi).ravel(), c[tri], u, low])


def _evaluate(x: np.ndarray, n: int, wt: np.ndarray, sc: _Scaling, derivatives: bool = False,
              cache: dict | None = None):
    """Scaled (h, l, p) entries (n_freq, 3) and, optionally, their derivatives (n_freq, 3, n_par).

    ``cache`` (a dict owned by the caller) keeps the entries and ``Z^-1 Phi^T``
    of the last ``x``: Levenberg-Marquardt asks for the Jacobian at the point
    whose residuals it has just evaluated, and the batched solve is the
    dominant cost of both.  The cached values are the ones a fresh
    evaluation would give, bit for bit.
    """
    lw, phi, lc, u, low, dlw, ddiag = _unpack(x, n, sc)
    wr2 = np.exp(2 * lw)
    if cache is not None and cache.get("x") is not None and np.array_equal(cache["x"], x):
        ent, g = cache["ent"], cache["g"]
    else:
        ent = np.broadcast_to(u - low / (wt**2)[:, None], (wt.size, 3)).astype(complex)
        g = None
        if n:
            z = np.diag(wr2)[None] - (wt**2)[:, None, None] * np.eye(n) + 1j * wt[:, None, None] * (lc @ lc.T)
            g = np.linalg.solve(z, np.broadcast_to(phi.T, (wt.size, n, 2)))  # Z^-1 Phi^T, (nf, n, 2)
            s = phi @ g
            ent = ent + np.stack([s[:, a, b] for a, b in _PAIRS], -1)
        if cache is not None:
            cache.update(x=np.array(x, dtype=float), ent=ent, g=g)
    if not derivatives:
        return ent
    d = np.zeros((wt.size, 3, n_parameters(n)), dtype=complex)
    if n:
        ga = [g[:, :, a] for a in (0, 1)]  # (nf, n) columns for the two flange DOFs
        for e, (a, b) in enumerate(_PAIRS):
            d[:, e, :n] = -2 * wr2 * dlw * ga[a] * ga[b]  # dZ = 2 w_r^2 dlog(w_r) e_r e_r^T
            for i in (0, 1):  # d / d Phi[i, r]: delta_ai G_rb + G_ra delta_bi
                d[:, e, n + i * n : n + (i + 1) * n] = (ga[b] if a == i else 0) + (ga[a] if b == i else 0)
        ltg = np.einsum("kj,fka->fja", lc, g)  # (L_c^T G)[j, a]
        j, k = _tril(n)
        # chain rule of the boxed log diagonal (1 off the diagonal); all (j, k) pairs at once: the
        # element-wise operations and their order are those of a loop over the pairs, so the
        # values are the same to the last bit
        fac = np.where(j == k, ddiag[j], 1.0)
        iwf = -1j * wt[:, None] * fac
        cols = slice(3 * n, 3 * n + j.size)
        # dC = E_jk L^T + L E_kj  ->  G^T dC G [a, b] = G_ja (L^T G)_kb + (L^T G)_ka G_jb
        for e, (a, b) in enumerate(_PAIRS):
            d[:, e, cols] = iwf * (g[:, j, a] * ltg[:, k, b] + ltg[:, k, a] * g[:, j, b])
    k0 = 3 * n + n * (n + 1) // 2
    for e in range(3):
        d[:, e, k0 + e] = 1.0
        d[:, e, k0 + 3 + e] = -1.0 / wt**2
    return ent, d


def _entries(x: np.ndarray, n: int, wt: np.ndarray, sc: _Scaling, cache: dict) -> tuple:
    """Scaled (h, l, p) entries (n_freq, 3) complex and ``G = Z^-1 Phi^T`` (n_freq, n, 2), compiled.

    The values of :func:`_evaluate` (its reference) to round-off.  ``cache`` (a dict owned by the caller)
    keeps them for the last ``x``: Levenberg-Marquardt asks for the Jacobian at the point whose residuals
    it has just evaluated.
    """
    if cache.get("x") is not None and np.array_equal(cache["x"], x):
        return cache["ent"], cache["g"]
    # numba loads with the first fit, not with the package
    from ._modal_kernel import modal_entries

    lw, phi, lc, u, low = _unpack(x, n, sc)[:5]
    ent = np.broadcast_to(u - low / (wt**2)[:, None], (wt.size, 3)).astype(complex)
    g = np.empty((wt.size, n, 2), dtype=complex)
    if n and modal_entries(np.exp(2 * lw), np.ascontiguousarray(phi), lc @ lc.T, np.ascontiguousarray(wt, dtype=float),
                           ent, g):
        raise np.linalg.LinAlgError("Singular matrix")
    cache.update(x=np.array(x, dtype=float), ent=ent, g=g)
    return ent, g


def _jacobian_rows(x: np.ndarray, n: int, wt: np.ndarray, sc: _Scaling, cache: dict, kmat: np.ndarray,
                   row_scale: np.ndarray) -> np.ndarray:
    """Real Jacobian (2 n_freq m, n_par) of the residuals ``row_scale K (S~(x) - ...)``, compiled.

    ``kmat`` (n_freq, m, 3) complex maps the scaled entries to the m residuals of a line, ``row_scale``
    (n_freq, m) float scales them; the real parts of all lines come first, then the imaginary parts (the
    layout of the residual vector).  Equals ``matmul(kmat, d) * row_scale`` with ``d`` the derivatives of
    :func:`_evaluate` (its reference) to round-off.
    """
    from ._modal_kernel import modal_jacobian

    _, g = _entries(x, n, wt, sc, cache)
    lw, _, lc, _, _, dlw, ddiag = _unpack(x, n, sc)
    j, k = _tril(n)
    out = np.empty((2,) + kmat.shape[:2] + (n_parameters(n),))
    modal_jacobian(g, -2 * np.exp(2 * lw) * dlw, lc, j, k, np.where(j == k, ddiag[j], 1.0),
                   np.ascontiguousarray(wt, dtype=float), np.ascontiguousarray(kmat, dtype=complex),
                   np.ascontiguousarray(row_scale, dtype=float), out)
    return out.reshape(-1, out.shape[-1])


class _Problem:
    """Whitened residuals ``W (S_model - S_raw)`` and their Jacobian for a fixed mode count."""

    def __init__(self, data: FitData, sc: _Scaling, n: int, compiled: bool | None = None):
        self.n, self.sc = n, sc
        self.wt = 2 * np.pi * data.frequency_hz / sc.w0
        self.w = np.ascontiguousarray(data.weight * sc.entry)  # acts on scaled entries
        self.target = data.target / sc.entry
        self.cache: dict = {}
        self.compiled = self.wt.size >= _COMPILED_LINES if compiled is None else compiled
        self.ones = None  # unit row scales of the compiled Jacobian, made on its first call

    def residual(self, x) -> np.ndarray:
        if self.compiled:
            ent = _entries(x, self.n, self.wt, self.sc, self.cache)[0]
        else:
            ent = _evaluate(x, self.n, self.wt, self.sc, cache=self.cache)
        r = np.einsum("fke,fe->fk", self.w, ent - self.target)
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    def jacobian(self, x) -> np.ndarray:
        if not self.compiled:
            _, d = _evaluate(x, self.n, self.wt, self.sc, derivatives=True, cache=self.cache)
            jac = np.matmul(self.w, d).reshape(-1, d.shape[-1])  # (nf, k, e) @ (nf, e, p)
            return np.concatenate([jac.real, jac.imag], axis=0)
        if self.ones is None:
            self.ones = np.ones(self.w.shape[:2])
        return _jacobian_rows(x, self.n, self.wt, self.sc, self.cache, self.w, self.ones)


@dataclass(frozen=True)
class MeasurementData:
    """The hammer tests themselves, for the final fit in measurement space.

    Attributes
    ----------
    artifact : ArtifactReceptances
    measured : (n_freq, m) complex, the measured FRFs (m/N)
    component : (m,) int, predicted receptance of each column: 0 = H11, 1 = H12 (= H21), 2 = H22
    sigma : (n_freq, m) float, their noise standard deviations (m/N, > 0)
    """

    artifact: ArtifactReceptances
    measured: np.ndarray
    component: np.ndarray
    sigma: np.ndarray

    def __post_init__(self) -> None:
        if not np.all(self.sigma > 0):
            raise ModelError("modal fit: every noise standard deviation must be > 0 (give a noise floor or level)")

    def with_measured(self, measured: np.ndarray, artifact: ArtifactReceptances | None = None) -> "MeasurementData":
        return MeasurementData(self.artifact if artifact is None else artifact, measured, self.component, self.sigma)


class _MeasurementProblem:
    """Residuals ``sqrt(2) (H_k(S_model) - H_k^measured) / sigma_k`` of every measured FRF, and their Jacobian."""

    def __init__(self, data: MeasurementData, sc: _Scaling, n: int, compiled: bool | None = None):
        self.n, self.sc, self.data = n, sc, data
        self.wt = data.artifact.omega / sc.w0
        self.scale = math.sqrt(2.0) / data.sigma
        self.cache: dict = {}
        self.compiled = self.wt.size >= _COMPILED_LINES if compiled is None else compiled
        self.matrix = None  # the artifact's receptances, contiguous, made on the first evaluation

    def _block(self, ent: np.ndarray) -> np.ndarray:
        e = ent * self.sc.entry
        b = np.empty(e.shape[:-1] + (2, 2), dtype=complex)
        b[..., 0, 0], b[..., 0, 1], b[..., 1, 0], b[..., 1, 1] = e[..., 0], e[..., 1], e[..., 1], e[..., 2]
        return b

    def _tests(self, x) -> tuple:
        """Predicted (H11, H12, H22) (n_freq, 3) and their derivatives (n_freq, 3, 3) by the block entries.

        The values of :func:`.inverse.forward_artifact` and :func:`.inverse.forward_jacobian` (the
        references) to round-off, both from one compiled pass; kept for the last ``x`` like the entries.
        """
        c = self.cache
        if c.get("tests_x") is not None and np.array_equal(c["tests_x"], x):
            return c["h"], c["k"]
        from ._modal_kernel import artifact_lines

        ent = _entries(x, self.n, self.wt, self.sc, c)[0]
        if self.matrix is None:
            self.matrix = np.ascontiguousarray(self.data.artifact.matrix, dtype=complex)
        h = np.empty(ent.shape, dtype=complex)
        k = np.empty(ent.shape + (3,), dtype=complex)
        artifact_lines(self.matrix, ent, np.ascontiguousarray(self.sc.entry, dtype=float), h, k)
        c.update(tests_x=np.array(x, dtype=float), h=h, k=k)
        return h, k

    def residual(self, x) -> np.ndarray:
        if self.compiled:
            g = self._tests(x)[0]
        else:
            g = forward_artifact(self._block(_evaluate(x, self.n, self.wt, self.sc, cache=self.cache)),
                                 self.data.artifact)
        r = (g[:, self.data.component] - self.data.measured) * self.scale
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    def jacobian(self, x) -> np.ndarray:
        if not self.compiled:
            ent, d = _evaluate(x, self.n, self.wt, self.sc, derivatives=True, cache=self.cache)
            k = forward_jacobian(self.data.artifact, self._block(ent))[:, self.data.component, :] * self.sc.entry
            jac = (np.matmul(k, d) * self.scale[..., None]).reshape(-1, d.shape[-1])
            return np.concatenate([jac.real, jac.imag], axis=0)
        k = self._tests(x)[1][:, self.data.component, :] * self.sc.entry
        return _jacobian_rows(x, self.n, self.wt, self.sc, self.cache, k, self.scale)


@dataclass(frozen=True)
class ModalFit:
    """Result of :func:`fit_modal_model`.

    Attributes
    ----------
    model : ModalModel
    chi2 : float
        Sum of squared whitened residuals on all lines.
    n_residuals : int
        N, real residuals on all lines.
    bic : dict of int to float
        BIC of every mode count tried (on the search lines).
    x : (n_par,) float
        Scaled parameters (warm start for :func:`refine`).
    scaling : object
        Internal scaling, needed by :func:`refine`.
    search_x : dict of int to array
        Scaled parameters of every mode count tried, as fitted on the search
        lines (start values for :func:`fit_mode_count`).
    """

    model: ModalModel
    chi2: float
    n_residuals: int
    bic: dict
    x: np.ndarray = field(repr=False)
    scaling: object = field(repr=False)
    search_x: dict = field(default_factory=dict, repr=False)

    @property
    def reduced_chi2(self) -> float:
        """chi2 / (N - k): about 1 when model and noise level are right."""
        return self.chi2 / max(1, self.n_residuals - self.x.size)


def _bic(chi2: float, n_res: int, n_par: int) -> float:
    return n_res * math.log(chi2 / n_res) + n_par * math.log(n_res)


def _solve(problem: _Problem, x0: np.ndarray, max_nfev: int = 400, lam: float = 1e-3) -> tuple[np.ndarray, float]:
    """Levenberg-Marquardt on the normal equations (the Jacobians are tall and narrow).

    Marquardt's diagonal scaling; the damping shrinks by 3 after a
    successful step and grows by 4 after a failed one.  Stops when the
    Gauss-Newton decrement ``g^T (J^T J)^-1 g`` (the chi2 a full step could
    still gain) is below ``_CHI2_TOL``, when an accepted step lowers chi2 by
    less than ``_TOL`` relative, when three accepted steps gained less than
    ``_CHI2_STALL`` each on average (a flat valley: the block no longer
    changes where the data constrain it), or after ``max_nfev`` residual
    evaluations.  ``lam`` is the initial damping (small
    for a start close to the optimum, e.g. a bootstrap refit).

    Returns
    -------
    x : (n_par,) float
    chi2 : float
    """
    x = np.array(x0, dtype=float)
    r = problem.residual(x)
    cost = float(r @ r)
    if not np.isfinite(cost):
        raise ConvergenceError("modal fit: non-finite residuals at the start values")
    nfev = 1
    gains: list[float] = []
    while nfev < max_nfev:
        jac = problem.jacobian(x)
        a = jac.T @ jac
        g = jac.T @ r
        d = np.maximum(np.diag(a), 1e-12 * max(float(np.max(np.diag(a))), 1e-300))
        try:
            # Gauss-Newton decrement: the chi2 a full step could still gain
            if float(g @ np.linalg.solve(a + 1e-12 * np.diag(d), g)) < _CHI2_TOL:
                break
        except np.linalg.LinAlgError:
            pass
        improved = False
        while nfev < max_nfev:
            try:
                step = -np.linalg.solve(a + lam * np.diag(d), g)
            except np.linalg.LinAlgError:
                lam *= 4.0
                if lam > 1e12:
                    break
                continue
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                r_new = problem.residual(x + step)
            nfev += 1
            c_new = float(r_new @ r_new)
            if np.isfinite(c_new) and c_new < cost:
                decrease = cost - c_new
                x, r, cost = x + step, r_new, c_new
                lam = max(lam / 3.0, 1e-12)
                improved = True
                break
            lam *= 4.0
            if lam > 1e12:
                break
        if not improved or decrease <= _TOL * cost:
            break
        gains.append(decrease)
        if len(gains) >= 3 and sum(gains[-3:]) < 3 * _CHI2_STALL:
            break
    return x, cost


def _pole_columns(problem: _Problem, w: float, z: float) -> np.ndarray:
    """Whitened real design columns (m, 3) of a real-mode residue at scaled pole (w, zeta)."""
    q = 1.0 / (w**2 - problem.wt**2 + 2j * z * w * problem.wt)
    a = problem.w * q[:, None, None]  # (nf, k, e): column e is entry e of the residue
    a = a.reshape(-1, 3)
    return np.concatenate([a.real, a.imag])


def _residual_columns(problem: _Problem) -> np.ndarray:
    """Whitened real design columns (m, 6) of the residual matrices U and L."""
    up = problem.w.reshape(-1, 3)
    low = (-problem.w / (problem.wt**2)[:, None, None]).reshape(-1, 3)
    a = np.concatenate([up, low], axis=1)
    return np.concatenate([a.real, a.imag])


def _rhs(problem: _Problem) -> np.ndarray:
    b = np.einsum("fke,fe->fk", problem.w, problem.target).ravel()
    return np.concatenate([b.real, b.imag])


def _linear_start(problem: _Problem, poles: list[tuple[float, float]]) -> tuple[np.ndarray, float]:
    """Start values for given scaled poles (w_r, zeta_r) from a linear fit of real-mode residues.

    With a diagonal damping matrix the model is ``sum_r R_r / (w_r^2 - w^2 +
    2 i zeta_r w_r w) + U - L / w^2``, linear in the symmetric residues R_r.
    Each fitted R_r is projected onto rank one (its leading eigenpair) to
    give the mode shape; the nonlinear refinement takes it from there.
    """
    n = len(poles)
    aa = np.concatenate([_pole_columns(problem, w, z) for w, z in poles] + [_residual_columns(problem)], axis=1)
    bb = _rhs(problem)
    coef, *_ = np.linalg.lstsq(aa, bb, rcond=None)
    chi2 = float(np.sum((aa @ coef - bb) ** 2))
    phi = np.zeros((2, n))
    for r in range(n):
        ev, vec = np.linalg.eigh(_sym(coef[3 * r : 3 * r + 3]))
        phi[:, r] = vec[:, -1] * math.sqrt(max(ev[-1], 1e-6 * max(abs(ev).max(), 1e-12)))
    lw = np.log([w for w, _ in poles]) if n else np.zeros(0)
    lc = np.diag([math.sqrt(2 * z * w) for w, z in poles]) if n else np.zeros((0, 0))
    return _pack(lw, phi, lc, coef[3 * n : 3 * n + 3], coef[3 * n + 3 :], problem.sc), chi2


class _Projector:
    """Least-squares fit with fixed columns, and the chi2 when three columns are added.

    The orthonormal basis comes from the eigen-decomposition of the Gram
    matrix of the (equilibrated) columns: these design matrices are tall and
    narrow, where a Householder QR is needlessly slow.  Directions with
    eigenvalues below 1e-12 of the largest are dropped (linearly dependent
    columns), which leaves the least-squares residual unchanged.
    """

    def __init__(self, fixed: np.ndarray, rhs: np.ndarray):
        self.q = _orthonormal(fixed)
        self.r = rhs - self.q @ (self.q.T @ rhs)

    def chi2_with(self, cols: np.ndarray) -> float:
        c = cols - self.q @ (self.q.T @ cols)
        qc = _orthonormal(c)
        r = self.r - qc @ (qc.T @ self.r)
        return float(r @ r)


def _orthonormal(a: np.ndarray) -> np.ndarray:
    """Orthonormal basis (m, k') of the column space of ``a`` (m, k)."""
    # the sums of np.linalg.norm(a, axis=0), without its conjugate copy; the masks only copy when they drop
    # something.  Column-major like the masked copies, so that BLAS sums in the same order (the Gram matrix
    # of near-dependent columns has ill-conditioned eigenvectors: its round-off shows in the basis)
    norm = np.sqrt(np.add.reduce(a * a, axis=0))
    pos = norm > 0
    a = np.divide(a, norm, order="F") if pos.all() else a[:, pos] / norm[pos]
    ev, vec = np.linalg.eigh(a.T @ a)
    keep = ev > 1e-12 * ev[-1]
    q = a @ (np.divide(vec, np.sqrt(ev), order="F") if keep.all() else vec[:, keep] / np.sqrt(ev[keep]))
    # one re-orthogonalisation pass restores orthonormality lost to the Gram matrix's rounding
    ev2, vec2 = np.linalg.eigh(q.T @ q)
    return q @ (vec2 / np.sqrt(ev2))


def _grow(sc: _Scaling, x: np.ndarray, n: int, w: float, zeta: float, shape: np.ndarray) -> np.ndarray:
    """Parameters of ``n`` modes plus a new one (frequency w, diagonal damping, given shape)."""
    lw, phi, lc, u, low = _unpack(x, n, sc)[:5]
    lc2 = np.zeros((n + 1, n + 1))
    lc2[:n, :n] = lc
    lc2[n, n] = math.sqrt(2 * zeta * w)
    return _pack(np.append(lw, math.log(w)), np.column_stack([phi, shape]), lc2, u, low, sc)


def _scan(problem: _Problem, poles: list[tuple[float, float]], zetas=(0.005, 0.03), n_grid: int = 60):
    """Best added pole on a log grid (band widened by 20 % each side) by the linear real-mode fit.

    Returns (chi2, w, zeta), or None when every grid point lies next to an
    existing pole.
    """
    wt = problem.wt
    fixed = np.concatenate([_pole_columns(problem, w, z) for w, z in poles] + [_residual_columns(problem)], axis=1)
    proj = _Projector(fixed, _rhs(problem))
    best = None
    for w in np.geomspace(wt[0] / 1.2, wt[-1] * 1.2, n_grid):
        if any(abs(math.log(w / p[0])) < 0.02 for p in poles):
            continue
        for z in zetas:
            c2 = proj.chi2_with(_pole_columns(problem, float(w), z))
            if best is None or c2 < best[0]:
                best = (c2, float(w), z)
    return best


def _polish(problem: _Problem, poles: list[tuple[float, float]], sweeps: int = 2) -> list[tuple[float, float]]:
    """Coordinate search of each pole (frequency +-8 %, damping x 1/2..2) by linear fits.

    Cheap and robust: only linear least-squares problems are solved, so no
    pole can run away; the nonlinear refinement starts from the result.
    """
    poles = list(poles)
    rhs = _rhs(problem)
    res_cols = _residual_columns(problem)
    for _ in range(sweeps):
        for r in range(len(poles)):
            others = [_pole_columns(problem, w, z) for k, (w, z) in enumerate(poles) if k != r]
            proj = _Projector(np.concatenate(others + [res_cols], axis=1), rhs)
            w0, z0 = poles[r]
            best = (proj.chi2_with(_pole_columns(problem, w0, z0)), w0, z0)
            for w in w0 * np.geomspace(0.92, 1.08, 9):
                for z in z0 * np.array([0.5, 0.71, 1.0, 1.41, 2.0]):
                    z = float(min(z, 1.0))
                    c2 = proj.chi2_with(_pole_columns(problem, float(w), z))
                    if c2 < best[0]:
                        best = (c2, float(w), z)
            poles[r] = best[1:]
    return poles


def fit_modal_model(data: FitData, max_modes: int = 8, decimate: int | None = None) -> ModalFit:
    """Fit the reciprocal, passive modal model; choose the mode count by BIC.

    Parameters
    ----------
    data : FitData
    max_modes : int
        Largest mode count tried.
    decimate : int, optional
        Use every ``decimate``-th line for the mode-count search (default:
        keep at most about 600 lines).  The final refinement uses all lines.

    Returns
    -------
    ModalFit
    """
    nf = data.frequency_hz.size
    step = decimate if decimate is not None else max(1, int(math.ceil(nf / _SEARCH_LINES)))
    search = data.subset(slice(None, None, step))
    sc = _Scaling(data.frequency_hz, data.target)
    n_res = 2 * search.target.size
    fits: dict[int, np.ndarray] = {}
    bic: dict[int, float] = {}
    prob = _Problem(search, sc, 0)
    x, _ = _linear_start(prob, [])
    x, chi2 = _solve(prob, x)
    fits[0], bic[0] = x, _bic(chi2, n_res, n_parameters(0))
    rises = 0
    poles: list[tuple[float, float]] = []  # real-mode poles of the linear search
    for n in range(1, max_modes + 1):
        prob = _Problem(search, sc, n)
        new = _scan(prob, poles)
        if new is None:
            break
        poles = _polish(prob, poles + [new[1:]])
        starts = [_linear_start(prob, poles)[0]]
        # also the refined model of one mode fewer plus the new pole
        lw = _unpack(fits[n - 1], n - 1, sc)[0]
        extra = [p for p in poles if all(abs(math.log(p[0]) - v) > 0.02 for v in lw)]
        if extra:
            xl = _linear_start(prob, poles)[0]
            k = poles.index(extra[0])
            shape = _unpack(xl, n, sc)[1][:, k]
            starts.append(_grow(sc, fits[n - 1], n - 1, extra[0][0], extra[0][1], shape))
        x, chi2 = min((_solve(prob, x0, max_nfev=_SEARCH_NFEV) for x0 in starts), key=lambda t: t[1])
        fits[n], bic[n] = x, _bic(chi2, n_res, n_parameters(n))
        rises = rises + 1 if bic[n] > min(v for m, v in bic.items() if m < n) else 0
        if rises >= 2:
            break
    n_best = min(bic, key=bic.get)
    x, chi2 = _solve(_Problem(data, sc, n_best), fits[n_best])
    return ModalFit(model=sc.model(x, n_best), chi2=chi2, n_residuals=2 * data.target.size, bic=bic, x=x, scaling=sc,
                    search_x=fits)


def fit_mode_count(fit: ModalFit, data: FitData, n_modes: int) -> ModalFit:
    """The model with ``n_modes`` modes (one of the counts tried by the search), refined on all lines of ``data``."""
    if n_modes not in fit.search_x:
        raise ModelError(f"modal fit: mode count {n_modes} was not tried (tried: {sorted(fit.search_x)})")
    x, chi2 = _solve(_Problem(data, fit.scaling, n_modes), fit.search_x[n_modes])
    return ModalFit(model=fit.scaling.model(x, n_modes), chi2=chi2, n_residuals=2 * data.target.size, bic=fit.bic,
                    x=x, scaling=fit.scaling, search_x=fit.search_x)


def refine(fit: ModalFit, data: FitData | MeasurementData, max_nfev: int = 100) -> ModalFit:
    """Refit the same mode count to new data, weights or residual space, starting from ``fit``.

    With :class:`FitData` the residuals are the whitened differences to the
    line-by-line block; with :class:`MeasurementData` they are the
    normalised misfits of the hammer tests themselves.  The latter has no
    bias from inverting noisy data (the line-by-line block is a nonlinear
    function of the measurements, so noise biases it at second order, most
    where the inversion amplifies noise) and is used for the final fit and
    the bootstrap.  The returned fit keeps ``fit.bic``.
    """
    n = fit.model.n_modes
    if isinstance(data, MeasurementData):
        problem, n_res = _MeasurementProblem(data, fit.scaling, n), 2 * data.measured.size
    else:
        problem, n_res = _Problem(data, fit.scaling, n), 2 * data.target.size
    x, chi2 = _solve(problem, fit.x, max_nfev=max_nfev, lam=1e-6)
    return ModalFit(model=fit.scaling.model(x, n), chi2=chi2, n_residuals=n_res, bic=fit.bic, x=x,
                    scaling=fit.scaling, search_x=fit.search_x)
