"""``identify_spindle``: the spindle-holder flange receptances from standard-artifact hammer tests.

>>> spindle = bayes_rcsa.identify_spindle("artifact.toml", samples=50, seed=0)
>>> spindle.save("spindle_out")                       # spindle_x.csv, spindle_samples.npz, ...
>>> post = bayes_rcsa.identify("setup.toml", spindle_samples=spindle.samples)

The same as ``bayes-rcsa spindle artifact.toml --samples 50 --out spindle_out``
(this call and :meth:`SpindleInterface.save`).  See docs/spindle.md.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from ..errors import DataError, SetupError
from ..messages import warning_log
from .result import Result, saving

__all__ = ["identify_spindle", "SpindleInterface"]


@dataclass
class SpindleInterface(Result):
    """The identified flange receptances of a spindle, per direction (what ``bayes-rcsa spindle`` writes).

    Attributes
    ----------
    summary : dict
        spindle_summary.json of a save with plots (modal models, noise, flagged bands, warnings).
    receptances : dict of direction to PointReceptance
        The smoothed flange blocks [[h, l], [n, p]] (m/N, 1/N, rad/N, rad/(N m)): the setup's ``[spindle]`` files.
    raw : dict of direction to PointReceptance
        The line-by-line inverse coupling (noisy; for inspection).
    samples : SpindleSamples or None
        The bootstrap samples (``None`` with ``samples=0``); pass them to ``identify``, ``predict`` or
        ``lobes`` as ``spindle_samples=``.
    path : Path or None
        The folder it was saved to or loaded from.
    warnings : tuple of str
    identifications : dict of direction to SpindleIdentification, or None
        The full identification (modal fit, measured and reproduced tests); ``None`` when loaded from files,
        which then can neither be saved again nor drawn.
    """

    title: ClassVar[str] = "Spindle flange receptances"
    files: ClassVar[tuple[str, ...]] = ("spindle_<d>.csv", "spindle_<d>_raw.csv", "spindle_<d>_reliability.csv",
                                        "spindle_samples.npz", "spindle_summary.json", "spindle_<d>.png",
                                        "artifact_<d>.png")

    summary: dict
    receptances: dict
    raw: dict
    samples: object = None
    path: Path | None = None
    warnings: tuple[str, ...] = ()
    identifications: dict | None = field(default=None, repr=False, compare=False)
    artifact: object = field(default=None, repr=False, compare=False)  # the ArtifactSetup

    @property
    def directions(self) -> tuple[str, ...]:
        return tuple(self.summary["directions"])

    # -- numbers ---------------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """spindle_summary.json (as written with plots)."""
        return self.summary

    def headline(self) -> list[tuple[str, str]]:
        rows = []
        for d, s in self.summary["directions"].items():
            lo, hi = s["frequency_range_hz"]
            bands = ", ".join(f"{a:g}-{b:g} Hz" for a, b in s["unreliable_bands_hz"]) or "none"
            rows += [(f"direction {d}", f"{s['modal_model']['n_modes']} modes, {lo:g}-{hi:g} Hz, "
                      f"reduced chi2 {s['reduced_chi2']:.3g}"),
                     (f"unreliable inversion bands ({d})", bands)]
        n = 0 if self.samples is None else self.samples.n_samples
        return rows + [("bootstrap samples", f"{n} per direction")]

    def _written(self) -> list[str]:
        files = [f"spindle_{d}.csv" for d in self.directions]
        return files + ([self.summary["samples_file"]] if self.summary["samples_file"] else [])

    def summary_line(self) -> str:
        return f"wrote {', '.join(self._written())} in {self.path}"

    def summary_data(self) -> dict:
        return {"spindle_files": {d: f"spindle_{d}.csv" for d in self.directions},
                "samples": self.summary["samples_file"]}

    # -- files -----------------------------------------------------------------------------------------------
    def _in_memory(self, what: str) -> None:
        if self.identifications is None:
            raise SetupError(f"{what}: this spindle result was loaded from {self.path}; its identification is not in "
                             "memory (run identify_spindle again)")

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the files of ``bayes-rcsa spindle`` into ``folder``; returns spindle_summary.json's path."""
        from ..spindle.outputs import SUMMARY_FILE, write_outputs

        self._in_memory("save")
        with saving(folder, force) as out:
            write_outputs(self.artifact, self.identifications, out, plots=plots, seed=self.summary["seed"],
                          warnings=self.warnings, samples=self.samples)
        self.path = Path(folder)
        return self.path / SUMMARY_FILE

    @classmethod
    def load(cls, folder) -> "SpindleInterface":
        """Read a folder written by :meth:`save` (or by ``bayes-rcsa spindle``)."""
        from ..io.receptance_csv import read_spindle_csv
        from ..spindle.outputs import SUMMARY_FILE
        from ..spindle.uncertainty import load_spindle_samples

        folder = Path(folder)
        try:
            summary = json.loads((folder / SUMMARY_FILE).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise DataError(f"{folder}: no {SUMMARY_FILE}; not written by bayes-rcsa spindle") from None
        directions = list(summary["directions"])
        samples = (load_spindle_samples(folder / summary["samples_file"]) if summary["samples_file"] else None)
        return cls(summary=summary,
                   receptances={d: read_spindle_csv(folder / f"spindle_{d}.csv") for d in directions},
                   raw={d: read_spindle_csv(folder / f"spindle_{d}_raw.csv", check=False) for d in directions},
                   samples=samples, path=folder, warnings=tuple(summary.get("warnings", ())))

    # -- pictures --------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``spindle_<d>`` (raw vs smoothed block) and ``artifact_<d>`` (measured vs reproduced tests) per direction."""
        from ..spindle.plots import receptance_figure, reproduction_figure

        self._in_memory("figures")
        out = {}
        for d, r in self.identifications.items():
            out[f"spindle_{d}"] = receptance_figure(r)
            out[f"artifact_{d}"] = reproduction_figure(r)
        return out


def _check(value, name: str, lo: int, hi: int | None = None) -> int:
    if isinstance(value, bool) or int(value) != value or value < lo or (hi is not None and value > hi):
        expected = f"an integer in [{lo}, {hi}]" if hi is not None else f"an integer >= {lo}"
        raise SetupError(f"{name} {value}: expected {expected}")
    return int(value)


def identify_spindle(artifact, *, samples: int = 50, seed: int = 0, directions=None, max_modes: int | None = None,
                     workers: int = 2, progress: bool = False) -> SpindleInterface:
    """Identify the spindle's flange receptances from hammer tests on a standard artifact.

    Parameters
    ----------
    artifact : path of the artifact TOML file, or a loaded :class:`bayes_rcsa.spindle.artifact.ArtifactSetup`
    samples : int
        Bootstrap samples of the flange receptance per direction (0: none).  About 0.5 s CPU each per
        direction of about 4000 lines, after about 15 s for the fit and the bootstrap's start fits.
    seed : int
        Seed of the bootstrap (the samples do not depend on ``workers``).
    directions : sequence of {"x", "y"}, optional; default every measured direction
    max_modes : int in [1, 20], optional; default the artifact's ``[fit] max_modes``
    workers : int >= 1, worker processes (one direction each)
    progress : bool
        Print the time estimate and a progress bar on stderr.

    Returns
    -------
    SpindleInterface
    """
    with warning_log() as log:
        seed = _check(seed, "--seed", 0)
        if max_modes is not None:
            max_modes = _check(max_modes, "--max-modes", 1, 20)
        from ..spindle.artifact import ArtifactSetup, load_artifact
        from ..spindle.identification import estimated_cpu_seconds, identify_directions
        from ..spindle.outputs import spindle_samples, summary_document

        setup = artifact if isinstance(artifact, ArtifactSetup) else load_artifact(artifact)
        directions = tuple(directions) if directions else tuple(sorted(setup.measurements))
        missing = [d for d in directions if d not in setup.measurements]
        if missing:
            raise SetupError(f"--directions: {setup.path} has no measurement for {missing}; measured: "
                             f"{sorted(setup.measurements)}")
        samples, workers = _check(samples, "--samples", 0), _check(workers, "--workers", 1)
        workers = min(workers, len(directions))
        bar = None
        if progress:
            from ..stability.progress import ProgressBar, format_seconds

            per = estimated_cpu_seconds(samples)
            rounds = -(-len(directions) // workers)  # directions run side by side in `workers` processes
            print(f"spindle: {', '.join(directions)}: inverse coupling, modal smoothing"
                  + (f", {samples} bootstrap samples each" if samples else "")
                  + f" ({workers} worker process{'es' if workers > 1 else ''}): estimated "
                  f"{format_seconds(per * rounds)}", file=sys.stderr)
            bar = ProgressBar("spindle")
        try:
            results = identify_directions(setup, directions, n_samples=samples, seed=seed, max_modes=max_modes,
                                          workers=workers, progress=bar)
        finally:
            if bar is not None:
                bar.close()
        bootstrap = spindle_samples(setup, results, seed)
        warnings = tuple(log)
    summary = summary_document(setup, results, seed, plots=True, samples=bootstrap is not None, warnings=warnings)
    from ..model.receptance import PointReceptance

    return SpindleInterface(
        summary=summary,
        receptances={d: PointReceptance(r.frequency_hz, r.smoothed, source=f"spindle_{d}.csv") for d, r in results.items()},
        raw={d: PointReceptance(r.frequency_hz, r.raw, source=f"spindle_{d}_raw.csv") for d, r in results.items()},
        samples=bootstrap, warnings=warnings, identifications=results, artifact=setup)
