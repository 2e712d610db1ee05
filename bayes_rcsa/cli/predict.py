"""``bayes-rcsa predict``: posterior predictive FRFs and natural-frequency intervals at any clamping length."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._arguments import parse_directions
from ._common import (Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float_list,
                      parse_frequency_grid)

__all__ = ["register", "run"]

DESCRIPTION = """\
Predict the tool-point FRF at clamping lengths inside the feasible range, measured or not, from the
posterior draws of 'bayes-rcsa identify' pushed through the RCSA model.

Writes to --out:
  frequencies.json         per clamping length, direction and mode: natural-frequency quantiles of the
                           model q05/q25/q50/q75/q95 (Hz), the predictive interval of a new measured
                           peak (noise included) predictive_peak_q05/q50/q95_hz with
                           measured_in_predictive_90, the measured value where a measurement exists,
                           peak magnitude and dynamic stiffness intervals, parameter influence; the
                           fit's convergence (converged, posterior_status), interval_definitions,
                           warnings (every warning printed, the input checks' included)
  frf_bands.csv            |H| quantiles and median Re/Im H per line
  frf_bands.png            median |H| with 50 % and 90 % bands and mode intervals
  natural_frequencies.png  dominant natural frequency against clamping length
  report.md, report.html   measured-vs-predicted table (cf. paper Table 4), all modes, and what the
                           data do not determine
Predictions at measured lengths use the measurement's frequency lines (so measured and predicted
natural frequencies follow the same rule on the same lines), elsewhere the spindle file's grid.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "predict",
        help="posterior predictive FRFs and natural-frequency credible intervals at any clamping length",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("setup", type=Path, metavar="SETUP", help="setup file (TOML) the posterior was identified from")
    p.add_argument("--posterior", type=Path, required=True, metavar="FILE",
                   help="posterior.nc written by 'bayes-rcsa identify'")
    p.add_argument("--lengths", default=None, metavar="L1,L2,...",
                   help="clamping lengths in m, e.g. 0.025,0.030,0.035,0.040 (default: the measured lengths)")
    p.add_argument("--directions", default=None, metavar="D1,D2",
                   help="directions, e.g. x,y (default: every direction with a spindle receptance)")
    p.add_argument("--tool", default=None, help="tool name (default: the setup's only tool)")
    p.add_argument("--freq", default=None, metavar="START,STOP,STEP",
                   help="common frequency grid in Hz (default: measurement lines or the spindle grid)")
    p.add_argument("--max-draws", type=nonnegative_int, default=1000, metavar="N",
                   help="use a random subset of at most N posterior draws (default 1000; 0 = all)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the draw subset (default 0)")
    p.add_argument("--spindle-uncertainty", type=Path, default=None, metavar="FILE",
                   help="spindle_samples.npz of 'bayes-rcsa spindle': the spindle receptance's own uncertainty enters "
                   "the predictive bands (default: the setup's spindle files as they are)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_force_argument(p)
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.prediction import predict

    lengths = None if args.lengths is None else parse_float_list(args.lengths, "--lengths", positive=True)
    directions = None if args.directions is None else parse_directions(args.directions)
    freq = parse_frequency_grid(args.freq) if args.freq is not None else None
    check_output_directory(args.out, args.force)  # refused before the prediction is computed (again under the lock)
    result = predict(args.setup, args.posterior, lengths, directions=directions, tool=args.tool, frequency_hz=freq,
                     max_draws=None if args.max_draws == 0 else args.max_draws, seed=args.seed,
                     spindle_samples=args.spindle_uncertainty, progress=not args.quiet)
    result.save(args.out, force=args.force, plots=not args.no_plots)
    return Summary(result.summary_line(),
                   {"out": str(args.out), "frequencies": str(args.out / "frequencies.json"),
                    "report": str(args.out / "report.md"), **result.summary_data()},
                   warnings=result.warnings)
