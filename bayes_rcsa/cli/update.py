"""``bayes-rcsa update``: cutting-test outcomes update an existing posterior (no new hammer-test fit).

Parsing and printing only; the work is :func:`bayes_rcsa.cuts.workflow.run_update`
(importance re-weighting with an ESS check) and the files are written by
:func:`bayes_rcsa.cuts.workflow.write_update`.  See docs/stability.md,
"Cutting tests update the posterior".
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..errors import SetupError
from ._common import Summary, add_force_argument, check_output_directory, command_warnings, merge_warnings, \
    nonnegative_int, parse_float, positive_int
from ._arguments import CUT_FLAGS, add_cutting_arguments, boundary_width, cutting_from_arguments, parse_fraction, \
    parse_speeds

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
    from ..cuts import CoefficientPrior
    from ..cuts.mcmc import MCMCSettings
    from ..cuts.update import UpdateSettings
    from ..cuts.workflow import run_update, write_update
    from ..io.atomic import directory_is_empty, directory_lock, new_output_directory
    from ..stability import Tolerances
    from ..stability.methods import MethodOptions

    cutting, kt_tol, kr_tol, warnings = cutting_from_arguments(args, kr_tolerance=True)
    prior = CoefficientPrior.from_tolerances(cutting.kt, kt_tol, cutting.kr, kr_tol)
    width = boundary_width(args.boundary_width)
    label_error = parse_float(args.label_error, "--label-error")
    if not (0 <= label_error < 0.5):
        raise SetupError(f"--label-error {args.label_error}: expected a probability in [0, 0.5)")
    min_ess = parse_float(args.min_ess, "--min-ess", positive=True)
    if min_ess < 1:
        raise SetupError(f"--min-ess {args.min_ess}: expected >= 1")
    clamping = None if args.clamping_length is None else parse_float(args.clamping_length, "--clamping-length",
                                                                      positive=True)
    speeds = None
    level = parse_float(args.level, "--level", positive=True)
    if level > 1:
        raise SetupError(f"--level {args.level}: expected a probability in (0, 1]")
    # the ± of --kt is the prior spread that the cuts narrow, not a tolerance of the recommendation's neighbourhood
    tol = Tolerances(parse_fraction(args.speed_tolerance, "--speed-tolerance", 0.0, 0.2),
                     parse_fraction(args.depth_margin, "--depth-margin", 1e-3, 1.0), 0.0)
    max_depth = None if args.max_depth is None else parse_float(args.max_depth, "--max-depth", positive=True)
    if args.speeds is not None:
        speeds = parse_speeds(args.speeds)
        if clamping is None:
            raise SetupError("--speeds compares the lobes at --clamping-length; give --clamping-length M")
    options = MethodOptions(intervals=args.intervals, max_modes=args.max_modes)
    mcmc = None if args.no_mcmc else MCMCSettings(args.mcmc_walkers, args.mcmc_steps)
    if not directory_is_empty(args.out):
        check_output_directory(args.out, args.force)  # refused before the work (checked again under the lock)
    result = run_update(args.setup, args.posterior, args.cuts, cutting, clamping, prior, width, label_error,
                        args.method, options, UpdateSettings(args.particles, min_ess), args.draws, args.seed,
                        args.tool, speeds, level, tol, max_depth, mcmc)
    doc = result.document
    doc["warnings"] = merge_warnings(command_warnings(), warnings, doc["warnings"])
    with directory_lock(args.out), new_output_directory(check_output_directory(args.out, args.force)):
        paths = write_update(result, args.out)
    kt = doc["kt_pa"]["after"]
    ess = doc["ess"]["draws"]
    ess = ess if ess is not None and np.isfinite(ess) else None
    msg = (f"wrote {paths[0]}, {paths[1].name}; {doc['inputs']['n_cuts']} cuts, "
           + ("MCMC fallback, " if doc["sampler"] == "mcmc" else "") + ("ESS unknown of " if ess is None else f"ESS {ess:.0f} of ")
           + f""
           f"{doc['ess']['n_draws']} draws; K_t {kt[1]:.4g} Pa (90 % {kt[0]:.4g}-{kt[2]:.4g})")
    lobes = doc.get("lobes")
    if lobes is not None:
        b, a = lobes["hammer_only"]["recommended"], lobes["with_cuts"]["recommended"]
        fmt = lambda r: "none" if r is None else f"{r['spindle_speed_rpm']:.0f} rpm, {r['depth_m'] * 1e3:.3f} mm"  # noqa: E731
        msg += f"; recommendation hammer only {fmt(b)} -> with cuts {fmt(a)}"
    return Summary(msg, {"out": str(args.out), "posterior": str(paths[0]), "update": str(paths[1]),
                         "ess_draws": ess, "kt_pa": kt, "kr_pa": doc["kr_pa"]["after"],
                         "recommended": None if lobes is None else lobes["with_cuts"]["recommended"]},
                   warnings=tuple(doc["warnings"]))


def cut_term_from_arguments(args, problem, setup):
    """The :class:`~bayes_rcsa.cuts.joint.CutTerm` of ``identify --cuts`` (None without --cuts); checks everything."""
    if args.cuts is None:
        given = [f"--{n.replace('_', '-')}" for n in CUT_FLAGS if getattr(args, n, None) is not None]
        if given:
            raise SetupError(f"{', '.join(given)} need(s) --cuts CSV")
        return None
    if args.method == "deterministic":
        raise SetupError("--cuts needs a Bayesian method (multi or single): the outcomes enter the posterior")
    if args.resume:
        raise SetupError("--cuts cannot be combined with --resume (the checkpoint does not record the cuts)")
    missing = [o for o, v in (("--cut-flutes", args.cut_flutes), ("--cut-kt", args.cut_kt), ("--cut-kr", args.cut_kr))
               if v is None]
    if missing:
        raise SetupError(f"--cuts needs {', '.join(missing)}")
    from ..cuts import CoefficientPrior, DEFAULT_LABEL_ERROR
    from ..cuts.data import cut_groups, prepare_cuts
    from ..cuts.frf import configuration_caches
    from ..cuts.joint import CutTerm
    from ..io.checks import warn_all
    from ..stability.posterior_frf import flute_length
    from ..stability.tests_io import read_cut_table

    ns = argparse.Namespace(kt=args.cut_kt, kr=args.cut_kr, flutes=args.cut_flutes, immersion=args.cut_immersion,
                            angles=args.cut_angles, milling=args.cut_milling, feed=args.cut_feed, pitch=args.cut_pitch,
                            allow_unusual=False)
    cutting, kt_tol, kr_tol, warnings = cutting_from_arguments(ns, kr_tolerance=True)
    warn_all(warnings)
    prior = CoefficientPrior.from_tolerances(cutting.kt, kt_tol, cutting.kr, kr_tol)
    width = boundary_width(args.cut_boundary_width or "0.1")
    label_error = DEFAULT_LABEL_ERROR if args.cut_label_error is None else parse_float(args.cut_label_error,
                                                                                       "--cut-label-error")
    if not (0 <= label_error < 0.5):
        raise SetupError(f"--cut-label-error {args.cut_label_error}: expected a probability in [0, 0.5)")
    length = None if args.cut_clamping_length is None else parse_float(args.cut_clamping_length,
                                                                       "--cut-clamping-length", positive=True)
    cuts = prepare_cuts(read_cut_table(args.cuts), cutting, length, setup.tools, args.cut_tool,
                        lambda name: flute_length(setup.tools[name]), option_prefix="--cut-")
    pm = problem.parameters
    lengths = sorted({float(l) for l in cuts.clamping_length_m})
    fitted = sorted({float(o.configuration.clamping_length) for o in problem.observations})
    if pm.growth.has_growth:
        pm.growth.check_lengths(lengths, "cut clamping length")
    elif any(all(abs(l - f) > 1e-9 for f in fitted) for l in lengths):
        raise SetupError(f"--cuts: cuts at clamping length(s) {lengths} m, but this fit (one length, no growth law) "
                         f"predicts only {fitted} m; fit several lengths or cut at a fitted length")
    for d in ("x", "y"):
        if d not in setup.spindle:
            raise SetupError(f"{setup.path}: [spindle] {d} is needed for --cuts (both directions are coupled)")
    sx, sy = setup.spindle["x"].frequency_hz, setup.spindle["y"].frequency_hz
    f = sx[(sx >= max(sx[0], sy[0])) & (sx <= min(sx[-1], sy[-1]))]
    dummy = {k: (np.zeros((1, f.size), complex),) * 2 for k in cuts.setups()}
    cut_groups(cuts, dummy, f)  # refuses speeds outside the band before any sampling
    model = setup.model()
    return CutTerm(pm, model, configuration_caches(model, cuts.setups(), f), f, cuts, prior, width, label_error)


def cut_coefficients(result, term, seed: int):
    """(K_t, K_r, w) for every posterior draw of ``result`` (its conditional given the cuts) and their summary
    (quantiles) for summary.json's ``cuts``."""
    kt, kr, w = term.coefficient_draws(result.flat_theta, np.random.default_rng([seed, 23]))
    q = lambda v: [float(x) for x in np.quantile(v, [0.05, 0.5, 0.95])]  # noqa: E731
    info = {"file": str(term.cuts.table.path), "n_cuts": term.cuts.n_cuts, "kt_pa_q05_q50_q95": q(kt),
            "kr_pa_q05_q50_q95": q(kr), "coefficient_prior": term.prior.describe(),
            "boundary_width": term.width.describe(), "label_error": term.label_error}
    return (kt, kr, w), info


def write_cut_coefficients(out_dir, draws, info) -> None:
    """Add the per-draw coefficients of :func:`cut_coefficients` to ``out_dir``/posterior.nc."""
    from ..cuts.joint import add_coefficients_to_posterior

    add_coefficients_to_posterior(Path(out_dir) / "posterior.nc", *draws,
                                  {"cuts_file": info["file"], "n_cuts": info["n_cuts"]})
