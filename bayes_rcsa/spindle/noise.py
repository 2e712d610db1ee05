"""Noise level of measured FRFs, estimated from the data themselves.

Estimator
---------
On a grid fine enough to resolve every resonance (several lines per
half-power bandwidth), the true FRF is smooth from line to line while the
measurement noise is independent between lines.  The third difference
``D_k = H_{k+3} - 3 H_{k+2} + 3 H_{k+1} - H_k`` then removes the FRF (up to
its third derivative) and keeps the noise, whose variance it multiplies by
``1 + 9 + 9 + 1 = 20``.  With noise standard deviation ``rel |H|`` per line
(circular complex Gaussian), ``|D_k| / sqrt(sum_j c_j^2 |H_j|^2)`` is
Rayleigh distributed with median ``rel sqrt(ln 2)``; the median over all
lines is robust to the few lines (sharp peaks, antiresonances) where the
FRF itself leaks into ``D_k``::

    rel = median_k |D_k| / sqrt(sum_j c_j^2 |H_{k+j}|^2) / sqrt(ln 2)

The tests check it recovers the noise level of synthetic data to within a
few per cent.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import DataError

__all__ = ["estimate_relative_noise", "noise_sigma"]

_C3 = np.array([-1.0, 3.0, -3.0, 1.0])


def estimate_relative_noise(values) -> float:
    """Relative noise standard deviation of an FRF, from its third differences.

    Parameters
    ----------
    values : (n_freq,) complex, m/N

    Returns
    -------
    float
        Estimated ``rel`` in ``sigma = rel |H|`` (e.g. 0.01 for 1 % noise).

    Raises
    ------
    DataError
        Fewer than 20 lines, or an FRF that is zero over the whole record.
    """
    h = np.asarray(values, dtype=complex)
    if h.ndim != 1 or h.size < 20:
        raise DataError(f"noise estimate: need a 1-D FRF of at least 20 lines, got shape {h.shape}")
    d = np.convolve(h, _C3[::-1], mode="valid")  # d[k] = sum_j c_j h[k + j]
    scale = np.sqrt(np.convolve(np.abs(h) ** 2, _C3[::-1] ** 2, mode="valid"))
    ok = scale > 0
    if not ok.any():
        raise DataError("noise estimate: the FRF is zero on every line")
    return float(np.median(np.abs(d[ok]) / scale[ok]) / math.sqrt(math.log(2.0)))


def noise_sigma(values, relative: float, floor: float = 0.0) -> np.ndarray:
    """Per-line standard deviation ``relative |H| + floor`` (m/N), shape (n_freq,)."""
    return relative * np.abs(np.asarray(values)) + floor
