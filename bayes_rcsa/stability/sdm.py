"""First-order semi-discretisation of milling stability on modal x/y models, batched over models, speeds and depths.

Model
-----
The tool tip carries the modes of :class:`~bayes_rcsa.stability.modal_fit.ModalModel`
in X and in Y (no cross coupling; ``None`` = rigid direction).  Every mode
has unit participation at the tip, so the tip displacement is
q = (Σ_{r∈X} ξ_r, Σ_{r∈Y} ξ_r) and each mode obeys

    ξ_r'' + 2 ζ_r ω_r ξ_r' + ω_r^2 ξ_r = F_{dir(r)}(t) / m_r,
    F(t) = a [H_c(t) q(t) - Σ_l H_l(t) q(t - τ_l)],

with H the directional matrices of :mod:`~bayes_rcsa.stability.cutting`
(H_c = Σ_l H_l for milling), a the axial depth and τ_l = pitch_l/Ω the
delays.  The equation is periodic with the tooth period (equal pitch) or the
revolution (variable pitch).  The same core takes any delayed oscillator of
this form with its own H_c and H_l (e.g. the delayed Mathieu equation of the
tests, :func:`periodic_dde_radius`).

Semi-discretisation
-------------------
The principal period T is cut into m intervals of length Δt = T/m.  On
interval i the periodic coefficients are replaced by their exact interval
averages (:func:`~bayes_rcsa.stability.cutting.interval_directional_matrices`),
the delayed tip displacement by the straight line through its values at
t_i - τ and t_{i+1} - τ, and - the batched variant - the current tip
displacement in the cutting force likewise by the straight line through q_i
and q_{i+1} (the first-order scheme of Ding et al. 2010, "A full-discretization
method for prediction of milling stability", IJMTM 50:502).  The structural
part is then integrated exactly, mode by mode:

    y_{i+1} = P y_i + (Γ0 - Γ1/Δt) b F_i + (Γ1/Δt) b F_{i+1},
    P = e^{A Δt},  Γ0 = ∫_0^Δt e^{A s} ds,  Γ1 = ∫_0^Δt e^{A s} (Δt - s) ds,

with y_r = (ξ_r, ξ_r'/ω_r) and A_r = ω_r [[0, 1], [-1, -2ζ_r]].  F_{i+1}
depends on q_{i+1} = U y_{i+1}, which is solved for with one 2 x 2 system
per interval.  The point of the construction: P, Γ0 and Γ1 depend on the
structure and the speed only, never on the depth, so one set serves every
depth of a bisection and they are 2 x 2 per mode (no dense matrix
exponential per depth).  The scheme converges as O(Δt^2) like the classical
semi-discretisation (tests/test_stability_sdm.py: the exact autonomous slot
boundary, the delayed Mathieu equation, doubling m).

Only the two tip displacements are kept per past interval, so the state
z_i = (y_i, q_{i-1}, ..., q_{i-L}) has dimension d = 2n + 2L (L = m for equal
pitch), and the monodromy matrix Φ maps z_0 to z_m.  The cut is stable iff
the spectral radius ρ(Φ) < 1.

Vectorisation
-------------
Every batch point (model, speed, depth) runs at once; Φ is never formed as
d x d products but applied (m steps that update the 2n state rows; the
memory rows shift).  ρ(Φ) is obtained either

* ``solver="arnoldi"`` (default): a batched Arnoldi iteration of ``krylov``
  (14) steps on the action of Φ; the Ritz value of largest modulus is
  accepted when its residual |h_{k+1,k} s_k| is below 1e-6 relative.  The few
  points that have not converged are repeated with twice the Krylov
  dimension, and so on, ending with the dense eigenvalues once the Krylov
  space would be as large as Φ; or
* ``solver="eig"``: explicit Φ and all its eigenvalues (reference; cost d^3).

Discretisation
--------------
``intervals`` is the number m of intervals per tooth period (equal pitch;
N m per revolution for variable pitch).  The default,
:func:`default_intervals`, takes the rule m >= max(30, 30 f_max T) (at least
30 intervals per vibration cycle of the highest mode) and rounds it up to
the ladder 30·2^{j/2} (30, 43, 60, 85, 120, ...), so that the speeds of a
job share a few values of m and are batched together.  Discretisation error
of the default (tests/test_stability_sdm.py, docs/stability.md): below 1 % in
the limit depth against the exact slot boundary of the Insperger-Stépán
1-DOF case, < 1 % change when m is doubled, and 5e-4 in the dominant
multiplier of the delayed Mathieu equation (default m = 60; 1.2e-3 at m = 40,
O(Δt^2)).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..caching import BoundedCache
from ..errors import SetupError
from .cutting import CuttingConditions, interval_directional_matrices
from ._sdm_kernel import apply_monodromy

__all__ = [
    "SDMResult",
    "sdm_stability_map",
    "sdm_depth_limit",
    "sdm_depth_limits_batch",
    "spectral_radius",
    "spectral_radius_batch",
    "periodic_dde_radius",
    "monodromy_matrices",
    "default_intervals",
    "phi_functions",
    "depth_limit_from_radius",
    "INTERVALS_PER_CYCLE",
    "MIN_INTERVALS",
]

INTERVALS_PER_CYCLE = 30
MIN_INTERVALS = 30
_RITZ_TOL = 1e-6
_BATCH_RITZ_TOL = 1e-4
# Padding mode of a batch whose models have different mode counts: decoupled
# (zero participation and zero inverse mass) and heavily damped, so its
# multipliers e^{-ζωT} stay far inside the unit circle.
_PAD_ZETA = 0.9


@dataclass(frozen=True)
class SDMResult:
    """Semi-discretisation stability map.

    Attributes
    ----------
    speed_rpm : (n_speed,) rpm
    depth_m : (n_depth,) m
    spectral_radius : (n_speed, n_depth) ρ(Φ) of the monodromy matrix
    stable : (n_speed, n_depth) bool, ρ < 1
    depth_limit_m : (n_speed,) m, lowest depth where ρ reaches 1 (linear
        interpolation of ρ between grid depths, starting from ρ at a = 0);
        +inf when the whole depth grid is stable at that speed
    intervals : (n_speed,) int, m used at each speed
    """

    speed_rpm: np.ndarray
    depth_m: np.ndarray
    spectral_radius: np.ndarray
    stable: np.ndarray
    depth_limit_m: np.ndarray
    intervals: np.ndarray


# ----------------------------------------------------------------------------------------
# structural models of a batch
def _all_modes(modes_x, modes_y):
    """(omega, zeta) of all modes of both directions."""
    ms = [mm for mm in (modes_x, modes_y) if mm is not None]
    if not ms:
        raise SetupError("at least one of modes_x, modes_y must be given")
    return np.concatenate([mm.omega for mm in ms]), np.concatenate([mm.damping_ratio for mm in ms])


@dataclass(frozen=True)
class _Modal:
    """Modes of a batch, X modes first, padded to common counts: arrays (n, G)."""

    omega: np.ndarray  # rad/s
    zeta: np.ndarray
    inv_mass: np.ndarray  # 1/kg, 0 for padding
    weight: np.ndarray  # participation at the tip, 1 or 0 (padding)
    nx: int

    @property
    def n(self) -> int:
        return self.omega.shape[0]

    def take(self, idx) -> "_Modal":
        return _Modal(self.omega[:, idx], self.zeta[:, idx], self.inv_mass[:, idx], self.weight[:, idx], self.nx)


def _modal_batch(pairs, index) -> _Modal:
    """Modes of the points of a batch.

    Parameters
    ----------
    pairs : sequence of (ModalModel or None, ModalModel or None), the distinct (X, Y) models
    index : (G,) int, model pair of each point
    """
    for mx, my in pairs:
        if mx is None and my is None:
            raise SetupError("at least one of modes_x, modes_y must be given")
    nx = max(0 if mx is None else mx.n_modes for mx, _ in pairs)
    ny = max(0 if my is None else my.n_modes for _, my in pairs)
    w_pad = max(float(np.max(_all_modes(mx, my)[0])) for mx, my in pairs)
    P = len(pairs)
    omega = np.full((nx + ny, P), w_pad)
    zeta = np.full((nx + ny, P), _PAD_ZETA)
    inv_mass = np.zeros((nx + ny, P))
    weight = np.zeros((nx + ny, P))
    for p, (mx, my) in enumerate(pairs):
        for model, off in ((mx, 0), (my, nx)):
            if model is None:
                continue
            k = model.n_modes
            omega[off : off + k, p] = model.omega
            zeta[off : off + k, p] = model.damping_ratio
            inv_mass[off : off + k, p] = 1.0 / model.mass
            weight[off : off + k, p] = 1.0
    idx = np.asarray(index, dtype=int)
    return _Modal(omega[:, idx], zeta[:, idx], inv_mass[:, idx], weight[:, idx], nx)


def _ladder(m):
    """Smallest value of 30·2^{j/2} (rounded up to an integer) that is >= m, elementwise."""
    m = np.asarray(m, dtype=float)
    j = np.maximum(np.ceil(2 * np.log2(np.maximum(m, MIN_INTERVALS) / MIN_INTERVALS) - 1e-9), 0)
    out = np.ceil(MIN_INTERVALS * 2.0 ** (j / 2) - 1e-9)
    out = np.where(out < m, np.ceil(MIN_INTERVALS * 2.0 ** ((j + 1) / 2) - 1e-9), out)
    return out.astype(int)


def default_intervals(modes_x, modes_y, cutting: CuttingConditions, speed_rpm) -> np.ndarray:
    """Intervals per tooth period: max(MIN_INTERVALS, INTERVALS_PER_CYCLE f_max T) rounded up to 30·2^{j/2}; (n_speed,) int."""
    f_max = _all_modes(modes_x, modes_y)[0].max() / (2 * np.pi)
    return _intervals_from_fmax(f_max, cutting, speed_rpm)


def _intervals_from_fmax(f_max, cutting, speed_rpm):
    T = cutting.tooth_period(speed_rpm)
    return _ladder(np.maximum(MIN_INTERVALS, np.ceil(INTERVALS_PER_CYCLE * np.asarray(f_max) * T - 1e-9)))


# ----------------------------------------------------------------------------------------
# batched matrix functions
def phi_functions(A: np.ndarray, dt, order: int = 12):
    """P = e^{AΔt}, Γ0 = ∫_0^Δt e^{As} ds, Γ1 = ∫_0^Δt e^{As}(Δt - s) ds for stacks of matrices.

    Parameters
    ----------
    A : (..., k, k) 1/s
    dt : (...) s, broadcast against the batch shape of A
    order : int, Taylor order

    Returns
    -------
    P, G0, G1 : (..., k, k); G0 in s, G1 in s^2

    Notes
    -----
    Horner evaluation of φ_2(X) = Σ_j X^j/(j+2)! on X = A Δt/2^s with
    ||X||_1 <= 1/2 (truncation below 0.5^13/14! ≈ 1e-15 relative), then
    φ_1 = I + X φ_2, e^X = I + X φ_1 and s doublings
    P(2h) = P(h)^2, Γ0(2h) = (I + P(h)) Γ0(h), Γ1(2h) = Γ1(h) + h Γ0(h) + P(h) Γ1(h).
    """
    A = np.asarray(A, dtype=float)
    dt = np.broadcast_to(np.asarray(dt, dtype=float), A.shape[:-2])
    k = A.shape[-1]
    X = A * dt[..., None, None]
    norm = float(np.max(np.sum(np.abs(X), axis=-2), initial=0.0))
    s = int(np.ceil(np.log2(norm / 0.5))) if norm > 0.5 else 0
    h = dt / 2.0**s
    X = X / 2.0**s
    eye = np.eye(k)
    fact = np.cumprod(np.arange(1, order + 3, dtype=float))  # fact[j-1] = j!
    phi2 = np.broadcast_to(eye / fact[order + 1], X.shape).copy()
    for j in range(order - 1, -1, -1):
        phi2 = X @ phi2
        phi2 += eye / fact[j + 1]
    phi1 = eye + X @ phi2
    P = eye + X @ phi1
    hh = h[..., None, None]
    G0 = phi1 * hh
    G1 = phi2 * hh**2
    for _ in range(s):
        G1 = G1 + hh * G0 + P @ G1
        G0 = G0 + P @ G0
        P = P @ P
        hh = 2 * hh
    return P, G0, G1


# ----------------------------------------------------------------------------------------
# discretisation of the periodic coefficients
@dataclass(frozen=True)
class _Discretisation:
    m: int  # intervals per principal period
    h_current: np.ndarray  # (m, 2, 2) coefficient of q(t), interval averages
    groups: tuple  # ((H_l (m,2,2), r_l, f_l), ...) per distinct delay: lag r_l + f_l intervals
    L: int  # memory length (past tip displacements kept)


def _delay_groups(delayed, m):
    groups = []
    L = 0
    for H, lag in delayed:
        r = int(np.floor(lag + 1e-9))
        f = lag - r if lag - r > 1e-9 else 0.0
        if r < 2:
            raise SetupError(f"a delay of {lag:.4g} intervals spans fewer than 2 intervals; increase intervals")
        groups.append((np.asarray(H, dtype=float).reshape(m, 2, 2), r, f))
        L = max(L, r + (1 if f > 0 else 0))
    return tuple(groups), L


#: :func:`_discretise` results of the latest (cut, intervals) pairs: a search over depth asks for the same ones at
#: every step (about 15 % of a lobes run's SDM work).  Keyed by the cut (frozen, compared by value) with the types
#: of its fields (a float32 coefficient computes differently from an equal float), bounded, arrays read-only.
_DISCRETISED_MAX = 16
_DISCRETISED = BoundedCache(_DISCRETISED_MAX)


def _discretise(cutting: CuttingConditions, m_tooth: int) -> tuple[_Discretisation, float]:
    """Interval matrices of a cut and the principal period as a multiple of 60/n (s·rpm / 60), shared between
    calls (:data:`_DISCRETISED`; the arrays are read-only)."""
    try:
        key = (cutting, int(m_tooth), tuple(type(getattr(cutting, f.name)) for f in fields(cutting)))
        hit = _DISCRETISED.get(key)
    except TypeError:  # a cut with an unhashable field: computed every time
        return _discretise_uncached(cutting, m_tooth)
    if hit is None:
        hit = _discretise_uncached(cutting, m_tooth)
        disc = hit[0]
        for a in (disc.h_current, *(H for H, _, _ in disc.groups)):
            a.setflags(write=False)
        _DISCRETISED.put(key, hit)
    return hit


def _discretise_uncached(cutting: CuttingConditions, m_tooth: int) -> tuple[_Discretisation, float]:
    """Interval matrices of a cut and the principal period as a multiple of 60/n (s·rpm / 60)."""
    N = cutting.flutes
    if cutting.equal_pitch:
        m = int(m_tooth)
        dphi = 2 * np.pi / (N * m)
        start = dphi * np.arange(m)
        H = interval_directional_matrices(cutting, start, start + dphi)
        return _Discretisation(m, H, ((H, m, 0.0),), m), 1.0 / N
    m = int(m_tooth) * N
    dphi = 2 * np.pi / m
    start = dphi * np.arange(m)
    pitches = cutting.pitches
    delayed = []
    total = np.zeros((m, 2, 2))
    for p in np.unique(np.round(pitches, 12)):
        teeth = [j for j in range(N) if abs(pitches[j] - p) < 1e-9]
        H = interval_directional_matrices(cutting, start, start + dphi, teeth=teeth)
        total += H
        delayed.append((H, p / dphi))  # the delay in intervals does not depend on the speed
    groups, L = _delay_groups(delayed, m)
    return _Discretisation(m, total, groups, L), 1.0


@dataclass(frozen=True)
class _Steps:
    """Speed-dependent (depth-free) step matrices of a batch and its depths; batch axis last.

    P : (n, 2, 2, G) e^{A_r Δt} per mode
    ga, gb : (n, 2, G) the weights of F_i and F_{i+1}, (Γ0 - Γ1/Δt) b_r and (Γ1/Δt) b_r
    minv : (m, 2, 2, G) (I - a diag(g) H_c,i)^{-1}, g = U (Γ1/Δt) b
    """

    P: np.ndarray
    ga: np.ndarray
    gb: np.ndarray
    minv: np.ndarray
    weight: np.ndarray  # (n, G)
    depth: np.ndarray  # (G,)
    disc: _Discretisation
    nx: int

    @property
    def n(self) -> int:
        return self.P.shape[0]

    @property
    def L(self) -> int:
        return self.disc.L

    @property
    def dim(self) -> int:
        return 2 * self.n + 2 * self.L

    @property
    def size(self) -> int:
        return self.depth.size

    def subset(self, idx) -> "_Steps":
        return _Steps(self.P[..., idx], self.ga[..., idx], self.gb[..., idx], self.minv[..., idx],
                      self.weight[:, idx], self.depth[idx], self.disc, self.nx)


def _structure_steps(modal: _Modal, dt: np.ndarray):
    """Per-mode P, Γ-weights and the tip compliance g of one interval; depth-free."""
    w, z = modal.omega, modal.zeta  # (n, G)
    A = np.zeros(w.shape + (2, 2))
    A[..., 0, 1] = w
    A[..., 1, 0] = -w
    A[..., 1, 1] = -2 * z * w
    P, G0, G1 = phi_functions(A, np.broadcast_to(dt, w.shape))
    b = modal.inv_mass / w  # force enters the scaled velocity row
    inv_dt = 1.0 / dt
    ga = ((G0[..., :, 1] - G1[..., :, 1] * inv_dt[..., None]) * b[..., None]).transpose(0, 2, 1)
    gb = ((G1[..., :, 1] * inv_dt[..., None]) * b[..., None]).transpose(0, 2, 1)
    g = np.stack([np.sum(modal.weight[: modal.nx] * gb[: modal.nx, 0], axis=0),
                  np.sum(modal.weight[modal.nx :] * gb[modal.nx :, 0], axis=0)])  # (2, G)
    return np.ascontiguousarray(P.transpose(0, 2, 3, 1)), ga, gb, g


def _depth_solve(disc: _Discretisation, g: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(m, 2, 2, G) inverses of I - a diag(g) H_c,i (closed-form 2 x 2)."""
    Hc = disc.h_current[..., None]  # (m, 2, 2, 1)
    ag = depth * g  # (2, G)
    m00 = 1.0 - ag[0] * Hc[:, 0, 0]
    m01 = -ag[0] * Hc[:, 0, 1]
    m10 = -ag[1] * Hc[:, 1, 0]
    m11 = 1.0 - ag[1] * Hc[:, 1, 1]
    det = m00 * m11 - m01 * m10
    if np.any(np.abs(det) < 1e-12):
        raise SetupError("semi-discretisation: singular interval step (depth far beyond any stability limit)")
    out = np.empty((disc.m, 2, 2, depth.size))
    out[:, 0, 0] = m11 / det
    out[:, 0, 1] = -m01 / det
    out[:, 1, 0] = -m10 / det
    out[:, 1, 1] = m00 / det
    return out


