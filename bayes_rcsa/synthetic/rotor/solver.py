"""Receptances of a :class:`~bayes_rcsa.synthetic.rotor.structure.Structure` by modal superposition.

Method (two stages, then a residual):

1. **Undamped real modes.**  ``K φ = ω² M φ`` is solved with
   :func:`scipy.linalg.eigh`; the modes below ``cutoff_hz`` are kept,
   mass-normalised (``Φᵀ M Φ = I``, ``Φᵀ K Φ = Λ``).
2. **Complex modes of the reduced damped system.**  In modal coordinates the
   damping is not diagonal (hysteretic loss factors differ between
   components, viscous dampers sit at joints), so the reduced quadratic
   problem ``(Λ + iΦᵀDΦ) + λ ΦᵀCΦ + λ² I`` is linearised into the complex
   symmetric pencil ``λ A + B``, ``A = [[C_r, I], [I, 0]]``,
   ``B = [[K_r, 0], [0, −I]]`` and solved with :func:`scipy.linalg.eig`.
   Normalising ``yᵀ A y = 1`` (transpose, not conjugate) gives the exact
   partial fractions ``(K_r + iωC_r − ω²I)⁻¹ = Σ_r x_r x_rᵀ / (iω − λ_r)``
   (the hysteretic term is frequency independent, so the expansion is exact
   for every ω).  Poles with ``Im λ > 0`` are the physical modes:
   natural frequency ``|λ|/2π``, damping ratio ``−Re λ / |λ|``.
3. **Residual (static correction).**  The truncated modes contribute their
   static flexibility ``(K + iD)⁻¹ − Φ K_r⁻¹ Φᵀ`` at the response/excitation
   degrees of freedom, constant in frequency; the result is exact at ω = 0.

:func:`direct_receptance` solves the full complex system line by line
(dense LU) as the reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .structure import Structure

__all__ = ["ModalSolution", "modal_solution", "direct_receptance"]


@dataclass(frozen=True)
class ModalSolution:
    """Complex-mode expansion of a structure at a few degrees of freedom.

    Attributes
    ----------
    dofs : (n_io,) int
        Degrees of freedom of the receptance block (response = excitation set).
    poles : (2m,) complex, rad/s
        Eigenvalues λ of the reduced damped system (``x ∝ e^{λt}``).
    shapes : (n_io, 2m) complex
        Modal vectors at ``dofs``; residue of mode r between i and j is
        ``shapes[i, r] * shapes[j, r]``.
    residual : (n_io, n_io) complex
        Static flexibility of the truncated modes.
    undamped_hz : (m,) float
        Frequencies of the kept undamped modes, Hz.
    """

    dofs: np.ndarray
    poles: np.ndarray
    shapes: np.ndarray
    residual: np.ndarray
    undamped_hz: np.ndarray

    def receptance(self, frequency_hz) -> np.ndarray:
        """Receptance block at ``dofs``.

        Parameters
        ----------
        frequency_hz : (n_freq,) float, Hz

        Returns
        -------
        (n_freq, n_io, n_io) complex
            u/F (m/N), u/M (1/N), θ/F (rad/N), θ/M (rad/(N m)) as the dofs dictate.
        """
        s = 2j * np.pi * np.asarray(frequency_hz, dtype=float)
        g = 1.0 / (s[:, None] - self.poles[None, :])
        H = np.einsum("ir,jr,fr->fij", self.shapes, self.shapes, g, optimize=True)
        return H + self.residual[None, :, :]

    def modes(self) -> list[dict]:
        """Physical modes (``Im λ > 0``), ordered by frequency.

        Returns
        -------
        list of dict
            ``eigenfrequency_hz`` (|λ|/2π), ``damped_frequency_hz`` (Im λ/2π),
            ``damping_ratio``, ``residues`` ((n_io, n_io) complex as nested
            lists are left to the caller: here a complex ndarray).
        """
        out = []
        for r in np.argsort(np.abs(self.poles)):
            lam = self.poles[r]
            if lam.imag <= 0:
                continue
            mag = abs(lam)
            out.append({
                "pole": lam,
                "eigenfrequency_hz": mag / (2 * np.pi),
                "damped_frequency_hz": lam.imag / (2 * np.pi),
                "damping_ratio": -lam.real / mag,
                "residues": np.outer(self.shapes[:, r], self.shapes[:, r]),
            })
        out.sort(key=lambda m: m["eigenfrequency_hz"])
        return out


def modal_solution(structure: Structure, dofs, cutoff_hz: float = 40e3, min_modes: int = 12) -> ModalSolution:
    """Build the complex-mode expansion of ``structure`` at ``dofs``.

    Parameters
    ----------
    structure : Structure
        Must be restrained (positive definite K).
    dofs : sequence of int
    cutoff_hz : float, Hz
        Undamped modes up to this frequency are kept (at least ``min_modes``).
    min_modes : int

    Returns
    -------
    ModalSolution
    """
    dofs = np.asarray(dofs, dtype=int)
    w2, Phi = sla.eigh(structure.K, structure.M)
    w2 = np.maximum(w2, 0.0)
    m = max(min(min_modes, w2.size), int(np.searchsorted(w2, (2 * np.pi * cutoff_hz) ** 2)))
    Phi = Phi[:, :m]
    Kr = np.diag(w2[:m]) + 1j * (Phi.T @ structure.D @ Phi)
    Cr = Phi.T @ structure.C @ Phi
    eye = np.eye(m)
    zero = np.zeros((m, m))
    A = np.block([[Cr, eye], [eye, zero]]).astype(complex)
    B = np.block([[Kr, zero], [zero, -eye]])
    lam, Y = sla.eig(-B, A)
    norm = np.einsum("ir,ij,jr->r", Y, A, Y)
    # a (numerically) defective pair has y^T A y = 0 and no partial fraction of its own; never met in
    # practice with distinct damped poles, dropped rather than divided by zero
    ok = np.abs(norm) > 1e-14 * np.abs(norm).max()
    lam, Y = lam[ok], Y[:, ok] / np.sqrt(norm[ok])[None, :]
    X = Y[:m]
    shapes = Phi[dofs] @ X
    # static flexibility of the full model minus that of the kept modes
    E = np.zeros((structure.n_dof, dofs.size))
    E[dofs, np.arange(dofs.size)] = 1.0
    full = np.linalg.solve(structure.K + 1j * structure.D, E)[dofs]
    kept = Phi[dofs] @ np.linalg.solve(Kr, Phi[dofs].T)
    return ModalSolution(dofs=dofs, poles=lam, shapes=shapes, residual=full - kept,
                         undamped_hz=np.sqrt(w2[:m]) / (2 * np.pi))


def direct_receptance(structure: Structure, dofs, frequency_hz) -> np.ndarray:
    """Reference: dense complex solve of the full system at every line.

    Parameters
    ----------
    structure : Structure
    dofs : sequence of int
    frequency_hz : (n_freq,) float, Hz

    Returns
    -------
    (n_freq, n_io, n_io) complex
    """
    dofs = np.asarray(dofs, dtype=int)
    E = np.zeros((structure.n_dof, dofs.size))
    E[dofs, np.arange(dofs.size)] = 1.0
    out = np.empty((len(frequency_hz), dofs.size, dofs.size), dtype=complex)
    for k, f in enumerate(np.asarray(frequency_hz, dtype=float)):
        out[k] = np.linalg.solve(structure.dynamic_stiffness(2 * np.pi * f), E)[dofs]
    return out
