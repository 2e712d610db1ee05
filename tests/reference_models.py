"""Independent reference models for the forward-model acceptance tests.

Nothing here imports the beam, section or coupling code of ``bayes_rcsa``:
the point of these models is to check the library against a different
formulation (no inverse crime).

* Sections: circular (hollow) sections with Cowper's shear coefficient,
  written out again from Cowper (1966).
* Beams: Timoshenko finite elements with the interdependent interpolation of
  Friedman & Kosmatka (1993, Comput. Struct. 47:473), whose cubic/quadratic
  shape functions solve the static Timoshenko equations exactly, so the
  element is free of shear locking; stiffness and *consistent* mass
  (translational + rotary inertia) are integrated by Gauss quadrature.
* Assemblies: a chain of nodes (u, psi per node) joined by links (beam
  elements or lumped translational/rotational springs), with optional
  grounded springs (bearings).  Because every link joins two consecutive
  nodes, the dynamic stiffness is block tridiagonal and end receptances
  follow from a sweep of 2x2 static condensations vectorised over frequency.

DOFs per node: u (lateral displacement, m) and psi (cross-section rotation,
rad, equal to du/dz in the Euler-Bernoulli limit), work-conjugate to the
force F (N) and moment M (N m).  Harmonic convention x(t) = Re{X e^{i w t}}.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import scipy.linalg


# ---------------------------------------------------------------- sections --


@dataclass(frozen=True)
class RefSection:
    """EI (N m^2, complex), kGA (N, complex), rhoA (kg/m), rhoI (kg m)."""

    EI: complex
    kGA: complex
    rhoA: float
    rhoI: float

    def __add__(self, other: "RefSection") -> "RefSection":
        return RefSection(self.EI + other.EI, self.kGA + other.kGA, self.rhoA + other.rhoA, self.rhoI + other.rhoI)


def cowper_kappa(nu: float, m: float) -> float:
    """Cowper (1966) shear coefficient of a hollow circle, m = d_inner / d_outer."""
    a = (1.0 + m * m) ** 2
    return 6.0 * (1.0 + nu) * a / ((7.0 + 6.0 * nu) * a + (20.0 + 12.0 * nu) * m * m)


def tube(E: float, rho: float, nu: float, eta: float, d_out: float, d_in: float = 0.0) -> RefSection:
    """Section of a solid (d_in = 0) or hollow circular shaft with loss factor eta."""
    area = math.pi * (d_out**2 - d_in**2) / 4.0
    inertia = math.pi * (d_out**4 - d_in**4) / 64.0
    G = E / (2.0 * (1.0 + nu))
    damp = 1.0 + 1j * eta
    return RefSection(E * damp * inertia, cowper_kappa(nu, d_in / d_out) * G * damp * area, rho * area, rho * inertia)


# ---------------------------------------------------------- beam elements --

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)
_GAUSS_X = 0.5 * (_GAUSS_X + 1.0)  # on [0, 1]
_GAUSS_W = 0.5 * _GAUSS_W


def fk_shape_functions(phi: float, h: float, xi: np.ndarray):
    """Friedman-Kosmatka interpolation at xi = z/h in [0, 1].

    Returns (Nu, Npsi, dNpsi, gamma), each (n_points, 4): displacement and
    rotation shape functions, the rotation derivative d psi/dz and the shear
    strain u' - psi per unit nodal DOF (u1, psi1, u2, psi2).
    """
    c = 1.0 / (1.0 + phi)
    x = xi[:, None]
    x2, x3 = x * x, x * x * x
    Nu = c * np.hstack([
        2 * x3 - 3 * x2 - phi * x + 1 + phi,
        h * (x3 - (2 + phi / 2) * x2 + (1 + phi / 2) * x),
        -(2 * x3 - 3 * x2 - phi * x),
        h * (x3 - (1 - phi / 2) * x2 - (phi / 2) * x),
    ])
    Npsi = c * np.hstack([
        6 * (x2 - x) / h,
        3 * x2 - (4 + phi) * x + 1 + phi,
        -6 * (x2 - x) / h,
        3 * x2 - (2 - phi) * x,
    ])
    dNpsi = c * np.hstack([
        6 * (2 * x - 1) / h**2,
        (6 * x - (4 + phi)) / h,
        -6 * (2 * x - 1) / h**2,
        (6 * x - (2 - phi)) / h,
    ])
    dNu = c * np.hstack([
        (6 * x2 - 6 * x - phi) / h,
        3 * x2 - (4 + phi) * x + 1 + phi / 2,
        -(6 * x2 - 6 * x - phi) / h,
        3 * x2 - (2 - phi) * x - phi / 2,
    ])
    return Nu, Npsi, dNpsi, dNu - Npsi


def fk_element(section: RefSection, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness (4, 4) complex and consistent mass (4, 4) real of one element.

    The interpolation parameter phi = 12 EI / (kGA h^2) uses the real moduli so
    that the mass matrix stays real when the loss factors of a composite
    section differ; the complex moduli enter the stiffness integral.
    """
    phi = 12.0 * section.EI.real / (section.kGA.real * h * h)
    Nu, Npsi, dNpsi, gamma = fk_shape_functions(phi, h, _GAUSS_X)
    w = _GAUSS_W[:, None, None] * h
    K = np.sum(w * (section.EI * dNpsi[:, :, None] * dNpsi[:, None, :]
                    + section.kGA * gamma[:, :, None] * gamma[:, None, :]), axis=0)
    M = np.sum(w * (section.rhoA * Nu[:, :, None] * Nu[:, None, :]
                    + section.rhoI * Npsi[:, :, None] * Npsi[:, None, :]), axis=0)
    return K, M