def _steps(modal: _Modal, disc: _Discretisation, period: np.ndarray, depth: np.ndarray) -> _Steps:
    dt = np.asarray(period, dtype=float) / disc.m
    P, ga, gb, g = _structure_steps(modal, dt)
    return _Steps(P, ga, gb, _depth_solve(disc, g, depth), modal.weight, depth, disc, modal.nx)


def _mat2(H, q):
    """(2, 2) @ (2, b, G) with a shared matrix."""
    return np.stack([H[0, 0] * q[0] + H[0, 1] * q[1], H[1, 0] * q[0] + H[1, 1] * q[1]])


def _apply_numpy(steps: _Steps, V: np.ndarray) -> np.ndarray:
    """Φ V by numpy calls per step; the readable reference of the compiled :func:`_apply` (tests compare them)."""
    d, b, G = V.shape
    n, L, nx, disc = steps.n, steps.L, steps.nx, steps.disc
    m = disc.m
    a = steps.depth
    P = steps.P[:, :, :, None, :]  # (n, 2, 2, 1, G)
    ga = steps.ga[:, :, None, :]  # (n, 2, 1, G)
    gb = steps.gb[:, :, None, :]
    wx, wy = steps.weight[:nx, None, :], steps.weight[nx:, None, :]
    # history buffer: slot L + i holds q_i; the initial memory (q_{-1}, ..., q_{-L}) fills slots L-1..0
    hist = np.empty((L + m + 1, 2, b, G))
    hist[:L] = V[2 * n :].reshape(L, 2, b, G)[::-1]
    y = V[: 2 * n].reshape(n, 2, b, G)
    hist[L] = [np.sum(wx * y[:nx, 0], axis=0), np.sum(wy * y[nx:, 0], axis=0)]
    gx = np.sum(wx * gb[:nx, 0], axis=0)  # tip compliance of the F_{i+1} weight, (1, G)
    gy = np.sum(wy * gb[nx:, 0], axis=0)
    for i in range(m):
        D = 0.0
        E = 0.0
        for H, r, f in disc.groups:
            Hi = H[i]
            if f:
                D = D + _mat2(Hi, (1 - f) * hist[L + i - r] + f * hist[L + i - r - 1])
                E = E + _mat2(Hi, (1 - f) * hist[L + i + 1 - r] + f * hist[L + i - r])
            else:
                D = D + _mat2(Hi, hist[L + i - r])
                E = E + _mat2(Hi, hist[L + i + 1 - r])
        Hc = disc.h_current[i]
        F0 = a * (_mat2(Hc, hist[L + i]) - D)  # force at t_i, (2, b, G)
        yn = P[:, :, 0] * y[:, None, 0] + P[:, :, 1] * y[:, None, 1]  # 2 x 2 per mode
        yn[:nx] += ga[:nx] * F0[0]
        yn[nx:] += ga[nx:] * F0[1]
        aE = a * E
        rx = np.sum(wx * yn[:nx, 0], axis=0) - gx * aE[0]
        ry = np.sum(wy * yn[nx:, 0], axis=0) - gy * aE[1]
        mi = steps.minv[i]
        q1 = np.stack([mi[0, 0] * rx + mi[0, 1] * ry, mi[1, 0] * rx + mi[1, 1] * ry])
        F1 = a * _mat2(Hc, q1) - aE
        yn[:nx] += gb[:nx] * F1[0]
        yn[nx:] += gb[nx:] * F1[1]
        hist[L + i + 1] = q1
        y = yn
    mem = hist[m : L + m][::-1].reshape(2 * L, b, G)  # q_{m-1}, ..., q_{m-L}
    return np.concatenate([y.reshape(2 * n, b, G), mem], axis=0)


