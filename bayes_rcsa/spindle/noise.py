"""Noise level of measured FRFs, estimated from the data themselves.

The spindle identification fits one relative noise level per measured FRF with the package's one model-free
estimate, :func:`bayes_rcsa.stats.noise.relative_noise_scale` (second differences, median over the lines; its
module docstring compares it with the third differences this module used before), on at least
:data:`MIN_LINES` lines and refusing an FRF without an estimate (:class:`~bayes_rcsa.errors.DataError`): the
identification has no other noise level to fall back on.  The grid must resolve every resonance (several lines
per half-power bandwidth), as the identification's finite differences need anyway.
"""

from __future__ import annotations

from ..stats.noise import noise_sigma, relative_noise_scale

__all__ = ["estimate_relative_noise", "noise_sigma", "MIN_LINES"]

#: Fewest lines of a measured FRF for its noise estimate (the identification's minimum since its first version):
#: the estimate's relative standard error is about 0.7 / sqrt(n) (the median of n exponential variates, under a
#: square root), 16 % at 20 lines.
MIN_LINES = 20


def estimate_relative_noise(values) -> float:
    """Relative noise standard deviation of an FRF (``rel`` in ``sigma = rel |H|``, e.g. 0.01 for 1 % noise).

    Parameters
    ----------
    values : (n_freq,) complex, m/N

    Returns
    -------
    float

    Raises
    ------
    DataError
        Fewer than :data:`MIN_LINES` lines, or an FRF that is zero over the whole record.
    """
    return relative_noise_scale(values, min_lines=MIN_LINES, strict=True)
