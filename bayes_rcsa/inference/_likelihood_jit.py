"""The compiled per-line terms of :meth:`.likelihood.FRFLikelihood._terms` (numba; imported on the first call).

Kept apart so that importing the likelihood (reading a setup, ``--help``, the error paths) does not import numba.
"""

from __future__ import annotations

from numba import njit

__all__ = ["likelihood_terms"]


@njit(cache=True, fastmath=False, nogil=True)
def likelihood_terms(h, data, coherence, starts, eps2, q, var):  # pragma: no cover - compiled
    """Fill ``q = |h - data|^2 / v`` and ``var = v`` of the noise model, line by line.

    ``v_n = (|h_n|^2 + eps2 max_band |h|^2) / gamma_n``, the maximum over each measurement's lines.  The
    operations, their order and their rounding are those of the numpy expressions this replaces (no fused
    multiply-add: ``fastmath`` off), so the numbers are the same bit for bit; a NaN propagates through the
    band maximum as through ``np.maximum.reduceat``.

    Parameters
    ----------
    h : (n, n_lines) float64, the model FRFs' float view (real, imaginary interleaved), m/N
    data : (2 n_lines,) float64, the measured FRFs' float view, m/N
    coherence : (n_lines,) float64
    starts : (n_meas + 1,) int64, first line of each measurement, then ``n_lines``
    eps2 : float, the squared relative noise floor
    q, var : (n, n_lines) float64, filled
    """
    n = q.shape[0]
    n_meas = starts.size - 1
    for s in range(n):
        for m in range(n_meas):
            a, b = starts[m], starts[m + 1]
            peak = 0.0
            for j in range(a, b):
                x = h[s, 2 * j] * h[s, 2 * j] + h[s, 2 * j + 1] * h[s, 2 * j + 1]
                var[s, j] = x
                if j == a or (peak == peak and (x > peak or x != x)):  # np.maximum: a NaN wins and stays
                    peak = x
            floor = eps2 * peak
            for j in range(a, b):
                v = (var[s, j] + floor) / coherence[j]
                var[s, j] = v
                rr = h[s, 2 * j] - data[2 * j]
                ri = h[s, 2 * j + 1] - data[2 * j + 1]
                q[s, j] = (rr * rr + ri * ri) / v
