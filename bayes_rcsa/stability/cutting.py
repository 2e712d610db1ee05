"""Cutting model of peripheral milling for chatter stability: conditions and directional factors.

Axis and sign convention
------------------------
All vectors live in the machine's X-Y plane seen from the spindle, looking
along the tool axis towards the tool tip (X to the right, Y up).  The cutter
turns clockwise in this view (a right-hand cutter on M03).  ``q = (q_x, q_y)``
is the displacement of the tool tip relative to the (rigid) workpiece and
``F = (F_x, F_y)`` the cutting force acting on the tool.

The cutting mechanics are written in the *feed frame*: axis 1 along the feed
(the direction the tool advances), axis 2 obtained by turning axis 1 by +90°
(counter-clockwise in the view above).  The immersion angle φ of a tooth is
measured clockwise from axis 2, so a tooth at φ = π/2 points along the feed.
With ``feed='x'`` the feed frame is the machine frame (Altintas' textbook
convention); with ``feed='y'`` axis 1 is +Y and axis 2 is −X.  The
directional matrices returned here are already rotated to the machine frame,
so they multiply machine-frame displacements and give machine-frame forces.

A tooth at angle φ removes the chip ``h = f_z sin φ + (Δq_1 sin φ + Δq_2 cos φ)``
(feed frame, Δq = q(t) − q(t − τ)) when ``φ_entry < φ < φ_exit``; the
tangential and radial forces are ``F_t = K_t a h`` and ``F_r = K_r a h`` with
the axial depth ``a``.  The regenerative part of the force is therefore
``F = a H(φ) Δq`` with, in the feed frame,

    H(φ) = [[-(K_t cos φ + K_r sin φ) sin φ, -(K_t cos φ + K_r sin φ) cos φ],
            [ (K_t sin φ - K_r cos φ) sin φ,  (K_t sin φ - K_r cos φ) cos φ]]     (Pa)

This is Altintas' ``(K_t/2)[A(φ)]`` (Manufacturing Automation, 2nd ed., ch. 3).
The helix angle is neglected (straight flutes), as in the zero-order and
semi-discretisation models of the paper being reproduced.

Radial immersion
----------------
``radial_immersion`` is the radial depth of cut divided by the tool diameter
(1.0 = slotting).  Up milling: φ_entry = 0, φ_exit = arccos(1 − 2 r).
Down milling: φ_entry = arccos(2 r − 1), φ_exit = π.  Alternatively the
entry and exit angles may be given directly (radians, 0 ≤ φ_entry < φ_exit ≤ π).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError

__all__ = [
    "CuttingConditions",
    "tooth_matrix",
    "directional_matrix",
    "mean_directional_matrix",
    "interval_directional_matrices",
]

_MILLING = ("up", "down")
_FEED = ("x", "y")


@dataclass(frozen=True)
class CuttingConditions:
    """Process parameters of a milling cut that matter for regenerative chatter.

    Attributes
    ----------
    kt, kr : float, Pa
        Tangential and radial cutting-force coefficients (N/m^2), > 0 and >= 0.
    flutes : int
        Number of teeth N >= 1.
    radial_immersion : float or None
        Radial depth of cut / tool diameter, in (0, 1]; required unless both
        ``entry_angle`` and ``exit_angle`` are given.
    milling : {"down", "up"}
        Down (climb) or up (conventional) milling; used with ``radial_immersion``.
    entry_angle, exit_angle : float or None, rad
        Explicit immersion angles (clockwise from the feed-normal axis); when
        given they override ``radial_immersion``/``milling``.
    feed : {"x", "y"}
        Machine axis along which the tool advances (default "x").
    pitch_angles : tuple of float or None, rad
        Angular spacing to each tooth from the tooth ahead of it, summing to
        2π (variable pitch).  ``None`` means equal pitch 2π/N.
    """

    kt: float
    kr: float
    flutes: int
    radial_immersion: float | None = None
    milling: str = "down"
    entry_angle: float | None = None
    exit_angle: float | None = None
    feed: str = "x"
    pitch_angles: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        for name in ("kt", "kr"):
            v = getattr(self, name)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
                raise SetupError(f"cutting coefficient {name}={v!r}: expected a finite number in Pa")
        if self.kt <= 0 or self.kr < 0:
            raise SetupError(f"cutting coefficients kt={self.kt!r} Pa, kr={self.kr!r} Pa: expected kt > 0 and kr >= 0")
        if int(self.flutes) != self.flutes or self.flutes < 1:
            raise SetupError(f"flutes={self.flutes!r}: expected an integer >= 1")
        object.__setattr__(self, "flutes", int(self.flutes))
        if self.milling not in _MILLING:
            raise SetupError(f"milling={self.milling!r}: expected one of {_MILLING}")
        if self.feed not in _FEED:
            raise SetupError(f"feed={self.feed!r}: expected one of {_FEED}")
        explicit = self.entry_angle is not None or self.exit_angle is not None
        if explicit:
            if self.entry_angle is None or self.exit_angle is None:
                raise SetupError("entry_angle and exit_angle must be given together (radians)")
            a, b = float(self.entry_angle), float(self.exit_angle)
            if not (math.isfinite(a) and math.isfinite(b) and 0.0 <= a < b <= math.pi + 1e-12):
                raise SetupError(
                    f"entry/exit angles {a!r}, {b!r} rad: expected 0 <= entry < exit <= pi"
                )
        else:
            r = self.radial_immersion
            if r is None or not math.isfinite(r) or not (0.0 < r <= 1.0):
                raise SetupError(
                    f"radial_immersion={r!r}: expected radial depth / tool diameter in (0, 1] (1 = slotting)"
                )
        if self.pitch_angles is not None:
            p = np.asarray(self.pitch_angles, dtype=float)
            if p.shape != (self.flutes,) or not np.all(np.isfinite(p)) or np.any(p <= 0):
                raise SetupError(
                    f"pitch_angles {self.pitch_angles!r}: expected {self.flutes} positive angles in rad"
                )
            if abs(p.sum() - 2 * math.pi) > 1e-9:
                raise SetupError(f"pitch_angles sum to {p.sum():.12g} rad, expected 2*pi")
            object.__setattr__(self, "pitch_angles", tuple(float(v) for v in p))

    # -- derived geometry ---------------------------------------------------------------
    @property
    def angles(self) -> tuple[float, float]:
        """(φ_entry, φ_exit) in rad."""
        if self.entry_angle is not None:
            return float(self.entry_angle), float(self.exit_angle)
        r = float(self.radial_immersion)
        if self.milling == "up":
            return 0.0, math.acos(1.0 - 2.0 * r)
        return math.acos(2.0 * r - 1.0), math.pi

    @property
    def equal_pitch(self) -> bool:
        """True when all teeth are equally spaced."""
        if self.pitch_angles is None:
            return True
        return bool(np.allclose(self.pitch_angles, 2 * math.pi / self.flutes, rtol=0, atol=1e-12))

    @property
    def pitches(self) -> np.ndarray:
        """(N,) rad: angle from each tooth to the tooth ahead of it (its delay is pitch/Ω)."""
        if self.pitch_angles is None:
            return np.full(self.flutes, 2 * math.pi / self.flutes)
        return np.asarray(self.pitch_angles, dtype=float)

    @property
    def tooth_offsets(self) -> np.ndarray:
        """(N,) rad: angular position of each tooth at t = 0 (tooth j = 0 at 0)."""
        # Tooth j trails tooth j-1 by pitches[j]; the tooth ahead sits at a larger angle.
        p = self.pitches
        return -np.concatenate(([0.0], np.cumsum(p[1:])))

    @property
    def rotation(self) -> np.ndarray:
        """(2, 2) R with q_feed = R q_machine."""
        if self.feed == "x":
            return np.eye(2)
        # feed along +Y: axis 1 = +Y, axis 2 = -X
        return np.array([[0.0, 1.0], [-1.0, 0.0]])

    def tooth_period(self, speed_rpm) -> np.ndarray:
        """Mean tooth-passing period 60/(N n) in s."""
        return 60.0 / (self.flutes * np.asarray(speed_rpm, dtype=float))


def _feed_frame_matrix(kt: float, kr: float, s, c) -> np.ndarray:
    """(..., 2, 2) H of one tooth in the feed frame from sin/cos of its angle."""
    out = np.empty(np.shape(s) + (2, 2))
    g = kt * c + kr * s
    e = kt * s - kr * c
    out[..., 0, 0] = -g * s
    out[..., 0, 1] = -g * c
    out[..., 1, 0] = e * s
    out[..., 1, 1] = e * c
    return out


def _to_machine(cutting: CuttingConditions, h_feed: np.ndarray) -> np.ndarray:
    r = cutting.rotation
    return r.T @ h_feed @ r


def tooth_matrix(cutting: CuttingConditions, phi) -> np.ndarray:
    """Directional matrix of one tooth at angle ``phi`` while it cuts, machine frame.

    Parameters
    ----------
    phi : (...) rad

    Returns
    -------
    (..., 2, 2) Pa, zero where the tooth is outside [φ_entry, φ_exit].
    """
    phi = np.mod(np.asarray(phi, dtype=float), 2 * np.pi)
    a, b = cutting.angles
    inside = (phi >= a) & (phi < b)  # half-open: a tooth leaving and one entering are not both counted
    h = _feed_frame_matrix(cutting.kt, cutting.kr, np.sin(phi), np.cos(phi)) * inside[..., None, None]
    return _to_machine(cutting, h)


def directional_matrix(cutting: CuttingConditions, rotation_angle) -> np.ndarray:
    """Instantaneous directional matrix summed over all teeth.

    Parameters
    ----------
    rotation_angle : (...) rad, angle Ω t turned by the cutter since t = 0.

    Returns
    -------
    (..., 2, 2) Pa: F = a H (q(t) - q(t - τ)) for equal pitch.
    """
    ang = np.asarray(rotation_angle, dtype=float)[..., None] + cutting.tooth_offsets
    return tooth_matrix(cutting, ang).sum(axis=-3)


def _antiderivative(cutting: CuttingConditions, phi: np.ndarray) -> np.ndarray:
    """(..., 2, 2) ∫_0^φ H dφ of one tooth in the feed frame (no entry/exit gating)."""
    s2 = np.sin(phi) ** 2 / 2.0  # ∫ sin cos
    iss = phi / 2.0 - np.sin(2 * phi) / 4.0  # ∫ sin^2
    icc = phi / 2.0 + np.sin(2 * phi) / 4.0  # ∫ cos^2
    kt, kr = cutting.kt, cutting.kr
    out = np.empty(np.shape(phi) + (2, 2))
    out[..., 0, 0] = -(kt * s2 + kr * iss)
    out[..., 0, 1] = -(kt * icc + kr * s2)
    out[..., 1, 0] = kt * iss - kr * s2
    out[..., 1, 1] = kt * s2 - kr * icc
    return out


def _gated_integral(cutting: CuttingConditions, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """∫_lo^hi g(φ) H(φ) dφ of one tooth (feed frame), hi - lo <= 2π, any real lo."""
    a, b = cutting.angles
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    base = np.floor(lo / (2 * np.pi)) * 2 * np.pi
    lo0, hi0 = lo - base, hi - base  # lo0 in [0, 2π), hi0 < 4π
    total = np.zeros(lo.shape + (2, 2))
    for shift in (0.0, 2 * np.pi):
        u = np.clip(lo0, a + shift, b + shift)
        v = np.clip(hi0, a + shift, b + shift)
        total += _antiderivative(cutting, v - shift) - _antiderivative(cutting, u - shift)
    return total


def mean_directional_matrix(cutting: CuttingConditions) -> np.ndarray:
    """Average over one revolution of the directional matrix summed over the teeth.

    H0 = (N / 2π) ∫_{φ_entry}^{φ_exit} H(φ) dφ, machine frame (Pa).  Each tooth
    contributes the same average whatever the pitch.  This is the zero-order
    (Altintas-Budak) matrix: H0 = N K_t/(4π) [α] in the textbook's notation.

    Returns
    -------
    (2, 2) Pa
    """
    a, b = cutting.angles
    h = _antiderivative(cutting, np.array(b)) - _antiderivative(cutting, np.array(a))
    return _to_machine(cutting, cutting.flutes / (2 * np.pi) * h)


def interval_directional_matrices(cutting: CuttingConditions, start_angle, stop_angle, teeth=None) -> np.ndarray:
    """Exact average of the summed directional matrix over cutter-rotation intervals.

    Parameters
    ----------
    start_angle, stop_angle : (n,) rad, cutter rotation Ω t at the interval ends
        (stop > start, stop - start <= 2π).
    teeth : sequence of int or None
        Sum only over these teeth (default all).

    Returns
    -------
    (n, 2, 2) Pa: (1/Δφ) ∫ Σ_j g_j H(φ_j) dφ, machine frame.
    """
    lo = np.asarray(start_angle, dtype=float)
    hi = np.asarray(stop_angle, dtype=float)
    idx = range(cutting.flutes) if teeth is None else teeth
    off = cutting.tooth_offsets
    acc = np.zeros(lo.shape + (2, 2))
    for j in idx:  # N <= a handful; vectorised over intervals
        acc += _gated_integral(cutting, lo + off[j], hi + off[j])
    acc /= (hi - lo)[..., None, None]
    return _to_machine(cutting, acc)