def fk_closed_form_stiffness(section: RefSection, h: float) -> np.ndarray:
    """Textbook closed form of the (shear-locking-free) Timoshenko element stiffness."""
    EI, kGA = section.EI, section.kGA
    phi = 12.0 * EI / (kGA * h * h)
    return EI / (h**3 * (1 + phi)) * np.array([
        [12, 6 * h, -12, 6 * h],
        [6 * h, (4 + phi) * h * h, -6 * h, (2 - phi) * h * h],
        [-12, -6 * h, 12, -6 * h],
        [6 * h, (2 - phi) * h * h, -6 * h, (4 + phi) * h * h],
    ])


# ----------------------------------------------------------------- chains --


@dataclass(frozen=True)
class BeamElement:
    """A beam element between two consecutive nodes."""

    K: np.ndarray  # (4, 4) complex
    M: np.ndarray  # (4, 4) real

    def dynamic_stiffness(self, omega: np.ndarray) -> np.ndarray:
        return self.K[None] - (omega**2)[:, None, None] * self.M[None]


@dataclass(frozen=True)
class ContactSprings:
    """Lumped translational (k_x + i w c_x, N/m) and rotational (k_t + i w c_t, N m/rad)
    springs between two consecutive nodes that share the same position."""

    k_x: float
    k_t: float
    c_x: float = 0.0
    c_t: float = 0.0

    def dynamic_stiffness(self, omega: np.ndarray) -> np.ndarray:
        kx = self.k_x + 1j * omega * self.c_x
        kt = self.k_t + 1j * omega * self.c_t
        D = np.zeros((omega.size, 4, 4), dtype=complex)
        for i, k in ((0, kx), (1, kt)):
            D[:, i, i] = k
            D[:, i + 2, i + 2] = k
            D[:, i, i + 2] = -k
            D[:, i + 2, i] = -k
        return D


# A grounded spring: node index -> function omega (n,) -> (n, 2, 2) complex stiffness.
Ground = dict[int, Callable[[np.ndarray], np.ndarray]]


def bearing(k_radial: complex, k_tilt: complex = 0.0) -> Callable[[np.ndarray], np.ndarray]:
    """A grounded (complex, i.e. hysteretically damped) bearing spring."""

    def stiffness(omega: np.ndarray) -> np.ndarray:
        out = np.zeros((omega.size, 2, 2), dtype=complex)
        out[:, 0, 0] = k_radial
        out[:, 1, 1] = k_tilt
        return out

    return stiffness


def mesh(segments: Sequence[tuple[float, RefSection]], h_max: float) -> tuple[list[BeamElement], list[int]]:
    """Split uniform segments (length m, section) into elements no longer than h_max.

    Returns the elements and the node index at the start of every segment
    followed by the last node index (len(segments) + 1 entries).
    """
    elements, boundaries = [], [0]
    for length, section in segments:
        n = max(1, math.ceil(length / h_max - 1e-9))
        K, M = fk_element(section, length / n)
        elements.extend(BeamElement(K, M) for _ in range(n))
        boundaries.append(boundaries[-1] + n)
    return elements, boundaries


def _inv(a: np.ndarray) -> np.ndarray:
    """Inverse of a stack (n, 2, 2) by the adjugate (numpy's batched LAPACK call
    has a large per-matrix overhead for 2x2 systems)."""
    det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    out = np.empty_like(a)
    out[:, 0, 0] = a[:, 1, 1] / det
    out[:, 1, 1] = a[:, 0, 0] / det
    out[:, 0, 1] = -a[:, 0, 1] / det
    out[:, 1, 0] = -a[:, 1, 0] / det
    return out


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of stacks of 2x2 matrices, (n, 2, 2) each."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=complex)
    for i in (0, 1):
        for k in (0, 1):
            out[:, i, k] = a[:, i, 0] * b[:, 0, k] + a[:, i, 1] * b[:, 1, k]
    return out


