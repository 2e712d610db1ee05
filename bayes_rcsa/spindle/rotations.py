"""Rotational receptances at the artifact's free end.

Two routes are provided.

Exact (default, used by the identification)
    The closed-form solution of Namazi's equations (:func:`.inverse.inverse_exact`)
    returns ``E = (A_ff + S)^-1``; the full 2x2 assembly block at point 1,
    rotations included, is then ``G11 = A11 - A1f E Af1``
    (:func:`free_end_block`).  No finite difference is taken, so there is no
    truncation error: the rotations are as good as the artifact model.

First-order finite differences (the textbook baseline)
    With points 1 and 2 a signed distance ``s = z1 - z2`` apart (z towards
    the free end), theta ~ du/dz and a moment approximated by a couple of
    forces at the two points (``M = F s``)::

        N11 = (H11 - H21) / s,   L11 = (H11 - H12) / s,
        P11 = (H11 - H12 - H21 + H22) / s^2

    Two errors remain whatever the spacing.  The difference quotient is the
    slope du/dz of the centre line, while the coupling's rotation is the
    Timoshenko section rotation psi; they differ by the shear angle
    V / (kappa G A), which does not shrink with s (about 7 % of N11 at
    1 kHz for a 20 mm steel blank).  And the quotients are values at the
    *midpoint* of the points (an O(s) truncation error; the second-order
    formulae need a third point, which the artifact test does not have).
    Small ``s`` also divides the measurement noise by ``s`` (N) and ``s^2``
    (P).  docs/spindle.md tabulates the errors on the synthetic artifact
    (N: 1-25 %, P: 1-250 % over 500-3000 Hz for s = 2.5-40 mm, noise-free);
    the function is kept for comparison, and the identification does not use it.
"""

from __future__ import annotations

import numpy as np

from ..errors import SetupError
from ..model.coupling import matmul2
from .substructure import ArtifactReceptances

__all__ = ["finite_difference_block", "free_end_block"]


def finite_difference_block(h11, h12, h21, h22, separation: float) -> np.ndarray:
    """First-order finite-difference 2x2 block at point 1.

    Parameters
    ----------
    h11, h12, h21, h22 : (n_freq,) complex, m/N
        ``hPQ`` = displacement at P per force at Q.  Give ``h21 = h12`` (or
        vice versa) when only one cross FRF was measured.
    separation : float
        m, signed ``z1 - z2`` (positive when point 1 lies nearer the free end).

    Returns
    -------
    (n_freq, 2, 2) complex ``[[H11, L11], [N11, P11]]`` with L11 and N11
    averaged (the block is reciprocal).
    """
    s = float(separation)
    if not np.isfinite(s) or s == 0:
        raise SetupError(f"finite differences need two distinct points (separation {separation!r} m)")
    h11, h12, h21, h22 = (np.asarray(v, dtype=complex) for v in (h11, h12, h21, h22))
    n11 = (h11 - h21) / s
    l11 = (h11 - h12) / s
    p11 = (h11 - h12 - h21 + h22) / s**2
    out = np.empty(h11.shape + (2, 2), dtype=complex)
    out[..., 0, 0] = h11
    out[..., 0, 1] = out[..., 1, 0] = 0.5 * (n11 + l11)
    out[..., 1, 1] = p11
    return out


def free_end_block(ar: ArtifactReceptances, e: np.ndarray) -> np.ndarray:
    """Full assembly block at point 1 from the identified coupling term ``E = (A_ff + S)^-1``.

    Parameters
    ----------
    ar : ArtifactReceptances
    e : (n_freq, 2, 2) complex, from :func:`.inverse.inverse_exact`

    Returns
    -------
    (n_freq, 2, 2) complex ``G11 = A11 - A1f E Af1``.
    """
    return ar.block("1", "1") - matmul2(ar.block("1", "f"), matmul2(e, ar.block("f", "1")))
