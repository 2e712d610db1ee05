"""First-order semi-discretisation (Insperger & Stépán 2004) of milling stability for modal x/y models.

Model
-----
The tool tip carries the modes of :class:`~bayes_rcsa.stability.modal_fit.ModalModel`
in X and in Y (no cross coupling; ``None`` = rigid direction).  Every mode
has unit participation at the tip, so with the modal coordinates ξ
(n = n_x + n_y) and the selector U (2 x n, ones where a mode belongs to X
resp. Y) the tip displacement is q = U ξ and

    M ξ'' + C ξ' + K ξ = a U^T Σ_j g_j H(φ_j(t)) (q(t) - q(t - τ_j)),

with H the directional matrix of :mod:`~bayes_rcsa.stability.cutting`, a the
axial depth and τ_j = pitch_j/Ω the delay of tooth j.  In first-order form
y = (ξ, ξ'/ω_s) (velocities scaled by a reference frequency ω_s so that the
state matrix is balanced) this is y' = A(t) y + Σ_l B_l(t) q(t - τ_l),
periodic with the tooth period (equal pitch) or the revolution (variable
pitch).

Semi-discretisation
-------------------
The principal period T is cut into m intervals of length Δt = T/m.  On
interval i the periodic coefficients are replaced by their exact averages
over the interval (:func:`~bayes_rcsa.stability.cutting.interval_directional_matrices`)
and the delayed tip displacement by the straight line through its values at
t_i - τ and t_{i+1} - τ (first order); those values are themselves linear
interpolations of the stored q_{i-k} (exact grid values for equal pitch,
where τ = mΔt).  The ODE is then solved exactly on the interval:

    y_{i+1} = P_i y_i + (Γ0_i - Γ1_i/Δt) B_i q(t_i - τ) + (Γ1_i/Δt) B_i q(t_{i+1} - τ),
    P_i = e^{A_i Δt},  Γ0_i = ∫_0^Δt e^{A_i s} ds,  Γ1_i = ∫_0^Δt e^{A_i s} (Δt - s) ds.

Only the two tip displacements are kept per past interval, so the state
z_i = (y_i, q_{i-1}, ..., q_{i-L}) has dimension d = 2n + 2L (L = m for equal
pitch), and the monodromy matrix Φ maps z_0 to z_m.  The cut is stable iff
the spectral radius ρ(Φ) < 1.

Vectorisation
-------------
Everything runs on batches of grid points at once: the matrix functions by
a batched Taylor series with scaling and squaring, and the monodromy never
as d x d products but as its action, m steps that each update only the 2n
state rows (the memory rows shift).  ρ(Φ) is obtained either

* ``solver="arnoldi"`` (default): a batched Arnoldi iteration of ``krylov``
  (14) steps on the action of Φ; the Ritz value of largest modulus is
  accepted when its residual |h_{k+1,k} s_k| is below 1e-6 relative.  The few
  points that have not converged are repeated with twice the Krylov
  dimension, and so on, ending with the dense eigenvalues once the Krylov
  space would be as large as Φ.  The multipliers of a delayed oscillator fall
  off quickly away from the dominant ones, so 14 steps converge almost
  everywhere; or
* ``solver="eig"``: explicit Φ and all its eigenvalues (reference; cost d^3).

Discretisation
--------------
``intervals`` is the number m of intervals per tooth period (equal pitch;
N m per revolution for variable pitch).  The default,
:func:`default_intervals`, is m = max(30, ceil(20 f_max T)): at least 20
intervals per vibration cycle of the highest mode.  First-order
semi-discretisation converges as O(Δt^2); with this rule the limit depth
changes by less than 1 % when m is doubled (tests/test_stability_sdm.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from .cutting import CuttingConditions, interval_directional_matrices
from .modal_fit import ModalModel

__all__ = [
    "SDMResult",
    "sdm_stability_map",
    "sdm_depth_limit",
    "spectral_radius",
    "monodromy_matrices",
    "default_intervals",
    "phi_functions",
    "depth_limit_from_radius",
    "INTERVALS_PER_CYCLE",
    "MIN_INTERVALS",
]

INTERVALS_PER_CYCLE = 20
MIN_INTERVALS = 30
_RITZ_TOL = 1e-6


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
# structural model
def _modes(model: ModalModel | None):
    if model is None:  # rigid direction
        return np.zeros(0), np.zeros(0), np.zeros(0)
    return model.mass, model.damping, model.stiffness


def _all_modes(modes_x, modes_y):
    """(omega, zeta) of all modes of both directions."""
    ms = [mm for mm in (modes_x, modes_y) if mm is not None]
    if not ms:
        raise SetupError("at least one of modes_x, modes_y must be given")
    return np.concatenate([mm.omega for mm in ms]), np.concatenate([mm.damping_ratio for mm in ms])


@dataclass(frozen=True)
class _Structure:
    A0: np.ndarray  # (2n, 2n) 1/s, scaled state (ξ, ξ'/ω_s)
    force_rows: np.ndarray  # (n, 2): maps tip force (N) to the scaled-velocity derivative, (1/ω_s) M^-1 U^T
    U: np.ndarray  # (2, n)


def _structure(modes_x, modes_y) -> _Structure:
    mx, cx, kx = _modes(modes_x)
    my, cy, ky = _modes(modes_y)
    w, _ = _all_modes(modes_x, modes_y)
    m = np.concatenate([mx, my])
    c = np.concatenate([cx, cy])
    k = np.concatenate([kx, ky])
    n = m.size
    ws = float(np.exp(np.mean(np.log(w))))  # balances the ω^2 and 1 entries of A
    U = np.zeros((2, n))
    U[0, : mx.size] = 1.0
    U[1, mx.size :] = 1.0
    A0 = np.zeros((2 * n, 2 * n))
    A0[:n, n:] = ws * np.eye(n)
    A0[n:, :n] = -np.diag(k / m) / ws
    A0[n:, n:] = -np.diag(c / m)
    return _Structure(A0, (U / m).T / ws, U)


def default_intervals(modes_x, modes_y, cutting: CuttingConditions, speed_rpm) -> np.ndarray:
    """Intervals per tooth period, max(MIN_INTERVALS, ceil(INTERVALS_PER_CYCLE f_max T)); (n_speed,) int."""
    f_max = _all_modes(modes_x, modes_y)[0].max() / (2 * np.pi)
    T = cutting.tooth_period(speed_rpm)
    return np.maximum(MIN_INTERVALS, np.ceil(INTERVALS_PER_CYCLE * f_max * T - 1e-9)).astype(int)


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
# discretisation of the cutting process
@dataclass(frozen=True)
class _Discretisation:
    period_factor: float  # principal period = period_factor * 60/n_rpm
    m: int  # intervals per principal period
    h_total: np.ndarray  # (m, 2, 2) Pa, interval averages summed over the teeth
    groups: tuple  # ((H_l (m,2,2), r_l, f_l), ...) per distinct delay
    L: int  # memory length (past tip displacements kept)


def _discretise(cutting: CuttingConditions, m_tooth: int) -> _Discretisation:
    N = cutting.flutes
    if cutting.equal_pitch:
        m = int(m_tooth)
        dphi = 2 * np.pi / (N * m)
        start = dphi * np.arange(m)
        H = interval_directional_matrices(cutting, start, start + dphi)
        return _Discretisation(1.0 / N, m, H, ((H, m, 0.0),), m)
    m = int(m_tooth) * N
    dphi = 2 * np.pi / m
    start = dphi * np.arange(m)
    pitches = cutting.pitches
    groups = []
    total = np.zeros((m, 2, 2))
    L = 0
    for p in np.unique(np.round(pitches, 12)):
        teeth = [j for j in range(N) if abs(pitches[j] - p) < 1e-9]
        H = interval_directional_matrices(cutting, start, start + dphi, teeth=teeth)
        total += H
        lag = p / dphi  # the delay in intervals does not depend on the speed
        r = int(np.floor(lag + 1e-9))
        f = lag - r if lag - r > 1e-9 else 0.0
        if r < 2:
            raise SetupError(f"pitch {p:.4g} rad spans fewer than 2 intervals; increase intervals")
        groups.append((H, r, f))
        L = max(L, r + (1 if f > 0 else 0))
    return _Discretisation(1.0, m, total, tuple(groups), L)


@dataclass(frozen=True)
class _Steps:
    """Per-interval maps of a batch: y_{i+1} = P_i y_i + W_i (q_{i-k_hi}, ..., q_{i-k_lo}).

    Arrays keep the batch axis last: on stacks of 4 x 4 matrices the products
    are memory bound, and contiguous batch vectors halve the traffic.  The
    lags k_lo..k_hi form one contiguous block so that the delayed values are
    one slice of the history buffer.
    """

    P: np.ndarray  # (m, 2n, 2n, G)
    W: np.ndarray  # (m, 2n, 2 (k_hi - k_lo + 1), G), columns from lag k_hi down to k_lo
    k_lo: int
    k_hi: int
    n: int
    L: int
    U: np.ndarray

    @property
    def dim(self) -> int:
        return 2 * self.n + 2 * self.L

    @property
    def size(self) -> int:
        return self.P.shape[-1]

    def subset(self, idx) -> "_Steps":
        return _Steps(self.P[..., idx], self.W[..., idx], self.k_lo, self.k_hi, self.n, self.L, self.U)


def _steps(struct: _Structure, disc: _Discretisation, speed: np.ndarray, depth: np.ndarray) -> _Steps:
    n = struct.U.shape[1]
    T = disc.period_factor * 60.0 / speed
    dt = T / disc.m
    a = depth[:, None, None, None]
    # regenerative stiffness per unit depth on the scaled velocity rows: (m, n, n)
    FHU = np.einsum("ia,mab,bj->mij", struct.force_rows, disc.h_total, struct.U)
    A = np.broadcast_to(struct.A0, (depth.size, disc.m, 2 * n, 2 * n)).copy()
    A[..., n:, :n] += a * FHU[None]
    P, G0, G1 = phi_functions(A, np.broadcast_to(dt[:, None], (depth.size, disc.m)))
    inv_dt = (1.0 / dt)[:, None, None, None]
    Ga = (G0 - G1 * inv_dt)[..., :, n:]  # weight of the delayed value at the interval start
    Gb = (G1 * inv_dt)[..., :, n:]  # ... and at its end (only velocity columns meet B)
    lags: dict[int, np.ndarray] = {}
    for H, r, f in disc.groups:
        FH = -np.einsum("ia,mab->mib", struct.force_rows, H)  # (m, n, 2): B / a, velocity rows
        Ra = np.einsum("gmij,mjb->gmib", Ga, FH) * a
        Rb = np.einsum("gmij,mjb->gmib", Gb, FH) * a
        # q(t_i - τ) = (1-f) q_{i-r} + f q_{i-r-1};  q(t_{i+1} - τ) = (1-f) q_{i-r+1} + f q_{i-r}
        for lag, w in ((r, (1 - f) * Ra + f * Rb), (r - 1, (1 - f) * Rb), (r + 1, f * Ra)):
            if lag != r + 1 or f > 0:
                lags[lag] = lags[lag] + w if lag in lags else w
    k_lo, k_hi = min(lags), max(lags)
    W = np.zeros((disc.m, 2 * n, 2 * (k_hi - k_lo + 1), depth.size))
    for lag, w in lags.items():
        c = 2 * (k_hi - lag)
        W[:, :, c : c + 2] = w.transpose(1, 2, 3, 0)
    return _Steps(np.ascontiguousarray(P.transpose(1, 2, 3, 0)), W, k_lo, k_hi, n, disc.L, struct.U)


def _apply(steps: _Steps, V: np.ndarray) -> np.ndarray:
    """Φ V for a batch: V (d, b, G) -> (d, b, G), by m structured steps."""
    d, b, G = V.shape
    n2, L, m = 2 * steps.n, steps.L, steps.P.shape[0]
    # history buffer: slot L + i - k holds q_{i-k}; the initial memory fills slots 0..L-1
    hist = np.empty((L + m, 2, b, G))
    hist[:L] = V[n2:].reshape(L, 2, b, G)[::-1]
    Y = V[:n2]
    width = steps.k_hi - steps.k_lo + 1
    for i in range(m):
        lo = L + i - steps.k_hi
        delayed = hist[lo : lo + width].reshape(2 * width, b, G)
        Ynew = np.einsum("ijg,jbg->ibg", steps.P[i], Y)
        Ynew += np.einsum("ijg,jbg->ibg", steps.W[i], delayed)
        hist[L + i] = np.einsum("ij,jbg->ibg", steps.U, Y[: steps.n])
        Y = Ynew
    mem = hist[m : L + m][::-1].reshape(2 * L, b, G)  # q_{m-1}, ..., q_{m-L}
    return np.concatenate([Y, mem], axis=0)


def _explicit(steps: _Steps) -> np.ndarray:
    """(G, d, d) monodromy matrices of the batch."""
    d = steps.dim
    eye = np.broadcast_to(np.eye(d)[:, :, None], (d, d, steps.size))
    return np.ascontiguousarray(_apply(steps, eye).transpose(2, 0, 1))


def _arnoldi_radius(steps: _Steps, krylov: int, rng: np.random.Generator):
    """Dominant Ritz modulus and a convergence flag per batch point."""
    G, d = steps.size, steps.dim
    k = min(krylov, d)
    V = np.zeros((k + 1, d, G))
    H = np.zeros((G, k + 1, k))
    v0 = rng.standard_normal(d)
    V[0] = (v0 / np.linalg.norm(v0))[:, None]
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
    theta, S = np.linalg.eig(H[:, :k, :k])
    i = np.argmax(np.abs(theta), axis=1)
    rows = np.arange(G)
    rho = np.abs(theta[rows, i])
    resid = np.abs(H[:, k, k - 1]) * np.abs(S[rows, k - 1, i])
    converged = resid <= _RITZ_TOL * np.maximum(rho, 1e-12)
    return rho, converged


def _radius_batch(steps: _Steps, solver: str, krylov: int, rng) -> np.ndarray:
    if solver == "eig":
        return np.max(np.abs(np.linalg.eigvals(_explicit(steps))), axis=-1)
    rho = np.empty(steps.size)
    todo = np.arange(steps.size)
    k = krylov
    while todo.size:
        sub = steps if todo.size == steps.size else steps.subset(todo)
        if k >= sub.dim:  # a full Krylov space costs more than the dense eigenvalues
            rho[todo] = np.max(np.abs(np.linalg.eigvals(_explicit(sub))), axis=-1)
            break
        r, ok = _arnoldi_radius(sub, k, rng)
        rho[todo[ok]] = r[ok]
        todo = todo[~ok]
        k *= 2  # the few unconverged points get a larger Krylov space
    return rho


# ----------------------------------------------------------------------------------------
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
    (G, d, d), d = 2 n + 2 L, in the scaled state (ξ, ξ'/ω_s, q_{-1}, ..., q_{-L}).
    """
    struct = _structure(modes_x, modes_y)
    disc = _discretise(cutting, intervals)
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    depth = np.atleast_1d(np.asarray(depth_m, dtype=float))
    return _explicit(_steps(struct, disc, speed, depth))


