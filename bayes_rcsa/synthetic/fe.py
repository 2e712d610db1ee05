"""Timoshenko beam finite elements and a banded frequency-response solver.

This is the synthetic bench's own structural model, deliberately written
apart from the RCSA forward model (:mod:`bayes_rcsa.model`): it shares only
the section properties, never the beam or coupling code, so that the two
cross-check each other.

Element
-------
Two-node Timoshenko element with the interdependent interpolation of
Friedman & Kosmatka (1993, Comput. Struct. 47:473).  Its shape functions
solve the static Timoshenko equations exactly, so the stiffness is exact
for a statically loaded uniform segment and the element does not lock in
shear.  With ``phi = 12 EI / (kGA L^2)`` the stiffness is::

    K = EI / ((1 + phi) L^3) [[ 12,   6L,          -12,  6L         ],
                              [ 6L,   (4+phi)L^2,  -6L,  (2-phi)L^2 ],
                              [-12,  -6L,           12, -6L         ],
                              [ 6L,   (2-phi)L^2,  -6L,  (4+phi)L^2 ]]

and the consistent mass (translational + rotary inertia) is the exact
integral of the same shape functions (closed form in :func:`element_mass`).
Structural damping enters through the complex moduli E(1 + i eta) of the
sections, i.e. a complex stiffness matrix; the mass matrix uses the real
``phi`` (mass is not damped).

Model
-----
An :class:`FEModel` is built from *chains* (meshed beams along the common
axis z: spindle + holder, and the tool), *joints* (spring-dampers between two
nodes or from a node to the ground: bearings, the tool-holder contact),
point masses and single-DOF resonators.  DOFs are numbered by increasing z so
that the dynamic stiffness ``Z(w) = K + i w C - w^2 M`` is banded with a small
half-bandwidth (3 for a single chain, about 7 for two parallel chains).

Solver
------
:func:`receptance` factorises the banded ``Z(w)`` by Gaussian elimination
without pivoting, one compiled pass per frequency line, and returns
the requested columns of ``Z^-1``.  The cost is ``O(n_freq n_dof p^2)`` with
half-bandwidth ``p``, instead of ``O(n_freq n_dof^3)`` for a dense solve per
line (:func:`dense_receptance`, kept as the reference).  Omitting pivoting is
safe here because every line carries structural damping, so no pivot (a
condensed dynamic stiffness of the part of the structure eliminated so far)
vanishes; the tests compare against the pivoted dense solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import ModelError, SetupError
from ..model.sections import SectionProperties

__all__ = [
    "element_stiffness",
    "element_mass",
    "mesh",
    "Chain",
    "NodeRef",
    "Joint",
    "PointMass",
    "Resonator",
    "FEModel",
    "assemble",
    "receptance",
    "dense_receptance",
]

# Nodes closer than this (m) are the same position: far below any mesh size
# yet above round-off of sums of decimal lengths.
_Z_TOL = 1e-9


def element_stiffness(length: float, section: SectionProperties) -> np.ndarray:
    """Stiffness matrix of one Timoshenko element.

    Parameters
    ----------
    length : float
        m, > 0.
    section : SectionProperties
        Complex EI (N m^2) and kGA (N) carry structural damping.

    Returns
    -------
    (4, 4) complex
        DOFs (u1, psi1, u2, psi2); N/m, N/rad, N m/rad.
    """
    L = float(length)
    EI, kGA = complex(section.EI), complex(section.kGA)
    phi = 12.0 * EI / (kGA * L * L)
    c = EI / ((1.0 + phi) * L**3)
    L2 = L * L
    return c * np.array(
        [
            [12.0, 6 * L, -12.0, 6 * L],
            [6 * L, (4 + phi) * L2, -6 * L, (2 - phi) * L2],
            [-12.0, -6 * L, 12.0, -6 * L],
            [6 * L, (2 - phi) * L2, -6 * L, (4 + phi) * L2],
        ],
        dtype=complex,
    )


def element_mass(length: float, section: SectionProperties) -> np.ndarray:
    """Consistent mass matrix of one Timoshenko element (translational + rotary).

    Parameters
    ----------
    length : float
        m, > 0.
    section : SectionProperties
        rhoA (kg/m) and rhoI (kg m); ``phi`` uses the real parts of EI, kGA.

    Returns
    -------
    (4, 4) float
        DOFs (u1, psi1, u2, psi2); kg, kg m, kg m^2.
    """
    L = float(length)
    phi = 12.0 * complex(section.EI).real / (complex(section.kGA).real * L * L)
    p2 = phi * phi
    m1 = 13 / 35 + 7 * phi / 10 + p2 / 3
    m2 = 11 / 210 + 11 * phi / 120 + p2 / 24
    m3 = 9 / 70 + 3 * phi / 10 + p2 / 6
    m4 = 13 / 420 + 3 * phi / 40 + p2 / 24
    m5 = 1 / 105 + phi / 60 + p2 / 120
    m6 = 1 / 140 + phi / 60 + p2 / 120
    L2 = L * L
    mt = section.rhoA * L / (1 + phi) ** 2 * np.array(
        [
            [m1, m2 * L, m3, -m4 * L],
            [m2 * L, m5 * L2, m4 * L, -m6 * L2],
            [m3, m4 * L, m1, -m2 * L],
            [-m4 * L, -m6 * L2, -m2 * L, m5 * L2],
        ]
    )
    r1 = 6 / 5
    r2 = 1 / 10 - phi / 2
    r3 = 2 / 15 + phi / 6 + p2 / 3
    r4 = -1 / 30 - phi / 6 + p2 / 6
    mr = section.rhoI / ((1 + phi) ** 2 * L) * np.array(
        [
            [r1, r2 * L, -r1, r2 * L],
            [r2 * L, r3 * L2, -r2 * L, r4 * L2],
            [-r1, -r2 * L, r1, -r2 * L],
            [r2 * L, r4 * L2, -r2 * L, r3 * L2],
        ]
    )
    return mt + mr


def mesh(breakpoints: Sequence[float], max_size: float) -> np.ndarray:
    """Node positions with a node at every breakpoint and elements no longer than ``max_size``.

    Parameters
    ----------
    breakpoints : sequence of float
        m; sorted and de-duplicated here (points closer than 1 nm merge).
    max_size : float
        m, > 0, the longest allowed element.

    Returns
    -------
    (n_nodes,) float, strictly increasing.
    """
    if not (math.isfinite(max_size) and max_size > 0):
        raise SetupError(f"mesh size {max_size!r} m: expected a finite value > 0")
    pts = np.unique(np.asarray(breakpoints, dtype=float))
    keep = np.concatenate([[True], np.diff(pts) > _Z_TOL])
    pts = pts[keep]
    if pts.size < 2:
        raise SetupError("a beam chain needs two distinct end positions")
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(math.ceil((b - a) / max_size - 1e-9)))
        out.append(a + (b - a) * np.arange(1, n + 1) / n)
    return np.concatenate(out)


@dataclass(frozen=True)
class Chain:
    """A meshed beam along the common axis.

    Attributes
    ----------
    name : str
    z : (n_nodes,) m, strictly increasing node positions
    sections : tuple of SectionProperties, one per element (n_nodes - 1)
    """

    name: str
    z: np.ndarray
    sections: tuple[SectionProperties, ...]

    def __post_init__(self) -> None:
        z = np.asarray(self.z, dtype=float)
        if z.ndim != 1 or z.size < 2 or np.any(np.diff(z) <= 0):
            raise SetupError(f"chain {self.name!r}: node positions must be strictly increasing (>= 2 nodes)")
        if len(self.sections) != z.size - 1:
            raise SetupError(f"chain {self.name!r}: {len(self.sections)} sections for {z.size - 1} elements")
        object.__setattr__(self, "z", z)

    def node(self, z: float) -> int:
        """Index of the node at position ``z`` (m); raises if there is none."""
        i = int(np.argmin(np.abs(self.z - z)))
        if abs(self.z[i] - z) > _Z_TOL:
            raise ModelError(f"chain {self.name!r} has no node at z = {z!r} m")
        return i


@dataclass(frozen=True)
class NodeRef:
    """A node named by its chain and position ``z`` (m)."""

    chain: str
    z: float


@dataclass(frozen=True)
class Joint:
    """Spring-damper between node ``a`` and node ``b`` (``None``: the ground).

    Attributes
    ----------
    k_u : N/m, c_u : N s/m        translational stiffness and damping
    k_psi : N m/rad, c_psi : N m s/rad   rotational stiffness and damping
    """

    a: NodeRef
    b: NodeRef | None
    k_u: float = 0.0
    c_u: float = 0.0
    k_psi: float = 0.0
    c_psi: float = 0.0


@dataclass(frozen=True)
class PointMass:
    """Mass (kg) and rotary inertia (kg m^2) attached to a node."""

    node: NodeRef
    mass: float
    rotary_inertia: float = 0.0


@dataclass(frozen=True)
class Resonator:
    """A mass (kg) on a translational spring (N/m) and damper (N s/m) hung on a node.

    It adds one DOF: the mass's own displacement.
    """

    node: NodeRef
    mass: float
    stiffness: float
    damping: float


@dataclass(frozen=True)
class FEModel:
    """Assembled matrices of a structure; DOFs numbered by increasing z.

    Attributes
    ----------
    stiffness : (n_dof, n_dof) complex, includes structural damping
    damping : (n_dof, n_dof) float, viscous damping, N s/m etc.
    mass : (n_dof, n_dof) float
    dofs : dict of chain name to (n_nodes, 2) int
        Global DOF numbers of (u, psi) at every node of every chain.
    chains : dict of chain name to Chain
    bandwidth : int
        Half-bandwidth p: entries vanish for |i - j| > p.
    """

    stiffness: np.ndarray
    damping: np.ndarray
    mass: np.ndarray
    dofs: dict
    chains: dict
    bandwidth: int

    @property
    def n_dof(self) -> int:
        return self.mass.shape[0]

    def dof(self, node: NodeRef, which: str = "u") -> int:
        """Global DOF number of ``which`` ("u" or "psi") at ``node``."""
        if node.chain not in self.chains:
            raise ModelError(f"no chain named {node.chain!r}; chains: {sorted(self.chains)}")
        if which not in ("u", "psi"):
            raise ModelError(f"DOF {which!r}: expected 'u' or 'psi'")
        chain = self.chains[node.chain]
        return int(self.dofs[node.chain][chain.node(node.z), 0 if which == "u" else 1])


def assemble(
    chains: Sequence[Chain],
    joints: Sequence[Joint] = (),
    masses: Sequence[PointMass] = (),
    resonators: Sequence[Resonator] = (),
) -> FEModel:
    """Assemble stiffness, viscous damping and mass of chains, joints, masses and resonators.

    Parameters
    ----------
    chains : sequence of Chain
        Names must be unique.
    joints, masses, resonators : sequences
        Attachments referring to chain nodes by position.

    Returns
    -------
    FEModel
    """
    by_name = {c.name: c for c in chains}
    if len(by_name) != len(chains):
        raise SetupError("chain names must be unique")
    # (z, rank, key): rank keeps the chain order at equal z, resonators last.
    entries = []
    for rank, c in enumerate(chains):
        entries += [(float(z), rank, ("node", c.name, i)) for i, z in enumerate(c.z)]
    for j, r in enumerate(resonators):
        entries.append((float(r.node.z), len(chains), ("res", j)))
    entries.sort(key=lambda e: (round(e[0] / _Z_TOL), e[1]))
    dofs = {c.name: np.empty((c.z.size, 2), dtype=int) for c in chains}
    res_dof = {}
    n = 0
    for _, _, key in entries:
        if key[0] == "node":
            dofs[key[1]][key[2]] = (n, n + 1)
            n += 2
        else:
            res_dof[key[1]] = n
            n += 1

    K = np.zeros((n, n), dtype=complex)
    C = np.zeros((n, n))
    M = np.zeros((n, n))
    for c in chains:
        d = dofs[c.name]
        for e, sec in enumerate(c.sections):
            idx = np.concatenate([d[e], d[e + 1]])
            L = c.z[e + 1] - c.z[e]
            K[np.ix_(idx, idx)] += element_stiffness(L, sec)
            M[np.ix_(idx, idx)] += element_mass(L, sec)

    def node_dofs(ref: NodeRef) -> np.ndarray:
        try:
            chain = by_name[ref.chain]
        except KeyError:
            raise ModelError(f"no chain named {ref.chain!r}") from None
        return dofs[ref.chain][chain.node(ref.z)]

    for jt in joints:
        da = node_dofs(jt.a)
        db = node_dofs(jt.b) if jt.b is not None else None
        for slot, k, cv in ((0, jt.k_u, jt.c_u), (1, jt.k_psi, jt.c_psi)):
            i = da[slot]
            K[i, i] += k
            C[i, i] += cv
            if db is not None:
                j = db[slot]
                K[j, j] += k
                C[j, j] += cv
                K[i, j] -= k
                K[j, i] -= k
                C[i, j] -= cv
                C[j, i] -= cv
    for pm in masses:
        d = node_dofs(pm.node)
        M[d[0], d[0]] += pm.mass
        M[d[1], d[1]] += pm.rotary_inertia
    for j, r in enumerate(resonators):
        i = node_dofs(r.node)[0]
        m = res_dof[j]
        M[m, m] += r.mass
        for mat, v in ((K, r.stiffness), (C, r.damping)):
            mat[i, i] += v
            mat[m, m] += v
            mat[i, m] -= v
            mat[m, i] -= v

    nz = (K != 0) | (C != 0) | (M != 0)
    rows, cols = np.nonzero(nz)
    bandwidth = int(np.max(np.abs(rows - cols))) if rows.size else 0
    return FEModel(K, C, M, dofs, dict(by_name), bandwidth)


def _check_omega(omega) -> np.ndarray:
    w = np.asarray(omega, dtype=float)
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ModelError("angular frequencies must be a non-empty 1-D array of finite values > 0 rad/s")
    return w


def _band(a: np.ndarray, p: int) -> np.ndarray:
    """Band storage ``b[i, p + j - i] = a[i, j]`` of a square matrix, shape (n, 2p + 1)."""
    n = a.shape[0]
    b = np.zeros((n, 2 * p + 1), dtype=a.dtype)
    for off in range(-p, p + 1):
        diag = np.diagonal(a, off)
        if off >= 0:
            b[: n - off, p + off] = diag
        else:
            b[-off:, p + off] = diag
    return b


def receptance(model: FEModel, omega, inputs: Sequence[int], outputs: Sequence[int]) -> np.ndarray:
    """Receptances between selected DOFs, by a banded solve per frequency line (compiled).

    Parameters
    ----------
    model : FEModel
    omega : (n_freq,) rad/s, > 0
    inputs : sequence of int
        DOFs where a unit force/moment is applied (one column each).
    outputs : sequence of int
        DOFs whose response is returned.

    Returns
    -------
    (n_freq, n_out, n_in) complex
        ``H[f, a, b]`` = response at ``outputs[a]`` per unit load at ``inputs[b]``.

    Raises
    ------
    ModelError
        A zero pivot (an unconstrained or undamped structure).
    """
    # numba (and scipy through it) loads with the first solve, not with the package
    from ._fe_kernel import banded_receptance

    w = _check_omega(omega)
    p = model.bandwidth
    kb, cb, mb = (np.ascontiguousarray(_band(m.astype(complex), p))
                  for m in (model.stiffness, model.damping, model.mass))
    inputs = np.ascontiguousarray(inputs, dtype=np.int64)
    outputs = np.ascontiguousarray(outputs, dtype=np.int64)
    out = np.empty((w.size, outputs.size, inputs.size), dtype=complex)
    if banded_receptance(kb, cb, mb, np.ascontiguousarray(w, dtype=float), inputs, outputs, out):
        raise ModelError("singular dynamic stiffness (zero pivot): is the structure constrained and damped?")
    return out


def dense_receptance(model: FEModel, omega, inputs: Sequence[int], outputs: Sequence[int]) -> np.ndarray:
    """Reference: a pivoted dense solve of ``Z(w)`` for every frequency line, one at a time.

    Same arguments and result as :func:`receptance`; ``O(n_freq n_dof^3)``.
    Used by the tests and the benchmark as the naive implementation.
    """
    w = _check_omega(omega)
    inputs = np.asarray(inputs, dtype=int)
    outputs = np.asarray(outputs, dtype=int)
    rhs = np.zeros((model.n_dof, inputs.size), dtype=complex)
    rhs[inputs, np.arange(inputs.size)] = 1.0
    out = np.empty((w.size, outputs.size, inputs.size), dtype=complex)
    for i, wi in enumerate(w):
        z = model.stiffness + 1j * wi * model.damping - wi * wi * model.mass
        out[i] = np.linalg.solve(z, rhs)[outputs]
    return out