def _grounded(ground: Ground | None, node: int, omega: np.ndarray) -> np.ndarray | float:
    if ground and node in ground:
        return ground[node](omega)
    return 0.0


def end_point_receptance(links: Sequence, omega: np.ndarray, ground: Ground | None = None) -> np.ndarray:
    """Point receptance (n_freq, 2, 2) at the last node of a chain.

    Sweeps from the first node, condensing each node into the next:
    S_next = D_nn - D_nc (S + D_cc)^-1 D_cn.
    """
    omega = np.asarray(omega, dtype=float)
    S = np.zeros((omega.size, 2, 2), dtype=complex) + _grounded(ground, 0, omega)
    for node, link in enumerate(links, start=1):
        D = link.dynamic_stiffness(omega)
        X = S + D[:, :2, :2]
        S = D[:, 2:, 2:] - _mul(D[:, 2:, :2], _mul(_inv(X), D[:, :2, 2:]))
        S = S + _grounded(ground, node, omega)
    return _inv(S)


def end_stiffness(links: Sequence, omega: np.ndarray, ground: Ground | None = None) -> np.ndarray:
    """Dynamic stiffness (n_freq, 4, 4) between the first and last node of a chain
    (all interior nodes condensed), DOFs (u_first, psi_first, u_last, psi_last)."""
    omega = np.asarray(omega, dtype=float)
    T = links[0].dynamic_stiffness(omega).copy()
    T[:, :2, :2] += _grounded(ground, 0, omega)
    T[:, 2:, 2:] += _grounded(ground, 1, omega)
    for node, link in enumerate(links[1:], start=2):
        D = link.dynamic_stiffness(omega)
        X = T[:, 2:, 2:] + D[:, :2, :2]
        Tff, Tfc, Tcf = T[:, :2, :2], T[:, :2, 2:], T[:, 2:, :2]
        Xi = _inv(X)
        Xi_Tcf = _mul(Xi, Tcf)
        Xi_Dcn = _mul(Xi, D[:, :2, 2:])
        new = np.empty_like(T)
        new[:, :2, :2] = Tff - _mul(Tfc, Xi_Tcf)
        new[:, :2, 2:] = -_mul(Tfc, Xi_Dcn)
        new[:, 2:, :2] = -_mul(D[:, 2:, :2], Xi_Tcf)
        new[:, 2:, 2:] = D[:, 2:, 2:] - _mul(D[:, 2:, :2], Xi_Dcn) + _grounded(ground, node, omega)
        T = new
    return T


def end_receptances(links: Sequence, omega: np.ndarray, ground: Ground | None = None) -> np.ndarray:
    """Receptance matrix (n_freq, 4, 4) between the end nodes of a chain."""
    return np.linalg.inv(end_stiffness(links, omega, ground))


def global_matrices(links: Sequence[BeamElement], ground_static: dict[int, np.ndarray] | None = None):
    """Dense global stiffness (complex) and mass (real) of a chain of beam elements."""
    n = 2 * (len(links) + 1)
    K = np.zeros((n, n), dtype=complex)
    M = np.zeros((n, n))
    for i, e in enumerate(links):
        K[2 * i : 2 * i + 4, 2 * i : 2 * i + 4] += e.K
        M[2 * i : 2 * i + 4, 2 * i : 2 * i + 4] += e.M
    for node, k in (ground_static or {}).items():
        K[2 * node : 2 * node + 2, 2 * node : 2 * node + 2] += k
    return K, M


def natural_frequencies(links: Sequence[BeamElement], n_modes: int, skip: int = 0,
                        ground_static: dict[int, np.ndarray] | None = None,
                        clamped_nodes: Sequence[int] = ()) -> np.ndarray:
    """Undamped natural frequencies, rad/s, modes ``skip .. skip + n_modes - 1``.

    Uses the real parts of the stiffness (undamped structure); ``skip`` drops
    rigid-body modes of free structures; ``clamped_nodes`` have both DOFs
    removed (u = psi = 0).
    """
    K, M = global_matrices(links, ground_static)
    keep = np.setdiff1d(np.arange(K.shape[0]), [2 * n + i for n in clamped_nodes for i in (0, 1)])
    K, M = K.real[np.ix_(keep, keep)], M[np.ix_(keep, keep)]
    lam = scipy.linalg.eigh(K, M, eigvals_only=True, subset_by_index=[0, skip + n_modes - 1])
    return np.sqrt(np.abs(lam[skip:]))


# ------------------------------------------------ spindle-holder-tool model --


