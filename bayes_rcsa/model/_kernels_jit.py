"""The compiled loops of :mod:`bayes_rcsa.model._kernels` (numba; imported on their first call, not with the model).

See :mod:`._kernels` for the formula.  Kept apart so that reading a setup, ``--help`` and the error paths
do not import numba (and scipy through it): :mod:`._kernels` loads this module when a kernel first runs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["grid_profile_kernel", "grid_sums_kernel", "tool_point_kernel", "tool_point_kernel_batched", "tool_point_kernel_tip"]

@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _fill_set(kx, kt, cx, ct, hx, ht, starts, omega, C, out, s):  # pragma: no cover - compiled
    """Lines of parameter set ``s`` (the shared inner loop of both kernels)."""
    n_cfg = kx.shape[1]
    for c in range(n_cfg):
        kxr = kx[s, c]
        ktr = kt[s, c]
        cxs = cx[s, c]
        cts = ct[s, c]
        hxs = hx[s, c]
        hts = ht[s, c]
        for j in range(starts[c], starts[c + 1]):
            kxi = omega[j] * cxs + hxs
            kti = omega[j] * cts + hts
            axr = C[2, j] * kxr - C[3, j] * kxi + 1.0
            axi = C[2, j] * kxi + C[3, j] * kxr
            btr = C[4, j] * ktr - C[5, j] * kti + 1.0
            bti = C[4, j] * kti + C[5, j] * ktr
            kkr = kxr * ktr - kxi * kti
            kki = kxr * kti + kxi * ktr
            t1r = C[8, j] * btr - C[9, j] * bti
            t1i = C[8, j] * bti + C[9, j] * btr
            t2r = C[10, j] * axr - C[11, j] * axi
            t2i = C[10, j] * axi + C[11, j] * axr
            numr = (t1r * kxr - t1i * kxi) + (t2r * ktr - t2i * kti) - (C[12, j] * kkr - C[13, j] * kki)
            numi = (t1r * kxi + t1i * kxr) + (t2r * kti + t2i * ktr) - (C[12, j] * kki + C[13, j] * kkr)
            denr = axr * btr - axi * bti - (C[6, j] * kkr - C[7, j] * kki)
            deni = axr * bti + axi * btr - (C[6, j] * kki + C[7, j] * kkr)
            inv = 1.0 / (denr * denr + deni * deni)
            out[s, j] = complex(
                C[0, j] - (numr * denr + numi * deni) * inv,
                C[1, j] - (numi * denr - numr * deni) * inv,
            )


@njit(cache=True, fastmath=False, nogil=True)
def tool_point_kernel(kx, kt, cx, ct, hx, ht, starts, omega, C, out):  # pragma: no cover - compiled
    """Fill ``out`` (n_sets, n_lines) complex with the tool-point receptance.

    Parameters
    ----------
    kx, kt, cx, ct : (n_sets, n_configs) float64
    hx, ht : (n_sets, n_configs) float64, hysteretic (rate-independent) loss stiffness, N/m and N m/rad
    starts : (n_configs + 1,) int64, first line of each configuration
    omega : (n_lines,) rad/s
    C : (14, n_lines) packed coefficients from :func:`pack_coefficients`
    out : (n_sets, n_lines) complex128
    """
    for s in range(kx.shape[0]):
        _fill_set(kx, kt, cx, ct, hx, ht, starts, omega, C, out, s)


@njit(cache=True, fastmath=False, nogil=True)
def tool_point_kernel_batched(kx, kt, cx, ct, hx, ht, starts, omega, CB, out):  # pragma: no cover - compiled
    """:func:`tool_point_kernel` with coefficients per parameter set.

    ``CB`` is (B, 14, n_lines) with B = 1 (shared) or n_sets (a model term made
    the substructures depend on the parameters); the same arithmetic per line.
    """
    nb = CB.shape[0]
    for s in range(kx.shape[0]):
        _fill_set(kx, kt, cx, ct, hx, ht, starts, omega, CB[s if nb > 1 else 0], out, s)


@njit(cache=True, fastmath=False, nogil=True)
def tool_point_kernel_tip(kx, kt, cx, ct, hx, ht, starts, omega, C, Z, out):  # pragma: no cover - compiled
    """Tool-point receptance with a diagonal dynamic stiffness attached at the tool tip.

    With ``D = E + diag(1/Kx, 1/Kt)`` the full tool-point block without the
    attachment is ``H = T22 - T21 D^-1 T12`` and with the tip dynamic
    stiffness ``Z = diag(z_u, z_psi)`` it is ``H' = (H^-1 + Z)^-1 =
    H (I + Z H)^-1``.  Multiplying through by ``det(D) Kx Kt`` (as the
    fast path does) leaves one division per line::

        d = det(E) Kx Kt + E11 Kt + E00 Kx + 1
        G_ij = T22_ij d - N_ij Kx Kt - U_ij Kx - V_ij Kt
        h' = (G00 (d + z_psi G11) - z_psi G01 G10) / ((d + z_u G00)(d + z_psi G11) - z_u z_psi G01 G10)

    with the per-line constants ``N = T21 adj(E) T12``,
    ``U_ij = T21_i0 T12_0j``, ``V_ij = T21_i1 T12_1j``
    (:func:`tip_coefficients`).

    Parameters
    ----------
    kx, kt, cx, ct, hx, ht : (n_sets, n_configs) float64
    starts : (n_configs + 1,) int64
    omega : (n_lines,) rad/s
    C : (n_lines, 19) complex, from :func:`tip_coefficients`
    Z : (B, n_lines, 2) float or complex, B = 1 or n_sets
    out : (n_sets, n_lines) complex128
    """
    n_sets, n_cfg = kx.shape
    nb = Z.shape[0]
    for s in range(n_sets):
        b = s if nb > 1 else 0
        for c in range(n_cfg):
            for j in range(starts[c], starts[c + 1]):
                Kx = complex(kx[s, c], omega[j] * cx[s, c] + hx[s, c])
                Kt = complex(kt[s, c], omega[j] * ct[s, c] + ht[s, c])
                KK = Kx * Kt
                d = C[j, 0] * KK + C[j, 1] * Kt + C[j, 2] * Kx + 1.0
                g00 = C[j, 3] * d - C[j, 7] * KK - C[j, 11] * Kx - C[j, 15] * Kt
                g01 = C[j, 4] * d - C[j, 8] * KK - C[j, 12] * Kx - C[j, 16] * Kt
                g10 = C[j, 5] * d - C[j, 9] * KK - C[j, 13] * Kx - C[j, 17] * Kt
                g11 = C[j, 6] * d - C[j, 10] * KK - C[j, 14] * Kx - C[j, 18] * Kt
                zu = Z[b, j, 0]
                zp = Z[b, j, 1]
                a11 = d + zp * g11
                cross = g01 * g10
                num = g00 * a11 - zp * cross
                den = (d + zu * g00) * a11 - (zu * zp) * cross
                inv = 1.0 / (den.real * den.real + den.imag * den.imag)
                out[s, j] = complex((num.real * den.real + num.imag * den.imag) * inv,
                                    (num.imag * den.real - num.real * den.imag) * inv)


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _row_terms(kx, cx, hx, a, starts, omega, C, m):  # pragma: no cover - compiled
    """The per-line Moebius coefficients of grid row ``a`` (the work that depends on ``Kx`` alone), into ``m``
    (8, n_lines): rows ``n0, n1, d0, d1`` as (real, imaginary) pairs (see :func:`grid_sums_kernel`)."""
    for c in range(kx.shape[1]):
        kxr = kx[a, c]
        for j in range(starts[c], starts[c + 1]):
            kxi = omega[j] * cx[a, c] + hx[a, c]
            axr = C[2, j] * kxr - C[3, j] * kxi + 1.0  # e00 Kx + 1
            axi = C[2, j] * kxi + C[3, j] * kxr
            pkr = C[8, j] * kxr - C[9, j] * kxi  # p Kx
            pki = C[8, j] * kxi + C[9, j] * kxr
            m[0, j] = pkr
            m[1, j] = pki
            # n1 = p Kx e11 + q (e00 Kx + 1) - r Kx
            m[2, j] = (pkr * C[4, j] - pki * C[5, j]) + (C[10, j] * axr - C[11, j] * axi) \
                - (C[12, j] * kxr - C[13, j] * kxi)
            m[3, j] = (pkr * C[5, j] + pki * C[4, j]) + (C[10, j] * axi + C[11, j] * axr) \
                - (C[12, j] * kxi + C[13, j] * kxr)
            m[4, j] = axr
            m[5, j] = axi
            # d1 = (e00 Kx + 1) e11 - g Kx
            m[6, j] = (axr * C[4, j] - axi * C[5, j]) - (C[6, j] * kxr - C[7, j] * kxi)
            m[7, j] = (axr * C[5, j] + axi * C[4, j]) - (C[6, j] * kxi + C[7, j] * kxr)


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _moebius(m, j, ktr, kti):  # pragma: no cover - compiled
    """``(n0 + n1 Kt) / (d0 + d1 Kt)`` on line ``j`` (real, imaginary) from :func:`_row_terms`'s ``m``."""
    numr = m[0, j] + m[2, j] * ktr - m[3, j] * kti
    numi = m[1, j] + m[2, j] * kti + m[3, j] * ktr
    denr = m[4, j] + m[6, j] * ktr - m[7, j] * kti
    deni = m[5, j] + m[6, j] * kti + m[7, j] * ktr
    inv = 1.0 / (denr * denr + deni * deni)
    return (numr * denr + numi * deni) * inv, (numi * denr - numr * deni) * inv


