"""Compiled banded solve of :func:`bayes_rcsa.synthetic.fe.receptance` (numba; imported on its first call).

One frequency line at a time: the line's band ``K + i w C - w^2 M`` is formed in a work array of a few
kilobytes and eliminated there.  The vectorised numpy form it replaces walked every line at every pivot
(``n_dof`` strided passes over an ``(n_freq, n_dof, 2p + 1)`` array plus three such temporaries to form it),
which made the bench memory-bound.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["banded_receptance"]


@njit(cache=True, fastmath=False, nogil=True)
def banded_receptance(kb, cb, mb, omega, inputs, outputs, out):  # pragma: no cover - compiled
    """Fill ``out[f, a, b]`` with the response at ``outputs[a]`` to a unit load at ``inputs[b]``.

    ``kb``, ``cb``, ``mb`` (n, 2p + 1) complex band storage ``b[i, p + j - i] = A[i, j]`` of the stiffness,
    damping and mass matrices; ``omega`` (n_freq,) rad/s; ``out`` (n_freq, n_out, n_in) complex.  Gaussian
    elimination without pivoting (see the module notes of :mod:`bayes_rcsa.synthetic.fe`).  Returns 0, or
    1 + the first row whose pivot is zero (``out`` is then incomplete).
    """
    n, w = kb.shape
    p = (w - 1) // 2
    nr = inputs.size
    a = np.empty((n, w), dtype=np.complex128)
    x = np.empty((n, nr), dtype=np.complex128)
    for f in range(omega.size):
        wf = omega[f]
        for i in range(n):
            for j in range(w):
                a[i, j] = kb[i, j] + 1j * wf * cb[i, j] - wf * wf * mb[i, j]
            for r in range(nr):
                x[i, r] = 0.0
        for r in range(nr):
            x[inputs[r], r] = 1.0
        for k in range(n):
            piv = a[k, p]
            if piv == 0:
                return k + 1
            for d in range(1, min(p, n - 1 - k) + 1):
                fac = a[k + d, p - d] / piv
                # row k + d, band columns p - d .. 2p - d are the matrix columns k .. k + p of row k
                for j in range(p + 1):
                    a[k + d, p - d + j] -= fac * a[k, p + j]
                for r in range(nr):
                    x[k + d, r] -= fac * x[k, r]
        for k in range(n - 1, -1, -1):
            m = min(p, n - 1 - k)
            for r in range(nr):
                s = x[k, r]
                for j in range(1, m + 1):
                    s -= a[k, p + j] * x[k + j, r]
                x[k, r] = s / a[k, p]
        for o in range(outputs.size):
            for r in range(nr):
                out[f, o, r] = x[outputs[o], r]
    return 0
