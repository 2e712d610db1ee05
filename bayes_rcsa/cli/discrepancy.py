"""``bayes-rcsa discrepancy``: find what the model is missing, name it, add it, show the gap shrink."""

from __future__ import annotations

import argparse
import sys
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
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_force_argument(p)
    p.add_argument("--verbose", action="store_true", help="one progress line per step on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..discrepancy.workflow import (HELD_OUT_GAP_NOTE, DiscrepancyOptions, run_discrepancy, validate,
                                        write_discrepancy)
    from ..io.atomic import directory_lock
    from ..io.setup import load_setup

    out = Path(args.out)
    check_output_directory(out, args.force)  # before anything is computed
    lengths = tuple(parse_float_list(args.lengths, "--lengths", positive=True)) if args.lengths is not None else None
    cands = None
    if args.candidates is not None:
        cands = tuple(c.strip() for c in args.candidates.split(",") if c.strip())
        if not cands:
            raise SetupError(f"--candidates {args.candidates!r}: expected a comma-separated list of effect names")
    setup = load_setup(args.setup)
    options = DiscrepancyOptions(lengths=lengths, candidates=cands, seed=args.seed, n_refit=args.refit)
    validate(setup, options)  # bad candidates, too few lines: refused before anything is written
    say = (lambda s: print(f"bayes-rcsa discrepancy: {s}", file=sys.stderr)) if args.verbose else None
    with directory_lock(out):
        check_output_directory(out, args.force)
        result = run_discrepancy(setup, options, progress=say)
        files = write_discrepancy(result, out, plots=not args.no_plots, overwrite=args.force)
    r = result.report
    def pct(key):
        return "at the noise floor" if r[f"{key}_at_noise_floor"] else f"{100 * r[key]:.2g} %"

    gap = f"systematic gap {pct('gap_before')} -> {pct('gap_after')}"
    if r["named_effect"]:
        extra = f" (confounded with {', '.join(r['confounded_with'])})" if r["confounded_with"] else ""
        both = " + ".join([r["named_effect"], *r["also_named"]])
        human = f"named {both}{extra}: {gap}; wrote {out}/discrepancy.json and setup.amended.toml"
    elif r["adequate"]:
        held = r.get("gap_held_out_after")
        if held is not None and held > HELD_OUT_GAP_NOTE:
            gaps = (f"systematic gap {100 * r['gap_fitted_after']:.3g} % at the fitted lengths, {100 * held:.3g} % "
                    "at the others, where the fit does not carry")
        else:
            gaps = f"systematic gap {pct('gap_before')}"
        human = f"model adequate, nothing named ({gaps}); wrote {out}/discrepancy.json"
    else:
        human = f"model inadequate and no known effect explains it: statistical discrepancy added ({gap}); " \
                f"wrote {out}/discrepancy.json"
    data = {"out": str(out), "files": [str(f) for f in files], "adequate": r["adequate"],
            "named_effect": r["named_effect"], "also_named": r["also_named"], "confounded_with": r["confounded_with"],
            "gap_before": r["gap_before"], "gap_after": r["gap_after"], "gap_grew": r["gap_grew"],
            "usable_for_prediction": r["usable_for_prediction"]}
    warnings = tuple(r["warnings"])
    return Summary(human, data, warnings)
