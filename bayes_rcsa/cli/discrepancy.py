"""``bayes-rcsa discrepancy``: find what the model is missing, name it, add it, show the gap shrink."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import SetupError
from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float_list, positive_int

__all__ = ["register", "run"]

DESCRIPTION = """\
Fit the setup's model, look for systematic disagreement with the measurements (residual correlation,
resonance shifts, trends with clamping length, prior-bound pile-up), rank the candidate effects
(model terms: contact_damping, tip_mass, fluted_section, extra_mode, nonlinear_stiffness_law,
joint_loss_factor, stiffness_step, spindle_error, spindle_rotation_omitted, ...) by a score test, refit them, and name the
one the tempered evidence supports.  Nothing named but the model inadequate: a statistical
discrepancy term widens the intervals instead.

Writes to --out: discrepancy.json, summary.md, frf_before_after.png, residuals_before_after.png,
frequency_errors.png, stiffness_before_after.png and, when an effect is named, setup.amended.toml
(the setup with the effect in its [model] table).  See docs/discrepancy.md.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "discrepancy",
        help="find and name what the model is missing (tip mass, joint damping, ...), add it, show the gap shrink",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("setup", type=Path, metavar="SETUP", help="setup file (TOML)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--lengths", default=None, metavar="L1,L2,...",
                   help="clamping lengths to fit in m, e.g. 0.025,0.040 (default: all measured; the others are "
                        "held out and predicted)")
    p.add_argument("--candidates", default=None, metavar="A,B,...",
                   help="candidate effects to test (default: every registered effect not in the setup's [model])")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed (default 0)")
    p.add_argument("--refit", type=positive_int, default=None, metavar="N",
                   help="refit only the N best candidates of the score test (default: refit every candidate)")
    p.add_argument("--library", type=Path, default=None, metavar="FILE",
                   help="population.nc of 'bayes-rcsa library': when nothing is named, the contact law's shape "
                        "between the fitted lengths takes the library's prior for the setup's holder type and shank "
                        "diameter instead of the whole range between the parallel and the series law "
                        "(docs/discrepancy.md)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_force_argument(p)
    p.add_argument("--verbose", action="store_true", help="one progress line per step on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.model_check import check_model

    check_output_directory(args.out, args.force)  # before anything is computed
    lengths = parse_float_list(args.lengths, "--lengths", positive=True) if args.lengths is not None else None
    cands = None
    if args.candidates is not None:
        cands = [c.strip() for c in args.candidates.split(",") if c.strip()]
        if not cands:
            raise SetupError(f"--candidates {args.candidates!r}: expected a comma-separated list of effect names")
    lib = {} if args.library is None else {"library": args.library}  # the call without --library is unchanged
    result = check_model(args.setup, lengths=lengths, candidates=cands, seed=args.seed, n_refit=args.refit,
                         progress=args.verbose, **lib)
    result.save(args.out, force=args.force, plots=not args.no_plots)
    data = {"out": str(args.out), "files": [str(f) for f in result.saved_files], **result.summary_data()}
    return Summary(result.summary_line(), data, result.warnings)
