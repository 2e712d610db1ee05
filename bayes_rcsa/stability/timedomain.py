"""Time-domain simulation of regenerative milling, an independent check of the lobe solvers.

The modal tool of :mod:`~bayes_rcsa.stability.sdm` (unit participation, X and
Y modes) is integrated with the classical fourth-order Runge-Kutta scheme.
Each tooth j cuts the chip

    h_j = g_j [ f_z sin φ_j + (q(t) - q(t - τ_j)) · (sin φ_j, cos φ_j) ]      (feed frame)

and pushes the tool with F = a h_j (-(K_t cos φ_j + K_r sin φ_j), K_t sin φ_j - K_r cos φ_j)
(feed frame, rotated to the machine frame), see
:mod:`~bayes_rcsa.stability.cutting`.  With ``nonlinear=True`` the chip is
set to zero when h_j < 0 (the tooth leaves the cut); the default linear model
keeps the regenerative equation exactly linear, so the growth of a
perturbation measures the largest Floquet multiplier.

Nothing here is shared with the semi-discretisation: the delay is resolved
on the integration grid (cubic Hermite interpolation of the stored tip
displacement and velocity at the RK half steps), the directional factors are
evaluated pointwise, and stability is read from the simulated motion:

* the state is sampled once per principal period T (tooth period, or the
  revolution for variable pitch); for a stable cut the samples converge to
  the forced periodic motion, so the differences d_k = s_{k+1} - s_k decay;
* the growth per period is exp(slope) of a least-squares line through
  log ||d_k|| over the second half of the run; chatter if it exceeds 1
  (linear model) or if the differences keep more than ``1e-3`` of the
  forced amplitude at the end (nonlinear model).

All probe points are integrated together: with a common number of steps per
period the cutter angle at every step is the same for all of them, only the
step length differs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from .cutting import CuttingConditions

__all__ = ["TimeDomainResult", "simulate_milling"]


@dataclass(frozen=True)
class TimeDomainResult:
    """Outcome of :func:`simulate_milling` for each probe point.

    Attributes
    ----------
    speed_rpm, depth_m : (n_case,)
    growth : (n_case,) estimated growth of a perturbation per principal period (≈ ρ(Φ))
    residual : (n_case,) RMS |d_k| over the last quarter / RMS tip amplitude (dimensionless)
    chatter : (n_case,) bool
    samples : (n_case, n_period, 2) m, tip displacement (X, Y) once per principal period
    steps_per_period : int
    """

    speed_rpm: np.ndarray
    depth_m: np.ndarray
    growth: np.ndarray
    residual: np.ndarray
    chatter: np.ndarray
    samples: np.ndarray
    steps_per_period: int


def _modal(modes_x, modes_y):
    parts = [(mm, d) for mm, d in ((modes_x, 0), (modes_y, 1)) if mm is not None]
    if not parts:
        raise SetupError("at least one of modes_x, modes_y must be given")
    w = np.concatenate([mm.omega for mm, _ in parts])
    z = np.concatenate([mm.damping_ratio for mm, _ in parts])
    m = np.concatenate([mm.mass for mm, _ in parts])
    direction = np.concatenate([np.full(mm.n_modes, d) for mm, d in parts])
    return w, z, m, direction


def simulate_milling(
    modes_x,
    modes_y,
    cutting: CuttingConditions,
    speed_rpm,
    depth_m,
    feed_per_tooth: float = 5e-5,
    periods: int = 300,
    steps_per_period: int | None = None,
    nonlinear: bool = False,
    rng: np.random.Generator | None = None,
    initial_amplitude: float = 1e-7,
) -> TimeDomainResult:
    """Simulate milling at probe points and decide stable/chatter from the motion.

    Parameters
    ----------
    modes_x, modes_y : ModalModel or None (rigid direction)
    cutting : CuttingConditions
    speed_rpm, depth_m : (n_case,) rpm, m
    feed_per_tooth : float, m
    periods : int
        Principal periods simulated (tooth periods for equal pitch).
    steps_per_period : int or None
        RK4 steps per principal period; default resolves the highest mode
        with >= 40 steps per cycle (and >= 64 per period).
    nonlinear : bool
        Zero the chip when the tooth leaves the cut.
    rng : numpy Generator for the initial perturbation (default seed 0)
    initial_amplitude : float, m, size of the random initial modal displacement

    Returns
    -------
    TimeDomainResult
    """
    rng = np.random.default_rng(0) if rng is None else rng
    speed = np.atleast_1d(np.asarray(speed_rpm, dtype=float))
    depth = np.broadcast_to(np.asarray(depth_m, dtype=float), speed.shape).copy()
    if np.any(speed <= 0) or np.any(depth < 0):
        raise SetupError("speeds must be > 0 rpm and depths >= 0 m")
    w, z, mass, direction = _modal(modes_x, modes_y)
    n = w.size
    N = cutting.flutes
    T = (60.0 / speed) / (N if cutting.equal_pitch else 1)  # principal period per case
    if steps_per_period is None:
        steps_per_period = int(max(48, np.ceil(24 * w.max() / (2 * np.pi) * T.max())))
    S = int(steps_per_period)
    h = T / S  # (n_case,)
    rev_steps = S * (N if cutting.equal_pitch else 1)  # steps per revolution
    dphi = 2 * np.pi / rev_steps
    offsets = cutting.tooth_offsets
    delays = cutting.pitches / dphi  # per tooth, in steps (speed independent)
    if np.any(delays < 1.0):
        raise SetupError("steps_per_period too small for the tooth pitch")
    phi_entry, phi_exit = cutting.angles
    R = cutting.rotation
    kt, kr = cutting.kt, cutting.kr

    def tooth_terms(step_pos):
        """Per tooth at fractional step position: gate, sin, cos (n_tooth,)."""
        ang = np.mod(step_pos * dphi + offsets, 2 * np.pi)
        g = ((ang >= phi_entry) & (ang < phi_exit)).astype(float)
        return g, np.sin(ang), np.cos(ang)

    # precompute the tooth terms at whole and half steps of one revolution
    pos = np.arange(2 * rev_steps) / 2.0
    G_, S_, C_ = (np.array(x) for x in zip(*[tooth_terms(p) for p in pos]))  # (2*rev_steps, N)

    n_steps = S * periods
    q_hist = np.zeros((n_steps + 1, speed.size, 2))  # tip displacement at grid points
    v_hist = np.zeros((n_steps + 1, speed.size, 2))  # tip velocity
    onehot = np.zeros((n, 2))
    onehot[np.arange(n), direction] = 1.0

    def tip(xi):
        return xi @ onehot

    groups = [(dly, np.nonzero(np.abs(delays - dly) < 1e-9)[0]) for dly in np.unique(np.round(delays, 9))]

    def delayed(k_pos):
        """Tip displacement at grid position k_pos - delay_j, (n_case, N, 2); zero before t = 0."""
        out = np.zeros((speed.size, N, 2))
        for dly, teeth in groups:  # one group for equal pitch
            x = k_pos - dly
            if x < 0:
                continue  # the tool had not moved yet: the surface carries no waviness
            i0 = int(np.floor(x + 1e-9))
            t = x - i0
            if t < 1e-9:
                out[:, teeth] = q_hist[i0][:, None, :]
                continue
            a0, a1 = q_hist[i0], q_hist[i0 + 1]
            b0, b1 = v_hist[i0] * h[:, None], v_hist[i0 + 1] * h[:, None]
            h00, h10, h01, h11 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2
            out[:, teeth] = (h00 * a0 + h10 * b0 + h01 * a1 + h11 * b1)[:, None, :]
        return out

    # the factors of every stage that depend on the cutter angle only, per (half) step of a revolution, and the
    # modal constants: each element is the product the stage formed itself, in the same order, so the numbers are
    # the same; the stages (four per step, thousands of steps) are then a few array operations each
    FS_ = feed_per_tooth * S_
    A_ = -(kt * C_ + kr * S_)
    B_ = kt * S_ - kr * C_
    RT, onehot_T = R.T, onehot.T
    damping = 2 * z * w
    stiffness = w**2
    depth_col = depth[:, None]

    def accel(xi, xd, qd, half_index, q=None):
        """Modal accelerations (n_case, n) at one stage (``q``: the tip displacement ``tip(xi)`` if known)."""
        g, s, c = G_[half_index], S_[half_index], C_[half_index]
        if q is None:
            q = tip(xi)  # (n_case, 2) machine frame
        dq = (q[:, None, :] - qd) @ RT  # (n_case, N, 2) feed frame
        hchip = g * (FS_[half_index] + dq[..., 0] * s + dq[..., 1] * c)
        if nonlinear:
            hchip = np.maximum(hchip, 0.0)
        force = np.empty((hchip.shape[0], 2))
        force[:, 0] = np.add.reduce(A_[half_index] * hchip, axis=1)  # ndarray.sum without its wrapper
        force[:, 1] = np.add.reduce(B_[half_index] * hchip, axis=1)
        F = depth_col * (force @ R)  # machine frame
        modal_force = F @ onehot_T  # unit participation
        return modal_force / mass - damping * xd - stiffness * xi

    xi = initial_amplitude * rng.standard_normal((speed.size, n))
    xd = np.zeros((speed.size, n))
    q_hist[0] = tip(xi)
    v_hist[0] = tip(xd)
    samples = np.empty((speed.size, periods, 2))
    states = np.empty((speed.size, periods + 1, 2 * n))
    states[:, 0] = np.concatenate([xi, xd / w], axis=1)
    hh = h[:, None]
    half_h, sixth_h = 0.5 * hh, hh / 6.0  # the step's factors as the stages formed them ((0.5 * hh) * xd, ...)
    qd2 = delayed(0)
    for k in range(n_steps):
        base = (2 * k) % (2 * rev_steps)
        # the delayed motion at the step's start is the previous step's at its end: the history it interpolates
        # (at least one step back, as delays are >= 1 step) is the same
        qd0 = qd2
        qd1 = delayed(k + 0.5)
        qd2 = delayed(k + 1.0)
        # RK4 on (xi, xd); the half-step delayed values come from the stored history
        a1 = accel(xi, xd, qd0, base, q_hist[k])
        x2, v2 = xi + half_h * xd, xd + half_h * a1
        a2 = accel(x2, v2, qd1, base + 1)
        x3, v3 = xi + half_h * v2, xd + half_h * a2
        a3 = accel(x3, v3, qd1, base + 1)
        x4, v4 = xi + hh * v3, xd + hh * a3
        a4 = accel(x4, v4, qd2, (base + 2) % (2 * rev_steps))
        xi = xi + sixth_h * (xd + 2 * v2 + 2 * v3 + v4)
        xd = xd + sixth_h * (a1 + 2 * a2 + 2 * a3 + a4)
        q_hist[k + 1] = tip(xi)
        v_hist[k + 1] = tip(xd)
        if (k + 1) % S == 0:
            p = (k + 1) // S
            samples[:, p - 1] = q_hist[k + 1]
            states[:, p] = np.concatenate([xi, xd / w], axis=1)
    diffs = np.linalg.norm(np.diff(states, axis=1), axis=-1)  # (n_case, periods)
    half = periods // 2
    t_idx = np.arange(half, periods)
    logd = np.log(np.maximum(diffs[:, half:], 1e-300))
    slope = np.polyfit(t_idx, logd.T, 1)[0]
    growth = np.exp(slope)
    quarter = periods - periods // 4
    amp = np.sqrt(np.mean(np.sum(states[:, quarter:, :] ** 2, axis=-1), axis=1))
    residual = np.sqrt(np.mean(diffs[:, quarter:] ** 2, axis=1)) / np.maximum(amp, 1e-300)
    chatter = residual > 1e-3 if nonlinear else growth > 1.0
    return TimeDomainResult(speed, depth, growth, residual, chatter, samples, S)
