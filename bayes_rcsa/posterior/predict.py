"""Posterior predictive tool-point FRFs and per-mode credible intervals.

For every requested configuration (clamping length, direction, tool) the
contact parameters of each posterior draw are carried to the clamping
length by the growth law and pushed through the batched forward model
(:class:`bayes_rcsa.model.ConfigurationStack`, one call per configuration
for all draws).  From the draws of ``H`` this module derives

* quantile bands of ``|H|``, ``Re H`` and ``Im H`` at the levels
  :data:`QUANTILE_LEVELS` (median, 50 % and 90 % central intervals);
* the *modes* of the configuration: local maxima of the posterior-median
  ``|H|`` that reach :data:`MODE_REL_HEIGHT` of its largest value and stand
  out of their surroundings by :data:`MODE_REL_PROMINENCE` of it.  Each
  mode owns the band between the minima of the median ``|H|`` on either
  side, so neighbouring modes never share a line;
* per mode and per draw, the natural frequency (the project's rule,
  :func:`bayes_rcsa.posterior.natural_frequency`, applied within the mode's
  band), the peak magnitude ``max |H|`` on the band's lines (m/N) and the
  dynamic stiffness ``1 / max |H|`` (N/m).  A draw whose maximum falls on a
  band edge has no resonance inside the band: it gets ``NaN`` for all three,
  is left out of the quantiles and counted in ``nan_fraction``;
* where a measurement of the configuration exists, the same three
  quantities of the measured FRF in the same band;
* with a :class:`PredictiveNoise`, the posterior-predictive interval of the
  peak a *new hammer test* would show: every draw's FRF gets the fit's
  measurement noise (circular complex Gaussian with the likelihood's
  variance ``s^2 (|H|^2 + (eps max|H|)^2)``, coherence 1, ``s`` one of the
  draw's fitted noise scales) and the same natural-frequency rule is
  applied to the noisy FRF.  The model interval says where the noise-free
  resonance of the model lies; the predictive one says where a measured
  peak will fall, and is the one to compare a new measurement with.

With spindle samples (:class:`bayes_rcsa.spindle.SpindleSamples`, the
bootstrap samples of ``bayes-rcsa spindle``) every draw also gets one
sample of the flange receptance (balanced random assignment,
:func:`bayes_rcsa.spindle.assign_samples`; the same sample for all targets
of a draw, as the spindle is one machine), so the bands and intervals
include the spindle uncertainty.

:func:`parameter_influence` reports how much each contact parameter alone
moves the predicted natural frequencies across its posterior range, which
shows whether a poorly determined parameter matters for the predictions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import SetupError
from ..model.assembly import Configuration, ConfigurationStack, ToolPointModel
from ..model.receptance import FRF
from ..params.forward import ForwardModel
from .draws import PosteriorDraws
from ..model.natural_frequencies import natural_frequency

__all__ = [
    "QUANTILE_LEVELS",
    "QUANTILE_KEYS",
    "MODE_REL_HEIGHT",
    "MODE_REL_PROMINENCE",
    "PredictionTarget",
    "PredictiveNoise",
    "noisy_frf",
    "FRFBands",
    "ModePrediction",
    "Prediction",
    "prediction_targets",
    "predictive_frf",
    "find_modes",
    "mode_statistics",
    "predict",
    "parameter_influence",
    "quantile_dict",
    "column_quantiles",
]

QUANTILE_LEVELS = (0.05, 0.25, 0.5, 0.75, 0.95)
QUANTILE_KEYS = ("q05", "q25", "q50", "q75", "q95")
# A resonance of the median |H| counts as a mode if it reaches 10 % of the
# largest |H| of the configuration (smaller ones hardly matter for chatter)
# and rises 5 % of that maximum above the valley towards its next higher
# neighbour (so a shoulder on a flank is not a mode of its own).
MODE_REL_HEIGHT = 0.10
MODE_REL_PROMINENCE = 0.05
INFLUENCE_BINS = 5  # equally populated bins of a parameter's draws for parameter_influence
_LENGTH_MATCH = 1e-7  # m, as in the inference package: lengths given in mm match file values to 0.1 um


@dataclass(frozen=True)
class PredictionTarget:
    """A configuration to predict, its frequency lines and its measurement if any.

    Attributes
    ----------
    configuration : Configuration
    frequency_hz : (n_freq,) Hz, strictly increasing
    measured : FRF or None
        A measurement of this configuration (its own lines).
    fitted : bool
        Whether the measurement was used in the fit.
    """

    configuration: Configuration
    frequency_hz: np.ndarray
    measured: FRF | None = None
    fitted: bool = False


@dataclass(frozen=True)
class PredictiveNoise:
    """The fit's measurement-noise model, for simulating new hammer tests.

    Attributes
    ----------
    scale : (n_draws,) float
        Relative noise scale ``s`` of each draw (one of the draw's fitted
        ``sigma_j``, chosen at random: a new test is as noisy as one of the
        fitted ones).
    floor : float
        Noise floor ``eps`` relative to the largest ``|H|`` of the FRF (the
        likelihood's ``noise_floor``).
    rng : numpy.random.Generator
        Draws the noise.
    source : str
        Where the model came from, for the outputs.
    """

    scale: np.ndarray
    floor: float
    rng: np.random.Generator
    source: str = ""

    @classmethod
    def from_draws(cls, draws: PosteriorDraws, floor: float, rng: np.random.Generator,
                   source: str = "") -> "PredictiveNoise | None":
        """Per draw, one of its noise scales ``sigma_j`` picked uniformly; ``None`` without noise scales."""
        names = [n for n in draws.parameters.noise_names if n in draws.values]
        if not names:
            return None
        s = np.column_stack([np.asarray(draws.values[n], dtype=float) for n in names])
        pick = rng.integers(0, len(names), size=s.shape[0])
        return cls(s[np.arange(s.shape[0]), pick], float(floor), rng, source)


def noisy_frf(h: np.ndarray, noise: PredictiveNoise) -> np.ndarray:
    """``h`` plus one simulated measurement noise realisation per draw.

    Parameters
    ----------
    h : (n_draws, n_freq) complex, m/N
        Noise-free FRFs of the draws.
    noise : PredictiveNoise
        ``scale`` must have ``n_draws`` entries.

    Returns
    -------
    (n_draws, n_freq) complex, m/N
        ``h + r`` with ``r`` circular complex Gaussian of variance
        ``s^2 (|h|^2 + (eps max_n |h|)^2)`` per line (coherence 1), as in
        :mod:`bayes_rcsa.inference.likelihood`.
    """
    h = np.asarray(h)
    a = np.abs(h)
    var = noise.scale[:, None] ** 2 * (a**2 + (noise.floor * np.max(a, axis=-1, keepdims=True)) ** 2)
    z = noise.rng.standard_normal(h.shape) + 1j * noise.rng.standard_normal(h.shape)
    return h + np.sqrt(var / 2.0) * z


@dataclass(frozen=True)
class FRFBands:
    """Quantiles of the predictive FRF of one configuration.

    Attributes
    ----------
    configuration : Configuration
    frequency_hz : (n_freq,) Hz
    magnitude, real, imag : (5, n_freq) m/N
        Quantiles of ``|H|``, ``Re H``, ``Im H`` at :data:`QUANTILE_LEVELS`.
    measured : FRF or None
    """

    configuration: Configuration
    frequency_hz: np.ndarray
    magnitude: np.ndarray
    real: np.ndarray
    imag: np.ndarray
    measured: FRF | None = None


@dataclass(frozen=True)
class ModePrediction:
    """Credible intervals of one mode of one configuration.

    Attributes
    ----------
    configuration : Configuration
    mode : int
        1, 2, ... in order of increasing frequency.
    dominant : bool
        The mode with the largest median peak of the configuration.
    band_hz : (lo, hi) Hz
    natural_frequency_hz, peak_magnitude, dynamic_stiffness : dict
        ``{"q05": ..., ..., "q95": ...}`` (Hz, m/N, N/m); ``None`` where no
        draw has a resonance inside the band.
    measured_hz, measured_peak_magnitude : float or None
        Of the measured FRF in the same band (``None`` without measurement
        or when its maximum lies on a band edge).
    has_measurement, fitted : bool
    nan_fraction : float
        Share of draws without a resonance inside the band.
    predictive_peak_hz : dict or None
        Posterior-predictive quantiles of the peak frequency of a new,
        noisy measurement (``None`` without a noise model).
    """

    configuration: Configuration
    mode: int
    dominant: bool
    band_hz: tuple[float, float]
    natural_frequency_hz: dict
    peak_magnitude: dict
    dynamic_stiffness: dict
    measured_hz: float | None
    measured_peak_magnitude: float | None
    has_measurement: bool
    fitted: bool
    nan_fraction: float
    predictive_peak_hz: dict | None = None

    def as_dict(self) -> dict:
        """The ``frequencies.json`` entry of this mode (strict JSON values)."""
        c = self.configuration
        out = {
            "clamping_length": c.clamping_length,
            "direction": c.direction,
            "tool": c.tool,
            "mode": self.mode,
            "dominant": self.dominant,
            "band_lo_hz": self.band_hz[0],
            "band_hi_hz": self.band_hz[1],
        }
        out.update({f"{k}_hz": v for k, v in self.natural_frequency_hz.items()})
        pp = self.predictive_peak_hz
        if pp is not None:
            out.update({f"predictive_peak_{k}_hz": pp[k] for k in ("q05", "q50", "q95")})
        if self.has_measurement:
            out["measured_hz"] = self.measured_hz
            q50, m = self.natural_frequency_hz["q50"], self.measured_hz
            out["error_q50_pct"] = None if q50 is None or m is None else 100.0 * (q50 - m) / m
            lo, hi = self.natural_frequency_hz["q05"], self.natural_frequency_hz["q95"]
            out["measured_in_90"] = None if lo is None or m is None else bool(lo <= m <= hi)
            if pp is not None:
                plo, phi = pp["q05"], pp["q95"]
                out["measured_in_predictive_90"] = None if plo is None or m is None else bool(plo <= m <= phi)
            out["fitted"] = self.fitted
        out["peak_magnitude"] = dict(self.peak_magnitude, unit="m/N")
        out["dynamic_stiffness"] = dict(self.dynamic_stiffness, unit="N/m")
        if self.has_measurement:
            out["peak_magnitude"]["measured"] = self.measured_peak_magnitude
            mp = self.measured_peak_magnitude
            out["dynamic_stiffness"]["measured"] = None if mp is None else 1.0 / mp
        out["nan_fraction"] = self.nan_fraction
        return out


@dataclass(frozen=True)
class Prediction:
    """Everything :func:`predict` computed.

    Attributes
    ----------
    n_draws : int
    bands : tuple of FRFBands, one per target
    modes : tuple of ModePrediction
    influence : tuple of dict
        See :func:`parameter_influence`.
    spindle_uncertainty : dict or None
        :meth:`SpindleSamples.describe` of the spindle samples mixed into the
        draws (``None``: the setup's spindle for every draw).
    """

    n_draws: int
    bands: tuple
    modes: tuple
    influence: tuple
    spindle_uncertainty: dict | None = None


def column_quantiles(a: np.ndarray, levels=QUANTILE_LEVELS) -> np.ndarray:
    """Quantiles over the first axis, as ``numpy.quantile(a, levels, axis=0)`` (linear interpolation).

    Sorting the transposed, contiguous copy once is several times faster
    than numpy's partition along the strided first axis for many levels.

    Parameters
    ----------
    a : (n_draws, n) finite values
    levels : (n_levels,) in [0, 1]

    Returns
    -------
    (n_levels, n)
    """
    s = np.sort(np.ascontiguousarray(np.asarray(a, dtype=float).T), axis=1)
    n = s.shape[1]
    out = np.empty((len(levels), s.shape[0]))
    for i, q in enumerate(levels):
        pos = q * (n - 1)
        lo = int(np.floor(pos))
        hi = min(lo + 1, n - 1)
        frac = pos - lo
        out[i] = s[:, lo] * (1.0 - frac) + s[:, hi] * frac
    return out


def quantile_dict(x, keys: Sequence[str] = QUANTILE_KEYS, levels: Sequence[float] = QUANTILE_LEVELS) -> dict:
    """Quantiles of the finite values of ``x`` as ``{key: float or None}``."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {k: None for k in keys}
    return {k: float(v) for k, v in zip(keys, np.quantile(x, levels))}


# -- targets -----------------------------------------------------------------


def _measurement_for(setup, configuration: Configuration):
    for m in setup.measurements:
        c = m.configuration
        if c.direction == configuration.direction and c.tool == configuration.tool and \
                abs(c.clamping_length - configuration.clamping_length) < _LENGTH_MATCH:
            return m
    return None


def prediction_targets(
    setup,
    lengths: Sequence[float],
    directions: Sequence[str] | None = None,
    tool: str | None = None,
    frequency_hz=None,
    fit_lengths: Sequence[float] = (),
) -> list[PredictionTarget]:
    """Configurations to predict, with their frequency lines and measurements.

    Parameters
    ----------
    setup : Setup
    lengths : sequence of float, m
    directions : sequence of {"x", "y"}, optional
        Default: every direction with a spindle receptance.
    tool : str, optional
        Default: the setup's only tool.
    frequency_hz : (n_freq,) Hz, optional
        Common grid.  Default: the measurement's lines where a measurement
        exists (so that predicted and measured natural frequencies use the
        same lines), otherwise the spindle file's grid.
    fit_lengths : sequence of float, m
        Clamping lengths used in the fit (marks measurements as fitted).

    Raises
    ------
    SetupError
        Unknown direction or tool, a grid outside the spindle data.
    """
    if tool is None:
        if len(setup.tools) != 1:
            raise SetupError(f"the setup defines several tools {sorted(setup.tools)}; name one (--tool)")
        tool = next(iter(setup.tools))
    elif tool not in setup.tools:
        raise SetupError(f"--tool {tool!r}: unknown; the setup defines {sorted(setup.tools)}")
    dirs = tuple(directions) if directions else tuple(sorted(setup.spindle))
    for d in dirs:
        if d not in setup.spindle:
            raise SetupError(f"direction {d!r}: the setup has spindle receptances for {sorted(setup.spindle)} only")
    grid = None if frequency_hz is None else np.asarray(frequency_hz, dtype=float)
    targets = []
    for length in lengths:
        for d in dirs:
            cfg = Configuration(float(length), d, tool)
            spindle_f = setup.spindle[d].frequency_hz
            m = _measurement_for(setup, cfg)
            measured = m.frf if m is not None else None
            if grid is not None:
                f = grid
            elif measured is not None:
                f = measured.frequency_hz
                f = f[(f >= spindle_f[0]) & (f <= spindle_f[-1])]
            else:
                f = spindle_f
            if f.size < 3:
                raise SetupError(f"{cfg.label()}: fewer than 3 frequency lines inside the spindle data "
                                 f"({spindle_f[0]:g}-{spindle_f[-1]:g} Hz)")
            if f[0] < spindle_f[0] or f[-1] > spindle_f[-1]:
                raise SetupError(f"frequency grid {f[0]:g}-{f[-1]:g} Hz leaves the spindle data "
                                 f"({spindle_f[0]:g}-{spindle_f[-1]:g} Hz, direction {d})")
            fitted = measured is not None and any(abs(length - l) < _LENGTH_MATCH for l in fit_lengths)
            targets.append(PredictionTarget(cfg, f, measured, fitted))
    return targets


# -- predictive draws and modes ----------------------------------------------


def predictive_frf(draws: PosteriorDraws, model: ToolPointModel, configuration: Configuration, frequency_hz,
                   cache=None, spindle_samples=None, assignment: np.ndarray | None = None) -> np.ndarray:
    """Tool-point FRF of every draw, (n_draws, n_freq) complex m/N.

    ``cache`` (a :class:`CachedConfiguration` of the same configuration and
    lines) saves the precomputation when given.  The draws' parameter model
    (growth law, model terms) is applied through
    :class:`bayes_rcsa.params.ForwardModel`.

    Parameters
    ----------
    spindle_samples : SpindleSamples, optional
        Flange-receptance samples; draw ``i`` uses sample ``assignment[i]``.
    assignment : (n_draws,) int, optional
        Required with ``spindle_samples`` (:func:`bayes_rcsa.spindle.assign_samples`).
    """
    if cache is None:
        cache = model.precompute(configuration, frequency_hz)
    forward = ForwardModel(draws.parameters, ConfigurationStack([cache]), model, spindle_samples=spindle_samples)
    if spindle_samples is not None and assignment is None:
        raise SetupError("predictive_frf: spindle samples need an assignment of samples to draws (assign_samples)")
    return forward.frf(draws.values, assignment)


def find_modes(frequency_hz, magnitude, rel_height: float = MODE_REL_HEIGHT,
               rel_prominence: float = MODE_REL_PROMINENCE) -> list[tuple[float, float, float]]:
    """Modes of a (median) magnitude curve and the band each one owns.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz
    magnitude : (n_freq,) m/N

    Returns
    -------
    list of (band_lo_hz, band_hi_hz, peak_hz), increasing in frequency; band
    edges are the lines of least magnitude between neighbouring modes (or
    between the outermost modes and the ends of the grid).
    """
    from scipy.signal import find_peaks

    f = np.asarray(frequency_hz, dtype=float)
    a = np.asarray(magnitude, dtype=float)
    top = float(np.max(a))
    peaks, _ = find_peaks(a, height=rel_height * top, prominence=rel_prominence * top)
    if peaks.size == 0:
        # monotone magnitude: no resonance inside the grid
        return []
    edges = [int(np.argmin(a[: peaks[0] + 1]))]
    for p0, p1 in zip(peaks[:-1], peaks[1:]):
        edges.append(int(p0 + np.argmin(a[p0 : p1 + 1])))
    edges.append(int(peaks[-1] + np.argmin(a[peaks[-1] :])))
    out = []
    for k, p in enumerate(peaks):
        lo, hi = edges[k], edges[k + 1]
        # a band needs lines on both sides of the peak for the parabola
        lo = min(lo, p - 1) if p > 0 else lo
        hi = max(hi, p + 1) if p < f.size - 1 else hi
        out.append((float(f[max(lo, 0)]), float(f[min(hi, f.size - 1)]), float(f[p])))
    return out


def mode_statistics(frequency_hz, h, band: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency and peak magnitude of FRFs within a band.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz
    h : (..., n_freq) complex, m/N
    band : (lo, hi) Hz

    Returns
    -------
    natural_frequency : (...) Hz
    peak_magnitude : (...) m/N, ``max |h|`` on the band's lines
        Both ``NaN`` where the maximum lies on a band edge.
    """
    f = np.asarray(frequency_hz, dtype=float)
    fn = natural_frequency(f, h, band)
    mask = (f >= band[0]) & (f <= band[1])
    peak = np.max(np.abs(np.asarray(h)[..., mask]), axis=-1)
    return fn, np.where(np.isfinite(fn), peak, np.nan)


def _mode_predictions(target: PredictionTarget, f: np.ndarray, h: np.ndarray, median_mag: np.ndarray,
                      h_noisy: np.ndarray | None = None):
    """ModePrediction of every mode and the per-draw natural frequencies (n_draws,) of each."""
    modes = find_modes(f, median_mag)
    if not modes:
        return [], []
    peaks = [float(np.max(median_mag[(f >= lo) & (f <= hi)])) for lo, hi, _ in modes]
    dominant = int(np.argmax(peaks))
    out, freqs = [], []
    meas = target.measured
    for k, (lo, hi, _) in enumerate(modes):
        fn, pk = mode_statistics(f, h, (lo, hi))
        m_hz = m_pk = None
        if meas is not None:
            fm = meas.frequency_hz
            if np.count_nonzero((fm >= lo) & (fm <= hi)) >= 3:
                a, b = mode_statistics(fm, meas.values, (lo, hi))
                m_hz = float(a) if np.isfinite(a) else None
                m_pk = float(b) if np.isfinite(b) else None
        with np.errstate(divide="ignore", invalid="ignore"):
            stiffness = 1.0 / pk
        pp = None if h_noisy is None else quantile_dict(natural_frequency(f, h_noisy, (lo, hi)))
        out.append(ModePrediction(
            configuration=target.configuration, mode=k + 1, dominant=(k == dominant), band_hz=(lo, hi),
            natural_frequency_hz=quantile_dict(fn), peak_magnitude=quantile_dict(pk),
            dynamic_stiffness=quantile_dict(stiffness), measured_hz=m_hz, measured_peak_magnitude=m_pk,
            has_measurement=meas is not None, fitted=target.fitted,
            nan_fraction=float(np.mean(~np.isfinite(fn))), predictive_peak_hz=pp,
        ))
        freqs.append(fn)
    return out, freqs


def predict(draws: PosteriorDraws, model: ToolPointModel, targets: Sequence[PredictionTarget],
            influence: bool = True, noise: PredictiveNoise | None = None, spindle_samples=None,
            rng: np.random.Generator | None = None) -> Prediction:
    """Posterior predictive FRF bands and per-mode intervals for every target.

    Parameters
    ----------
    draws : PosteriorDraws
        Use :meth:`PosteriorDraws.subset` beforehand to bound the cost.
    model : ToolPointModel
    targets : sequence of PredictionTarget
    influence : bool
        Also run :func:`parameter_influence`.
    noise : PredictiveNoise, optional
        Also compute each mode's posterior-predictive peak interval of a new
        measurement (``predictive_peak_hz``).
    spindle_samples : SpindleSamples, optional
        Bootstrap samples of the flange receptance: every draw uses one of
        them (the same for all targets), so the bands and intervals include
        the spindle uncertainty.  Directions without samples keep the
        setup's spindle.
    rng : numpy.random.Generator, optional
        Assigns the samples to the draws (:func:`bayes_rcsa.spindle.assign_samples`);
        required with ``spindle_samples``.

    Returns
    -------
    Prediction
    """
    assignment = None
    if spindle_samples is not None:
        if rng is None:
            raise SetupError("predict: spindle samples need an explicit numpy.random.Generator (rng) to assign them "
                             "to the draws")
        from ..spindle.uncertainty import assign_samples  # the spindle package only when samples are used

        assignment = assign_samples(draws.n_draws, spindle_samples.n_samples, rng)
    levels = QUANTILE_LEVELS
    bands, modes, freqs = [], [], []
    for t in targets:
        h = predictive_frf(draws, model, t.configuration, t.frequency_hz, spindle_samples=spindle_samples,
                           assignment=assignment)
        q_mag = column_quantiles(np.abs(h), levels)
        q_re = column_quantiles(h.real, levels)
        q_im = column_quantiles(h.imag, levels)
        bands.append(FRFBands(t.configuration, t.frequency_hz, q_mag, q_re, q_im, t.measured))
        h_noisy = None if noise is None else noisy_frf(h, noise)
        m, fn = _mode_predictions(t, t.frequency_hz, h, q_mag[2], h_noisy)
        modes += m
        freqs += fn
    infl = tuple(parameter_influence(draws, modes, freqs)) if influence else ()
    return Prediction(draws.n_draws, tuple(bands), tuple(modes), infl,
                      None if spindle_samples is None else spindle_samples.describe())


def parameter_influence(draws: PosteriorDraws, modes: Sequence[ModePrediction], frequencies: Sequence[np.ndarray],
                        n_bins: int = INFLUENCE_BINS) -> list[dict]:
    """How much the predicted natural frequencies depend on each sampled parameter (contact, growth, terms).

    The draws are split into ``n_bins`` equally populated bins of one
    parameter's value; within each bin the other parameters follow their
    posterior *given* that value (e.g. along a ridge).  The spread of the
    bin medians of a mode's predicted natural frequency is that parameter's
    influence: 0 means the prediction is the same wherever the parameter
    lies in its posterior.  (A one-at-a-time sweep with the others held at
    their medians would leave a ridge and exaggerate the influence of
    correlated parameters.)  With 1000 draws and 5 bins the Monte Carlo
    noise of a bin median is about 0.09 posterior standard deviations of the
    frequency, so influences below about 0.1 of the 90 % interval width are
    indistinguishable from none.

    Parameters
    ----------
    draws : PosteriorDraws
    modes : sequence of ModePrediction
    frequencies : sequence of (n_draws,) Hz
        Per-draw natural frequency of each mode (``NaN`` allowed).
    n_bins : int

    Returns
    -------
    list of dict
        ``{"parameter", "posterior_q05", "posterior_q95", "clamping_length",
        "direction", "mode", "dominant", "delta_hz", "delta_pct",
        "interval_width_hz", "fraction_of_interval"}``: ``delta_hz`` is the
        largest minus the smallest bin median, ``fraction_of_interval`` its
        ratio to the width of the mode's 90 % interval.
    """
    names = list(draws.sampled)
    if not names or not modes or draws.n_draws < 2 * n_bins:
        return []
    order = {n: np.argsort(np.asarray(draws.values[n]), kind="stable") for n in names}
    ranges = {n: tuple(float(v) for v in np.quantile(draws.values[n], [0.05, 0.95])) for n in names}
    out = []
    for m, fn in zip(modes, frequencies):
        fn = np.asarray(fn, dtype=float)
        q = m.natural_frequency_hz
        width = None if q["q05"] is None else q["q95"] - q["q05"]
        for name in names:
            medians = []
            for chunk in np.array_split(fn[order[name]], n_bins):
                chunk = chunk[np.isfinite(chunk)]
                if chunk.size:
                    medians.append(float(np.median(chunk)))
            delta = float(max(medians) - min(medians)) if len(medians) == n_bins else None
            out.append({
                "parameter": name,
                "posterior_q05": ranges[name][0],
                "posterior_q95": ranges[name][1],
                "clamping_length": m.configuration.clamping_length,
                "direction": m.configuration.direction,
                "mode": m.mode,
                "dominant": m.dominant,
                "delta_hz": delta,
                "delta_pct": None if delta is None or q["q50"] is None else 100.0 * delta / q["q50"],
                "interval_width_hz": width,
                "fraction_of_interval": None if delta is None or not width else delta / width,
            })
    return out
