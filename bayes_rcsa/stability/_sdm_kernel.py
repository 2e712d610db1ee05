"""Compiled monodromy action of the batched semi-discretisation (:mod:`bayes_rcsa.stability.sdm`).

One loop over (batch point, vector) runs the m interval steps with scalar
arithmetic: the per-step work is a 2 x 2 map per mode and a 2 x 2 solve,
far too small for numpy calls to pay off (the numpy version of the same
loop spent > 90 % of its time in call overhead).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["apply_monodromy"]


@njit(cache=True, nogil=True)
def apply_monodromy(P, ga, gb, minv, weight, depth, hc, hd, lag_r, lag_f, nx, L, V):  # pragma: no cover - compiled
    """Φ V for every batch point.

    Parameters
    ----------
    P : (n, 2, 2, G) per-mode e^{A Δt}
    ga, gb : (n, 2, G) weights of the force at the interval start and end
    minv : (m, 2, 2, G) inverses of I - a diag(g) H_c,i
    weight : (n, G) tip participation (1, or 0 for padding modes)
    depth : (G,) m
    hc : (m, 2, 2) coefficient of the current tip displacement
    hd : (n_groups, m, 2, 2) coefficients of the delayed tip displacements
    lag_r, lag_f : (n_groups,) int and float, delay = r + f intervals
    nx : int, the first nx modes belong to X
    L : int, memory length
    V : (d, B, G), d = 2 n + 2 L

    Returns
    -------
    (d, B, G)
    """
    n = P.shape[0]
    G = P.shape[3]
    m = hc.shape[0]
    B = V.shape[1]
    ng = hd.shape[0]
    out = np.empty_like(V)
    hist = np.empty((L + m + 1, 2))
    y = np.empty((n, 2))
    for g in range(G):
        a = depth[g]
        gx = 0.0
        gy = 0.0
        for r in range(n):
            if r < nx:
                gx += weight[r, g] * gb[r, 0, g]
            else:
                gy += weight[r, g] * gb[r, 0, g]
        for bb in range(B):
            for k in range(L):
                hist[L - 1 - k, 0] = V[2 * n + 2 * k, bb, g]
                hist[L - 1 - k, 1] = V[2 * n + 2 * k + 1, bb, g]
            qx = 0.0
            qy = 0.0
            for r in range(n):
                y[r, 0] = V[2 * r, bb, g]
                y[r, 1] = V[2 * r + 1, bb, g]
                if r < nx:
                    qx += weight[r, g] * y[r, 0]
                else:
                    qy += weight[r, g] * y[r, 0]
            hist[L, 0] = qx
            hist[L, 1] = qy
            for i in range(m):
                dx = 0.0
                dy = 0.0
                ex = 0.0
                ey = 0.0
                for l in range(ng):
                    rr = lag_r[l]
                    f = lag_f[l]
                    s0 = L + i - rr
                    ux = (1.0 - f) * hist[s0, 0]
                    uy = (1.0 - f) * hist[s0, 1]
                    vx = (1.0 - f) * hist[s0 + 1, 0] + f * hist[s0, 0]
                    vy = (1.0 - f) * hist[s0 + 1, 1] + f * hist[s0, 1]
                    if f > 0.0:
                        ux += f * hist[s0 - 1, 0]
                        uy += f * hist[s0 - 1, 1]
                    h00 = hd[l, i, 0, 0]
                    h01 = hd[l, i, 0, 1]
                    h10 = hd[l, i, 1, 0]
                    h11 = hd[l, i, 1, 1]
                    dx += h00 * ux + h01 * uy
                    dy += h10 * ux + h11 * uy
                    ex += h00 * vx + h01 * vy
                    ey += h10 * vx + h11 * vy
                c00 = hc[i, 0, 0]
                c01 = hc[i, 0, 1]
                c10 = hc[i, 1, 0]
                c11 = hc[i, 1, 1]
                q0x = hist[L + i, 0]
                q0y = hist[L + i, 1]
                f0x = a * (c00 * q0x + c01 * q0y - dx)
                f0y = a * (c10 * q0x + c11 * q0y - dy)
                cx = 0.0
                cy = 0.0
                for r in range(n):
                    y0 = y[r, 0]
                    y1 = y[r, 1]
                    fr = f0x if r < nx else f0y
                    n0 = P[r, 0, 0, g] * y0 + P[r, 0, 1, g] * y1 + ga[r, 0, g] * fr
                    n1 = P[r, 1, 0, g] * y0 + P[r, 1, 1, g] * y1 + ga[r, 1, g] * fr
                    y[r, 0] = n0
                    y[r, 1] = n1
                    if r < nx:
                        cx += weight[r, g] * n0
                    else:
                        cy += weight[r, g] * n0
                aex = a * ex
                aey = a * ey
                rx = cx - gx * aex
                ry = cy - gy * aey
                q1x = minv[i, 0, 0, g] * rx + minv[i, 0, 1, g] * ry
                q1y = minv[i, 1, 0, g] * rx + minv[i, 1, 1, g] * ry
                f1x = a * (c00 * q1x + c01 * q1y) - aex
                f1y = a * (c10 * q1x + c11 * q1y) - aey
                for r in range(n):
                    fr = f1x if r < nx else f1y
                    y[r, 0] += gb[r, 0, g] * fr
                    y[r, 1] += gb[r, 1, g] * fr
                hist[L + i + 1, 0] = q1x
                hist[L + i + 1, 1] = q1y
            for r in range(n):
                out[2 * r, bb, g] = y[r, 0]
                out[2 * r + 1, bb, g] = y[r, 1]
            for k in range(L):
                out[2 * n + 2 * k, bb, g] = hist[L + m - 1 - k, 0]
                out[2 * n + 2 * k + 1, bb, g] = hist[L + m - 1 - k, 1]
    return out
