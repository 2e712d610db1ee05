"""Impact-hammer measurement realism: complex noise, coherence, analyser line width.

Noise model
-----------
The averaged FRF estimate at each line gets circular complex Gaussian noise
with standard deviation (of the complex value)::

    sigma(f) = noise_relative |H(f)| + noise_floor

The relative part stands for force/response calibration and impact
variability, the floor for the sensor and amplifier noise, which dominates
near antiresonances where |H| is small.

Coherence
---------
For an H1 estimate averaged over ``n`` impacts with uncorrelated output
noise, the variance of the estimate is about ``(1 - g2) / (n g2) |H|^2``
(Bendat & Piersol, random data, ch. 9).  Solving for the ordinary coherence
``g2`` with that variance equal to ``sigma^2`` gives::

    g2 = |H|^2 / (|H|^2 + n sigma^2)

which is close to one at resonances and drops near antiresonances, as in
real hammer tests.  It is computed from the noise-free FRF, so it is the
coherence the test *would* show on average, not a noisy estimate of it.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SetupError
from ..stats.noise import noise_sigma

__all__ = ["coherence", "add_measurement_noise", "line_average_offsets"]


def coherence(values: np.ndarray, sigma: np.ndarray, n_averages: int) -> np.ndarray:
    """Expected ordinary coherence, (n_freq,) in [0, 1]; see the module notes."""
    p = np.abs(values) ** 2
    den = p + n_averages * sigma**2
    # A line with H = 0 and no noise at all carries no information: coherence 0.
    return np.divide(p, den, out=np.zeros_like(p), where=den > 0)


def add_measurement_noise(
    values, relative: float, floor: float, n_averages: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy FRF and its coherence.

    Parameters
    ----------
    values : (n_freq,) complex, m/N, the noise-free FRF
    relative : float >= 0
    floor : float >= 0, m/N
    n_averages : int >= 1
    rng : numpy.random.Generator
        Consumed in a fixed order (2 n_freq standard normals), so a given
        seed reproduces the data exactly.

    Returns
    -------
    noisy : (n_freq,) complex, m/N
    coherence : (n_freq,) float in [0, 1]
    """
    h = np.asarray(values, dtype=complex)
    if not (math.isfinite(relative) and relative >= 0 and math.isfinite(floor) and floor >= 0):
        raise SetupError(f"noise relative = {relative!r}, floor = {floor!r}: expected finite values >= 0")
    sigma = noise_sigma(h, relative, floor)
    z = rng.standard_normal((2, h.size))
    noisy = h + sigma * (z[0] + 1j * z[1]) / math.sqrt(2.0)
    return noisy, coherence(h, sigma, n_averages)


def line_average_offsets(resolution_hz: float, n_points: int = 8) -> np.ndarray:
    """Offsets (Hz) of the midpoint rule over one analyser line ``[-r/2, r/2]``, shape (n_points,)."""
    return resolution_hz * ((np.arange(n_points) + 0.5) / n_points - 0.5)
