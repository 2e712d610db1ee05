"""``bayes-rcsa predict``: posterior predictive FRFs and natural-frequency intervals at any clamping length."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import SetupError
from ._common import (Summary, add_force_argument, check_output_directory, command_warnings, merge_warnings,
                      nonnegative_int, parse_float_list, parse_frequency_grid)

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
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_force_argument(p)
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..io.atomic import directory_lock, directory_is_empty, new_output_directory
    from ..io.progress import Heartbeat
    from ..io.setup import load_setup
    from ..posterior.prediction_outputs import run_prediction, write_prediction_outputs

    if not args.posterior.is_file():
        raise SetupError(f"--posterior {args.posterior}: no such file (posterior.nc written by 'bayes-rcsa identify')")
    setup = load_setup(args.setup)
    from ..io.checks import warn_all
    from ..posterior.setup_match import posterior_setup_warnings

    warn_all(posterior_setup_warnings(args.posterior, setup))  # a posterior of another geometry says so
    if args.lengths is not None:
        lengths = parse_float_list(args.lengths, "--lengths", positive=True)
    else:
        lengths = sorted({m.clamping_length for m in setup.measurements})
    directions = None
    if args.directions is not None:
        directions = [d.strip() for d in args.directions.split(",") if d.strip()]
        bad = [d for d in directions if d not in ("x", "y")]
        if bad or not directions:
            raise SetupError(f"--directions {args.directions!r}: expected a comma-separated list of x and y")
    freq = parse_frequency_grid(args.freq) if args.freq is not None else None
    if not args.force and not directory_is_empty(args.out):
        check_output_directory(args.out)  # refused before the prediction is computed (checked again under the lock)
    with Heartbeat(f"predict: {len(lengths)} clamping length(s)", enabled=not args.quiet):
        result = run_prediction(setup, args.posterior, lengths, directions, args.tool, freq,
                                max_draws=None if args.max_draws == 0 else args.max_draws, seed=args.seed)
    # the posterior, not the (possibly edited) setup, defines the model: say where they differ
    warns = [note.removeprefix("warning:").strip() for note in result.meta.get("parameter_model_notes", [])
             if note.startswith("warning:")]
    n_nan = sum(1 for m in result.prediction.modes if m.nan_fraction > 0)
    if n_nan:
        warns.append(f"{n_nan} mode(s) have draws without a resonance inside the mode band "
                     "(see nan_fraction in frequencies.json)")
    # the fit behind the posterior: a prediction from an unconverged fit says so
    status = result.meta.get("posterior_status") or {}
    converged = status.get("converged")
    if converged is False:
        warns.append(f"the posterior {args.posterior} did not converge; these intervals are not reliable")
    # every warning printed (the data checks' and these) also goes into frequencies.json
    warns = merge_warnings(command_warnings(), warns)
    with directory_lock(args.out), new_output_directory(check_output_directory(args.out, args.force)):
        write_prediction_outputs(result, args.out, plots=not args.no_plots, warnings=warns)
    n_pred = len(result.prediction.modes)
    return Summary(
        f"{n_pred} mode interval(s) at {len(lengths)} clamping length(s) from {result.draws.n_draws} draws; "
        f"results in {args.out}",
        {"out": str(args.out), "frequencies": str(args.out / "frequencies.json"),
         "report": str(args.out / "report.md"), "n_draws": int(result.draws.n_draws),
         "posterior_converged": converged},
        warnings=tuple(warns),
    )
