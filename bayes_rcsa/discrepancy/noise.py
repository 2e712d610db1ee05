"""The measurement's own noise level, estimated from the measured FRF alone.

A model that misses the data absorbs the misfit into its fitted noise scale:
on the rotor bench with a slotted holder the remainder model's scale at
40 mm was 0.07-0.13 against the bench's 2 %.  The scatter of a measured
resonance peak, and with it the posterior-predictive interval of a measured
mode and the observation variance of the mode-frequency bias, is set by the
noise of the *measurement*, not by the misfit of the model, nor by the
part of the noise that a flexible model (the remainder's smooth FRF
discrepancy) absorbs and so leaves out of its fitted scale.  The discrepancy
workflow uses the package's one model-free estimate,
:func:`bayes_rcsa.stats.noise.relative_noise_scale` (second differences,
median over the band; NaN with fewer than 5 lines), alone for the measured
peak's scatter; this module keeps its name for the workflow's imports.
"""

from __future__ import annotations

from ..stats.noise import relative_noise_scale

__all__ = ["relative_noise_scale"]
