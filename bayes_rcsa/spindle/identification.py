"""The spindle identification workflow for one direction: noise, inversion, smoothing, flags, samples.

1. Noise level of every FRF: given in the artifact file, else estimated
   from the data (:mod:`.noise`); ``sigma = rel |H| + floor``.
2. Line-by-line inverse coupling in closed form (:mod:`.inverse`, Namazi's
   equations; the finite-difference route of :mod:`.rotations` is biased
   for Timoshenko artifacts and only kept for comparison) -> the raw block.
3. Modal smoothing (:mod:`.smoothing`) in three stages: weights linearised
   at the raw block (mode-count search), again at the smoothed block (the
   raw block is far off in ill-conditioned bands, and so are weights
   computed there), then a fit to the hammer tests themselves.
4. Reliability: the noise propagated through the coupling at the smoothed
   block gives the relative standard deviation of the block per line,
   ``eps(f) = ||std(S)|| / ||S||`` in the scaled Frobenius norm (h, l, n, p
   divided by typical magnitudes ``lam_h^2``, ``lam_h lam_p``, ``lam_p^2``, so
   that no entry dominates by its units and the zero crossings of single
   entries do not count as unreliable).  Lines with ``eps`` above the
   threshold are flagged; the smoothed model bridges them.
5. Bootstrap samples (:mod:`.uncertainty`): fresh noise on the hammer
   tests (and, optionally, perturbed artifact material properties), refit
   in measurement space.  Replicates cycle through the BIC-best mode count
   and the next larger counts tried: the noise-only spread of one model
   structure is far narrower than the error the structure itself makes
   (measured on the synthetic bench: the tool-point natural frequency
   predicted with the identified spindle was off by about 17 noise-only
   standard deviations, and the mode-count mixture brings the truth within
   or next to the sample range; docs/spindle.md).
"""

from __future__ import annotations

import math
import os
import queue
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from ..threads import THREAD_VARIABLES
from .artifact import ArtifactSetup
from .inverse import combine_cross, forward_artifact, forward_jacobian, inverse_exact, propagated_std, unreliable_bands
from .noise import estimate_relative_noise, noise_sigma
from .smoothing import (
    FitData, MeasurementData, ModalFit, block_entries, fit_mode_count, fit_modal_model, is_passive, is_reciprocal, refine,
    whitened_data,
)
from .substructure import artifact_receptances, scaled_segments
from .uncertainty import bootstrap

__all__ = ["SpindleIdentification", "identify_direction", "identify_directions", "estimated_cpu_seconds",
           "block_error"]
# Residual evaluations per bootstrap refit: it starts at the nominal optimum,
# about one standard deviation from its own, and a few Gauss-Newton steps get
# there; the cap bounds the cost of crawling along flat valleys (mode pairs
# that only matter inside flagged bands).
_BOOTSTRAP_NFEV = 40
_COMPONENT = {"h11": 0, "h12": 1, "h21": 1, "h22": 2}
# CPU seconds per direction measured on the synthetic artifact (3801 lines, benchmarks/spindle.py, 2026-11-30 on
# the 2-core development machine): the nominal fit (3.5), the bootstrap start fits (two larger mode counts,
# 1.7), one replicate (0.18); `bayes-rcsa spindle --workers 1 --samples 50` took 28.2 s CPU for two directions,
# this estimate 2 x 14.2 s.  (The former 7.0 / 8.0 / 0.5 predated the speed-ups of issue #41's rounds: 2.8x high.)
_COST_FIT, _COST_STARTS, _COST_SAMPLE = 3.5, 1.7, 0.18


def estimated_cpu_seconds(n_samples: int) -> float:
    """CPU seconds :func:`identify_direction` takes for one direction of about 4000 lines."""
    return _COST_FIT + (_COST_STARTS + _COST_SAMPLE * n_samples if n_samples else 0.0)


