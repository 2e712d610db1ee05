"""Impact-hammer measurement noise of the rotor bench (H1 averaging over hits).

Each of ``n`` hits gives ``H_k = H (1 + √n σ_r ε_k) + √n σ_f δ_k`` with
``ε_k, δ_k`` independent standard complex normal (E|ε|² = 1).  The file holds
the average over the hits, whose noise therefore has standard deviation
``σ_r |H|`` (relative) and ``σ_f`` (floor, m/N): the configured
``noise_relative`` and ``noise_floor`` are the noise of the *averaged* FRF.
With unit force spectra the ordinary coherence is
``γ² = |Σ H_k|² / (n Σ |H_k|²)``; it falls where the floor dominates
(anti-resonances) and is 1 for a single hit.
"""

from __future__ import annotations

import numpy as np

__all__ = ["hammer_average"]


def hammer_average(clean, relative: float, floor: float, n_averages: int, rng: np.random.Generator):
    """Averaged noisy FRF and its coherence.

    Parameters
    ----------
    clean : (n_freq,) complex, m/N
    relative : float
        Relative standard deviation of the averaged FRF.
    floor : float, m/N
        Absolute standard deviation of the averaged FRF.
    n_averages : int
    rng : numpy.random.Generator
        The only source of randomness; draws ``(n_averages, n_freq, 4)``
        standard normals.

    Returns
    -------
    values : (n_freq,) complex, m/N
    coherence : (n_freq,) float in [0, 1]
    """
    h = np.asarray(clean, dtype=complex)
    n = int(n_averages)
    z = rng.standard_normal((n, h.size, 4)) * np.sqrt(0.5 * n)
    eps = z[..., 0] + 1j * z[..., 1]
    delta = z[..., 2] + 1j * z[..., 3]
    hits = h[None, :] * (1.0 + relative * eps) + floor * delta
    mean = hits.mean(axis=0)
    power = (np.abs(hits) ** 2).sum(axis=0)
    coherence = np.abs(hits.sum(axis=0)) ** 2 / (n * np.where(power > 0, power, 1.0))
    return mean, np.clip(coherence, 0.0, 1.0)
