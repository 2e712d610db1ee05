"""Finite-element assembly of the rotor bench: beams, springs, dampers and rigid bodies.

A :class:`Structure` collects global matrices of a planar bending model
(one lateral direction at a time) as dense arrays:

* ``K`` — real (elastic) stiffness, N/m, N/rad, N m/rad;
* ``D`` — hysteretic stiffness (imaginary part of the complex stiffness,
  ``K + iD``): loss factors of the materials and joints;
* ``C`` — viscous damping (bearings, contact, housing mounts), N s/m ...;
* ``M`` — mass, kg, kg m, kg m^2.

Equation of motion in the harmonic convention ``x(t) = Re{X e^{+iωt}}``:
``(K + iD + iωC − ω²M) X = F``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .elements import element_mass, element_stiffness
from .sections import BeamSection

__all__ = ["Structure", "mesh_points"]


def mesh_points(breaks, max_size: float) -> np.ndarray:
    """Node coordinates containing every break point, no element longer than ``max_size``.

    Parameters
    ----------
    breaks : sequence of float, m
        Coordinates that must be nodes (sorted or not; duplicates merged
        within 1e-9 m).
    max_size : float, m

    Returns
    -------
    (n_nodes,) float, m, increasing
    """
    b = np.unique(np.round(np.asarray(breaks, dtype=float), 12))
    pts = [b[0]]
    for z0, z1 in zip(b[:-1], b[1:]):
        if z1 - z0 < 1e-9:
            continue
        n = max(1, int(np.ceil((z1 - z0) / max_size - 1e-9)))
        pts.extend(z0 + (z1 - z0) * np.arange(1, n + 1) / n)
    return np.asarray(pts)


@dataclass
class Structure:
    """Dense global matrices of a planar Timoshenko model, built incrementally.

    Attributes
    ----------
    n_dof : int
    K, D, C, M : (n_dof, n_dof) float
    labels : dict of str to int
        Named degrees of freedom (e.g. ``"tip.u"``).
    """

    n_dof: int = 0
    K: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    D: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    C: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    M: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    labels: dict = field(default_factory=dict)

    def _grow(self, n: int) -> None:
        for name in ("K", "D", "C", "M"):
            old = getattr(self, name)
            new = np.zeros((self.n_dof + n, self.n_dof + n))
            new[: self.n_dof, : self.n_dof] = old
            setattr(self, name, new)
        self.n_dof += n

    def add_nodes(self, n: int) -> np.ndarray:
        """Add ``n`` nodes (u, θ each).

        Returns
        -------
        (n, 2) int
            Their dof indices ``[u, θ]``.
        """
        start = self.n_dof
        self._grow(2 * n)
        return start + np.arange(2 * n).reshape(n, 2)

    def add_beam(self, dofs: np.ndarray, z: np.ndarray, sections) -> None:
        """Timoshenko elements between consecutive nodes.

        Parameters
        ----------
        dofs : (n_nodes, 2) int
        z : (n_nodes,) float, m
        sections : sequence of BeamSection, length n_nodes − 1
        """
        for e, sec in enumerate(sections):
            L = float(z[e + 1] - z[e])
            idx = np.r_[dofs[e], dofs[e + 1]]
            Ke = element_stiffness(sec.EI, sec.kGA, L)
            phi = float((12.0 * sec.EI / (sec.kGA * L**2)).real)
            Me = element_mass(sec.rhoA, sec.rhoI, L, phi)
            ix = np.ix_(idx, idx)
            self.K[ix] += Ke.real
            self.D[ix] += Ke.imag
            self.M[ix] += Me

    def add_spring(self, dofs, coeffs, k: float = 0.0, c: float = 0.0, eta: float = 0.0) -> None:
        """A spring–damper on the relative coordinate ``s = Σ coeffs·q[dofs]``.

        Adds ``k a aᵀ`` to K, ``η k a aᵀ`` to D and ``c a aᵀ`` to C.

        Parameters
        ----------
        dofs : sequence of int
        coeffs : sequence of float
        k : float
            Stiffness (N/m or N m/rad).
        c : float
            Viscous damping (N s/m or N m s/rad).
        eta : float
            Hysteretic loss factor of the spring.
        """
        a = np.zeros(self.n_dof)
        np.add.at(a, np.asarray(dofs, dtype=int), np.asarray(coeffs, dtype=float))
        aa = np.outer(a, a)
        self.K += k * aa
        self.D += eta * k * aa
        self.C += c * aa

    def add_rigid_body(self, dofs, mass: float, inertia: float, offset: float = 0.0) -> None:
        """A rigid body attached to a node: centre at ``offset`` along z, rotary inertia about its centre.

        Parameters
        ----------
        dofs : (2,) int
            ``[u, θ]`` of the attachment node.
        mass : float, kg
        inertia : float, kg m^2 (about the centre, bending axis)
        offset : float, m
            Centre of mass relative to the node along z.
        """
        u, t = int(dofs[0]), int(dofs[1])
        e = offset
        self.M[u, u] += mass
        self.M[u, t] += mass * e
        self.M[t, u] += mass * e
        self.M[t, t] += inertia + mass * e * e

    def copy(self) -> "Structure":
        """Deep copy."""
        return Structure(self.n_dof, self.K.copy(), self.D.copy(), self.C.copy(), self.M.copy(), dict(self.labels))

    def dynamic_stiffness(self, omega: float) -> np.ndarray:
        """``K + iD + iωC − ω²M`` at one angular frequency (rad/s).

        Returns
        -------
        (n_dof, n_dof) complex
        """
        return self.K + 1j * self.D + 1j * omega * self.C - omega**2 * self.M
