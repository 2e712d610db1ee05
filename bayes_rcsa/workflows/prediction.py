"""Posterior predictive tool-point FRFs and natural-frequency intervals at any clamping length (``bayes-rcsa predict``).

:func:`predict` pushes the posterior draws of an identification through the RCSA model at the requested
clamping lengths (measured or not) and returns a :class:`Prediction` that writes frequencies.json,
frf_bands.csv, the plots and report.md/.html.  The job lives in
:mod:`bayes_rcsa.posterior.prediction_outputs`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Sequence

from ..errors import SetupError
from ..messages import merge_warnings, warning_log
from .result import Result, saving
from ._posterior_input import is_path, posterior_parts, setup_of

__all__ = ["predict", "Prediction", "DEFAULT_MAX_DRAWS"]

#: Posterior draws used by default (a random subset; None = all).
DEFAULT_MAX_DRAWS = 1000


@dataclass
class Prediction(Result):
    """Natural-frequency intervals and FRF bands at the requested clamping lengths.

    Attributes
    ----------
    document : dict
        The frequencies.json document: per clamping length, direction and mode the natural-frequency
        quantiles (Hz), the predictive interval of a new measured peak, the measured value where one exists,
        the fit's convergence and the warnings.
    warnings : tuple of str
    folder : Path or None, where the files were written or read (None until saved)
    run : PredictionRun or None, the prediction in memory (FRF bands per line); None after :meth:`load`
    """

    title: ClassVar[str] = "Tool-point prediction"
    files: ClassVar[tuple[str, ...]] = ("frequencies.json", "frf_bands.csv", "report.md", "report.html",
                                        "frf_bands.png", "frf_zoom.png", "natural_frequencies.png")

    document: dict
    warnings: tuple[str, ...] = ()
    folder: Path | None = None
    run: object = field(default=None, repr=False, compare=False)

    @property
    def predictions(self) -> list[dict]:
        """One entry per clamping length, direction and mode (frequencies.json ``predictions``)."""
        return self.document["predictions"]

    @property
    def converged(self) -> bool | None:
        """Whether the fit behind the posterior converged (None when unknown)."""
        return self.document["converged"]

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self.document))

    def headline(self) -> list[tuple[str, str]]:
        rows = []
        for m in self.predictions:
            if not m.get("dominant"):
                continue
            lo, mid, hi = m.get("q05_hz"), m.get("q50_hz"), m.get("q95_hz")
            value = "-" if mid is None else (f"{mid:.1f} Hz" + ("" if lo is None or hi is None
                                                                 else f" (90 %: {lo:.1f} to {hi:.1f} Hz)"))
            if m.get("measured_hz") is not None:
                value += f", measured {m['measured_hz']:.1f} Hz"
            rows.append((f"natural frequency at {m['clamping_length'] * 1e3:g} mm, {m['direction']}", value))
        rows.append(("posterior draws", str(self.document["n_draws"])))
        rows.append(("converged", {True: "yes", False: "no", None: "unknown"}[self.converged]))
        return rows

    def summary_line(self) -> str:
        return (f"{len(self.predictions)} mode interval(s) at {len(self.document['lengths'])} clamping length(s) from "
                f"{self.document['n_draws']} draws; results in {self.folder}")

    def summary_data(self) -> dict:
        return {"n_draws": int(self.document["n_draws"]), "posterior_converged": self.converged}

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write frequencies.json, frf_bands.csv, report.md/.html and (``plots``) the PNG plots; returns the folder."""
        from ..errors import OutputError
        from ..posterior.prediction_outputs import write_prediction_outputs

        if self.run is None:
            raise OutputError("this Prediction was read from its files (Prediction.load): its FRF bands per line are "
                              "not held in memory; compute it again with bayes_rcsa.predict to write it")
        with saving(folder, force) as out:
            write_prediction_outputs(self.run, out, plots=plots, warnings=self.warnings)
        self.folder = Path(folder)
        return self.folder

    @classmethod
    def load(cls, folder) -> "Prediction":
        from ._documents import read_document

        folder = Path(folder)
        document = read_document(folder, "frequencies.json", "predict")
        return cls(document, tuple(document.get("warnings", ())), folder)

    def figures(self) -> dict:
        """FRF bands, the zoom on each dominant mode and the natural frequency against clamping length
        (needs the prediction in memory: empty after :meth:`load`)."""
        if self.run is None:
            return {}
        from ..posterior import plots as P

        p = self.run.prediction
        return {"frf_bands": P.frf_band_plot(p.bands, p.modes, None,
                                             title=f"Posterior predictive |H| ({self.run.meta['n_draws']} draws)")
                ["figure"],
                "frf_zoom": P.frf_zoom_plot(p.bands, p.modes, None)["figure"],
                "natural_frequencies": P.natural_frequency_plot(p.modes, None)["figure"]}


