"""Receptance coupling of substructures (rigid and elastic joints).

Joining end 2 of substructure A to end 1 of substructure B through a joint
with compliance ``K^-1`` (zero for a rigid joint) gives, with
``D = A22 + B11 + K^-1``::

    C11 = A11 - A12 D^-1 A21        C12 = A12 D^-1 B12
    C21 = B21 D^-1 A21              C22 = B22 - B21 D^-1 B12

All functions work on arrays of 2x2 blocks with arbitrary leading
dimensions, e.g. ``(n_sets, n_freq, 2, 2)``, using the closed-form 2x2
inverse, so a batch of parameter sets costs a few vectorised array operations.
"""

from __future__ import annotations

import numpy as np

from .timoshenko import TwoPort

__all__ = ["inv2", "matmul2", "contact_compliance", "couple", "attach", "rigid_coupling", "elastic_coupling",
           "add_end_impedance"]


def inv2(a: np.ndarray) -> np.ndarray:
    """Closed-form inverse of an array of 2x2 matrices, shape (..., 2, 2)."""
    a00, a01, a10, a11 = a[..., 0, 0], a[..., 0, 1], a[..., 1, 0], a[..., 1, 1]
    det = a00 * a11 - a01 * a10
    out = np.empty(np.broadcast_shapes(a.shape), dtype=np.result_type(a, complex))
    out[..., 0, 0] = a11 / det
    out[..., 0, 1] = -a01 / det
    out[..., 1, 0] = -a10 / det
    out[..., 1, 1] = a00 / det
    return out


def matmul2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of broadcastable arrays of 2x2 matrices, written out elementwise.

    Faster than ``np.matmul`` for millions of tiny matrices.
    """
    shape = np.broadcast_shapes(a.shape, b.shape)
    out = np.empty(shape, dtype=np.result_type(a, b))
    for i in range(2):
        for j in range(2):
            out[..., i, j] = a[..., i, 0] * b[..., 0, j] + a[..., i, 1] * b[..., 1, j]
    return out


def contact_compliance(omega, k_xf, k_thetaM, c_xf=0.0, c_thetaM=0.0, h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
    """Compliance K^-1 of the diagonal contact stiffness, shape (..., n_freq, 2, 2).

    Parameters
    ----------
    omega : (n_freq,) rad/s
    k_xf : N/m, k_thetaM : N m/rad, c_xf : N s/m, c_thetaM : N m s/rad
    h_xf : N/m, h_thetaM : N m/rad
        Hysteretic (rate-independent) loss stiffness, ``eta k`` for a loss
        factor ``eta``: the joint stiffness is ``k + i (omega c + h)``.
        Scalars or arrays broadcastable against ``(..., 1)`` (one value per
        parameter set, the frequency axis is appended).  ``numpy.inf``
        stiffness gives a rigid joint in that direction.
    """
    omega = np.asarray(omega, dtype=float)
    kx = np.asarray(k_xf, dtype=float)[..., None] + 1j * (omega * np.asarray(c_xf, dtype=float)[..., None]
                                                          + np.asarray(h_xf, dtype=float)[..., None])
    kt = np.asarray(k_thetaM, dtype=float)[..., None] + 1j * (omega * np.asarray(c_thetaM, dtype=float)[..., None]
                                                              + np.asarray(h_thetaM, dtype=float)[..., None])
    shape = np.broadcast_shapes(kx.shape, kt.shape)
    out = np.zeros(shape + (2, 2), dtype=complex)
    with np.errstate(divide="ignore"):
        out[..., 0, 0] = np.where(np.isinf(kx.real), 0.0, 1.0 / kx)
        out[..., 1, 1] = np.where(np.isinf(kt.real), 0.0, 1.0 / kt)
    return out


def couple(a: TwoPort, b: TwoPort, compliance: np.ndarray | None = None) -> TwoPort:
    """Join end 2 of ``a`` to end 1 of ``b``; the result's ends are a1 and b2.

    Parameters
    ----------
    a, b : TwoPort
    compliance : (..., n_freq, 2, 2) or None
        Joint compliance K^-1; ``None`` for a rigid joint.
    """
    d = a.r22 + b.r11
    if compliance is not None:
        d = d + compliance
    dinv = inv2(d)
    return TwoPort(
        r11=a.r11 - matmul2(a.r12, matmul2(dinv, a.r21)),
        r12=matmul2(a.r12, matmul2(dinv, b.r12)),
        r21=matmul2(b.r21, matmul2(dinv, a.r21)),
        r22=b.r22 - matmul2(b.r21, matmul2(dinv, b.r12)),
    )


def attach(point: np.ndarray, b: TwoPort, compliance: np.ndarray | None = None) -> np.ndarray:
    """Point receptance at end 2 of ``b`` after joining its end 1 to a point substructure.

    ``point`` is the (..., n_freq, 2, 2) point receptance of the substructure
    it is joined to (e.g. the spindle at the holder flange)::

        C22 = B22 - B21 (S + B11 + K^-1)^-1 B12
    """
    d = point + b.r11
    if compliance is not None:
        d = d + compliance
    return b.r22 - matmul2(b.r21, matmul2(inv2(d), b.r12))


def rigid_coupling(a11, a12, a21, a22, b11) -> np.ndarray:
    """The paper's rigid coupling ``C11 = A11 - A12 (A22 + B11)^-1 A21``."""
    return a11 - matmul2(a12, matmul2(inv2(a22 + b11), a21))


def elastic_coupling(a11, a12, a21, a22, b11, compliance) -> np.ndarray:
    """Elastic coupling ``C11 = A11 - A12 (A22 + B11 + K^-1)^-1 A21``."""
    return a11 - matmul2(a12, matmul2(inv2(a22 + b11 + compliance), a21))


def add_end_impedance(tool: TwoPort, z_u: np.ndarray, z_psi: np.ndarray) -> TwoPort:
    """Tool two-port with a diagonal dynamic stiffness ``diag(z_u, z_psi)`` added at end 2 (Woodbury update).

    Parameters
    ----------
    tool : TwoPort, blocks (B0, n_lines, 2, 2)
    z_u, z_psi : (B, n_lines) complex or real, N/m and N m/rad

    Returns
    -------
    TwoPort with blocks (B, n_lines, 2, 2) (B broadcast against B0)
    """
    r22 = tool.r22
    m = np.empty(np.broadcast_shapes(r22.shape, z_u.shape + (2, 2)), dtype=complex)
    # M = I + R22 Z with Z diagonal: column k of R22 scaled by z_k
    m[..., 0, 0] = 1.0 + r22[..., 0, 0] * z_u
    m[..., 1, 0] = r22[..., 1, 0] * z_u
    m[..., 0, 1] = r22[..., 0, 1] * z_psi
    m[..., 1, 1] = 1.0 + r22[..., 1, 1] * z_psi
    w = inv2(m)
    w[..., 0, :] *= z_u[..., None]  # W = Z M^-1: row k scaled by z_k
    w[..., 1, :] *= z_psi[..., None]
    w_r21 = matmul2(w, tool.r21)
    w_r22 = matmul2(w, r22)
    return TwoPort(
        r11=tool.r11 - matmul2(tool.r12, w_r21),
        r12=tool.r12 - matmul2(tool.r12, w_r22),
        r21=tool.r21 - matmul2(r22, w_r21),
        r22=r22 - matmul2(r22, w_r22),
    )