def _apply(steps: _Steps, V: np.ndarray) -> np.ndarray:
    """Φ V for a batch: V (d, b, G) -> (d, b, G), by m steps (compiled kernel)."""
    disc = steps.disc
    hd = np.stack([H for H, _, _ in disc.groups])
    lag_r = np.array([r for _, r, _ in disc.groups], dtype=np.int64)
    lag_f = np.array([f for _, _, f in disc.groups], dtype=float)
    # writeable C-contiguous arrays only: numba compiles another version for every read-only or strided
    # argument (about a second each on a fresh install)
    def c(a):
        return np.require(a, float, ("C", "W"))

    return apply_monodromy(c(steps.P), c(steps.ga), c(steps.gb), c(steps.minv), c(steps.weight), c(steps.depth),
                           c(disc.h_current), c(hd), lag_r, lag_f, steps.nx, disc.L, c(V))


def _explicit(steps: _Steps) -> np.ndarray:
    """(G, d, d) monodromy matrices of the batch."""
    d = steps.dim
    eye = np.broadcast_to(np.eye(d)[:, :, None], (d, d, steps.size))
    return np.ascontiguousarray(_apply(steps, eye).transpose(2, 0, 1))


def _arnoldi_radius(steps: _Steps, krylov: int, rng: np.random.Generator, tol: float = _RITZ_TOL, v0=None):
    """Dominant Ritz modulus, a convergence flag (residual <= tol relative) and the real part of the
    dominant Ritz vector (d, G) per batch point.  ``v0`` (d, G): start vectors (default: one random
    vector from ``rng`` for all points)."""
    G, d = steps.size, steps.dim
    k = min(krylov, d)
    V = np.zeros((k + 1, d, G))
    H = np.zeros((G, k + 1, k))
    if v0 is None:
        v = rng.standard_normal(d)
        V[0] = (v / np.linalg.norm(v))[:, None]
    else:
        V[0] = v0 / np.maximum(np.linalg.norm(v0, axis=0), 1e-300)
    for j in range(k):
        w = _apply(steps, V[j][:, None, :])[:, 0, :]
        for _ in range(2):  # classical Gram-Schmidt, repeated once for orthogonality
            h = np.einsum("idg,dg->ig", V[: j + 1], w)
            w -= np.einsum("idg,ig->dg", V[: j + 1], h)
            H[:, : j + 1, j] += h.T
        beta = np.linalg.norm(w, axis=0)
        scale = np.maximum(np.abs(H[:, : j + 1, j]).max(axis=1), 1e-300)
        broke = beta <= 1e-13 * scale  # invariant subspace found: the Ritz values are exact
        H[:, j + 1, j] = np.where(broke, 0.0, beta)
        V[j + 1] = np.where(broke, 0.0, w / np.where(broke, 1.0, beta))
    Hk = H[:, :k, :k]
    theta = np.linalg.eigvals(Hk)
    i = np.argmax(np.abs(theta), axis=1)
    rows = np.arange(G)
    mu = theta[rows, i]
    rho = np.abs(mu)
    # eigenvector of the dominant Ritz value by one step of inverse iteration (a shift 1e-10 off the
    # eigenvalue keeps the solve regular; the result is the eigenvector to ~1e-10): cheaper than eig
    shift = (mu * (1 + 1e-10) + 1e-300)[:, None, None] * np.eye(k)
    s_vec = np.linalg.solve(Hk - shift, np.ones((G, k, 1), dtype=complex))[..., 0]
    s_vec /= np.maximum(np.linalg.norm(s_vec, axis=1, keepdims=True), 1e-300)
    resid = np.abs(H[:, k, k - 1]) * np.abs(s_vec[:, k - 1])
    converged = resid <= tol * np.maximum(rho, 1e-12)
    # real part (plus imaginary part, so a real eigenvector never vanishes) of V_k s: lies in the
    # dominant invariant subspace, a good start for a neighbouring matrix (next depth of a search)
    x = np.einsum("idg,gi->dg", V[:k], s_vec)
    return rho, converged, x.real + x.imag


