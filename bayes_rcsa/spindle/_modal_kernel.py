"""Compiled line loops of the spindle modal fit (:mod:`.smoothing`; numba, imported on the first fit).

The Levenberg-Marquardt refinements of :mod:`.smoothing` evaluate the modal model and its Jacobian a few
hundred times on thousands of lines.  In numpy every evaluation is a batched LAPACK solve of ``n x n``
systems (one call per line, with its copies) and some twenty passes over ``(n_freq, 3, n_par)`` temporaries
for the derivatives and the whitening product; here each line is handled once, in a few hundred bytes of
work arrays.  The numpy form (:func:`.smoothing._evaluate`) stays as the reference the tests compare with:
the two agree to round-off (a different elimination order than LAPACK's, a different summation order than
BLAS's), not to the last bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["modal_entries", "modal_jacobian", "artifact_lines"]


@njit(cache=True, fastmath=False, nogil=True)
def modal_entries(wr2, phi, cmat, wt, ent, g):  # pragma: no cover - compiled
    """Add ``Phi Z^-1 Phi^T`` to ``ent`` and store ``G = Z^-1 Phi^T``, line by line.

    ``wr2`` (n,) squared scaled natural frequencies; ``phi`` (2, n) scaled mode shapes; ``cmat`` (n, n) scaled
    damping matrix; ``wt`` (n_freq,) scaled angular frequencies; ``ent`` (n_freq, 3) complex, the residual
    part of the entries (h, l, p) on entry; ``g`` (n_freq, n, 2) complex, filled.  ``Z = diag(wr2) - wt^2 I
    + i wt C`` is eliminated with partial pivoting.  Returns 0, or 1 when some ``Z`` is exactly singular
    (``ent`` and ``g`` are then incomplete).
    """
    n = wr2.size
    a = np.empty((n, n), dtype=np.complex128)
    x = np.empty((n, 2), dtype=np.complex128)
    for f in range(wt.size):
        w = wt[f]
        w2 = w**2
        for i in range(n):
            for j in range(n):
                a[i, j] = complex(0.0, w * cmat[i, j])
            a[i, i] = complex(wr2[i] - w2, w * cmat[i, i])
            x[i, 0] = phi[0, i]
            x[i, 1] = phi[1, i]
        for c in range(n):
            # the pivot of LAPACK's izamax: largest |re| + |im| (no squares to underflow)
            piv = c
            best = abs(a[c, c].real) + abs(a[c, c].imag)
            for i in range(c + 1, n):
                v = abs(a[i, c].real) + abs(a[i, c].imag)
                if v > best:
                    piv, best = i, v
            if best == 0.0:
                return 1
            if piv != c:
                for j in range(n):
                    a[c, j], a[piv, j] = a[piv, j], a[c, j]
                for k in range(2):
                    x[c, k], x[piv, k] = x[piv, k], x[c, k]
            inv = 1.0 / a[c, c]
            a[c, c] = inv  # the back substitution multiplies by the reciprocal pivots
            for i in range(c + 1, n):
                fac = a[i, c] * inv
                for j in range(c + 1, n):
                    a[i, j] -= fac * a[c, j]
                x[i, 0] -= fac * x[c, 0]
                x[i, 1] -= fac * x[c, 1]
        for i in range(n - 1, -1, -1):
            for k in range(2):
                s = x[i, k]
                for j in range(i + 1, n):
                    s -= a[i, j] * x[j, k]
                x[i, k] = s * a[i, i]
        for i in range(n):
            g[f, i, 0] = x[i, 0]
            g[f, i, 1] = x[i, 1]
        for e in range(3):
            ra = 0 if e < 2 else 1
            cb = 0 if e == 0 else 1
            s = 0j
            for r in range(n):
                s += phi[ra, r] * x[r, cb]
            ent[f, e] += s
    return 0


@njit(cache=True, fastmath=False, nogil=True)
def modal_jacobian(g, dfreq, lc, pair_j, pair_k, fac, wt, kmat, row_scale, out):  # pragma: no cover - compiled
    """Whitened real Jacobian rows ``out[0] = Re(J)``, ``out[1] = Im(J)``, shape (2, n_freq, m, n_par).

    ``J[f, k, p] = row_scale[f, k] sum_e kmat[f, k, e] d[f, e, p]`` with ``d`` the derivative of the scaled
    entries (h, l, p) with respect to the parameters (the columns of :func:`.smoothing._evaluate`).
    ``g`` (n_freq, n, 2) complex, ``Z^-1 Phi^T``; ``dfreq`` (n,) ``-2 w_r^2 dlog(w_r)/dy``; ``lc`` (n, n) the
    Cholesky factor of the damping matrix; ``pair_j``, ``pair_k`` (n_tri,) its lower-triangle entries in
    parameter order and ``fac`` (n_tri,) their chain-rule factors; ``wt`` (n_freq,); ``kmat`` (n_freq, m, 3)
    complex; ``row_scale`` (n_freq, m) float.  (Skipping the zeros of the sparse shape and residual columns
    of ``d`` was measured slower: the uniform loop over the parameters compiles better.)
    """
    n = dfreq.size
    n_tri = pair_j.size
    n_par = out.shape[3]
    k0 = 3 * n + n_tri
    m = kmat.shape[1]
    d = np.zeros((3, n_par), dtype=np.complex128)
    ltg = np.empty((n, 2), dtype=np.complex128)
    for f in range(wt.size):
        w = wt[f]
        for c in range(n):
            for b in range(2):
                s = 0j
                for r in range(n):
                    s += lc[r, c] * g[f, r, b]
                ltg[c, b] = s
        for e in range(3):
            a = 0 if e < 2 else 1
            b = 0 if e == 0 else 1
            for r in range(n):
                d[e, r] = dfreq[r] * g[f, r, a] * g[f, r, b]
                # d / d Phi[i, r]: delta_ai G_rb + delta_bi G_ra
                for i in range(2):
                    v = 0j
                    if a == i:
                        v += g[f, r, b]
                    if b == i:
                        v += g[f, r, a]
                    d[e, n + i * n + r] = v
            # dC = E_jk L^T + L E_kj  ->  G^T dC G [a, b] = G_ja (L^T G)_kb + (L^T G)_ka G_jb
            for q in range(n_tri):
                j, k = pair_j[q], pair_k[q]
                d[e, 3 * n + q] = complex(0.0, -w * fac[q]) * (g[f, j, a] * ltg[k, b] + ltg[k, a] * g[f, j, b])
            for p in range(k0, n_par):
                d[e, p] = 0.0
            d[e, k0 + e] = 1.0
            d[e, k0 + 3 + e] = -1.0 / w**2
        for k in range(m):
            rs = row_scale[f, k]
            for p in range(n_par):
                s = 0j
                for e in range(3):
                    s += kmat[f, k, e] * d[e, p]
                s *= rs
                out[0, f, k, p] = s.real
                out[1, f, k, p] = s.imag
    return 0


@njit(cache=True, fastmath=False, nogil=True)
def artifact_lines(matrix, ent, entry, h, k):  # pragma: no cover - compiled
    """Hammer-test receptances and their derivatives for a flange block, line by line.

    ``matrix`` (n_freq, 6, 6) complex, the artifact's free-free receptances (DOFs u_f, psi_f, u_1, psi_1, u_2,
    psi_2); ``ent`` (n_freq, 3) complex, scaled block entries (h, l, p) and ``entry`` (3,) their physical
    factors.  Fills ``h`` (n_freq, 3) with H11, H12, H22 (:func:`.inverse.forward_artifact`) and ``k``
    (n_freq, 3, 3) with their derivatives with respect to (h, l, p) (:func:`.inverse.forward_jacobian`).
    """
    for f in range(ent.shape[0]):
        s0 = ent[f, 0] * entry[0]
        s1 = ent[f, 1] * entry[1]
        s2 = ent[f, 2] * entry[2]
        b00 = matrix[f, 0, 0] + s0
        b01 = matrix[f, 0, 1] + s1
        b10 = matrix[f, 1, 0] + s1
        b11 = matrix[f, 1, 1] + s2
        det = b00 * b11 - b01 * b10
        e00, e01, e10, e11 = b11 / det, -b01 / det, -b10 / det, b00 / det
        p0, p1 = matrix[f, 2, 0], matrix[f, 2, 1]  # a_1: flange loads -> displacement at point 1
        q0, q1 = matrix[f, 4, 0], matrix[f, 4, 1]  # a_2
        u0 = e00 * p0 + e01 * p1  # alpha_1 = E a_1
        u1 = e10 * p0 + e11 * p1
        v0 = e00 * q0 + e01 * q1  # alpha_2 = E a_2
        v1 = e10 * q0 + e11 * q1
        h[f, 0] = matrix[f, 2, 2] - (p0 * u0 + p1 * u1)
        h[f, 1] = matrix[f, 2, 4] - (p0 * v0 + p1 * v1)
        h[f, 2] = matrix[f, 4, 4] - (q0 * v0 + q1 * v1)
        k[f, 0, 0], k[f, 0, 1], k[f, 0, 2] = u0 * u0, u0 * u1 + u1 * u0, u1 * u1
        k[f, 1, 0], k[f, 1, 1], k[f, 1, 2] = u0 * v0, u0 * v1 + u1 * v0, u1 * v1
        k[f, 2, 0], k[f, 2, 1], k[f, 2, 2] = v0 * v0, v0 * v1 + v1 * v0, v1 * v1
    return 0
