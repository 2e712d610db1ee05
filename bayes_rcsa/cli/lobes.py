"""``bayes-rcsa lobes``: stability lobes and a robust operating point from measured FRFs or posterior draws.

Parsing and printing only; the workflow is :func:`bayes_rcsa.workflows.stability_lobes.lobes` (``bayes_rcsa.lobes``).
See docs/stability.md.
"""

from __future__ import annotations

import argparse

from ._arguments import (DEFAULT_SPEED_POINTS, add_cutting_arguments, cutting_keywords, optional_float,
                         parse_averages, parse_fraction, parse_speeds)
from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float, positive_int

__all__ = ["register", "run"]

DEFAULT_BUDGET_S = 120.0  # = bayes_rcsa.workflows.stability_lobes.DEFAULT_BUDGET_S (not imported: --help stays light)


def register(subparsers) -> None:
    from ..stability.methods import STABILITY_METHODS, method_names

    names = method_names()
    p = subparsers.add_parser(
        "lobes",
        help="milling stability lobes (ZOA or SDM) and a robust operating point",
        description="Compute milling stability lobes from measured tool-point FRFs in X and Y "
        "(--measured-x/--measured-y; probabilistic from their coherence and averages or from repeated hits, "
        "else deterministic) or from posterior draws of the contact parameters "
        "(SETUP --posterior, probabilistic), and recommend the operating point with the largest removal rate "
        "whose neighbourhood (spindle-speed tolerance, depth margin, cutting-coefficient tolerance) is stable "
        "with probability >= --level.  Writes OUT/lobes.json, OUT/p_stable.npz and OUT/lobes.png.  "
        "Axis convention: X right, Y up seen from the spindle towards the tool tip, cutter turning clockwise "
        "in that view; --feed names the machine axis along which the tool advances.  Methods: "
        + "; ".join(f"{n}: {STABILITY_METHODS.get(n).summary}" for n in names) + ".",
    )
    src = p.add_argument_group("dynamics (one of the two modes)")
    src.add_argument("setup", nargs="?", metavar="SETUP", help="setup TOML (posterior mode)")
    src.add_argument("--posterior", metavar="FILE", help="posterior.nc of 'bayes-rcsa identify' (posterior mode)")
    src.add_argument("--clamping-length", metavar="M", help="clamping length in m (posterior mode)")
    src.add_argument("--draws", type=positive_int, default=500, metavar="N",
                     help="posterior draws used, or FRF realisations drawn from the measurement's random error in "
                     "measured mode (default 500)")
    src.add_argument("--seed", type=nonnegative_int, default=0,
                     help="seed for choosing posterior draws or drawing FRF realisations (default 0)")
    src.add_argument("--measured-x", metavar="FX[,FX2,...]",
                     help="measured tool-point FRF in X (CSV frequency_hz,real,imag[,coherence] or UFF58); several "
                     "comma-separated files (or UFF58 records) are repeated hits at the same point")
    src.add_argument("--measured-y", metavar="FY[,FY2,...]", help="measured tool-point FRF in Y (as --measured-x)")
    src.add_argument("--averages", metavar="N",
                     help="impacts averaged per measured FRF (default: the files' '# averages = N' header line); "
                     "with a coherence column it gives the FRF's random error (Bendat & Piersol) and "
                     "probabilistic lobes")
    src.add_argument("--deterministic", action="store_true",
                     help="measured mode: use the measured FRFs (the mean of repeated hits) as they are, without "
                     "their random error (P(stable) 0 or 1, the classical lobes), even when the files carry coherence "
                     "and averages")
    src.add_argument("--spindle-uncertainty", metavar="FILE",
                     help="posterior mode: spindle_samples.npz of 'bayes-rcsa spindle'; the spindle receptance's own "
                     "uncertainty enters the FRF draws (default: the setup's spindle files as they are)")
    add_cutting_arguments(p)
    grid = p.add_argument_group("grid, method and recommendation")
    grid.add_argument("--speeds", required=True, metavar="START:STOP[:COUNT]",
                      help=f"spindle speeds in rpm (default COUNT {DEFAULT_SPEED_POINTS}); the recommended speed "
                      "and its tolerance window stay inside this range")
    grid.add_argument("--max-depth", metavar="M", help="largest axial depth in m the recommendation may use (machine, "
                      "tool or power limit; reported as binding_limit when it sets the depth)")
    grid.add_argument("--flute-length", metavar="M", help="flute length in m (depth limit; posterior mode: "
                      "default from the setup's fluted tool segments)")
    grid.add_argument("--speed-tolerance", default="2%", metavar="FRAC",
                      help="± spindle-speed tolerance of the recommendation, e.g. 2%% or 0.02 (default 2%%)")
    grid.add_argument("--depth-margin", default="10%", metavar="FRAC",
                      help="depth margin of the recommendation: P(stable) >= level up to depth x (1 + margin), "
                      "e.g. 10%% (default)")
    grid.add_argument("--depth-points", type=positive_int, default=200, metavar="N", help="depth levels of the map (default 200)")
    grid.add_argument("--method", choices=names, default="zoa", help="stability method (default zoa)")
    grid.add_argument("--intervals", type=positive_int, metavar="M",
                      help="SDM intervals per tooth period (default: 30 per cycle of the highest mode, >= 30)")
    grid.add_argument("--max-modes", type=int, default=4, metavar="N", help="largest mode count of the SDM modal fit (default 4)")
    grid.add_argument("--sdm-exact", action="store_true",
                      help="--method sdm on every draw (default: above 48 draws, 12 exact draws and the others' zero-order "
                           "limits times their SDM/ZOA ratio, checked leave-one-out; minutes instead of seconds)")
    grid.add_argument("--level", metavar="P", help="P(stable) required over the neighbourhood (default 0.95)")
    grid.add_argument("--confidence", metavar="C",
                      help="confidence of the robust envelope (the depth below which P(stable) >= C at each speed, "
                      "written to lobes.json and drawn) and of the recommendation; sets --level (default: --level)")
    grid.add_argument("--budget", default=str(DEFAULT_BUDGET_S), metavar="S",
                      help=f"run time in s above which the estimate printed before the job comes with advice on "
                      f"cutting it (default {DEFAULT_BUDGET_S:g})")
    p.add_argument("--tests", metavar="CSV", help="cutting tests: spindle_speed_rpm,depth_m,outcome (stable|chatter)")
    p.add_argument("--quiet", action="store_true", help="no run-time estimate or progress bar on stderr")
    p.add_argument("--no-plots", action="store_true",
                   help="skip lobes.png (lobes.json and p_stable.npz hold every number it draws)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.stability_lobes import lobes

    kw = cutting_keywords(args)
    speeds = parse_speeds(args.speeds)
    check_output_directory(args.out, args.force)  # refused before the lobes are computed (again under the lock)
    result = lobes(
        posterior=args.posterior, setup=args.setup,
        clamping_length=optional_float(args.clamping_length, "--clamping-length"),
        measured_x=args.measured_x, measured_y=args.measured_y,
        averages=None if args.averages is None else parse_averages(args.averages),
        deterministic=args.deterministic, draws=args.draws, seed=args.seed, **kw, speeds_rpm=speeds,
        max_depth=optional_float(args.max_depth, "--max-depth"),
        flute_length=optional_float(args.flute_length, "--flute-length"),
        speed_tolerance=parse_fraction(args.speed_tolerance, "--speed-tolerance", 0.0, 0.2),
        depth_margin=parse_fraction(args.depth_margin, "--depth-margin", 1e-3, 1.0),
        depth_points=args.depth_points, method=args.method, intervals=args.intervals, max_modes=args.max_modes,
        sdm_exact=args.sdm_exact,
        level=optional_float(args.level, "--level"), confidence=optional_float(args.confidence, "--confidence"),
        tests=args.tests, spindle_samples=args.spindle_uncertainty, progress=not args.quiet,
        budget_s=parse_float(args.budget, "--budget", positive=True))
    path = result.save(args.out, force=args.force, plots=not args.no_plots)
    return Summary(result.summary_line(), {"out": str(args.out), "lobes": str(path), **result.summary_data()},
                   warnings=result.warnings)