@njit(cache=True, fastmath=False, nogil=True)
def grid_sums_kernel(kx, cx, hx, kt, ct, ht, starts, omega, C, d, w, q):  # pragma: no cover - compiled
    """Weighted squared residual sums on a separable contact grid, without forming the FRFs.

    For one ``Kx`` the receptance is a Moebius map of ``Kt`` (:mod:`._kernels`):
    ``h = t22 - (n0 + n1 Kt) / (d0 + d1 Kt)`` with ``n0 = p Kx``,
    ``n1 = p Kx e11 + q (e00 Kx + 1) - r Kx``, ``d0 = e00 Kx + 1`` and
    ``d1 = (e00 Kx + 1) e11 - g Kx``; so the per-line work that depends on
    ``Kx`` alone is done once per ``Kx`` and each grid point costs two complex
    multiply-adds, one division and the residual.

    Parameters
    ----------
    kx, cx, hx : (n_x, n_configs) float64, stiffness N/m, viscous N s/m and loss N/m of every grid row
    kt, ct, ht : (n_t, n_configs) float64, the same of every grid column (N m/rad, N m s/rad, N m/rad)
    starts : (n_configs + 1,) int64
    omega : (n_lines,) rad/s
    C : (14, n_lines) packed coefficients
    d : (2, n_lines) float64, real and imaginary part of the data, m/N
    w : (n_lines,) float64, weight of every line's squared residual
    q : (n_x, n_t, n_configs) float64, filled with ``sum_lines w |h - d|^2`` per configuration
    """
    n_x, n_cfg = kx.shape
    n_t = kt.shape[0]
    n_lines = omega.size
    m = np.empty((8, n_lines))
    for a in range(n_x):
        _row_terms(kx, cx, hx, a, starts, omega, C, m)
        for b in range(n_t):
            for c in range(n_cfg):
                ktr = kt[b, c]
                cts = ct[b, c]
                hts = ht[b, c]
                acc = 0.0
                for j in range(starts[c], starts[c + 1]):
                    xr, xi = _moebius(m, j, ktr, omega[j] * cts + hts)
                    rr = C[0, j] - d[0, j] - xr
                    ri = C[1, j] - d[1, j] - xi
                    acc += w[j] * (rr * rr + ri * ri)
                q[a, b, c] = acc


