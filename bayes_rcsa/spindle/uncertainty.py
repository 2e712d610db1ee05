"""Spindle-receptance uncertainty: bootstrap samples, the samples file, and their use downstream.

Bootstrap
---------
A parametric bootstrap over the measurement noise, the artifact model and
the model structure (:func:`bayes_rcsa.spindle.identification.identify_direction`
builds the replicates, :func:`bootstrap` collects them): each replicate
adds fresh circular complex noise of the estimated standard deviation to
the measured H11, H12, H21, H22, optionally perturbs the artifact's Young's
modulus and density (log-normal, the given relative standard deviations),
and refits the modal model to these hammer tests.  Replicates cycle
through the BIC-best mode count and the next larger counts the search
tried (starting from each count's own fit), because the spread of one
model structure under noise alone is much narrower than the error that
the choice of structure makes.  When a fit leaves more misfit than the
noise model explains (reduced chi2 = c > 1), its replicates get noise
inflated by sqrt(c).

Samples file (NPZ, ``numpy.load(..., allow_pickle=False)``)
------------------------------------------------------------
``format``        0-d str ``"bayes_rcsa.spindle_samples/1"``
``frequency_hz``  (n_freq,) float, Hz, strictly increasing
``directions``    (n_dir,) str, e.g. ``["x", "y"]``
``nominal_<d>``   (n_freq, 2, 2) complex128, the smoothed block ``[[h, l], [n, p]]``
``samples_<d>``   (n_samples, n_freq, 2, 2) complex128, bootstrap blocks
``metadata``      0-d str, JSON (source artifact file, seed, mode counts, inflation)

Units as in the spindle CSV: m/N, 1/N, rad/N, rad/(N m).  Every direction
has the same number of samples; sample ``i`` of every direction comes from
the same bootstrap replicate index (the directions are independent tests,
so this pairing carries no correlation, it only keeps indexing simple).

Use in identification, prediction and stability lobes
-----------------------------------------------------
The samples are an input of the forward model:
``bayes_rcsa.params.ForwardModel(parameters, stack, model,
spindle_samples=samples)`` evaluates every parameter set with its own
sample (``frf(values, spindle_sample=assignment)``), model terms included;
:func:`assign_samples` gives every posterior draw a sample.  ``identify``'s
natural-frequency summary, ``bayes_rcsa.posterior.run_prediction`` /
``predict`` and ``bayes_rcsa.stability.posterior_frf_draws`` take
``spindle_samples=``: mixing posterior draws of the contact with spindle
samples propagates the spindle uncertainty into tool-point predictive
intervals and P(stable).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..errors import DataError, SetupError
from ..io.atomic import atomic_path
from ..model.receptance import PointReceptance

__all__ = [
    "SAMPLES_FORMAT", "SpindleSamples", "save_spindle_samples", "load_spindle_samples", "bootstrap",
    "assign_samples",
]

SAMPLES_FORMAT = "bayes_rcsa.spindle_samples/1"


@dataclass(frozen=True)
class SpindleSamples:
    """Smoothed flange blocks and their bootstrap samples, per direction.

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz
    nominal : dict of direction to (n_freq, 2, 2) complex
    samples : dict of direction to (n_samples, n_freq, 2, 2) complex
    metadata : dict (JSON-able)
    source : str
        File name or description, used in messages.
    """

    frequency_hz: np.ndarray
    nominal: dict
    samples: dict
    metadata: dict = field(default_factory=dict)
    source: str = "<spindle samples>"

    def __post_init__(self) -> None:
        f = np.asarray(self.frequency_hz, dtype=float)
        if f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f)) or np.any(f <= 0) or np.any(np.diff(f) <= 0):
            raise DataError(f"{self.source}: frequency_hz must be a 1-D strictly increasing array of values > 0 Hz")
        object.__setattr__(self, "frequency_hz", f)
        if not self.nominal or set(self.nominal) != set(self.samples):
            raise DataError(f"{self.source}: nominal and samples must cover the same, non-empty set of directions")
        counts = set()
        nominal, samples = {}, {}
        for d in self.nominal:
            if d not in ("x", "y"):
                raise DataError(f"{self.source}: direction {d!r}: expected 'x' or 'y'")
            nom = np.asarray(self.nominal[d], dtype=complex)
            smp = np.asarray(self.samples[d], dtype=complex)
            if nom.shape != (f.size, 2, 2) or smp.ndim != 4 or smp.shape[1:] != (f.size, 2, 2):
                raise DataError(
                    f"{self.source}: direction {d!r}: nominal shape {nom.shape} and samples shape {smp.shape}; "
                    f"expected ({f.size}, 2, 2) and (n_samples, {f.size}, 2, 2)"
                )
            if not (np.all(np.isfinite(nom)) and np.all(np.isfinite(smp))):
                raise DataError(f"{self.source}: direction {d!r}: blocks contain NaN or inf")
            counts.add(smp.shape[0])
            nominal[d], samples[d] = nom, smp
        object.__setattr__(self, "nominal", nominal)
        object.__setattr__(self, "samples", samples)
        if len(counts) != 1 or 0 in counts:
            raise DataError(f"{self.source}: every direction needs the same, non-zero number of samples (got {counts})")

    @property
    def directions(self) -> list[str]:
        return sorted(self.nominal)

    @property
    def n_samples(self) -> int:
        return next(iter(self.samples.values())).shape[0]

    def receptance(self, direction: str, index: int | None = None) -> PointReceptance:
        """The nominal block (``index=None``) or sample ``index`` as a PointReceptance."""
        if direction not in self.nominal:
            raise SetupError(f"{self.source}: no spindle samples for direction {direction!r}; have {self.directions}")
        block = self.nominal[direction] if index is None else self.samples[direction][index]
        label = "nominal" if index is None else f"sample {index}"
        return PointReceptance(self.frequency_hz, block, source=f"{self.source} [{direction}, {label}]")

    def spindle(self, index: int | None = None) -> dict[str, PointReceptance]:
        """``{direction: PointReceptance}`` of the nominal blocks or of sample ``index``."""
        return {d: self.receptance(d, index) for d in self.directions}

    def describe(self) -> dict:
        """What the outputs record about the samples used: ``{"file", "n_samples", "directions"}``."""
        return {"file": self.source, "n_samples": self.n_samples, "directions": self.directions}

    def require_directions(self, directions: Sequence[str], option: str = "--spindle-uncertainty") -> None:
        """Raise :class:`SetupError` (naming ``option`` and the file) unless every direction has samples.

        Without samples in a direction the forward model keeps the setup's
        own spindle there; a product that should carry the spindle
        uncertainty in every direction checks first.
        """
        missing = sorted(set(directions) - set(self.directions))
        if missing:
            raise SetupError(f"{option} {self.source}: no samples for direction(s) {missing}; the file has "
                             f"{self.directions}")


def save_spindle_samples(path, samples: SpindleSamples) -> Path:
    """Write the samples file atomically (format in the module notes)."""
    arrays = {
        "format": np.array(SAMPLES_FORMAT),
        "frequency_hz": samples.frequency_hz,
        "directions": np.array(samples.directions),
        "metadata": np.array(json.dumps(samples.metadata, sort_keys=True, allow_nan=False)),
    }
    for d in samples.directions:
        arrays[f"nominal_{d}"] = samples.nominal[d]
        arrays[f"samples_{d}"] = samples.samples[d]
    path = Path(path)
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return path


def load_spindle_samples(path) -> SpindleSamples:
    """Read a spindle-samples file written by ``bayes-rcsa spindle``.

    Raises
    ------
    DataError
        Missing or unreadable file, wrong format tag, missing arrays, bad shapes or values.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: spindle samples file not found")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise DataError(f"{path}: not a readable NPZ spindle samples file ({exc})") from exc
    fmt = str(data.get("format", ""))
    if fmt != SAMPLES_FORMAT:
        raise DataError(f"{path}: format {fmt!r}, expected {SAMPLES_FORMAT!r}")
    try:
        directions = [str(d) for d in data["directions"]]
        nominal = {d: data[f"nominal_{d}"] for d in directions}
        samples = {d: data[f"samples_{d}"] for d in directions}
        metadata = json.loads(str(data["metadata"]))
    except KeyError as exc:
        raise DataError(f"{path}: missing array {exc.args[0]!r}") from None
    except json.JSONDecodeError as exc:
        raise DataError(f"{path}: metadata is not valid JSON ({exc})") from None
    return SpindleSamples(data["frequency_hz"], nominal, samples, metadata, source=str(path))


