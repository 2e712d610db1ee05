"""Files written by ``bayes-rcsa spindle`` (each atomically).

``spindle_<d>.csv``             smoothed flange block (data-contract spindle CSV; the setup's ``[spindle]`` file)
``spindle_<d>_raw.csv``         line-by-line inverse coupling (same format, for inspection)
``spindle_<d>_reliability.csv`` frequency_hz, relative_std, unreliable (0/1), std_h, std_l, std_p
``spindle_samples.npz``         bootstrap samples (:mod:`.uncertainty`), when requested
``spindle_summary.json``        modal models, mode-count criterion, noise, flagged bands, checks
``spindle_<d>.png``             raw vs smoothed receptances; ``artifact_<d>.png`` measured vs reproduced tests
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import SetupError
from ..io.atomic import atomic_write_text
from ..io.frf_csv import format_float
from ..io.receptance_csv import write_spindle_csv
from ..model.receptance import PointReceptance
from .artifact import ArtifactSetup
from .identification import SpindleIdentification
from .uncertainty import SpindleSamples, save_spindle_samples

__all__ = ["write_outputs", "spindle_samples", "summary_document", "output_files", "SUMMARY_FORMAT", "SUMMARY_FILE",
           "SAMPLES_FILE"]

SUMMARY_FORMAT = "bayes_rcsa.spindle_summary/1"
SUMMARY_FILE = "spindle_summary.json"
SAMPLES_FILE = "spindle_samples.npz"


def _reliability_csv(result: SpindleIdentification) -> str:
    lines = [
        f"# reliability of the inverse coupling, direction {result.direction}: relative_std = predicted relative "
        "standard deviation of the flange block (scaled Frobenius norm); unreliable = relative_std > "
        f"{result.threshold!r}; std_h m/N, std_l 1/N, std_p rad/(N m)",
        "frequency_hz,relative_std,unreliable,std_h,std_l,std_p",
    ]
    for row in zip(result.frequency_hz, result.block_error, result.unreliable, *result.std.T):
        f, eps, flag, sh, sl, sp = row
        lines.append(",".join([format_float(f), format_float(eps), "1" if flag else "0",
                               format_float(sh), format_float(sl), format_float(sp)]))
    return "\n".join(lines) + "\n"


def spindle_samples(setup: ArtifactSetup, results: Mapping[str, SpindleIdentification],
                    seed: int | None = None) -> SpindleSamples | None:
    """The bootstrap samples of every direction as one :class:`SpindleSamples` (``None`` without samples).

    Raises
    ------
    SetupError
        The directions were tested on different frequency grids (the samples hold one grid).
    """
    if not results or not all(r.samples is not None for r in results.values()):
        return None
    first = next(iter(results.values()))
    for d, r in results.items():
        if r.frequency_hz.shape != first.frequency_hz.shape or not np.allclose(r.frequency_hz, first.frequency_hz,
                                                                               rtol=1e-12, atol=0):
            raise SetupError(
                f"{setup.path}: directions {first.direction!r} and {d!r} were tested on different frequency "
                "grids, but the samples file holds one grid; run them separately (--directions) or "
                "re-measure on one grid"
            )
    meta = {"artifact_file": str(setup.path), "seed": seed,
            "n_modes": {d: r.fit.model.n_modes for d, r in results.items()},
            "noise_inflation": {d: r.inflation for d, r in results.items()}}
    return SpindleSamples(first.frequency_hz, {d: r.smoothed for d, r in results.items()},
                          {d: r.samples for d, r in results.items()}, meta, source=SAMPLES_FILE)


def output_files(results: Mapping[str, SpindleIdentification], plots: bool = True, samples: bool = False) -> list[str]:
    """Names of the files :func:`write_outputs` writes, in the order of spindle_summary.json's ``files``."""
    files = []
    for d in results:
        files += [f"spindle_{d}.csv", f"spindle_{d}_raw.csv", f"spindle_{d}_reliability.csv"]
        if plots:
            files += [f"spindle_{d}.png", f"artifact_{d}.png"]
    return files + ([SAMPLES_FILE] if samples else []) + [SUMMARY_FILE]


def summary_document(setup: ArtifactSetup, results: Mapping[str, SpindleIdentification], seed: int | None = None,
                     plots: bool = True, samples: bool = False, warnings: Sequence[str] = ()) -> dict:
    """The content of spindle_summary.json (``samples``: spindle_samples.npz is written)."""
    return {
        "format": SUMMARY_FORMAT,
        "artifact": {"file": str(setup.path), "name": setup.name,
                     "point_distances_from_free_end_m": list(setup.artifact.point_distances),
                     "artifact_length_m": setup.artifact.total_length},
        "seed": seed,
        "directions": {d: r.summary() for d, r in results.items()},
        "samples_file": SAMPLES_FILE if samples else None,
        "files": output_files(results, plots, samples),
        "warnings": list(warnings),
    }


def write_outputs(setup: ArtifactSetup, results: Mapping[str, SpindleIdentification], out_dir,
                  plots: bool = True, seed: int | None = None, warnings: Sequence[str] = (),
                  samples: SpindleSamples | None = None) -> dict:
    """Write every output file; return the summary dict (also written as JSON).

    Parameters
    ----------
    setup : ArtifactSetup
    results : dict of direction to SpindleIdentification
    out_dir : path-like
    plots : bool
    seed : int, optional
        Recorded in the summary and the samples' metadata.
    warnings : sequence of str
        The warnings the command printed (data checks of the artifact FRFs included), recorded as
        ``"warnings"`` in spindle_summary.json.
    samples : SpindleSamples, optional
        :func:`spindle_samples` of ``results`` when already made (made here otherwise).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for d, r in results.items():
        s = r.summary()
        head = [
            f"flange receptance of the spindle, direction {d}, identified by bayes-rcsa spindle from {setup.path.name}",
            f"reciprocal passive modal model, {s['modal_model']['n_modes']} modes (closed-form inverse coupling)",
            "unreliable inversion bands (Hz, bridged by the modal model): "
            + (", ".join(f"{lo:g}-{hi:g}" for lo, hi in r.bands) or "none"),
            "columns in m/N, 1/N, rad/N, rad/(N m)",
        ]
        name = f"spindle_{d}.csv"
        write_spindle_csv(out / name, PointReceptance(r.frequency_hz, r.smoothed, source=name), comments=head)
        raw_name = f"spindle_{d}_raw.csv"
        write_spindle_csv(out / raw_name, PointReceptance(r.frequency_hz, r.raw, source=raw_name), comments=[
            f"RAW line-by-line inverse coupling, direction {d} (noisy; use spindle_{d}.csv in setups)",
        ])
        atomic_write_text(out / f"spindle_{d}_reliability.csv", _reliability_csv(r))
        if plots:
            from .plots import receptance_plot, reproduction_plot

            receptance_plot(r, out / f"spindle_{d}.png")
            reproduction_plot(r, out / f"artifact_{d}.png")
    if samples is None:
        samples = spindle_samples(setup, results, seed)
    if samples is not None:
        save_spindle_samples(out / SAMPLES_FILE, samples)
    summary = summary_document(setup, results, seed, plots, samples is not None, warnings)
    atomic_write_text(out / SUMMARY_FILE, json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return summary
