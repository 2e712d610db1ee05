"""``bayes-rcsa spindle``: spindle-holder flange receptances from standard-artifact hammer tests."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._common import Summary, add_force_argument, check_output_directory, command_warnings, nonnegative_int

__all__ = ["register", "run"]

DESCRIPTION = """\
Identify the spindle's 2x2 flange receptances [[h, l], [n, p]] (per direction) from hammer tests on a
standard artifact: a shrink-fit holder with a bonded blank (rigid joint), described in ARTIFACT.toml
together with the measured FRFs H11 (free end), H12/H21 (cross to a second point) and H22 (second point),
as CSV or UFF58 files.

Steps: noise level of every FRF (estimated from the data unless [noise] relative is given); closed-form
inverse receptance coupling with the artifact's free-free Timoshenko model, line by line (Namazi's
equations solved exactly: no finite-difference rotations); a reciprocal, passive modal model fitted with
the noise-propagated weights and then to the tests themselves, its mode count chosen by BIC; lines where
the inversion amplifies the noise beyond [fit] unreliable_threshold are flagged; bootstrap samples over the measurement noise (and [uncertainty]
artifact-model errors) for `identify --spindle-uncertainty`.

Writes to --out: spindle_<d>.csv (the smoothed block: use it as the setup's [spindle] file),
spindle_<d>_raw.csv, spindle_<d>_reliability.csv, spindle_samples.npz (with --samples > 0),
spindle_summary.json (with every warning printed) and the plots spindle_<d>.png, artifact_<d>.png.
See docs/spindle.md.
"""


def _directions(text: str) -> tuple[str, ...]:
    vals = tuple(v.strip() for v in text.split(",") if v.strip())
    if not vals or any(v not in ("x", "y") for v in vals) or len(set(vals)) != len(vals):
        raise argparse.ArgumentTypeError(f"{text!r}: expected x, y or x,y")
    return vals


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "spindle",
        help="identify the spindle flange receptances from standard-artifact hammer tests",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("artifact", type=Path, metavar="ARTIFACT", help="artifact file (TOML), see docs/spindle.md")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--samples", type=nonnegative_int, default=50, metavar="N",
                   help="bootstrap samples of the flange receptance (0: none; default 50).  CPU cost per direction, "
                   "about 4000 lines: about 7 s for the fit, 8 s more for the bootstrap start fits, then "
                   "about 0.5 s per sample (about 40 s per direction at the default; the directions run in "
                   "parallel, see --workers); the estimate and a progress bar are printed on stderr")
    p.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default 0)")
    p.add_argument("--workers", type=nonnegative_int, default=2, metavar="N",
                   help="worker processes, one direction each (default 2; 1: run in this process).  The samples "
                   "do not depend on it")
    p.add_argument("--max-modes", type=nonnegative_int, default=None, metavar="N",
                   help="largest mode count tried by the modal smoothing (default: [fit] max_modes or 8)")
    p.add_argument("--directions", type=_directions, default=None, metavar="x,y",
                   help="directions to identify (default: all measured)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args) -> Summary:
    from ..errors import SetupError
    from ..spindle.artifact import load_artifact
    from ..spindle.identification import estimated_cpu_seconds, identify_directions
    from ..spindle.outputs import write_outputs

    if args.seed < 0:
        raise SetupError(f"--seed {args.seed}: expected an integer >= 0")
    if args.max_modes is not None and not 1 <= args.max_modes <= 20:
        raise SetupError(f"--max-modes {args.max_modes}: expected an integer in [1, 20]")
    setup = load_artifact(args.artifact)
    directions = args.directions or tuple(sorted(setup.measurements))
    missing = [d for d in directions if d not in setup.measurements]
    if missing:
        raise SetupError(f"--directions: {args.artifact} has no measurement for {missing}; measured: "
                         f"{sorted(setup.measurements)}")
    if args.workers < 1:
        raise SetupError(f"--workers {args.workers}: expected an integer >= 1")
    from ..io.atomic import directory_is_empty, directory_lock, new_output_directory

    if not args.force and not directory_is_empty(args.out):
        check_output_directory(args.out)  # refused before the identification runs (checked again under the lock)
    workers = min(args.workers, len(directions))
    bar = None
    if not args.quiet:
        from ..stability.progress import ProgressBar, format_seconds

        per = estimated_cpu_seconds(args.samples)
        rounds = -(-len(directions) // workers)  # directions run side by side in `workers` processes
        print(f"spindle: {', '.join(directions)}: inverse coupling, modal smoothing"
              + (f", {args.samples} bootstrap samples each" if args.samples else "")
              + f" ({workers} worker process{'es' if workers > 1 else ''}): estimated "
              f"{format_seconds(per * rounds)}", file=sys.stderr)
        bar = ProgressBar("spindle")
    try:
        results = identify_directions(setup, directions, n_samples=args.samples, seed=args.seed,
                                      max_modes=args.max_modes, workers=workers, progress=bar)
    finally:
        if bar is not None:
            bar.close()
    warns = command_warnings()  # every warning printed also goes into spindle_summary.json
    with directory_lock(args.out), new_output_directory(check_output_directory(args.out, args.force)):
        summary = write_outputs(setup, results, args.out, plots=not args.no_plots, seed=args.seed, warnings=warns)
    if not args.quiet:
        for d, s in summary["directions"].items():
            bands = ", ".join(f"{lo:g}-{hi:g} Hz" for lo, hi in s["unreliable_bands_hz"]) or "none"
            print(f"spindle: {d}: {s['modal_model']['n_modes']} modes, reduced chi2 {s['reduced_chi2']:.3g}, "
                  f"unreliable bands: {bands}", file=sys.stderr)
    files = {d: f"spindle_{d}.csv" for d in results}
    written = [*files.values(), *([summary["samples_file"]] if summary["samples_file"] else [])]  # --samples 0: none
    return Summary(f"wrote {', '.join(written)} in {args.out}",
                   {"out": str(args.out), "spindle_files": files, "samples": summary["samples_file"]})
