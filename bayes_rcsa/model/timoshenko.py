"""Exact free-free receptances of stepped Timoshenko beams.

Each uniform segment is represented by its exact dynamic stiffness matrix,
built from the four exponential solutions of the Timoshenko equations

    (kGA (u' - psi))' + rhoA w^2 u = 0
    (EI psi')' + kGA (u' - psi) + rhoI w^2 psi = 0

with u the lateral displacement and psi the cross-section rotation (the
rotational degree of freedom coupled in RCSA; it equals du/dz in the
Euler-Bernoulli limit).  Each exponential e^{lambda z} is normalised so that
its modulus is at most one on the segment (``e^{lambda (z - L)}`` for
Re(lambda) > 0), so the construction cannot overflow however high the
frequency or long the segment.  Segments are joined rigidly by assembling
the global dynamic stiffness, whose inverse gives the end receptances.

DOF order at every node: (u, psi); work-conjugate generalised forces (F, M).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import SetupError
from .sections import SectionProperties

__all__ = ["Segment", "TwoPort", "segment_dynamic_stiffness", "stepped_beam_dynamic_stiffness", "free_free_receptances"]


@dataclass(frozen=True)
class Segment:
    """A uniform beam segment.

    Parameters
    ----------
    length : float
        m, > 0.
    section : SectionProperties
    """

    length: float
    section: SectionProperties

    def __post_init__(self) -> None:
        if not (np.isfinite(self.length) and self.length > 0):
            raise SetupError(f"segment length {self.length!r} m: expected a finite value > 0")


@dataclass(frozen=True)
class TwoPort:
    """Receptances between the two ends of a substructure.

    Each attribute is a complex array of shape ``(..., n_freq, 2, 2)`` in the
    block convention ``[[h, l], [n, p]]``: ``r12`` maps the generalised force
    at end 2 to the displacement/rotation at end 1.
    """

    r11: np.ndarray
    r12: np.ndarray
    r21: np.ndarray
    r22: np.ndarray

    def as_matrix(self) -> np.ndarray:
        """The full ``(..., n_freq, 4, 4)`` receptance matrix, DOFs (u1, psi1, u2, psi2)."""
        top = np.concatenate([self.r11, self.r12], axis=-1)
        bottom = np.concatenate([self.r21, self.r22], axis=-1)
        return np.concatenate([top, bottom], axis=-2)

    @classmethod
    def from_matrix(cls, g: np.ndarray) -> "TwoPort":
        return cls(g[..., :2, :2], g[..., :2, 2:], g[..., 2:, :2], g[..., 2:, 2:])


def _wavenumbers(section: SectionProperties, omega: np.ndarray) -> np.ndarray:
    """The four roots lambda of the dispersion relation, shape (n_freq, 4)."""
    EI, kGA, rhoA, rhoI = section.EI, section.kGA, section.rhoA, section.rhoI
    w2 = omega.astype(complex) ** 2
    a = kGA * EI
    b = w2 * (kGA * rhoI + rhoA * EI)
    c = rhoA * w2 * (rhoI * w2 - kGA)
    disc = np.sqrt(b * b - 4 * a * c)
    # Choose the sign that avoids cancellation, then get the small root from
    # Vieta's product so both roots keep full relative precision.
    sign = np.where((np.conj(b) * disc).real >= 0, 1.0, -1.0)
    q = -0.5 * (b + sign * disc)
    s1 = q / a
    s2 = c / q
    r1, r2 = np.sqrt(s1), np.sqrt(s2)
    return np.stack([r1, -r1, r2, -r2], axis=-1)


def segment_dynamic_stiffness(segment: Segment, omega: np.ndarray) -> np.ndarray:
    """Exact dynamic stiffness of one free-free Timoshenko segment.

    Parameters
    ----------
    segment : Segment
    omega : (n_freq,) rad/s, > 0

    Returns
    -------
    (n_freq, 4, 4) complex
        Maps end displacements (u0, psi0, uL, psiL) to end forces
        (F0, M0, FL, ML), N/m, N/rad, N, N m/rad.
    """
    omega = np.asarray(omega, dtype=float)
    s = segment.section
    L = segment.length
    lam = _wavenumbers(s, omega)  # (n, 4)
    rhoA_w2 = s.rhoA * omega.astype(complex)[:, None] ** 2
    psi_amp = (s.kGA * lam**2 + rhoA_w2) / (s.kGA * lam)
    grows = lam.real >= 0
    e = np.exp(-np.abs(lam.real) * L + 1j * np.where(grows, -1.0, 1.0) * lam.imag * L)
    phi0 = np.where(grows, e, 1.0)
    phiL = np.where(grows, 1.0, e)
    shear = s.kGA * (lam - psi_amp)
    moment = s.EI * lam * psi_amp
    D = np.stack([phi0, psi_amp * phi0, phiL, psi_amp * phiL], axis=-2)
    F = np.stack([-shear * phi0, -moment * phi0, shear * phiL, moment * phiL], axis=-2)
    # K = F D^-1  <=>  D^T K^T = F^T
    return np.swapaxes(np.linalg.solve(np.swapaxes(D, -1, -2), np.swapaxes(F, -1, -2)), -1, -2)


def stepped_beam_dynamic_stiffness(segments: Sequence[Segment], omega: np.ndarray) -> np.ndarray:
    """Global dynamic stiffness of rigidly joined segments, shape (n_freq, 2N+2, 2N+2)."""
    if len(segments) == 0:
        raise SetupError("a beam needs at least one segment")
    omega = np.asarray(omega, dtype=float)
    n_dof = 2 * (len(segments) + 1)
    K = np.zeros((omega.size, n_dof, n_dof), dtype=complex)
    for i, seg in enumerate(segments):
        K[:, 2 * i : 2 * i + 4, 2 * i : 2 * i + 4] += segment_dynamic_stiffness(seg, omega)
    return K


def free_free_receptances(segments: Sequence[Segment], omega: np.ndarray) -> TwoPort:
    """End receptances of a free-free stepped Timoshenko beam.

    Parameters
    ----------
    segments : sequence of Segment
        In order from end 1 to end 2.
    omega : (n_freq,) rad/s, strictly positive (the free-free beam has rigid-body
        modes at 0 rad/s).

    Returns
    -------
    TwoPort
        Blocks of shape (n_freq, 2, 2), m/N, 1/N, rad/N, rad/(N m).
    """
    omega = np.asarray(omega, dtype=float)
    if omega.ndim != 1 or not np.all(np.isfinite(omega)) or np.any(omega <= 0):
        raise SetupError("angular frequencies must be a 1-D array of finite values > 0 rad/s")
    K = stepped_beam_dynamic_stiffness(segments, omega)
    n_dof = K.shape[-1]
    ends = [0, 1, n_dof - 2, n_dof - 1]
    rhs = np.zeros((n_dof, 4), dtype=complex)
    rhs[ends, np.arange(4)] = 1.0
    cols = np.linalg.solve(K, np.broadcast_to(rhs, K.shape[:-2] + rhs.shape))
    return TwoPort.from_matrix(cols[:, ends, :])