def _radius_batch(steps: _Steps, solver: str, krylov: int, rng, tol: float = _RITZ_TOL, v0=None):
    """ρ (G,) and dominant Ritz vectors (d, G) (zeros where dense eigenvalues were used)."""
    vec = np.zeros((steps.dim, steps.size))
    if solver == "eig":
        return np.max(np.abs(np.linalg.eigvals(_explicit(steps))), axis=-1), vec
    rho = np.empty(steps.size)
    todo = np.arange(steps.size)
    k = krylov
    start = v0
    while todo.size:
        sub = steps if todo.size == steps.size else steps.subset(todo)
        if k >= sub.dim:  # a full Krylov space costs more than the dense eigenvalues
            rho[todo] = np.max(np.abs(np.linalg.eigvals(_explicit(sub))), axis=-1)
            break
        r, ok, x = _arnoldi_radius(sub, k, rng, tol, None if start is None else start[:, todo])
        rho[todo[ok]] = r[ok]
        vec[:, todo[ok]] = x[:, ok]
        todo = todo[~ok]
        k *= 2  # the few unconverged points get a larger Krylov space
    return rho, vec


# ----------------------------------------------------------------------------------------
def _check_solver(solver):
    if solver not in ("arnoldi", "eig"):
        raise SetupError(f"solver={solver!r}: expected 'arnoldi' or 'eig'")