def predict(setup, posterior, lengths: Sequence[float] | None = None, *, directions: Sequence[str] | None = None,
            tool: str | None = None, frequency_hz=None, max_draws: int | None = DEFAULT_MAX_DRAWS, seed: int = 0,
            spindle_samples=None, progress: bool = False) -> Prediction:
    """Posterior predictive FRFs and natural-frequency intervals at ``lengths``.

    Parameters
    ----------
    setup : path of the setup TOML the posterior was identified from, or a loaded Setup (with its measurements)
    posterior : path of posterior.nc, or a ``Posterior`` (:func:`bayes_rcsa.identify`)
    lengths : (n_len,) m, clamping lengths (default: the setup's measured lengths)
    directions : sequence of "x"/"y" or None (default: every direction with a spindle receptance)
    tool : str or None, tool name (default: the setup's only tool)
    frequency_hz : (n_freq,) Hz or None, a common grid (default: the measurement's lines, else the spindle grid)
    max_draws : int or None, a random subset of at most this many draws (None: all)
    seed : int, seed of the draw subset and of the predictive noise
    spindle_samples : SpindleSamples, path of spindle_samples.npz (``bayes-rcsa spindle``) or None: the spindle
        receptance's own uncertainty enters the prediction
    progress : bool, a heartbeat on stderr while it runs

    Returns
    -------
    Prediction
    """
    from ..io.checks import warn_all
    from ..io.progress import Heartbeat
    from ..posterior.prediction_outputs import frequencies_document, run_prediction
    from ..posterior.setup_match import posterior_setup_warnings

    with warning_log() as log:
        parts = posterior_parts(posterior)
        if parts.draws is None and not Path(parts.path).is_file():
            raise SetupError(f"--posterior {parts.path}: no such file (posterior.nc written by 'bayes-rcsa identify')")
        loaded, _ = setup_of(setup)
        warn_all(posterior_setup_warnings(parts.path, loaded, summary_document=parts.summary))
        if lengths is None:
            lengths = sorted({m.clamping_length for m in loaded.measurements})
        lengths = [float(v) for v in lengths]
        if directions is not None:
            directions = list(directions)
            if not directions or any(d not in ("x", "y") for d in directions):
                raise SetupError(f"--directions {','.join(map(str, directions))!r}: expected a comma-separated list "
                                 "of x and y")
        if spindle_samples is not None:
            from ..spindle.uncertainty import load_spindle_samples

            spindle_samples = load_spindle_samples(spindle_samples) if is_path(spindle_samples) else spindle_samples
            spindle_samples.require_directions(directions or sorted(loaded.spindle))
        with Heartbeat(f"predict: {len(lengths)} clamping length(s)", enabled=progress):
            run = run_prediction(loaded, parts.path, lengths, directions, tool, frequency_hz, max_draws=max_draws,
                                 seed=seed, posterior_draws=parts.draws, inference_data=parts.inference_data,
                                 summary=parts.summary, spindle_samples=spindle_samples)
        # the posterior, not the (possibly edited) setup, defines the model: say where they differ
        warns = [note.removeprefix("warning:").strip() for note in run.meta.get("parameter_model_notes", [])
                 if note.startswith("warning:")]
        n_nan = sum(1 for m in run.prediction.modes if m.nan_fraction > 0)
        if n_nan:
            warns.append(f"{n_nan} mode(s) have draws without a resonance inside the mode band "
                         "(see nan_fraction in frequencies.json)")
        if (run.meta.get("posterior_status") or {}).get("converged") is False:
            warns.append(f"the posterior {parts.path} did not converge; these intervals are not reliable")
        # every warning issued (the data checks' and these) also goes into frequencies.json
        warns = merge_warnings(log, warns)
        from ..inference.results import to_jsonable

        return Prediction(to_jsonable(frequencies_document(run, warns)), tuple(warns), None, run)