def spectral_radius(
    modes_x,
    modes_y,
    cutting: CuttingConditions,
    speed_rpm,
    depth_m,
    intervals,
    solver: str = "arnoldi",
    krylov: int = 14,
    chunk: int = 2048,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """ρ(Φ) for paired (speed, depth) points, (G,).

    ``intervals`` is one int or one per point; points sharing m are batched.
    ``rng`` draws the Arnoldi start vector (default: fixed seed 0, so results
    are reproducible).
    """
    if solver not in ("arnoldi", "eig"):
        raise SetupError(f"solver={solver!r}: expected 'arnoldi' or 'eig'")
    rng = np.random.default_rng(0) if rng is None else rng
    struct = _structure(modes_x, modes_y)
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    depth = np.broadcast_to(np.asarray(depth_m, dtype=float), speed.shape)
    m_all = np.broadcast_to(np.asarray(intervals, dtype=int), speed.shape)
    if np.any(m_all < 2):
        raise SetupError(f"intervals {intervals!r}: expected >= 2 per tooth period")
    rho = np.empty(speed.size)
    for m in np.unique(m_all):
        disc = _discretise(cutting, int(m))
        idx = np.nonzero(m_all == m)[0]
        # keep the batch's step matrices near 50 MB
        per_point = disc.m * (2 * struct.U.shape[1]) ** 2 * 8 * 6
        size = int(max(16, min(chunk, 50e6 // per_point)))
        for s in range(0, idx.size, size):
            sel = idx[s : s + size]
            steps = _steps(struct, disc, speed[sel], depth[sel])
            rho[sel] = _radius_batch(steps, solver, krylov, rng)
    return rho


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