@dataclass(frozen=True)
class RefMaterial:
    E: float
    rho: float
    nu: float
    eta: float

    def section(self, d_out: float, d_in: float = 0.0) -> RefSection:
        return tube(self.E, self.rho, self.nu, self.eta, d_out, d_in)


# Materials and geometry of docs/setup.example.toml (ER32 collet chuck and a
# 7.94 mm carbide end mill, Table 1 of Zhao et al. 2024), restated here so that
# the reference does not go through the library's setup/geometry code.
STEEL = RefMaterial(200e9, 7850.0, 0.29, 0.002)
CARBIDE = RefMaterial(580e9, 14500.0, 0.22, 0.001)
HOLDER_SEGMENTS = ((0.020, 0.063, 0.0), (0.0595, 0.050, 0.00794))  # flange -> tip: length, d_out, d_in
TOOL_TOTAL = 0.1016
TOOL_SEGMENTS = ((0.030, 0.00794, 0.80), (0.0716, 0.00794, 1.0))  # tip -> shank: length, d, diameter ratio


@dataclass(frozen=True)
class SpindleShaft:
    """A hollow spindle shaft on two hysteretically damped spring bearings.

    Node 0 is the rear end, the last node the flange (front end) where the
    holder is attached.  ``segments`` are (length, section) from rear to front;
    bearings act at the segment boundaries listed in ``bearings``
    (boundary index -> (k_radial, k_tilt)).
    """

    segments: tuple[tuple[float, RefSection], ...]
    bearings: dict[int, tuple[complex, complex]]
    h_max: float = 0.005

    def links(self) -> tuple[list[BeamElement], Ground]:
        elements, boundaries = mesh(self.segments, self.h_max)
        ground = {boundaries[b]: bearing(*k) for b, k in self.bearings.items()}
        return elements, ground

    def flange_receptance(self, omega: np.ndarray) -> np.ndarray:
        """(n_freq, 2, 2) point receptance at the flange."""
        links, ground = self.links()
        return end_point_receptance(links, omega, ground)


def default_spindle() -> SpindleShaft:
    """A plausible spindle: 0.35 m hollow steel shaft (70/35 mm), rear bearing at
    50 mm, front bearing 30 mm behind the flange; bearing loss factor 0.05."""
    sec = STEEL.section(0.070, 0.035)
    eta_b = 0.05
    return SpindleShaft(
        segments=((0.050, sec), (0.270, sec), (0.030, sec)),
        bearings={1: (1.5e8 * (1 + 1j * eta_b), 2e5 * (1 + 1j * eta_b)),
                  2: (4.0e8 * (1 + 1j * eta_b), 1e6 * (1 + 1j * eta_b))},
    )


SegmentList = list[tuple[float, RefSection]]


def holder_tool_segments(clamping_length: float) -> tuple[SegmentList, SegmentList]:
    """Holder segments (clamped shank merged) flange -> holder tip, and tool
    overhang segments holder tip -> tool tip, for the example geometry.

    The clamped length lies inside the bore segment and inside the shank (true
    for clamping lengths below 59.5 mm and 71.6 mm).
    """
    (l1, d1o, d1i), (l2, d2o, d2i) = HOLDER_SEGMENTS
    (lf, df, rf), (ls, ds, rs) = TOOL_SEGMENTS
    assert clamping_length < min(l2, ls)
    holder = [
        (l1, STEEL.section(d1o, d1i)),
        (l2 - clamping_length, STEEL.section(d2o, d2i)),
        (clamping_length, STEEL.section(d2o, d2i) + CARBIDE.section(ds * rs)),
    ]
    overhang = [
        (ls - clamping_length, CARBIDE.section(ds * rs)),
        (lf, CARBIDE.section(df * rf)),
    ]
    return holder, overhang


def full_assembly_tool_point(spindle: SpindleShaft, clamping_length: float, contact: ContactSprings,
                             omega: np.ndarray, h_max: float = 0.002) -> np.ndarray:
    """Tool-point 2x2 receptance (n_freq, 2, 2) of one FE model of spindle shaft,
    holder (with clamped shank), lumped contact springs and tool overhang."""
    spindle_links, ground = spindle.links()
    holder, overhang = holder_tool_segments(clamping_length)
    holder_links, _ = mesh(holder, h_max)
    tool_links, _ = mesh(overhang, h_max)
    links = [*spindle_links, *holder_links, contact, *tool_links]
    return end_point_receptance(links, omega, ground)


def richardson(coarse, fine, order: int = 2):
    """Richardson extrapolation of results on meshes h and h/2 converging as h^order."""
    factor = 2.0**order
    return (factor * np.asarray(fine) - np.asarray(coarse)) / (factor - 1.0)
