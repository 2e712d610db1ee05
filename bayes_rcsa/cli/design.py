"""``bayes-rcsa design``: which hammer test next (expected reduction of a target's uncertainty)."""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from ..errors import SetupError
from ._arguments import optional_float, parse_coefficient
from ._common import (Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float,
                      parse_float_list, positive_int)

__all__ = ["register", "run"]

DESCRIPTION = """\
Rank candidate impact-hammer tests by the expected 90 % width of a target after each one.

With --posterior (posterior.nc of 'bayes-rcsa identify'): for every candidate test, measurements are
simulated from the posterior draws with the noise level and tempering the fit found, the draws are
re-weighted by each simulated measurement's likelihood, and the resulting 90 % widths are averaged
(nested Monte Carlo; a Laplace/Fisher approximation where the importance weights collapse).
A posterior fitted at one clamping length is first given the growth law's prior uncertainty.

Without --posterior (no data yet): which two clamping lengths of the feasible range minimise the
expected 90 % width of the dominant natural frequency averaged over the range (prior draws, Laplace).

  --target    frequency@L | stiffness@L | lobes@L:START:STOP[:COUNT]   (L in m, speeds in rpm)
  --candidates 0.030,0.035,0.040,tool:NAME@0.030,dir:y@0.030
  both required with --posterior, e.g.
  design setup.toml --posterior fit/posterior.nc --target frequency@0.035
         --candidates 0.030,0.040,dir:y@0.035 --out design

Writes to --out: design.json (ranking best first, expected widths with Monte Carlo errors, the
verdict whether another test is worth it) and design.png. See docs/design.md.

With --next-cut: which TEST CUT next (docs/stability.md, "Which cut next"). Every pair of
--speeds x --depths is a candidate; the posterior's draws with cutting coefficients from --kt V±T
(and the cuts made so far, --cuts) give each candidate's P(chatter) and the exact expected
uncertainty after its two possible outcomes of --next-cut-target: map (uncertain area of the
P(stable) map), depth@SPEED (90 % width of the depth limit there) or mrr@P (best removal rate at
P(stable) >= P; maximised). Candidates with P(chatter) > --risk-budget are never proposed.
  design SETUP --posterior P --next-cut --clamping-length 0.03 --speeds 5000:30000:25
         --depths 5e-6:8e-5:15 --kt 790e6±30% --kr 230e6 --flutes 4 --immersion 0.95
         --feed y [--cuts CUTS.csv] [--risk-budget 0.3] --out DIR
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("design", help="which hammer test next: expected uncertainty reduction of a target",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("setup", type=Path, metavar="SETUP", help="setup file (TOML)")
    p.add_argument("--posterior", type=Path, default=None, metavar="FILE",
                   help="posterior.nc written by 'bayes-rcsa identify' (omit for the no-data planning mode)")
    p.add_argument("--candidates", default=None, metavar="LIST",
                   help="candidate tests: clamping lengths in m, tool:NAME@L, dir:D@L (required with --posterior; "
                   "no-data mode: lengths only, default 7 lengths over the feasible range)")
    p.add_argument("--target", default=None, metavar="TARGET",
                   help="frequency@L, stiffness@L or lobes@L:START:STOP[:COUNT] (required with --posterior)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--draws", type=positive_int, default=1500, metavar="N",
                   help="posterior draws re-weighted (default 1500)")
    p.add_argument("--truths", type=positive_int, default=120, metavar="M",
                   help="simulated measurements per candidate (default 120)")
    p.add_argument("--method", choices=("auto", "importance", "laplace"), default="auto",
                   help="estimator (default auto: importance re-weighting, Laplace where the weights collapse)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed (default 0)")
    p.add_argument("--noise-scale", type=float, default=None, metavar="S",
                   help="no-data mode: relative noise of the future tests (default 0.02)")
    cut = p.add_argument_group("cutting conditions (lobes target)")
    cut.add_argument("--kt", default=None, metavar="PA", help="tangential cutting-force coefficient in Pa")
    cut.add_argument("--kr", default=None, metavar="PA", help="radial cutting-force coefficient in Pa")
    cut.add_argument("--flutes", type=positive_int, default=None, help="number of flutes")
    cut.add_argument("--immersion", default=None, metavar="R",
                     help="radial depth / tool diameter in (0, 1], 1 = slotting (as in lobes and update)")
    # the option's name before issue #45: one name for one quantity across commands, the old one still read
    cut.add_argument("--radial-immersion", dest="immersion", action=_DeprecatedName, new_name="--immersion",
                     help=argparse.SUPPRESS)
    cut.add_argument("--milling", choices=("down", "up"), default="down", help="down (climb) or up milling")
    p.add_argument("--no-plots", action="store_true", help="skip design.png")
    _add_next_cut_arguments(p)
    add_force_argument(p)
    p.set_defaults(func=run)


class _DeprecatedName(argparse.Action):
    """An option's former name: stores into the new option's ``dest`` and leaves a deprecation warning."""

    def __init__(self, option_strings, dest, new_name: str, **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new_name = new_name

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        namespace.deprecated_names = [*getattr(namespace, "deprecated_names", []), (option_string, self.new_name)]


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.experiment_design import design_test

    for old, new in getattr(args, "deprecated_names", ()):
        warnings.warn(f"{old} is deprecated; use {new} (the same option of lobes and update)", FutureWarning,
                      stacklevel=2)
    kw = _next_cut_keywords(args) if args.next_cut else _hammer_keywords(args)
    check_output_directory(args.out, args.force)  # refused before the design is computed (again under the lock)
    result = design_test(args.setup, args.posterior, target=args.target, draws=args.draws, seed=args.seed,
                    flutes=args.flutes, milling=args.milling, next_cut=args.next_cut, **kw)
    path = result.save(args.out, force=args.force, plots=not args.no_plots)
    return Summary(result.summary_line(), {"out": str(args.out), "design": str(path), **result.summary_data()},
                   warnings=result.warnings)


def _hammer_keywords(args) -> dict:
    """The hammer-test options as numbers (candidate lengths of the no-data plan; the lobes target's coefficients)."""
    candidates = args.candidates
    if args.posterior is None and candidates is not None:
        candidates = parse_float_list(candidates, "--candidates", positive=True)
    return {"candidates": candidates, "truths": args.truths, "method": args.method,
            "noise_scale": args.noise_scale, "kt": optional_float(args.kt, "--kt"),
            "kr": optional_float(args.kr, "--kr", positive=False),
            "radial_immersion": optional_float(args.immersion, "--immersion")}


# ------------------------------------------------------------- --next-cut (issue #23) --
def _add_next_cut_arguments(p) -> None:
    nc = p.add_argument_group("which test cut next (--next-cut; --kt V±T sets the coefficient prior)")
    nc.add_argument("--next-cut", action="store_true", help="rank candidate test cuts instead of hammer tests")
    nc.add_argument("--speeds", default=None, metavar="A:B[:N]", help="candidate speeds in rpm (default N 25)")
    nc.add_argument("--depths", default=None, metavar="C:D[:N]", help="candidate axial depths in m (default N 15)")
    nc.add_argument("--clamping-length", default=None, metavar="M", help="clamping length of the next cut in m")
    nc.add_argument("--cuts", default=None, metavar="CSV", help="cuts made so far (the 'update' file format)")
    nc.add_argument("--next-cut-target", default="map", metavar="T", help="map (default), depth@SPEED or mrr@P")
    nc.add_argument("--risk-budget", default="1", metavar="P",
                    help="largest P(chatter) of a proposed cut (default 1: no budget)")
    nc.add_argument("--feed", choices=("x", "y"), default="x", help="feed direction (default x)")
    nc.add_argument("--tool", default=None, metavar="NAME", help="tool (default: the setup's only tool)")
    nc.add_argument("--particles", type=positive_int, default=4, metavar="M",
                    help="coefficient draws per posterior draw (default 4)")


def _axis(text, option: str, count: int):
    import numpy as np

    parts = (text or "").split(":")
    if len(parts) not in (2, 3):
        raise SetupError(f"{option} {text!r}: expected START:STOP[:COUNT]")
    lo, hi = (parse_float(v, option, positive=True) for v in parts[:2])
    try:
        n = count if len(parts) == 2 else positive_int(parts[2])
    except argparse.ArgumentTypeError as exc:
        raise SetupError(f"{option} {text!r}: COUNT {exc}") from None
    if hi < lo or (hi == lo and n != 1):
        raise SetupError(f"{option} {text!r}: expected START <= STOP")
    return np.linspace(lo, hi, n)


def _next_cut_keywords(args) -> dict:
    """The --next-cut options as numbers: the coefficient prior, the candidate grid, the risk budget."""
    kt, kt_tol = parse_coefficient(args.kt, "--kt") if args.kt is not None else (None, 0.0)
    kr, kr_tol = parse_coefficient(args.kr, "--kr") if args.kr is not None else (None, 0.0)
    return {"candidates": args.candidates, "kt": kt, "kr": kr, "kt_tolerance": kt_tol, "kr_tolerance": kr_tol,
            "radial_immersion": optional_float(args.immersion, "--immersion"), "feed": args.feed,
            "speeds_rpm": None if args.speeds is None else _axis(args.speeds, "--speeds", 25),
            "depths_m": None if args.depths is None else _axis(args.depths, "--depths", 15),
            "clamping_length": optional_float(args.clamping_length, "--clamping-length"), "cuts": args.cuts,
            "next_cut_target": args.next_cut_target, "particles": args.particles, "tool": args.tool,
            "risk_budget": parse_float(args.risk_budget, "--risk-budget", positive=True)}