@dataclass(frozen=True)
class SpindleIdentification:
    """Everything identified for one direction.

    Attributes
    ----------
    direction : str
    frequency_hz : (n_freq,) Hz
    raw : (n_freq, 2, 2) complex, line-by-line inverse coupling
    smoothed : (n_freq, 2, 2) complex, the modal model on the grid (reciprocal, passive)
    fit : ModalFit
    measured : (n_freq, 3) complex, H11, H12 (combined), H22 in m/N
    reproduced : (n_freq, 3) complex, the same predicted by coupling ``smoothed`` to the artifact
    sigma : (n_freq, 3) float, their noise standard deviations, m/N
    noise_relative : dict of FRF key to float, the relative noise levels used
    noise_estimated : bool
    std : (n_freq, 3) float, propagated standard deviations of (h, l, p)
    block_error : (n_freq,) float, eps(f), relative standard deviation of the block
    unreliable : (n_freq,) bool
    bands : list of (lo, hi) Hz, runs of unreliable lines
    threshold : float
    condition : (n_freq,) float, condition number of the 3x3 inversion per line
    samples : (n_samples, n_freq, 2, 2) complex or None
    inflation : float, noise inflation of the nominal fit's replicates, sqrt(max(1, reduced chi2))
    sample_mode_counts : tuple of int, mode counts the replicates cycle through
    """

    direction: str
    frequency_hz: np.ndarray
    raw: np.ndarray
    smoothed: np.ndarray
    fit: ModalFit
    measured: np.ndarray
    reproduced: np.ndarray
    sigma: np.ndarray
    noise_relative: dict
    noise_estimated: bool
    std: np.ndarray
    block_error: np.ndarray
    unreliable: np.ndarray
    bands: list
    threshold: float
    condition: np.ndarray
    samples: np.ndarray | None = field(default=None, repr=False)
    inflation: float = 1.0
    sample_mode_counts: tuple = ()

    def summary(self) -> dict:
        """JSON-able summary (modal model, mode-count criterion, flags, noise)."""
        m = self.fit.model
        return {
            "direction": self.direction,
            "frequency_range_hz": [float(self.frequency_hz[0]), float(self.frequency_hz[-1])],
            "n_lines": int(self.frequency_hz.size),
            "inverse_coupling": "closed-form solution of Namazi's equations (exact rotations)",
            "noise_relative": {k: float(v) for k, v in self.noise_relative.items()},
            "noise_estimated_from_data": self.noise_estimated,
            "modal_model": {"n_modes": m.n_modes, **m.as_dict()},
            "mode_count_criterion": "BIC = N ln(chi2/N) + k ln N (unknown noise scale), minimum over the counts tried",
            "bic_by_mode_count": {str(k): float(v) for k, v in sorted(self.fit.bic.items())},
            "reduced_chi2": float(self.fit.reduced_chi2),
            "reciprocal": is_reciprocal(self.smoothed),
            "passive": is_passive(self.smoothed),
            "unreliable_threshold": self.threshold,
            "unreliable_fraction": float(np.mean(self.unreliable)),
            "unreliable_bands_hz": [list(b) for b in self.bands],
            "median_block_relative_std": float(np.median(self.block_error)),
            "n_samples": 0 if self.samples is None else int(self.samples.shape[0]),
            "bootstrap_noise_inflation": float(self.inflation),
            "bootstrap_mode_counts": list(self.sample_mode_counts),
        }


