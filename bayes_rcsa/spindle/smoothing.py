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
The model is fitted to the line-by-line identified block with the inverse
of its noise covariance as weight: the residual of line f is
``W_f (S_model - S_raw)`` with ``W = diag(1/sigma) K`` (``K``: forward
Jacobian of the coupling, :func:`.inverse.forward_jacobian`; ``sigma``: noise
of the hammer tests).  Up to first order this equals the misfit of the
hammer tests predicted by coupling ``S_model`` to the artifact, so lines
where the inversion amplifies noise (near spindle resonances and artifact
antiresonances) get little weight, and no line is discarded or clipped.
Parameters are in scaled units (w / w0, S = Lam S~ Lam) and refined by
Levenberg-Marquardt with an analytic Jacobian.

Mode count
----------
Modes are added greedily.  A new pole is the best point of a logarithmic
frequency grid (two start damping ratios) for a linear fit of real-mode
residues with the other poles held.  Two starts are refined for each mode
count and the better kept: the refined model of one mode fewer plus the
new pole, and the poles picked one by one by the linear scan alone (which
cannot be led astray by an earlier refinement).  The refinement keeps the
poles within a factor 3 of the band and damping ratios below 2.  The
mode count minimises the Bayesian information criterion for Gaussian
residuals with unknown common scale::

    BIC(n) = N ln(chi2_n / N) + k_n ln N,     k_n = 3 n + n (n + 1) / 2 + 6

(N real residuals; per mode a frequency and two shape entries, the
damping matrix, and six residual coefficients).  The unknown scale keeps
the criterion from adding modes to absorb a misfit that the noise model
does not explain.  The search runs on every ``decimate``-th line (the
default keeps at most about 1000), stops after two consecutive BIC
increases or at ``max_modes``, and the chosen model is finally refined on
all lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..errors import ConvergenceError, ModelError
from .inverse import forward_jacobian
from .substructure import ArtifactReceptances

__all__ = [
    "ModalModel", "FitData", "whitened_data", "block_entries", "ModalFit", "fit_modal_model", "refine", "n_parameters",
    "passivity_margin", "is_passive", "is_reciprocal",
]

_PAIRS = ((0, 0), (0, 1), (1, 1))
# Relative tolerance of the refinement: with thousands of residuals a relative
# change of chi2 of 1e-6 is far below one unit of chi2 (statistically nil).
_TOL = 1e-6
_DEBUG = False


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
        return self.shapes @ g + out

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
    """Scaled units: w~ = w / w0, S = Lam S~ Lam with Lam = diag(lam_h, lam_p)."""

    def __init__(self, frequency_hz: np.ndarray, reference: np.ndarray):
        self.w0 = 2 * np.pi * float(np.sqrt(frequency_hz[0] * frequency_hz[-1]))
        lam_h = math.sqrt(float(np.median(np.abs(reference[:, 0]))))
        lam_p = math.sqrt(float(np.median(np.abs(reference[:, 2]))))
        if not (lam_h > 0 and lam_p > 0):
            raise ModelError("modal fit: the identified flange block is zero")
        self.lam = np.array([lam_h, lam_p])
        self.entry = np.array([lam_h**2, lam_h * lam_p, lam_p**2])  # physical factor of (h, l, p)

    def model(self, x: np.ndarray, n: int) -> ModalModel:
        lw, phi, lc, u, low = _unpack(x, n)
        lam2 = np.outer(self.lam, self.lam)
        return ModalModel(
            natural_frequency_hz=np.exp(lw) * self.w0 / (2 * np.pi),
            shapes=phi * self.lam[:, None] * self.w0,
            damping=(lc @ lc.T) * self.w0,
            upper=_sym(u) * lam2,
            lower=_sym(low) * lam2 * self.w0**2,
        )


def _sym(v) -> np.ndarray:
    return np.array([[v[0], v[1]], [v[1], v[2]]], dtype=float)


def _unpack(x: np.ndarray, n: int):
    """Scaled parameters: log w_r (n), Phi (2, n), Cholesky factor of C (log diagonal), U (3), L (3)."""
    lw = x[:n]
    phi = x[n : 3 * n].reshape(2, n)
    tri = np.tril_indices(n)
    k = 3 * n + tri[0].size
    lc = np.zeros((n, n))
    lc[tri] = x[3 * n : k]
    lc[np.diag_indices(n)] = np.exp(np.diag(lc))
    return lw, phi, lc, x[k : k + 3], x[k + 3 : k + 6]


