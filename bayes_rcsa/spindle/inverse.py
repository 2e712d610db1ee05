"""Inverse receptance coupling: flange receptance of the spindle from artifact hammer tests.

Model
-----
The artifact (free-free two-port, flange ``f`` and points 1, 2; blocks
``A_PQ`` from :mod:`.substructure`) is joined rigidly at its flange to the
spindle, whose flange block ``S = [[h, l], [n, p]]`` is sought.  With the
same rigid-coupling algebra as :func:`bayes_rcsa.model.coupling.couple`, the
assembly receptance between points P and Q of the artifact is::

    G_PQ = A_PQ - A_Pf E A_fQ,        E = (A_ff + S)^-1                 (1)

Only the displacement/force entries are measured.  Writing ``a_P`` for the
first row of ``A_Pf`` (flange force and moment -> displacement at P) and
using reciprocity ``A_fQ = A_Qf^T``::

    r_PQ := A_PQ[0, 0] - H_PQ = a_P E a_Q^T                             (2)

Equation (2) is *linear* in the three entries of the symmetric 2x2 matrix
``E``: the three measurements r11, r12 (= r21) and r22 give a 3x3 linear
system per frequency line whose matrix is the symmetric square of
``V = [a_1; a_2]`` (determinant ``det(V)^3``).  Solving it and then
``S = E^-1 - A_ff`` is Namazi's set of nonlinear equations for
(H, L, N, P) at the flange solved in closed form, without finite-difference
rotations and hence without truncation error.  ``V`` is singular when the
points coincide; its conditioning degrades near frequencies where the
artifact cannot tell flange force from flange moment.

The classical route (finite-difference rotations at the free end, then
``S = A_f1 (A_11 - G_11)^-1 A_1f - A_ff``, the full-block inverse of the
coupling equation) is :func:`inverse_from_free_end_block`; see
:mod:`.rotations` for its accuracy.

Noise propagation
-----------------
Linearising (1) about S: ``dH_PQ = alpha_P^T dS alpha_Q`` with
``alpha_P = E a_P^T``.  :func:`forward_jacobian` returns this 3x3 map from
(dh, dl = dn, dp) to (dH11, dH12, dH22); its inverse propagates the
measurement noise to the identified block (:func:`propagated_std`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..model.coupling import inv2, matmul2
from .substructure import ArtifactReceptances

__all__ = [
    "MEASURED", "InverseResult", "forward_artifact", "inverse_exact", "inverse_from_free_end_block",
    "forward_jacobian", "propagated_std", "unreliable_bands", "combine_cross",
]

# Order of the (combined) measurements in arrays of shape (..., 3).
MEASURED = ("h11", "h12", "h22")


@dataclass(frozen=True)
class InverseResult:
    """Line-by-line identified flange block.

    Attributes
    ----------
    block : (n_freq, 2, 2) complex
        ``[[h, l], [n, p]]`` (l = n by construction), m/N, 1/N, rad/N, rad/(N m).
    e : (n_freq, 2, 2) complex
        ``(A_ff + S)^-1``, N/m, N, N/rad... (the coupling's inverse term).
    condition : (n_freq,) float
        2-norm condition number of the 3x3 system, columns scaled to unit norm.
    """

    block: np.ndarray
    e: np.ndarray
    condition: np.ndarray


def _rows(ar: ArtifactReceptances) -> tuple[np.ndarray, np.ndarray]:
    """a_1, a_2: (n_freq, 2) displacement at points 1, 2 per flange (F, M)."""
    return ar.block("1", "f")[:, 0, :], ar.block("2", "f")[:, 0, :]


def _sym_square(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row of the linear map (E00, E01, E11) -> a E b^T for symmetric E, shape (..., 3)."""
    return np.stack([a[..., 0] * b[..., 0], a[..., 0] * b[..., 1] + a[..., 1] * b[..., 0], a[..., 1] * b[..., 1]], axis=-1)


def combine_cross(h12: np.ndarray | None, h21: np.ndarray | None,
                  s12: np.ndarray | None = None, s21: np.ndarray | None = None):
    """Average the two cross measurements (the assembly is reciprocal).

    Returns
    -------
    h : (n_freq,) complex
    sigma : (n_freq,) float or None
        Standard deviation of the average when both sigmas are given.
    """
    if h12 is None and h21 is None:
        raise ModelError("the cross receptance (h12 or h21) is required")
    if h12 is None or h21 is None:
        return (h21 if h12 is None else h12), (s21 if h12 is None else s12)
    sigma = None if s12 is None or s21 is None else 0.5 * np.sqrt(s12**2 + s21**2)
    return 0.5 * (h12 + h21), sigma


def forward_artifact(block: np.ndarray, ar: ArtifactReceptances) -> np.ndarray:
    """Assembly receptances H11, H12 (= H21), H22 predicted for a flange block.

    Parameters
    ----------
    block : (..., n_freq, 2, 2) complex
        Spindle flange receptance S.
    ar : ArtifactReceptances

    Returns
    -------
    (..., n_freq, 3) complex, m/N, in the order of :data:`MEASURED`.
    """
    e = inv2(ar.block("f", "f") + block)
    a1, a2 = _rows(ar)
    out = []
    for (p, q), (ap, aq) in zip((("1", "1"), ("1", "2"), ("2", "2")), ((a1, a1), (a1, a2), (a2, a2))):
        ea = np.einsum("...ij,...j->...i", e, aq)
        out.append(ar.block(p, q)[:, 0, 0] - np.einsum("...i,...i->...", ap, ea))
    return np.stack(out, axis=-1)


def inverse_exact(ar: ArtifactReceptances, measured: np.ndarray) -> InverseResult:
    """Flange block from the three measured receptances, line by line (closed form).

    Parameters
    ----------
    ar : ArtifactReceptances
    measured : (n_freq, 3) complex
        H11, H12 (or the average of H12 and H21), H22 in m/N.

    Returns
    -------
    InverseResult

    Raises
    ------
    ModelError
        If the 3x3 system is exactly singular at some line (coinciding points).
    """
    measured = np.asarray(measured, dtype=complex)
    a1, a2 = _rows(ar)
    m = np.stack([_sym_square(a1, a1), _sym_square(a1, a2), _sym_square(a2, a2)], axis=-2)  # (n, 3, 3)
    r = np.stack([ar.block("1", "1")[:, 0, 0], ar.block("1", "2")[:, 0, 0], ar.block("2", "2")[:, 0, 0]], axis=-1)
    r = r - measured
    try:
        x = np.linalg.solve(m, r[..., None])[..., 0]
    except np.linalg.LinAlgError as exc:
        raise ModelError(
            "inverse coupling: the 3x3 system is singular (do the two measurement points coincide?)"
        ) from exc
    e = np.empty(x.shape[:-1] + (2, 2), dtype=complex)
    e[..., 0, 0], e[..., 0, 1], e[..., 1, 0], e[..., 1, 1] = x[..., 0], x[..., 1], x[..., 1], x[..., 2]
    block = inv2(e) - ar.block("f", "f")
    block = 0.5 * (block + np.swapaxes(block, -1, -2))  # remove round-off asymmetry of A_ff
    mn = m / np.linalg.norm(m, axis=-2, keepdims=True)
    return InverseResult(block=block, e=e, condition=np.linalg.cond(mn))


def inverse_from_free_end_block(ar: ArtifactReceptances, g11: np.ndarray) -> np.ndarray:
    """Classical inverse RCSA from a full 2x2 assembly block at point 1.

    From ``G11 = A11 - A1f (A_ff + S)^-1 Af1``::

        S = Af1 (A11 - G11)^-1 A1f - A_ff

    Parameters
    ----------
    ar : ArtifactReceptances
    g11 : (n_freq, 2, 2) complex
        Assembly block at point 1 (e.g. with finite-difference rotations).

    Returns
    -------
    (n_freq, 2, 2) complex flange block S.
    """
    x = inv2(ar.block("1", "1") - g11)
    return matmul2(ar.block("f", "1"), matmul2(x, ar.block("1", "f"))) - ar.block("f", "f")


def forward_jacobian(ar: ArtifactReceptances, block: np.ndarray) -> np.ndarray:
    """Derivative of (H11, H12, H22) with respect to (h, l = n, p) of the flange block.

    Parameters
    ----------
    ar : ArtifactReceptances
    block : (..., n_freq, 2, 2) complex

    Returns
    -------
    (..., n_freq, 3, 3) complex; ``[..., k, j]`` = dH_k / dS_j.
    """
    e = inv2(ar.block("f", "f") + block)
    a1, a2 = _rows(ar)
    al1 = np.einsum("...ij,...j->...i", e, a1)
    al2 = np.einsum("...ij,...j->...i", e, a2)
    return np.stack([_sym_square(al1, al1), _sym_square(al1, al2), _sym_square(al2, al2)], axis=-2)


def propagated_std(jacobian: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Standard deviations of (h, l, p) from independent circular noise on (H11, H12, H22).

    Parameters
    ----------
    jacobian : (n_freq, 3, 3) complex, from :func:`forward_jacobian`
    sigma : (n_freq, 3) float, noise standard deviations of the measurements, m/N

    Returns
    -------
    (n_freq, 3) float: m/N, 1/N, rad/(N m).
    """
    inv = np.linalg.inv(jacobian)
    return np.sqrt(np.einsum("fjk,fk->fj", np.abs(inv) ** 2, np.asarray(sigma, dtype=float) ** 2))


def unreliable_bands(frequency_hz: np.ndarray, flagged: np.ndarray) -> list[tuple[float, float]]:
    """Contiguous runs of flagged lines as (first, last) frequency pairs in Hz."""
    f = np.asarray(frequency_hz, dtype=float)
    flagged = np.asarray(flagged, dtype=bool)
    if not flagged.any():
        return []
    d = np.diff(np.concatenate([[0], flagged.astype(np.int8), [0]]))
    starts, stops = np.nonzero(d == 1)[0], np.nonzero(d == -1)[0] - 1
    return [(float(f[a]), float(f[b])) for a, b in zip(starts, stops)]
