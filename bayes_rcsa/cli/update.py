"""``bayes-rcsa update``: cutting-test outcomes update an existing posterior (no new hammer-test fit).

Parsing and printing only; the work is :func:`bayes_rcsa.workflows.cut_update.update`
(importance re-weighting with an ESS check), the files are written by
:meth:`bayes_rcsa.workflows.cut_update.CutUpdate.save`.  See docs/stability.md,
"Cutting tests update the posterior".
"""

from __future__ import annotations

import argparse

from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float, \
    positive_int
from ._arguments import add_cutting_arguments, boundary_width_numbers, cutting_keywords, parse_fraction, parse_speeds

__all__ = ["register", "run"]

KT_HELP = ("tangential cutting-force coefficient in Pa, with the prior spread of the cutting-force level, e.g. "
           "560e6±30%% (scales Kt and Kr together, sampled as a log-normal level with sd ln(1.3)); without ± it is held")
KR_HELP = ("radial cutting-force coefficient in Pa; a tolerance, e.g. 170e6±20%%, adds an independent spread of Kr/Kt "
           "(sampled on equally probable ratio nodes, each one more stability evaluation)")


def register(subparsers) -> None:
    from ..cuts import DEFAULT_BOUNDARY_WIDTH, DEFAULT_LABEL_ERROR
    from ..cuts.update import DEFAULT_MIN_ESS, DEFAULT_PARTICLES_PER_DRAW
    from ..stability.methods import method_names

    p = subparsers.add_parser(
        "update",
        help="update a posterior with cutting-test outcomes (stable/chatter), without redoing the hammer-test fit",
        description="Update the posterior of 'bayes-rcsa identify' with the outcomes of cutting tests: every draw of "
        "the contact, paired with draws of the cutting coefficients from their prior (--kt V±T), is weighted by the "
        "probability of the observed outcomes (a probit boundary of width --boundary-width on the stability limit of "
        "--method at each cut's speed, X and Y coupled), checked by its effective sample size and resampled.  Writes "
        "OUT/posterior.nc (with per-draw K_t/K_r, read by predict, lobes and report) and OUT/update.json (ESS, "
        "K_t/K_r quantiles, what each cut moved).  When the ESS collapses the posterior is sampled by MCMC instead "
        "(emcee; the hammer posterior approximated by a Gaussian), or refused with --no-mcmc (exit 2).",
    )
    p.add_argument("setup", metavar="SETUP", help="setup TOML of the fit")
    p.add_argument("--posterior", required=True, metavar="FILE", help="posterior.nc of 'bayes-rcsa identify'")
    p.add_argument("--cuts", required=True, metavar="CSV",
                   help="cutting tests: spindle_speed_rpm,depth_m,outcome (stable|chatter) and optional "
                   "clamping_length_m, radial_immersion, feed_direction, tool columns")
    p.add_argument("--clamping-length", metavar="M", help="clamping length in m of cuts without their own")
    p.add_argument("--tool", metavar="NAME", help="tool of cuts without their own (default: the setup's only tool)")
    add_cutting_arguments(p, KT_HELP, KR_HELP, required=True)
    lik = p.add_argument_group("likelihood and sampling")
    lik.add_argument("--boundary-width", default=str(DEFAULT_BOUNDARY_WIDTH), metavar="W|LO:HI",
                     help=f"width of the probit boundary in ln(depth / limit) (default {DEFAULT_BOUNDARY_WIDTH:g}); "
                     "LO:HI samples it log-uniformly")
    lik.add_argument("--label-error", default=str(DEFAULT_LABEL_ERROR), metavar="P",
                     help=f"probability that a cut far from the boundary is reported the other way (default "
                     f"{DEFAULT_LABEL_ERROR:g})")
    lik.add_argument("--method", choices=method_names(), default="zoa", help="stability method (default zoa)")
    lik.add_argument("--intervals", type=positive_int, metavar="M", help="SDM intervals per tooth period")
    lik.add_argument("--max-modes", type=positive_int, default=4, metavar="N", help="SDM modal fit modes (default 4)")
    lik.add_argument("--draws", type=positive_int, default=1000, metavar="N",
                     help="hammer-posterior draws used (default 1000)")
    lik.add_argument("--particles", type=positive_int, default=DEFAULT_PARTICLES_PER_DRAW, metavar="M",
                     help=f"cutting-coefficient draws per posterior draw (default {DEFAULT_PARTICLES_PER_DRAW})")
    lik.add_argument("--min-ess", default=str(DEFAULT_MIN_ESS), metavar="N",
                     help=f"least effective number of posterior draws accepted (default {DEFAULT_MIN_ESS:g})")
    lik.add_argument("--no-mcmc", action="store_true",
                     help="refuse (exit 2) when the ESS collapses instead of sampling the posterior by MCMC")
    lik.add_argument("--mcmc-steps", type=positive_int, default=300, metavar="N",
                     help="steps of the MCMC fallback (default 300, half burn-in)")
    lik.add_argument("--mcmc-walkers", type=positive_int, default=32, metavar="N",
                     help="walkers of the MCMC fallback (default 32)")
    lik.add_argument("--seed", type=nonnegative_int, default=0, help="seed of every random choice (default 0)")
    rec = p.add_argument_group("hammer only vs hammer + cuts (optional)")
    rec.add_argument("--speeds", metavar="START:STOP[:COUNT]",
                     help="speed grid in rpm: compare the lobes and the robust recommendation before and after the "
                     "cuts at --clamping-length and say how far each cut moved the recommendation")
    rec.add_argument("--level", default="0.95", metavar="P", help="P(stable) of the recommendation (default 0.95)")
    rec.add_argument("--speed-tolerance", default="2%", metavar="FRAC", help="± speed tolerance (default 2%%)")
    rec.add_argument("--depth-margin", default="10%", metavar="FRAC", help="depth margin (default 10%%)")
    rec.add_argument("--max-depth", metavar="M", help="largest axial depth in m the recommendation may use")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.cut_update import update

    cutting = cutting_keywords(args, kr_tolerance=True)
    numbers = dict(
        boundary_width=boundary_width_numbers(args.boundary_width),
        label_error=parse_float(args.label_error, "--label-error"),
        min_ess=parse_float(args.min_ess, "--min-ess", positive=True),
        clamping_length=None if args.clamping_length is None else parse_float(args.clamping_length,
                                                                               "--clamping-length", positive=True),
        level=parse_float(args.level, "--level", positive=True),
        speed_tolerance=parse_fraction(args.speed_tolerance, "--speed-tolerance", 0.0, 0.2),
        depth_margin=parse_fraction(args.depth_margin, "--depth-margin", 1e-3, 1.0),
        max_depth=None if args.max_depth is None else parse_float(args.max_depth, "--max-depth", positive=True),
        speeds_rpm=None if args.speeds is None else parse_speeds(args.speeds))
    check_output_directory(args.out, args.force)  # refused before the work (checked again when saving)
    result = update(args.setup, args.posterior, args.cuts, **cutting, **numbers, method=args.method,
                    intervals=args.intervals, max_modes=args.max_modes, draws=args.draws, particles=args.particles,
                    mcmc=not args.no_mcmc, mcmc_steps=args.mcmc_steps, mcmc_walkers=args.mcmc_walkers, seed=args.seed,
                    tool=args.tool)
    posterior = result.save(args.out, force=args.force)
    return Summary(result.summary_line(), {"out": str(args.out), "posterior": str(posterior),
                                           "update": str(posterior.with_name("update.json")), **result.summary_data()},
                   warnings=result.warnings)