def _pack(lw, phi, lc, u, low) -> np.ndarray:
    n = len(lw)
    tri = np.tril_indices(n)
    c = np.array(lc, dtype=float)
    c[np.diag_indices(n)] = np.log(np.diag(c))
    return np.concatenate([lw, np.asarray(phi).ravel(), c[tri], u, low])


def _evaluate(x: np.ndarray, n: int, wt: np.ndarray, derivatives: bool = False):
    """Scaled (h, l, p) entries (n_freq, 3) and, optionally, their derivatives (n_freq, 3, n_par)."""
    lw, phi, lc, u, low = _unpack(x, n)
    ent = np.broadcast_to(u - low / (wt**2)[:, None], (wt.size, 3)).astype(complex)
    if n:
        wr2 = np.exp(2 * lw)
        z = np.diag(wr2)[None] - (wt**2)[:, None, None] * np.eye(n) + 1j * wt[:, None, None] * (lc @ lc.T)
        g = np.linalg.solve(z, np.broadcast_to(phi.T, (wt.size, n, 2)))  # Z^-1 Phi^T, (nf, n, 2)
        s = phi @ g
        ent = ent + np.stack([s[:, a, b] for a, b in _PAIRS], -1)
    if not derivatives:
        return ent
    d = np.zeros((wt.size, 3, n_parameters(n)), dtype=complex)
    if n:
        ga = [g[:, :, a] for a in (0, 1)]  # (nf, n) columns for the two flange DOFs
        for e, (a, b) in enumerate(_PAIRS):
            d[:, e, :n] = -2 * wr2 * ga[a] * ga[b]  # d / d log w_r
            for i in (0, 1):  # d / d Phi[i, r]: delta_ai G_rb + G_ra delta_bi
                d[:, e, n + i * n : n + (i + 1) * n] = (ga[b] if a == i else 0) + (ga[a] if b == i else 0)
        ltg = np.einsum("kj,fka->fja", lc, g)  # (L_c^T G)[j, a]
        tri = np.tril_indices(n)
        for idx, (j, k) in enumerate(zip(*tri)):
            fac = lc[j, k] if j == k else 1.0  # chain rule of the log diagonal
            # dC = E_jk L^T + L E_kj  ->  G^T dC G [a, b] = G_ja (L^T G)_kb + (L^T G)_ka G_jb
            for e, (a, b) in enumerate(_PAIRS):
                d[:, e, 3 * n + idx] = -1j * wt * fac * (g[:, j, a] * ltg[:, k, b] + ltg[:, k, a] * g[:, j, b])
    k0 = 3 * n + n * (n + 1) // 2
    for e in range(3):
        d[:, e, k0 + e] = 1.0
        d[:, e, k0 + 3 + e] = -1.0 / wt**2
    return ent, d


