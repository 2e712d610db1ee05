"""Likelihood of measured tool-point FRFs given contact (and noise) parameters.

Noise model
-----------
Each band line ``n`` of measurement ``j`` has a complex residual
``r_n = H_model(f_n) - H_meas(f_n)``, modelled as circular complex Gaussian
with variance::

    sigma_n^2 = s_j^2 * v_n(theta),   v_n = (|H_model(f_n)|^2 + (eps * max_band |H_model|)^2) / gamma_n

``s_j`` (``sigma_j``) is the relative noise scale of measurement ``j``, a
sampled parameter; ``eps`` (``noise_floor``, default 0.01) keeps lines near
anti-resonances from dominating; ``gamma_n`` is the measured coherence
(1 when the file has none), which inflates the variance where the hammer
test was unreliable.  Lines with coherence below ``min_coherence`` (default
0.05) carry essentially no information and are left out (counted in the
summary).  The likelihood is computed on the complex FRF, so phase
information is used, not only magnitude.

The proportional part scales with the *model's* ``|H|``, not the measured
one, and the normalisation ``-sum ln(pi s^2 v_n)`` is kept.  Weights taken
from the noisy measured ``|H|`` are correlated with the noise itself; on
the synthetic bench this biased the weakly identified direction of the
posterior (the k_xf-k_thetaM trade-off) enough to lower the 90 % coverage
of k_xf from about 0.86 to 0.79 (benchmarks/calibration.py).  The floor
too is the model's: ``max_band |H_model|`` of the measurement's band lines,
per parameter set.  Taken from the measured band maximum (as before), it
grew with the noise itself, so the likelihood was not the model that
generates the data: where the noise is as large as the signal, the noise
scale's posterior sat below the truth and simulation-based calibration
failed (docs/calibration.md).  The data-only weights ``1 / v_n(measured)``
(with the measured floor) are still used by the optimiser's fast grid
stage (:mod:`.search`), where only the location of the optimum matters and
the noise is small; where a noise scale at its optimum exceeds 0.1 the grid
is searched again with this likelihood's own profile (with noise above the
signal the data-weighted grid ranked a wrong resonance first).

Honest intervals: tempering by the effective number of lines
-------------------------------------------------------------
When the model is imperfect (spindle receptance errors, a lumped contact
standing in for a distributed one, beam-theory idealisation), the residuals
of neighbouring lines are correlated: a smooth discrepancy spans many lines.
Treating them as independent makes the posterior far too narrow.  The
identification therefore

1. finds the posterior optimum with the full likelihood,
2. estimates the integrated autocorrelation length ``tau_r`` (in lines) of
   the normalised residuals there (:func:`residual_correlation_length`,
   FFT autocorrelation with Sokal's adaptive window, pooled over
   measurements), and
3. samples with the likelihood raised to the power ``beta = 1 / tau_r``,
   i.e. with ``n_lines / tau_r`` effective independent lines.

Together with the inferred noise scales (which absorb the *size* of the
discrepancy) this widens the intervals where the data cannot be trusted
line by line, and leaves them unchanged (``beta = 1``) for white noise.
It does not remove a systematic bias (e.g. from a wrong spindle file); see
docs/identification.md for the measured coverage in both situations.
The calibration test (tests/test_inference_calibration.py) checks that the
resulting 90 % intervals cover the truth in 80-97 % of replicated campaigns
from an independent finite-element model (measured: about 0.81-0.92).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import DataError, SetupError
from ..model.assembly import Configuration, ConfigurationStack, ToolPointModel
from ..model.receptance import FRF
from ..params.forward import ForwardModel
from ..params.model import ParameterModel
from .band import Band, MIN_LINES, band_mask

__all__ = [
    "band_floor",
    "noise_variance",
    "Observation",
    "NoiseModel",
    "FRFLikelihood",
    "make_observation",
    "residual_correlation_length",
    "weighted_sums",
]


@dataclass(frozen=True)
class Observation:
    """The band lines of one measured FRF.

    Attributes
    ----------
    configuration : Configuration
    frequency_hz : (n,) Hz
    values : (n,) complex, m/N
    coherence : (n,) or None
    band : Band
    source : str
    n_low_coherence : int
        Band lines dropped for coherence below the threshold.
    """

    configuration: Configuration
    frequency_hz: np.ndarray
    values: np.ndarray
    coherence: np.ndarray | None
    band: Band
    source: str
    n_low_coherence: int = 0

    @property
    def n_lines(self) -> int:
        return self.frequency_hz.size


def make_observation(frf: FRF, configuration: Configuration, band: Band, min_coherence: float = 0.05) -> Observation:
    """Restrict ``frf`` to ``band`` (and to lines of usable coherence).

    Raises
    ------
    DataError
        If fewer than three usable lines remain.
    """
    mask = band_mask(frf, band)
    n_low = 0
    coh = None
    if frf.coherence is not None:
        low = mask & (frf.coherence < min_coherence)
        n_low = int(np.count_nonzero(low))
        mask = mask & ~low
        if np.count_nonzero(mask) < MIN_LINES:
            raise DataError(
                f"{frf.source}: only {np.count_nonzero(mask)} lines of the band {band.lo_hz:g}-{band.hi_hz:g} Hz "
                f"have coherence >= {min_coherence:g}"
            )
        coh = frf.coherence[mask]
    return Observation(configuration, frf.frequency_hz[mask], frf.values[mask], coh, band, frf.source, n_low)


@dataclass(frozen=True)
class NoiseModel:
    """Shape of the noise variance (see the module docstring).

    Attributes
    ----------
    floor : float
        eps, relative to the largest ``|H|`` in the band of each measurement (the model's in the likelihood,
        the measured one in the optimiser's data-only grid weights).
    min_coherence : float
        Lines with lower coherence are left out.
    """

    floor: float = 0.01
    min_coherence: float = 0.05

    def __post_init__(self) -> None:
        if not (math.isfinite(self.floor) and self.floor >= 0):
            raise SetupError(f"likelihood noise_floor = {self.floor!r}: expected a finite number >= 0")
        if not (math.isfinite(self.min_coherence) and 0 <= self.min_coherence < 1):
            raise SetupError(f"likelihood min_coherence = {self.min_coherence!r}: expected 0 <= value < 1")

    def floor2(self, obs: Observation) -> float:
        """(eps max |H_meas|)^2 of one measurement, (m/N)^2 (the data-only grid weights)."""
        return float((self.floor**2) * np.max(np.abs(obs.values) ** 2))

    def variance_shape(self, obs: Observation) -> np.ndarray:
        """v_n (n,) in (m/N)^2 with the *measured* |H| (the optimiser's grid weights)."""
        v = np.abs(obs.values) ** 2 + self.floor2(obs)
        if obs.coherence is not None:
            v = v / obs.coherence
        if not np.all(v > 0):
            raise DataError(f"{obs.source}: zero receptance in the band and noise_floor = 0; set a positive noise floor")
        return v


def band_floor(abs2: np.ndarray, eps2: float, slices) -> np.ndarray:
    """The noise floor ``eps2 max_band |H|^2`` of every line, each measurement's own band maximum, (n, n_lines) (m/N)^2.

    Parameters
    ----------
    abs2 : (n, n_lines) float, ``|H_model|^2`` (m/N)^2 of n parameter sets
    eps2 : float, the squared relative noise floor
    slices : sequence of slice, each measurement's lines (contiguous, in order, covering ``n_lines``)
    """
    starts = np.array([sl.start for sl in slices])
    peak = np.maximum.reduceat(abs2, starts, axis=1)  # (n, n_meas): each measurement's band maximum
    return eps2 * np.repeat(peak, [sl.stop - sl.start for sl in slices], axis=1)


def noise_variance(abs2: np.ndarray, coherence: np.ndarray, eps2: float, slices, floor=None) -> np.ndarray:
    """The noise model's variance ``v_n = (|H_n|^2 + eps2 max_band |H|^2) / gamma_n`` on every line, (m/N)^2.

    The one formula of the likelihood's noise variance (the floor is each measurement's own band maximum of
    the *model* FRF); the optimiser's exact grid and the discrepancy workflow's noise draws use it too.

    Parameters
    ----------
    abs2 : (n, n_lines) float, ``|H_model|^2`` (m/N)^2 of n parameter sets
    coherence : (n_lines,) float in (0, 1]
    eps2 : float, the squared relative noise floor
    slices : sequence of slice, each measurement's lines (contiguous, in order, covering ``n_lines``)
    floor : (1 or n, n_lines) float, optional
        The floor held at a reference model (:func:`band_floor` of its ``|H|^2``) instead of each set's own:
        a least-squares solver that linearises at a point keeps it fixed over its steps (see
        :func:`bayes_rcsa.discrepancy.fit.whitened_residuals`).

    Returns
    -------
    (n, n_lines) float
    """
    if floor is None:
        floor = band_floor(abs2, eps2, slices)
    return (abs2 + floor) / coherence


# The compiled terms are loaded on the first evaluation: importing numba costs 0.3-0.6 s that reading a setup or
# reporting an error should not pay.
_TERMS = None


def _terms_kernel():
    global _TERMS
    if _TERMS is None:
        from ._likelihood_jit import likelihood_terms

        _TERMS = likelihood_terms
    return _TERMS


class FRFLikelihood:
    """Vectorised log-likelihood of all measurements for a batch of parameter vectors.

    Parameters
    ----------
    model : ToolPointModel
    observations : sequence of Observation
        One per measurement; their order defines ``sigma_0, sigma_1, ...``.
    parameters : ParameterModel
    noise : NoiseModel
    tempering : float
        beta in (0, 1], the power of the likelihood (1 / correlation length).

    Notes
    -----
    The forward model is precomputed on the band lines only, once.  A call
    costs one :meth:`bayes_rcsa.params.ForwardModel.frf` (without structural
    model terms: one :meth:`ConfigurationStack.frf`) plus a few elementwise
    operations per line.

    Attributes
    ----------
    parameters : ParameterModel
    forward : ForwardModel
        On :attr:`stack`, the band lines of all observations.
    """

    def __init__(
        self,
        model: ToolPointModel,
        observations: Sequence[Observation],
        parameters: ParameterModel,
        noise: NoiseModel = NoiseModel(),
        tempering: float = 1.0,
        stack: ConfigurationStack | None = None,
    ):
        if len(observations) == 0:
            raise SetupError("the likelihood needs at least one measurement")
        if parameters.n_measurements != len(observations):
            raise SetupError(f"the parameter model has {parameters.n_measurements} noise scales for "
                             f"{len(observations)} measurements")
        if not (0 < tempering <= 1):
            raise SetupError(f"likelihood tempering = {tempering!r}: expected 0 < beta <= 1")
        self.model = model
        self.observations = tuple(observations)
        self.parameters = parameters
        self.noise = noise
        self.tempering = float(tempering)
        self.stack = stack if stack is not None else ConfigurationStack(
            [model.precompute(o.configuration, o.frequency_hz) for o in self.observations]
        )
        self.data = np.concatenate([o.values for o in self.observations])
        v = np.concatenate([noise.variance_shape(o) for o in self.observations])
        self.weight = 1.0 / v  # data-only weights (the optimiser's grid stage)
        self._floor_eps2 = float(noise.floor) ** 2
        self._starts = np.array([sl.start for sl in self.stack.slices])
        self._starts_all = np.array([sl.start for sl in self.stack.slices] + [self.stack.n_lines], dtype=np.int64)
        self._data_f = np.array(self.data, dtype=np.complex128).view(np.float64)
        if not self._floor_eps2 > 0:
            # a model receptance of zero on any line would make a variance zero
            raise DataError("noise_floor = 0 needs a non-zero model receptance everywhere; set a positive noise floor")
        self.coherence = np.concatenate(
            [o.coherence if o.coherence is not None else np.ones(o.n_lines) for o in self.observations]
        )
        # the compiled terms' inputs: fresh C-contiguous float64 arrays (numba compiles one version per array type)
        self._coherence_f = np.array(self.coherence, dtype=np.float64)
        # Grid weights on the float view (re, im interleaved) of the complex residuals.
        self._w2 = np.repeat(self.weight, 2)
        self._float_slices = [slice(2 * s.start, 2 * s.stop) for s in self.stack.slices]
        self.lengths = np.array([o.configuration.clamping_length for o in self.observations])
        self.n_per = np.array([o.n_lines for o in self.observations])
        self.forward = ForwardModel(parameters, self.stack, model)
        self._noise_names = list(parameters.noise_names)

    @property
    def n_lines(self) -> int:
        return self.data.size

    def with_tempering(self, beta: float) -> "FRFLikelihood":
        """The same likelihood raised to the power ``beta`` (shares the cache)."""
        return FRFLikelihood(self.model, self.observations, self.parameters, self.noise, beta, stack=self.stack)

    def model_frf(self, theta: np.ndarray) -> np.ndarray:
        """Predicted FRF on all band lines, (n, n_lines) complex m/N."""
        return self.forward.frf_theta(theta)

    def _model_frf(self, v) -> np.ndarray:
        return self.forward.frf(v)

    def _floor2(self, abs2: np.ndarray) -> np.ndarray:
        """(eps max_band |H_model|)^2 per measurement, spread over its lines: (n, n_lines) from ``abs2`` = |H_model|^2."""
        peak = np.maximum.reduceat(abs2, self._starts, axis=1)  # (n, n_meas): each measurement's band maximum
        return self._floor_eps2 * peak[:, self.stack.index]

    def floor_of(self, h: np.ndarray) -> np.ndarray:
        """The noise floor ``eps2 max_band |h|^2`` of model FRFs ``h`` (n, n_lines) complex m/N.

        Returns (n, n_lines) (m/N)^2.
        """
        return band_floor(np.abs(np.atleast_2d(h)) ** 2, self._floor_eps2, self.stack.slices)

    def variance_of(self, h: np.ndarray, floor: np.ndarray | None = None) -> np.ndarray:
        """v_n of the noise model for model FRFs ``h`` (n, n_lines) complex m/N: (n, n_lines) in (m/N)^2.

        ``floor`` (1 or n, n_lines), optional: the floor held at a reference model (:meth:`floor_of`), for a
        least-squares solver; by default each set's own, as the likelihood has it.

        Raises
        ------
        DataError
            A zero variance (a model receptance of zero on a line with ``noise_floor = 0``).
        """
        var = noise_variance(np.abs(np.atleast_2d(h)) ** 2, self.coherence, self._floor_eps2, self.stack.slices,
                             floor)
        if not np.all(var > 0):
            raise DataError("noise_floor = 0 needs a non-zero model receptance everywhere; set a positive noise floor")
        return var

    def _terms(self, v):
        """|r_n|^2 / v_n and v_n for parameter values ``v``: two (n, n_lines) arrays.

        One compiled pass over the lines (:func:`._likelihood_jit.likelihood_terms`) where the model FRFs are a
        fresh C-contiguous array (always, from :class:`.ForwardModel`); the numpy expressions of
        :meth:`_terms_numpy`, the same numbers bit for bit, otherwise.  On the sampler's walker halves the
        numpy expressions' eight full-size temporaries cost about as much as the compiled FRF itself.
        """
        h = self._model_frf(v)
        if not (h.ndim == 2 and h.dtype == np.complex128 and h.flags.c_contiguous and h.flags.writeable):
            return self._terms_numpy(h)
        n, n_lines = h.shape
        q, var = np.empty((n, n_lines)), np.empty((n, n_lines))
        (_TERMS or _terms_kernel())(h.view(np.float64), self._data_f, self._coherence_f, self._starts_all,
                                    self._floor_eps2, q, var)
        return q, var

    def _terms_numpy(self, h):
        """:meth:`_terms` from model FRFs ``h`` (n, n_lines) complex (modified in place), with numpy."""
        hv = h.view(np.float64)
        var = hv[:, 0::2] ** 2 + hv[:, 1::2] ** 2  # |H_model|^2
        var += self._floor2(var)
        var /= self.coherence
        h -= self.data
        rv = h.view(np.float64)
        return (rv[:, 0::2] ** 2 + rv[:, 1::2] ** 2) / var, var

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Tempered log-likelihood, (n,) for theta (n, ndim)."""
        v = self.parameters.values(np.atleast_2d(theta))
        q, var = self._terms(v)
        s2 = np.column_stack([v[n] for n in self._noise_names]) ** 2  # (n, n_meas)
        qj = np.stack([q[:, sl].sum(axis=1) for sl in self.stack.slices], axis=1)
        ll = -np.sum(qj / s2 + self.n_per * np.log(np.pi * s2), axis=1) - np.log(var).sum(axis=1)
        return self.tempering * ll

    def pointwise(self, theta: np.ndarray) -> np.ndarray:
        """Tempered log-likelihood of every band line, (n, n_lines).

        Sums to :meth:`__call__` over the line axis; used for LOO/WAIC.
        """
        v = self.parameters.values(np.atleast_2d(theta))
        q, var = self._terms(v)
        s2 = np.column_stack([v[n] for n in self._noise_names])[:, self.stack.index] ** 2
        return self.tempering * (-q / s2 - np.log(np.pi * s2 * var))

    def variance_shape(self, theta: np.ndarray) -> np.ndarray:
        """v_n(theta) of the noise model (without ``s_j^2``), (n, n_lines) in (m/N)^2."""
        return self.variance_of(self.model_frf(theta))

    def normalised_residuals(self, theta: np.ndarray) -> np.ndarray:
        """``r_n / sigma_n`` for one parameter vector, (n_lines,) complex."""
        v = self.parameters.values(np.atleast_2d(theta))
        h = self._model_frf(v)[0]
        var = self.variance_of(h)[0]
        s = np.array([v[n][0] for n in self._noise_names])[self.stack.index]
        return (h - self.data) / (s * np.sqrt(var))


def weighted_sums(r: np.ndarray, w2: np.ndarray, float_slices) -> np.ndarray:
    """``sum_n w_n |r_n|^2`` per measurement, (n, n_meas), for complex ``r`` (n, n_lines).

    Works on the float view of ``r`` with einsum's own loops rather than a
    BLAS matrix product: on a small shared machine a multithreaded BLAS call
    per walker batch leaves spinning threads that slow everything else.
    """
    rv = r.view(np.float64)
    sq = rv * rv
    return np.stack([np.einsum("ij,j->i", sq[:, s], w2[s]) for s in float_slices], axis=1)


def residual_correlation_length(residuals: np.ndarray, slices: Sequence[slice], c: float = 5.0) -> float:
    """Integrated autocorrelation length (in lines) of normalised residuals.

    Parameters
    ----------
    residuals : (n_lines,) complex
        Normalised residuals of all measurements, concatenated.
    slices : sequence of slice
        Lines of each measurement (autocorrelation never crosses files).
    c : float
        Sokal's window constant: the sum stops at the smallest lag ``M``
        with ``M >= c * tau(M)``.

    Returns
    -------
    float >= 1
        ``tau_r = 1 + 2 sum_{k=1}^{M} rho(k)`` with ``rho`` the pooled
        autocorrelation ``Re sum z_n conj(z_{n+k}) / sum |z_n|^2``; values
        below 1 (anti-correlated residuals) are reported as 1 so that the
        likelihood is never sharpened beyond independent lines.
    """
    max_len = max(s.stop - s.start for s in slices)
    acov = np.zeros(max_len)
    total = 0.0
    for s in slices:
        z = np.asarray(residuals[s], dtype=complex)
        z = z - z.mean()
        n = z.size
        nfft = 1 << int(math.ceil(math.log2(2 * n)))
        spec = np.fft.fft(z, nfft)
        acf = np.fft.ifft(spec * np.conj(spec))[:n].real  # sum_n z_{n+k} conj(z_n)
        acov[:n] += acf
        total += acf[0]
    if total <= 0:
        return 1.0
    rho = acov / total
    taus = 2.0 * np.cumsum(rho) - 1.0
    m = np.arange(taus.size)
    window = m >= c * taus
    k = int(np.argmax(window)) if np.any(window) else taus.size - 1
    return float(max(1.0, taus[k]))