def monodromy_matrices(modes_x, modes_y, cutting: CuttingConditions, speed_rpm, depth_m, intervals: int) -> np.ndarray:
    """Explicit monodromy matrices Φ for paired (speed, depth) points.

    Parameters
    ----------
    modes_x, modes_y : ModalModel or None (rigid)
    cutting : CuttingConditions
    speed_rpm, depth_m : (G,) rpm, m (paired element by element)
    intervals : int, m per tooth period

    Returns
    -------
    (G, d, d), d = 2 n + 2 L, in the state (ξ_r, ξ_r'/ω_r per mode, q_{-1}, ..., q_{-L}).
    """
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    depth = np.broadcast_to(np.atleast_1d(np.asarray(depth_m, dtype=float)), speed.shape)
    disc, factor = _discretise(cutting, intervals)
    modal = _modal_batch([(modes_x, modes_y)], np.zeros(speed.size, dtype=int))
    return _explicit(_steps(modal, disc, factor * 60.0 / speed, depth))


def spectral_radius_batch(
    pairs,
    index,
    cutting: CuttingConditions,
    speed_rpm,
    depth_m,
    intervals,
    solver: str = "arnoldi",
    krylov: int = 14,
    chunk: int = 4096,
    rng: np.random.Generator | None = None,
    ritz_tol: float = _RITZ_TOL,
    start=None,
    vectors: bool = False,
):
    """ρ(Φ) for points that each have their own modal model, speed and depth, (G,).

    Parameters
    ----------
    pairs : sequence of (ModalModel or None, ModalModel or None), distinct (X, Y) models
    index : (G,) int, the model pair of each point
    cutting : CuttingConditions
    speed_rpm, depth_m : (G,) rpm, m
    intervals : (G,) int or int, m per tooth period; points sharing m are batched together
    solver, krylov : see :func:`spectral_radius`
    chunk : int, largest number of points processed at once (bounds memory)
    rng : numpy Generator for the Arnoldi start vector (default: fixed seed 0)
    ritz_tol : float, relative residual at which a dominant Ritz value is accepted
    start : (G,) object array of (d,) start vectors or None entries, or None (random start)
    vectors : bool, also return the dominant Ritz vectors as a (G,) object array (start of a next call)
    """
    _check_solver(solver)
    rng = np.random.default_rng(0) if rng is None else rng
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    depth = np.broadcast_to(np.asarray(depth_m, dtype=float), speed.shape)
    index = np.broadcast_to(np.asarray(index, dtype=int), speed.shape)
    m_all = np.broadcast_to(np.asarray(intervals, dtype=int), speed.shape)
    if np.any(m_all < 2):
        raise SetupError(f"intervals {intervals!r}: expected >= 2 per tooth period")
    modal = _modal_batch(pairs, np.arange(len(pairs)))
    rho = np.empty(speed.size)
    out_vec = np.empty(speed.size, dtype=object) if vectors else None
    for m in np.unique(m_all):
        disc, factor = _discretise(cutting, int(m))
        idx = np.nonzero(m_all == m)[0]
        for s in range(0, idx.size, chunk):
            sel = idx[s : s + chunk]
            steps = _steps(modal.take(index[sel]), disc, factor * 60.0 / speed[sel], depth[sel])
            v0 = None
            if start is not None and all(start[g] is not None and start[g].shape == (steps.dim,) for g in sel):
                v0 = np.stack([start[g] for g in sel], axis=1)
            rho[sel], vec = _radius_batch(steps, solver, krylov, rng, ritz_tol, v0)
            if vectors:
                for c, g in enumerate(sel):
                    out_vec[g] = vec[:, c] if np.any(vec[:, c]) else None
    return (rho, out_vec) if vectors else rho