@njit(cache=True, fastmath=False, nogil=True, error_model="numpy")
def grid_profile_kernel(kx, cx, hx, kt, ct, ht, starts, omega, C, d, coherence, eps2, q, lv):  # pragma: no cover
    """The likelihood's own sums on a separable contact grid: ``q = sum |h - d|^2 / v`` and ``lv = sum ln v``.

    ``v_n = (|h_n|^2 + eps2 max_config |h|^2) / coherence_n`` is the noise model's variance
    (:func:`bayes_rcsa.inference.likelihood.noise_variance`, one configuration per measurement), so each
    grid point needs its configuration's band maximum first: the lines' ``|h|^2`` and ``|h - d|^2`` are kept
    in two scratch rows and summed in a second pass.  The Moebius rearrangement is the one of
    :func:`grid_sums_kernel`.  ``error_model="numpy"``: a zero variance gives inf/nan (ranked -inf by the
    caller), as numpy does, instead of raising.

    Parameters
    ----------
    kx, cx, hx, kt, ct, ht, starts, omega, C, d : as :func:`grid_sums_kernel`
    coherence : (n_lines,) float in (0, 1]
    eps2 : float, the squared relative noise floor
    q, lv : (n_x, n_t, n_configs) float64, filled
    """
    n_x, n_cfg = kx.shape
    n_t = kt.shape[0]
    n_lines = omega.size
    m = np.empty((8, n_lines))
    a2 = np.empty(n_lines)
    r2 = np.empty(n_lines)
    for a in range(n_x):
        _row_terms(kx, cx, hx, a, starts, omega, C, m)
        for b in range(n_t):
            for c in range(n_cfg):
                ktr = kt[b, c]
                cts = ct[b, c]
                hts = ht[b, c]
                peak = 0.0
                for j in range(starts[c], starts[c + 1]):
                    xr, xi = _moebius(m, j, ktr, omega[j] * cts + hts)
                    hr = C[0, j] - xr
                    hi = C[1, j] - xi
                    h2 = hr * hr + hi * hi
                    a2[j] = h2
                    if h2 > peak:
                        peak = h2
                    rr = hr - d[0, j]
                    ri = hi - d[1, j]
                    r2[j] = rr * rr + ri * ri
                floor = eps2 * peak
                acc_q = 0.0
                acc_l = 0.0
                # sum ln v as the log of running products: one log per ~10 lines instead of one per line (the
                # logs were half the kernel's time); the product is folded into the sum before it can leave
                # [1e-150, 1e150], so it never under- or overflows (v > 0 is at least eps2 times the band's peak)
                prod = 1.0
                for j in range(starts[c], starts[c + 1]):
                    v = (a2[j] + floor) / coherence[j]
                    acc_q += r2[j] / v
                    prod *= v
                    if not 1e-150 < prod < 1e150:
                        acc_l += np.log(prod)
                        prod = 1.0
                q[a, b, c] = acc_q
                lv[a, b, c] = acc_l + np.log(prod)
