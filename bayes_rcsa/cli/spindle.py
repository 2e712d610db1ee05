"""``bayes-rcsa spindle``: spindle-holder flange receptances from standard-artifact hammer tests."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int

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
    from ..workflows.spindle import identify_spindle

    check_output_directory(args.out, args.force)  # refused before the identification runs (checked again on saving)
    result = identify_spindle(args.artifact, samples=args.samples, seed=args.seed, directions=args.directions,
                              max_modes=args.max_modes, workers=args.workers, progress=not args.quiet)
    result.save(args.out, force=args.force, plots=not args.no_plots)
    if not args.quiet:
        for d, s in result.summary["directions"].items():
            bands = ", ".join(f"{lo:g}-{hi:g} Hz" for lo, hi in s["unreliable_bands_hz"]) or "none"
            print(f"spindle: {d}: {s['modal_model']['n_modes']} modes, reduced chi2 {s['reduced_chi2']:.3g}, "
                  f"unreliable bands: {bands}", file=sys.stderr)
    return Summary(result.summary_line(), {"out": str(args.out), **result.summary_data()}, warnings=result.warnings)
