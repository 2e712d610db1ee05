"""``bayes-rcsa identifiability``: which contact parameters do the data pin down, from one length or several?"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._arguments import add_sampler_argument
from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float_list, positive_int

__all__ = ["register", "run"]

DESCRIPTION = """\
Fit every selected measured clamping length alone (the literature method: one constant contact) and all
of them together (growth law), with identical priors, and report per parameter and per fit:

  contraction   (Var_prior - Var_post)/Var_prior in the sampled coordinate (log10 k, g), printed as a
                percentage or, above 99.9 %, as 'prior width / posterior width = 3.2e3'
  verdict       'identified' (contraction >= 99 % and not held by a prior bound), 'identified
                only in combination with k_thetaM' (resp. k_xf: identified, but the marginal
                posterior width is >= 3 x the width at a fixed partner stiffness, a ridge),
                'weakly identified' (>= 50 %, or the posterior runs into a prior bound: the
                data give only a one-sided bound) or 'not identified' (< 50 %)
  ridge         posterior correlations, marginal / conditional widths of k_xf and k_thetaM, the
                stiff (determined) and sloppy (free) combinations of the two in physical terms,
                and the eigen-decomposition of the covariance of all contact parameters in log
                space (k_xf, k_thetaM, (1+g), ...)
  Fisher        eigenvalues and condition number of the Fisher information at the MAP point
  transfer      each fit's predicted natural frequencies at the other measured lengths vs the
                measurements, with 90 % intervals (cf. the reference paper's Tables 5-7)

Writes to --out: identifiability.json, identifiability.md/.html, corner_overlay.png, forest.png and,
per fit, fits/<name>/summary.json and posterior.nc (usable with 'bayes-rcsa predict').
Sampler settings come from the setup's [sampler] table unless given here; a short --max-steps gives a
quick look (reported as not converged).
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "identifiability",
        help="single- vs multi-length fits: contraction, ridges, Fisher information, transfer errors",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("setup", type=Path, metavar="SETUP", help="setup file (TOML)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--lengths", default=None, metavar="L1,L2,...",
                   help="measured clamping lengths to use in m, e.g. 0.025,0.040 (default: all measured)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed of every fit (default 0)")
    p.add_argument("--max-steps", type=positive_int, default=None, metavar="N",
                   help="cap on sampler steps per fit (default: [sampler] max_steps or 20000)")
    p.add_argument("--walkers", type=positive_int, default=None, metavar="N",
                   help="walkers per fit (even; default max(32, 4 x parameters))")
    p.add_argument("--check-every", type=positive_int, default=None, metavar="N",
                   help="steps between convergence checks (default: [sampler] check_every or 250)")
    add_sampler_argument(p, "--max-steps, --walkers, --check-every")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--no-posteriors", action="store_true", help="do not write each fit's posterior.nc and summary.json")
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.identifiability_study import identifiability

    lengths = parse_float_list(args.lengths, "--lengths", positive=True) if args.lengths is not None else None
    check_output_directory(args.out, args.force)  # before hours of sampling, not after (checked again on saving)
    result = identifiability(args.setup, lengths=lengths, seed=args.seed, max_steps=args.max_steps,
                             walkers=args.walkers, check_every=args.check_every, progress=not args.quiet,
                             sampler=args.sampler)
    result.save(args.out, force=args.force, plots=not args.no_plots, posteriors=not args.no_posteriors)
    if not args.quiet:
        for line in result.findings:
            print(line, file=sys.stderr)
    return Summary(result.summary_line(),
                   {"out": str(args.out), "identifiability": str(args.out / "identifiability.json"),
                    "report": str(args.out / "identifiability.md"), **result.summary_data()},
                   warnings=result.warnings)
