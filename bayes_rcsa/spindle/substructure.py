"""Free-free receptances of the artifact at its flange and at the two measurement points.

The artifact (holder + blank, rigid joint) is a stepped Timoshenko beam from
the flange (z = 0) to the blank's free end.  The segments are cut at the
measurement points so that each point is a node, the exact dynamic
stiffness of the whole beam is assembled
(:func:`bayes_rcsa.model.timoshenko.stepped_beam_dynamic_stiffness`) and
solved for unit loads at the three nodes of interest.  Cutting a uniform
segment does not change the beam: the dynamic stiffness is exact.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import SetupError
from ..model.sections import SectionProperties
from ..model.timoshenko import Segment, stepped_beam_dynamic_stiffness
from .artifact import Artifact

__all__ = ["ArtifactReceptances", "artifact_receptances", "scaled_segments"]

NODES = ("f", "1", "2")


@dataclass(frozen=True)
class ArtifactReceptances:
    """Free-free 2x2 blocks between the flange ``"f"`` and points ``"1"``, ``"2"``.

    Attributes
    ----------
    omega : (n_freq,) rad/s
    matrix : (n_freq, 6, 6) complex
        DOFs (u_f, psi_f, u_1, psi_1, u_2, psi_2); symmetric (reciprocal).
    """

    omega: np.ndarray
    matrix: np.ndarray

    def block(self, p: str, q: str) -> np.ndarray:
        """(n_freq, 2, 2) receptance from loads at ``q`` to responses at ``p``."""
        i, j = NODES.index(p), NODES.index(q)
        return self.matrix[:, 2 * i : 2 * i + 2, 2 * j : 2 * j + 2]


def _cut(segments: Sequence[Segment], positions: Sequence[float], tol: float = 1e-12) -> tuple[list[Segment], list[float]]:
    """Split ``segments`` at ``positions`` (m from end 1); return pieces and node positions."""
    cuts = sorted(set(float(p) for p in positions))
    out: list[Segment] = []
    start = 0.0
    for seg in segments:
        stop = start + seg.length
        a = start
        for c in cuts:
            if a + tol < c < stop - tol:
                out.append(Segment(c - a, seg.section))
                a = c
        out.append(Segment(stop - a, seg.section))
        start = stop
    nodes = np.concatenate([[0.0], np.cumsum([s.length for s in out])])
    return out, list(nodes)


def artifact_receptances(artifact: Artifact, omega, segments: Sequence[Segment] | None = None) -> ArtifactReceptances:
    """Free-free receptances of the artifact between flange and measurement points.

    Parameters
    ----------
    artifact : Artifact
    omega : (n_freq,) rad/s, > 0
    segments : sequence of Segment, optional
        Use these instead of ``artifact.segments()`` (e.g. with perturbed
        material properties); flange first, same total length.

    Returns
    -------
    ArtifactReceptances
    """
    omega = np.asarray(omega, dtype=float)
    segs = artifact.segments() if segments is None else list(segments)
    positions = artifact.point_positions()
    pieces, nodes = _cut(segs, positions)
    nodes = np.asarray(nodes)
    idx = [0]
    for z in positions:
        k = int(np.argmin(np.abs(nodes - z)))
        if abs(nodes[k] - z) > 1e-9:
            raise SetupError(f"no beam node at z = {z!r} m (artifact length {nodes[-1]!r} m)")
        idx.append(k)
    K = stepped_beam_dynamic_stiffness(pieces, omega)
    dofs = np.array([[2 * k, 2 * k + 1] for k in idx]).ravel()
    rhs = np.zeros((K.shape[-1], dofs.size), dtype=complex)
    rhs[dofs, np.arange(dofs.size)] = 1.0
    cols = np.linalg.solve(K, np.broadcast_to(rhs, K.shape[:-2] + rhs.shape))
    return ArtifactReceptances(omega=omega, matrix=cols[:, dofs, :])


def scaled_segments(segments: Sequence[Segment], youngs_factor: float = 1.0, density_factor: float = 1.0) -> list[Segment]:
    """Segments with every modulus scaled by ``youngs_factor`` and every density by ``density_factor``.

    Scaling E scales EI and kGA (G = E / 2(1 + nu)); scaling the density scales
    rhoA and rhoI.  Used to propagate artifact-model uncertainty.
    """
    out = []
    for s in segments:
        sec: SectionProperties = s.section
        new = dataclasses.replace(
            sec, EI=sec.EI * youngs_factor, kGA=sec.kGA * youngs_factor,
            rhoA=sec.rhoA * density_factor, rhoI=sec.rhoI * density_factor,
        )
        out.append(Segment(s.length, new))
    return out