def bootstrap(
    replicate: Callable[[np.random.Generator, int], np.ndarray],
    n_samples: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Collect ``n_samples`` bootstrap blocks from ``replicate(rng, index)``.

    Parameters
    ----------
    replicate : callable
        Draws replicate ``index`` with the generator and returns its (n_freq, 2, 2) block.
    n_samples : int >= 1
    rng : numpy.random.Generator
        Consumed in sample order, so a seed reproduces the samples.

    Returns
    -------
    (n_samples, n_freq, 2, 2) complex
    """
    if not (isinstance(n_samples, int) and n_samples >= 1):
        raise SetupError(f"number of bootstrap samples {n_samples!r}: expected an integer >= 1")
    return np.stack([replicate(rng, i) for i in range(n_samples)])


# ----------------------------------------------------------------- downstream


def assign_samples(n_draws: int, n_samples: int, rng: np.random.Generator) -> np.ndarray:
    """Spindle sample of every posterior draw: each sample used equally often, order random.

    Returns
    -------
    (n_draws,) int in [0, n_samples)
    """
    if n_samples < 1 or n_draws < 0:
        raise SetupError(f"assign_samples: n_draws = {n_draws}, n_samples = {n_samples}")
    return rng.permutation(np.arange(n_draws) % n_samples)