class _Problem:
    """Whitened residuals ``W (S_model - S_raw)`` and their Jacobian for a fixed mode count."""

    def __init__(self, data: FitData, sc: _Scaling, n: int):
        self.n, self.sc = n, sc
        self.wt = 2 * np.pi * data.frequency_hz / sc.w0
        self.w = data.weight * sc.entry  # acts on scaled entries
        self.target = data.target / sc.entry

    def residual(self, x) -> np.ndarray:
        r = np.einsum("fke,fe->fk", self.w, _evaluate(x, self.n, self.wt) - self.target)
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    def jacobian(self, x) -> np.ndarray:
        _, d = _evaluate(x, self.n, self.wt, derivatives=True)
        jac = np.einsum("fke,fep->fkp", self.w, d).reshape(-1, d.shape[-1])
        return np.concatenate([jac.real, jac.imag], axis=0)


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
    """

    model: ModalModel
    chi2: float
    n_residuals: int
    bic: dict
    x: np.ndarray = field(repr=False)
    scaling: object = field(repr=False)

    @property
    def reduced_chi2(self) -> float:
        """chi2 / (N - k): about 1 when model and noise level are right."""
        return self.chi2 / max(1, self.n_residuals - self.x.size)


def _bic(chi2: float, n_res: int, n_par: int) -> float:
    return n_res * math.log(chi2 / n_res) + n_par * math.log(n_res)


def _bounds(problem: _Problem, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Box for the scaled parameters: poles within a factor 3 of the band, damping ratio <= 2."""
    k = n_parameters(n)
    lo, hi = np.full(k, -np.inf), np.full(k, np.inf)
    w_lo, w_hi = problem.wt[0] / 3, problem.wt[-1] * 3
    lo[:n], hi[:n] = math.log(w_lo), math.log(w_hi)
    diag = 3 * n + np.array([j * (j + 1) // 2 + j for j in range(n)], dtype=int)  # row-major tril diagonal
    hi[diag] = 0.5 * math.log(2 * 2.0 * w_hi)  # C_rr = L_rr^2 <= 2 * zeta_max * w_max
    return lo, hi


def _solve(problem: _Problem, x0: np.ndarray, max_nfev: int = 400) -> tuple[np.ndarray, float]:
    lo, hi = _bounds(problem, problem.n)
    fin_lo, fin_hi = np.isfinite(lo), np.isfinite(hi)
    inner_lo, inner_hi = lo.copy(), hi.copy()
    inner_lo[fin_lo] += 1e-9 * (1 + np.abs(lo[fin_lo]))
    inner_hi[fin_hi] -= 1e-9 * (1 + np.abs(hi[fin_hi]))
    x0 = np.clip(x0, inner_lo, inner_hi)  # trf needs a start strictly inside the box
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        res = least_squares(problem.residual, x0, jac=problem.jacobian, method="trf", bounds=(lo, hi), xtol=_TOL,
                            ftol=_TOL, gtol=_TOL, max_nfev=max_nfev, x_scale="jac")
    if not np.all(np.isfinite(res.x)) or not np.isfinite(res.cost):
        raise ConvergenceError("modal fit: the least-squares refinement diverged (non-finite parameters)")
    return res.x, 2.0 * float(res.cost)


def _linear_start(problem: _Problem, poles: list[tuple[float, float]]) -> tuple[np.ndarray, float]:
    """Start values for given scaled poles (w_r, zeta_r) from a linear fit of real-mode residues.

    With a diagonal damping matrix the model is ``sum_r R_r / (w_r^2 - w^2 +
    2 i zeta_r w_r w) + U - L / w^2``, linear in the symmetric residues R_r.
    Each fitted R_r is projected onto rank one (its leading eigenpair) to
    give the mode shape; the nonlinear refinement takes it from there.
    """
    wt = problem.wt
    n = len(poles)
    ncol = 3 * n + 6
    basis = np.zeros((wt.size, 3, ncol), dtype=complex)
    for r, (w, z) in enumerate(poles):
        q = 1.0 / (w**2 - wt**2 + 2j * z * w * wt)
        for e in range(3):
            basis[:, e, 3 * r + e] = q
    for e in range(3):
        basis[:, e, 3 * n + e] = 1.0
        basis[:, e, 3 * n + 3 + e] = -1.0 / wt**2
    a = np.einsum("fke,fec->fkc", problem.w, basis).reshape(-1, ncol)
    b = np.einsum("fke,fe->fk", problem.w, problem.target).ravel()
    aa = np.concatenate([a.real, a.imag])
    bb = np.concatenate([b.real, b.imag])
    coef, *_ = np.linalg.lstsq(aa, bb, rcond=None)
    chi2 = float(np.sum((aa @ coef - bb) ** 2))
    phi = np.zeros((2, n))
    for r in range(n):
        ev, vec = np.linalg.eigh(_sym(coef[3 * r : 3 * r + 3]))
        phi[:, r] = vec[:, -1] * math.sqrt(max(ev[-1], 1e-6 * max(abs(ev).max(), 1e-12)))
    lw = np.log([w for w, _ in poles]) if n else np.zeros(0)
    lc = np.diag([math.sqrt(2 * z * w) for w, z in poles]) if n else np.zeros((0, 0))
    return _pack(lw, phi, lc, coef[3 * n : 3 * n + 3], coef[3 * n + 3 :]), chi2


def _grow(x: np.ndarray, n: int, w: float, zeta: float, shape: np.ndarray) -> np.ndarray:
    """Parameters of ``n`` modes plus a new one (frequency w, diagonal damping, given shape)."""
    lw, phi, lc, u, low = _unpack(x, n)
    lc2 = np.zeros((n + 1, n + 1))
    lc2[:n, :n] = lc
    lc2[n, n] = math.sqrt(2 * zeta * w)
    return _pack(np.append(lw, math.log(w)), np.column_stack([phi, shape]), lc2, u, low)


def _scan(problem: _Problem, poles: list[tuple[float, float]], zetas=(0.005, 0.03), n_grid: int = 80):
    """Best added pole on a log grid (band widened by 20 % each side) by the linear real-mode fit.

    Returns (w, zeta, shape) of the new mode, or None when every grid point
    lies next to an existing pole.
    """
    wt = problem.wt
    grid = np.geomspace(wt[0] / 1.2, wt[-1] * 1.2, n_grid)
    best = None
    for w in grid:
        if any(abs(math.log(w / p[0])) < 0.02 for p in poles):
            continue
        for z in zetas:
            x, c2 = _linear_start(problem, poles + [(float(w), z)])
            if best is None or c2 < best[0]:
                best = (c2, float(w), z, _unpack(x, len(poles) + 1)[1][:, -1])
    return None if best is None else best[1:]


def fit_modal_model(data: FitData, max_modes: int = 8, decimate: int | None = None) -> ModalFit:
    """Fit the reciprocal, passive modal model; choose the mode count by BIC.

    Parameters
    ----------
    data : FitData
    max_modes : int
        Largest mode count tried.
    decimate : int, optional
        Use every ``decimate``-th line for the mode-count search (default:
        keep at most about 1000 lines).  The final refinement uses all lines.

    Returns
    -------
    ModalFit
    """
    nf = data.frequency_hz.size
    step = decimate if decimate is not None else max(1, int(math.ceil(nf / 1000)))
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
    fresh: list[tuple[float, float]] = []  # poles chosen by the linear scan alone
    for n in range(1, max_modes + 1):
        prob = _Problem(search, sc, n)
        starts = []
        # (a) the refined n-1 mode model plus the best new pole
        prev_x = fits[n - 1]
        lw, _, lc, _, _ = _unpack(prev_x, n - 1)
        poles = [(float(np.exp(lw[r])), float(lc[r] @ lc[r]) / (2 * float(np.exp(lw[r])))) for r in range(n - 1)]
        new = _scan(prob, poles)
        if new is not None:
            starts.append(_grow(prev_x, n - 1, *new))
        # (b) poles picked one by one by the linear scan, never moved (robust to
        # a refinement that parked earlier poles where they no longer help)
        new = _scan(prob, fresh)
        if new is not None:
            fresh.append(new[:2])
            starts.append(_linear_start(prob, fresh)[0])
        if not starts:
            break
        x, chi2 = min((_solve(prob, x0) for x0 in starts), key=lambda t: t[1])
        fits[n], bic[n] = x, _bic(chi2, n_res, n_parameters(n))
        if _DEBUG:
            m = sc.model(x, n)
            print(n, chi2 / n_res, np.round(m.natural_frequency_hz, 1), np.round(m.damping_ratio, 4))
        rises = rises + 1 if bic[n] > min(v for m, v in bic.items() if m < n) else 0
        if rises >= 2:
            break
    n_best = min(bic, key=bic.get)
    x, chi2 = _solve(_Problem(data, sc, n_best), fits[n_best])
    return ModalFit(model=sc.model(x, n_best), chi2=chi2, n_residuals=2 * data.target.size, bic=bic, x=x, scaling=sc)


def refine(fit: ModalFit, data: FitData, max_nfev: int = 100) -> tuple[ModalModel, float]:
    """Refit the same mode count to new data (e.g. a bootstrap replicate), starting from ``fit``.

    Returns
    -------
    model : ModalModel
    chi2 : float
    """
    n = fit.model.n_modes
    x, chi2 = _solve(_Problem(data, fit.scaling, n), fit.x, max_nfev=max_nfev)
    return fit.scaling.model(x, n), chi2