def block_error(block: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Relative standard deviation of a block in the scaled Frobenius norm, shape (n_freq,).

    Parameters
    ----------
    block : (n_freq, 2, 2) complex
    std : (n_freq, 3) float, standard deviations of (h, l, p)
    """
    ent = block_entries(block)
    lam2_h = float(np.median(np.abs(ent[:, 0])))
    lam2_p = float(np.median(np.abs(ent[:, 2])))
    scale = np.array([lam2_h, math.sqrt(lam2_h * lam2_p), lam2_p])
    mult = np.array([1.0, 2.0, 1.0])  # l and n both count
    num = np.sum(mult * (std / scale) ** 2, axis=-1)
    den = np.sum(mult * (np.abs(ent) / scale) ** 2, axis=-1)
    return np.sqrt(num / den)


def _replicate_draws(g: np.random.Generator, setup: ArtifactSetup, shape: tuple) -> tuple:
    """The random numbers of one bootstrap replicate, in the order they are drawn.

    Returns
    -------
    z : (2, n_freq, m) float, standard normal (real and imaginary parts of the test noise)
    factors : (float, float) or None
        Log-normal factors of Young's modulus and density (positive whatever
        the draw), or None when the artifact file gives no material uncertainty.
    """
    z = g.standard_normal((2,) + tuple(shape))
    if not (setup.youngs_modulus_rsd or setup.density_rsd):
        return z, None
    fe = math.exp(setup.youngs_modulus_rsd * g.standard_normal())
    fr = math.exp(setup.density_rsd * g.standard_normal())
    return z, (fe, fr)


def _stages(fit: ModalFit, data: FitData, measurements: MeasurementData) -> ModalFit:
    """Second pass (weights at the smoothed block), then the measurement-space fit."""
    return refine(refine(fit, data, max_nfev=300), measurements, max_nfev=300)


def identify_direction(
    setup: ArtifactSetup,
    direction: str,
    n_samples: int = 0,
    rng: np.random.Generator | None = None,
    max_modes: int | None = None,
    structural_counts: int = 2,
    progress=None,
) -> SpindleIdentification:
    """Identify the flange receptance of one direction from the artifact tests.

    Parameters
    ----------
    setup : ArtifactSetup
        With measurements loaded.
    direction : {"x", "y"}
    n_samples : int
        Bootstrap samples to draw (0: none).
    rng : numpy.random.Generator
        Required when ``n_samples > 0``.
    max_modes : int, optional
        Overrides ``setup.max_modes``.
    structural_counts : int
        The bootstrap replicates cycle through the BIC-best mode count and up
        to this many larger counts (those the search tried), to express that
        the data do not pin down the model structure (docs/spindle.md).
    progress : callable(fraction) or None
        Called after the nominal fit, the start fits of the bootstrap and each
        replicate (fractions weighted by their measured cost).

    Returns
    -------
    SpindleIdentification
    """
    if direction not in setup.measurements:
        raise SetupError(f"{setup.path}: no [[measurement]] for direction {direction!r}; have {sorted(setup.measurements)}")
    if n_samples and rng is None:
        raise SetupError("bootstrap samples need an explicit random generator")
    meas = setup.measurements[direction]
    f = meas.frequency_hz
    omega = 2 * np.pi * f
    artifact = setup.artifact
    ar = artifact_receptances(artifact, omega)
    frfs = {k: v.values for k, v in meas.frfs().items()}
    keys = sorted(frfs)  # fixed order: reproducible draws

    estimated = setup.noise_relative is None
    rel = {k: (estimate_relative_noise(v) if estimated else setup.noise_relative) for k, v in frfs.items()}
    sig = {k: noise_sigma(v, rel[k], setup.noise_floor) for k, v in frfs.items()}
    if not all(np.all(s > 0) for s in sig.values()):
        raise SetupError(
            f"{setup.path}: direction {direction!r}: zero noise standard deviation on some lines; give "
            "[noise] relative and/or floor > 0"
        )
    g12, s12 = combine_cross(frfs.get("h12"), frfs.get("h21"), sig.get("h12"), sig.get("h21"))
    measured = np.stack([frfs["h11"], g12, frfs["h22"]], axis=-1)
    sigma = np.stack([sig["h11"], s12, sig["h22"]], axis=-1)
    inverse = inverse_exact(ar, measured)
    raw = inverse.block

    first = fit_modal_model(whitened_data(ar, raw, sigma), max_modes=max_modes or setup.max_modes)
    data = whitened_data(ar, raw, sigma, linearize_at=first.model.block(f))
    tests = MeasurementData(ar, np.stack([frfs[k] for k in keys], axis=-1),
                            np.array([_COMPONENT[k] for k in keys]), np.stack([sig[k] for k in keys], axis=-1))
    fit = _stages(first, data, tests)
    smoothed = fit.model.block(f)
    total = estimated_cpu_seconds(n_samples)
    if progress is not None:
        progress(_COST_FIT / total)

    std = propagated_std(forward_jacobian(ar, smoothed), sigma)
    eps = block_error(smoothed, std)
    flagged = eps > setup.unreliable_threshold
    inflation = math.sqrt(max(1.0, fit.reduced_chi2))

    samples, counts = None, ()
    if n_samples:
        n0 = fit.model.n_modes
        starts = [fit] + [_stages(fit_mode_count(first, data, n), data, tests)
                          for n in range(n0 + 1, n0 + 1 + structural_counts) if n in first.search_x]
        counts = tuple(s.model.n_modes for s in starts)
        segments = artifact.segments()
        if progress is not None:
            progress((_COST_FIT + _COST_STARTS) / total)

        def replicate(g: np.random.Generator, index: int) -> np.ndarray:
            start = starts[index % len(starts)]
            scale = math.sqrt(max(1.0, start.reduced_chi2))
            z, factors = _replicate_draws(g, setup, tests.measured.shape)
            noisy = tests.measured + scale * tests.sigma * (z[0] + 1j * z[1]) / math.sqrt(2.0)
            ar_b = ar
            if factors is not None:
                ar_b = artifact_receptances(artifact, omega, scaled_segments(segments, *factors))
            block = refine(start, tests.with_measured(noisy, ar_b), max_nfev=_BOOTSTRAP_NFEV).model.block(f)
            if progress is not None:
                progress((_COST_FIT + _COST_STARTS + _COST_SAMPLE * (index + 1)) / total)
            return block

        samples = bootstrap(replicate, n_samples, rng)

    return SpindleIdentification(
        direction=direction, frequency_hz=f, raw=raw, smoothed=smoothed, fit=fit, measured=measured,
        reproduced=forward_artifact(smoothed, ar), sigma=sigma, noise_relative=rel, noise_estimated=estimated,
        std=std, block_error=eps, unreliable=flagged, bands=unreliable_bands(f, flagged),
        threshold=setup.unreliable_threshold, condition=inverse.condition, samples=samples,
        inflation=inflation, sample_mode_counts=counts,
    )


# ------------------------------------------------------------ several directions


def _skip_draws(rng: np.random.Generator, setup: ArtifactSetup, direction: str, n_samples: int) -> None:
    """Advance ``rng`` past the bootstrap draws of ``direction`` (as :func:`identify_direction` makes them)."""
    meas = setup.measurements[direction]
    shape = (meas.frequency_hz.size, len(meas.frfs()))
    for _ in range(n_samples):
        _replicate_draws(rng, setup, shape)


def _direction_rng(seed: int, setup: ArtifactSetup, directions: tuple, index: int, n_samples: int):
    """The generator of ``directions[index]``: the seed's generator past the draws of the directions before it.

    This is the stream a sequential run (one generator used direction after
    direction) gives that direction, so the samples do not depend on the
    number of worker processes.  Skipping costs only the normal draws
    (about 0.02 s per direction at 50 samples), not the fits.
    """
    rng = np.random.default_rng(seed)
    for d in directions[:index]:
        _skip_draws(rng, setup, d, n_samples)
    return rng


_PROGRESS_QUEUE = None  # set in each worker process by _init_worker


def _init_worker(progress_queue) -> None:
    global _PROGRESS_QUEUE
    _PROGRESS_QUEUE = progress_queue


def _worker(setup: ArtifactSetup, directions: tuple, index: int, n_samples: int, seed: int,
            max_modes: int | None) -> SpindleIdentification:
    d = directions[index]

    def report(fraction: float) -> None:
        if _PROGRESS_QUEUE is not None:
            _PROGRESS_QUEUE.put((index, fraction))

    return identify_direction(setup, d, n_samples=n_samples, rng=_direction_rng(seed, setup, directions, index,
                              n_samples), max_modes=max_modes, progress=report)


def identify_directions(
    setup: ArtifactSetup,
    directions: tuple,
    n_samples: int = 0,
    seed: int = 0,
    max_modes: int | None = None,
    workers: int = 1,
    progress=None,
) -> dict:
    """Identify several directions, optionally in parallel worker processes.

    Parameters
    ----------
    setup : ArtifactSetup
    directions : tuple of str
        In the order their bootstrap draws are taken from the seed's generator.
    n_samples : int
        Bootstrap samples per direction.
    seed : int
        Seed of ``numpy.random.default_rng``.  Direction ``directions[i]``
        uses that generator advanced past the draws of ``directions[:i]``:
        the same samples, to the last bit, as one generator used direction
        after direction, whatever ``workers`` is.
    max_modes : int, optional
    workers : int
        Worker processes (at most one per direction); 1 runs in this process.
        The directions are independent, so two workers on two cores halve
        the wall time.
    progress : callable(fraction) or None
        Overall fraction done (the mean over the directions).

    Returns
    -------
    dict of direction to SpindleIdentification
    """
    directions = tuple(directions)
    workers = max(1, min(int(workers), len(directions)))
    done = [0.0] * len(directions)

    def update(index: int, fraction: float) -> None:
        done[index] = fraction
        if progress is not None:
            progress(sum(done) / len(done))

    if workers == 1:
        out = {}
        for i, d in enumerate(directions):
            out[d] = identify_direction(setup, d, n_samples=n_samples,
                                        rng=_direction_rng(seed, setup, directions, i, n_samples),
                                        max_modes=max_modes, progress=lambda f, i=i: update(i, f))
        return out

    import concurrent.futures as cf
    import multiprocessing

    # spawn: a fresh interpreter per worker (a forked child would inherit this process's BLAS threads)
    ctx = multiprocessing.get_context("spawn")
    progress_queue = ctx.Queue()
    # one BLAS thread per worker (read when the spawned interpreter imports numpy): two workers on two cores
    # with a BLAS thread per core each would fight for the cores
    saved = {k: os.environ.get(k) for k in THREAD_VARIABLES}
    os.environ.update({k: "1" for k in THREAD_VARIABLES})
    try:
        pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                                      initargs=(progress_queue,))
        futures = [pool.submit(_worker, setup, directions, i, n_samples, seed, max_modes)
                   for i in range(len(directions))]
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    with pool:
        pending = set(futures)
        while pending:
            try:
                update(*progress_queue.get(timeout=0.2))
            except queue.Empty:
                pass
            pending = {f for f in pending if not f.done()}
        results = {d: f.result() for d, f in zip(directions, futures)}
    while True:  # the last reports may arrive after their futures finished
        try:
            update(*progress_queue.get_nowait())
        except queue.Empty:
            break
    return results