def spectral_radius(
    modes_x,
    modes_y,
    cutting: CuttingConditions,
    speed_rpm,
    depth_m,
    intervals,
    solver: str = "arnoldi",
    krylov: int = 14,
    chunk: int = 4096,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """ρ(Φ) for paired (speed, depth) points of one modal model, (G,).

    ``intervals`` is one int or one per point; points sharing m are batched.
    ``rng`` draws the Arnoldi start vector (default: fixed seed 0, so results
    are reproducible).
    """
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    return spectral_radius_batch([(modes_x, modes_y)], np.zeros(speed.size, dtype=int), cutting, speed, depth_m,
                                 intervals, solver=solver, krylov=krylov, chunk=chunk, rng=rng)


def periodic_dde_radius(
    modes_x,
    modes_y,
    period_s: float,
    averages,
    delays_s,
    intervals: int | None = None,
    scale: float = 1.0,
    solver: str = "arnoldi",
    krylov: int = 14,
    rng: np.random.Generator | None = None,
) -> float:
    """Dominant Floquet multiplier modulus of a general periodic delayed oscillator.

    The modes of ``modes_x``/``modes_y`` obey ξ_r'' + 2ζω ξ_r' + ω^2 ξ_r = F_dir/m_r with
    F(t) = scale [C(t) q(t) - Σ_l D_l(t) q(t - τ_l)], q the tip displacement
    (sum of the modes of each direction), C and D_l periodic with ``period_s``.

    Parameters
    ----------
    modes_x, modes_y : ModalModel or None
    period_s : float, s, principal period T of the coefficients
    averages : callable (t_start (m,), t_stop (m,)) s -> (C (m, 2, 2), [D_l (m, 2, 2), ...])
        Interval averages of the coefficients, N/m per unit ``scale``.
    delays_s : sequence of float, s, the delays τ_l (>= 2 intervals each)
    intervals : int or None
        m per period; default max(30, 30 f_max T) rounded up to 30·2^{j/2}
        (the rule of :func:`default_intervals`).
    scale : float, the "depth" multiplying the coefficients

    Returns
    -------
    float, ρ(Φ) of the semi-discretised monodromy map.
    """
    _check_solver(solver)
    if intervals is None:
        f_max = _all_modes(modes_x, modes_y)[0].max() / (2 * np.pi)
        intervals = int(_ladder(max(MIN_INTERVALS, np.ceil(INTERVALS_PER_CYCLE * f_max * period_s - 1e-9))))
    m = int(intervals)
    edges = np.linspace(0.0, float(period_s), m + 1)
    current, delayed = averages(edges[:-1], edges[1:])
    current = np.asarray(current, dtype=float)
    if current.shape != (m, 2, 2) or len(delayed) != len(delays_s):
        raise SetupError(f"averages: expected C of shape ({m}, 2, 2) and one D per delay")
    dt = float(period_s) / m
    groups, L = _delay_groups([(D, tau / dt) for D, tau in zip(delayed, delays_s)], m)
    disc = _Discretisation(m, current, groups, L)
    modal = _modal_batch([(modes_x, modes_y)], np.zeros(1, dtype=int))
    steps = _steps(modal, disc, np.array([float(period_s)]), np.array([float(scale)]))
    return float(_radius_batch(steps, solver, krylov, np.random.default_rng(0) if rng is None else rng)[0][0])


def _free_radius(modes_x, modes_y, cutting, speed):
    """ρ(Φ) at zero depth: max |e^{λT}| over the structural poles, (n_speed,)."""
    w, z = _all_modes(modes_x, modes_y)
    T = (cutting.tooth_period(speed) if cutting.equal_pitch else 60.0 / speed)[:, None]
    return np.max(np.exp(-z * w * T), axis=-1)


def depth_limit_from_radius(depth: np.ndarray, rho: np.ndarray, rho0: np.ndarray) -> np.ndarray:
    """Lowest depth where ρ reaches 1, interpolating ρ linearly in depth from (0, ρ0).

    Parameters
    ----------
    depth : (n_depth,) m, increasing, > 0
    rho : (n_speed, n_depth)
    rho0 : (n_speed,) ρ at zero depth (< 1)

    Returns
    -------
    (n_speed,) m, +inf where ρ < 1 on the whole grid.
    """
    d = np.concatenate([[0.0], depth])
    r = np.concatenate([rho0[:, None], rho], axis=1)
    unstable = r >= 1.0
    has = unstable.any(axis=1)
    j = np.where(has, np.maximum(np.argmax(unstable, axis=1), 1), 1)
    rows = np.arange(r.shape[0])
    r0, r1 = r[rows, j - 1], r[rows, j]
    d0, d1 = d[j - 1], d[j]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(r1 > r0, (1.0 - r0) / (r1 - r0), 0.0)
    return np.where(has, d0 + t * (d1 - d0), np.inf)


def _check_grid(speed, depth):
    if speed.ndim != 1 or speed.size < 1 or np.any(speed <= 0) or np.any(np.diff(speed) <= 0):
        raise SetupError("speed_rpm must be a strictly increasing 1-D array of positive speeds")
    if depth.ndim != 1 or depth.size < 1 or np.any(depth <= 0) or np.any(np.diff(depth) <= 0):
        raise SetupError("depth_m must be a strictly increasing 1-D array of positive depths")


def _intervals_for(modes_x, modes_y, cutting, speed, intervals):
    if intervals is None:
        return default_intervals(modes_x, modes_y, cutting, speed)
    m = np.broadcast_to(np.asarray(intervals, dtype=int), speed.shape).copy()
    if np.any(m < 2):
        raise SetupError(f"intervals {intervals!r}: expected >= 2 per tooth period")
    return m


def sdm_stability_map(
    modes_x,
    modes_y,
    cutting: CuttingConditions,
    speed_rpm,
    depth_m,
    intervals=None,
    solver: str = "arnoldi",
    krylov: int = 14,
    rng: np.random.Generator | None = None,
) -> SDMResult:
    """Stability of every (speed, depth) grid point by first-order semi-discretisation.

    Parameters
    ----------
    modes_x, modes_y : ModalModel or None (rigid) of the tool-point receptances in X and Y
    cutting : CuttingConditions
    speed_rpm : (n_speed,) rpm, increasing
    depth_m : (n_depth,) m, increasing, > 0
    intervals : int, (n_speed,) ints or None
        Intervals per tooth period (default :func:`default_intervals`).
    solver : {"arnoldi", "eig"}
    krylov : int, Arnoldi steps
    rng : numpy Generator for the Arnoldi start vector (default seed 0)

    Returns
    -------
    SDMResult
    """
    speed = np.asarray(speed_rpm, dtype=float)
    depth = np.asarray(depth_m, dtype=float)
    _check_grid(speed, depth)
    m_sp = _intervals_for(modes_x, modes_y, cutting, speed, intervals)
    ss, dd = np.meshgrid(speed, depth, indexing="ij")
    mm = np.broadcast_to(m_sp[:, None], ss.shape)
    rho = spectral_radius(
        modes_x, modes_y, cutting, ss.ravel(), dd.ravel(), mm.ravel(), solver=solver, krylov=krylov, rng=rng
    ).reshape(ss.shape)
    limit = depth_limit_from_radius(depth, rho, _free_radius(modes_x, modes_y, cutting, speed))
    return SDMResult(speed, depth, rho, rho < 1.0, limit, m_sp)


def sdm_depth_limit(
    modes_x,
    modes_y,
    cutting: CuttingConditions,
    speed_rpm,
    depth_bracket,
    intervals=None,
    rtol: float = 1e-4,
    solver: str = "arnoldi",
    krylov: int = 14,
) -> np.ndarray:
    """Limit depth at each speed by bisection on ρ(Φ) = 1 inside a bracket.

    Parameters
    ----------
    speed_rpm : (n_speed,) rpm
    depth_bracket : (lo, hi) m, scalars or (n_speed,) arrays with ρ(lo) < 1 <= ρ(hi)
    intervals : as in :func:`sdm_stability_map`
    rtol : relative width of the final bracket

    Returns
    -------
    (n_speed,) m; nan where the bracket does not bracket a crossing.

    Notes
    -----
    Bisection finds *a* crossing inside the bracket; give a bracket whose
    lower end is stable, e.g. from a stability map.
    """
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    lo = np.broadcast_to(np.asarray(depth_bracket[0], dtype=float), speed.shape).copy()
    hi = np.broadcast_to(np.asarray(depth_bracket[1], dtype=float), speed.shape).copy()
    m_sp = _intervals_for(modes_x, modes_y, cutting, speed, intervals)

    def rho(a):
        return spectral_radius(modes_x, modes_y, cutting, speed, a, m_sp, solver=solver, krylov=krylov)

    ok = (rho(lo) < 1.0) & (rho(hi) >= 1.0)
    n_iter = int(np.ceil(np.log2(max(np.max((hi - lo) / (rtol * lo)), 2.0))))
    for _ in range(n_iter):
        mid = 0.5 * (lo + hi)
        st = rho(mid) < 1.0
        lo = np.where(st, mid, lo)
        hi = np.where(st, hi, mid)
    return np.where(ok, 0.5 * (lo + hi), np.nan)


def sdm_depth_limits_batch(
    pairs,
    index,
    cutting: CuttingConditions,
    speed_rpm,
    guess_m,
    intervals=None,
    rtol: float = 2e-3,
    expand: float = 1.6,
    max_expand: int = 8,
    krylov: int = 20,
    krylov_warm: int = 8,
    progress=None,
) -> np.ndarray:
    """Limit depth of many (model, speed) points at once: predicted bracket from a guess, then safeguarded secant.

    Parameters
    ----------
    pairs : sequence of (ModalModel or None, ModalModel or None), distinct (X, Y) models
    index : (G,) int, model of each point
    cutting : CuttingConditions
    speed_rpm : (G,) rpm
    guess_m : (G,) m, finite positive first guesses (e.g. the zero-order limits of the same FRFs)
    intervals : (G,) int or None (default rule of each point's model)
    rtol : float, relative width of the final bracket
    expand : float, bracket growth factor when the predicted bracket misses
    max_expand : int, growth steps before a point is declared free of chatter (+inf)
    krylov : int, Arnoldi steps of the first evaluation (fitted modal models often carry lightly damped
        modes whose multipliers crowd the unit circle; 14 steps rarely converge there, 20 mostly do)
    krylov_warm : int, Arnoldi steps of later evaluations, started from the point's previous dominant
        Ritz vector (doubled where they do not converge)
    progress : callable(fraction) or None, called after each batched evaluation

    Returns
    -------
    (G,) m, the depth where ρ(Φ) reaches 1 going up from the guess's stable side; +inf
    when the cut is still stable at guess·expand^max_expand.

    Notes
    -----
    Every evaluation is one batched call over all points still open.  The
    first step predicts the crossing from ρ at zero depth (known in closed
    form) and at the guess, by a straight line in depth, and evaluates just
    beyond it, so the bracket is usually found with two evaluations; then
    secant steps on ρ(a) - 1, kept inside the middle 90 % of the bracket,
    until the bracket is narrower than ``rtol`` or ρ is within 2e-4 of 1
    (the depth is then within about 4e-4 relative: ρ changes by 0.5-1 per
    unit relative depth near a crossing).
    """
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    index = np.broadcast_to(np.asarray(index, dtype=int), speed.shape)
    a0 = np.broadcast_to(np.asarray(guess_m, dtype=float), speed.shape).copy()
    if not np.all(np.isfinite(a0) & (a0 > 0)):
        raise SetupError("sdm_depth_limits_batch: guesses must be finite and > 0")
    if intervals is None:
        fmax = np.array([_all_modes(mx, my)[0].max() / (2 * np.pi) for mx, my in pairs])
        m_all = _intervals_from_fmax(fmax[index], cutting, speed)
    else:
        m_all = np.broadcast_to(np.asarray(intervals, dtype=int), speed.shape)
    G = speed.size
    budget = 5.0  # typical evaluations per point, for the progress fraction only
    done_evals = [0.0]

    vecs = np.empty(G, dtype=object)  # dominant Ritz vector of each point's last evaluation

    def rho(sel, a):
        # a stability decision and the secant step need ρ to ~1e-4 (the depth then to ~1e-4 relative,
        # well inside rtol); the looser Ritz tolerance saves Krylov passes near clustered multipliers.
        # From the second evaluation on, each point starts from its previous dominant Ritz vector:
        # the depth changes little, so a short Krylov space converges.
        warm = all(vecs[g] is not None for g in sel)
        r, v = spectral_radius_batch(pairs, index[sel], cutting, speed[sel], a, m_all[sel],
                                     krylov=krylov_warm if warm else krylov, ritz_tol=_BATCH_RITZ_TOL,
                                     start=vecs[sel] if warm else None, vectors=True)
        vecs[sel] = v
        done_evals[0] += sel.size
        if progress is not None:
            progress(min(0.99, done_evals[0] / (budget * G)))
        return r

    everyone = np.arange(G)
    rfree = _free_radius_batch(pairs, index, cutting, speed)
    r0 = rho(everyone, a0)
    stable0 = r0 < 1.0
    lo = np.where(stable0, a0, 0.0)
    rlo = np.where(stable0, r0, rfree)
    hi = np.where(stable0, np.inf, a0)
    rhi = np.where(stable0, np.inf, r0)
    # predicted crossing on the line through (0, ρ_free) and (a0, ρ(a0)), evaluated 3 % beyond it
    with np.errstate(divide="ignore", invalid="ignore"):
        pred = np.where(r0 > rfree, a0 * (1.0 - rfree) / (r0 - rfree), a0 * expand)
    pred = np.clip(pred, a0 / expand, a0 * expand)
    trial = np.where(stable0, np.maximum(pred * 1.03, a0 * 1.01), np.minimum(pred / 1.03, a0 / 1.01))
    r = rho(everyone, trial)
    st = r < 1.0
    lo, rlo = np.where(st & (trial > lo), trial, lo), np.where(st & (trial > lo), r, rlo)
    hi, rhi = np.where(~st & (trial < hi), trial, hi), np.where(~st & (trial < hi), r, rhi)
    # points the prediction did not bracket: grow (still stable) or shrink (still unstable) geometrically
    up = np.nonzero(~np.isfinite(hi))[0]
    down = np.nonzero((lo == 0.0) & ~st)[0]
    for _ in range(max_expand):
        if up.size == 0 and down.size == 0:
            break
        sel = np.concatenate([up, down])
        t = np.concatenate([lo[up] * expand, hi[down] / expand])
        rr = rho(sel, t)
        ru, rd = rr[: up.size], rr[up.size :]
        st_u, st_d = ru < 1.0, rd < 1.0
        lo[up[st_u]], rlo[up[st_u]] = t[: up.size][st_u], ru[st_u]
        hi[up[~st_u]], rhi[up[~st_u]] = t[: up.size][~st_u], ru[~st_u]
        lo[down[st_d]], rlo[down[st_d]] = t[up.size :][st_d], rd[st_d]
        hi[down[~st_d]], rhi[down[~st_d]] = t[up.size :][~st_d], rd[~st_d]
        up, down = up[st_u], down[~st_d]
    done = np.zeros(G, dtype=bool)
    best = np.full(G, np.nan)
    open_ = np.nonzero(np.isfinite(hi) & (hi - lo > rtol * hi))[0]
    for _ in range(60):
        if open_.size == 0:
            break
        l, h, rl, rh = lo[open_], hi[open_], rlo[open_], rhi[open_]
        t = np.clip((1.0 - rl) / np.maximum(rh - rl, 1e-300), 0.05, 0.95)
        trial = l + t * (h - l)
        rr = rho(open_, trial)
        st = rr < 1.0
        lo[open_[st]], rlo[open_[st]] = trial[st], rr[st]
        hi[open_[~st]], rhi[open_[~st]] = trial[~st], rr[~st]
        close = np.abs(rr - 1.0) < 2e-4
        best[open_[close]] = trial[close]
        done[open_[close]] = True
        keep = ~close & (hi[open_] - lo[open_] > rtol * hi[open_])
        open_ = open_[keep]
    if progress is not None:
        progress(1.0)
    out = np.where(np.isfinite(hi), 0.5 * (lo + hi), np.inf)
    return np.where(done, best, out)


def _free_radius_batch(pairs, index, cutting, speed):
    out = np.empty(speed.size)
    for p, (mx, my) in enumerate(pairs):
        sel = index == p
        if np.any(sel):
            out[sel] = _free_radius(mx, my, cutting, speed[sel])
    return out
