"""``bayes-rcsa identify``: Bayesian (or deterministic) identification of the tool-holder contact."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._arguments import add_cut_arguments, add_sampler_argument, cut_test_numbers
from ._common import Summary, add_force_argument, finite_float, nonnegative_int, positive_int

__all__ = ["register", "run"]

DESCRIPTION = """\
Identify the tool-holder contact stiffness (k_xf, k_thetaM) from measured tool-point FRFs.

Methods:
  multi          Bayesian; all selected measurements together.  Several clamping lengths: the
                 stiffness grows linearly and boundedly with clamping length (paper's Method II);
                 one clamping length (several tools): one shared contact (Method I).
  single         Bayesian fit of one clamping length with a constant contact (literature method).
  deterministic  Least-squares fit minimising the absolute percentage FRF difference in a band
                 around the dominant peak (the paper's baseline); one or several lengths.

Writes to --out: summary.json, posterior.nc (ArviZ InferenceData; Bayesian methods), trace.png,
corner.png, frf.png and the checkpoint chain.h5 (resumable with --resume after a crash).
With --sampler importance (or auto) and accepted importance sampling: no chain, so no trace.png
and no chain.h5; posterior.nc holds 4000 equally weighted (resampled) draws.
The likelihood band, noise model and priors can be tuned in the setup's [likelihood], [priors] and
[sampler] tables (see docs/identification.md).
"""


def _lengths(text: str) -> tuple[float, ...]:
    vals = tuple(float(v) for v in _numbers(text, "clamping lengths in m, e.g. 0.025,0.040"))
    if not vals or not all(v > 0 for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: expected comma-separated clamping lengths > 0 in m, e.g. 0.025,0.040")
    return vals


def _band(text: str) -> tuple[float, float]:
    vals = _numbers(text, "LO,HI in Hz, e.g. 1000,1600")
    if len(vals) != 2 or not 0 < vals[0] < vals[1]:
        raise argparse.ArgumentTypeError(f"{text!r}: expected LO,HI in Hz with 0 < LO < HI, e.g. 1000,1600")
    return vals[0], vals[1]


def _numbers(text: str, expected: str) -> list[float]:
    try:
        return [finite_float(v) for v in text.split(",") if v.strip()]
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected {expected}") from None


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "identify",
        help="identify the tool-holder contact from tool-point FRFs (emcee or deterministic)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("setup", type=Path, metavar="SETUP", help="setup file (TOML)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--lengths", type=_lengths, default=None, metavar="L1,L2,...",
                   help="use only measurements at these clamping lengths (m), e.g. 0.025,0.040")
    p.add_argument("--method", choices=("multi", "single", "deterministic"), default="multi",
                   help="identification method (default: multi)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed; same seed, same posterior (default 0)")
    p.add_argument("--max-steps", type=positive_int, default=None, metavar="N",
                   help="cap on sampler steps; reaching it is reported as not converged "
                        "(default: [sampler] max_steps or 20000)")
    p.add_argument("--resume", action="store_true", help="continue the run checkpointed in DIR/chain.h5 (an MCMC "
                   "chain: refused with --sampler importance)")
    add_sampler_argument(p, "--walkers, --max-steps, --check-every, --ess-min")
    add_force_argument(p, resumable=True)
    p.add_argument("--walkers", type=positive_int, default=None, metavar="N",
                   help="number of walkers (even; default max(32, 4 x parameters))")
    p.add_argument("--band", type=_band, default=None, metavar="LO,HI",
                   help="likelihood band in Hz for every measurement (default: rule around the dominant modes)")
    p.add_argument("--check-every", type=positive_int, default=None, metavar="N",
                   help="steps between convergence checks (default: [sampler] check_every or 250)")
    p.add_argument("--ess-min", type=finite_float, default=400.0, metavar="ESS",
                   help="bulk ESS required for convergence (default 400)")
    p.add_argument("--checkpoint-interval", type=finite_float, default=2.0, metavar="SECONDS",
                   help="seconds between checkpoint writes (default 2)")
    p.add_argument("--spindle-uncertainty", type=Path, default=None, metavar="FILE",
                   help="spindle samples (spindle_samples.npz from `bayes-rcsa spindle`): the predicted "
                        "natural-frequency intervals mix posterior draws with spindle samples (Bayesian methods)")
    p.add_argument("--allow-no-resonance", action="store_true",
                   help="proceed (with a warning) when a measurement holds no resonance in its band (default: "
                        "refuse; such a file cannot determine the contact)")
    p.add_argument("--tail-check", action=argparse.BooleanOptionalAction, default=None,
                   help="after sampling, compare every parameter's 90 %% interval ends with an importance-sampling "
                        "estimate of the same posterior (as many evaluations as the chain's, 2e4-1e5; "
                        "docs/identification.md); a disagreement makes the run not converged (default: on, except with --cuts, where "
                        "every evaluation runs the cuts' stability limits)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    lib = p.add_argument_group("tool library (docs/library.md)")
    lib.add_argument("--library", type=Path, default=None, metavar="FILE",
                     help="population.nc of 'bayes-rcsa library': the contact prior is the population predictive of "
                          "the setup's [holder] type and shank diameter (method multi)")
    lib.add_argument("--no-taps", action="store_true",
                     help="with --library: use no measurement; write a posterior.nc of population-predictive draws "
                          "(predict and lobes read it like any posterior)")
    add_cut_arguments(p)
    p.set_defaults(func=run)


def run(args) -> Summary:
    from ..workflows.identification import identify

    cuts = cut_test_numbers(args)  # None without --cuts
    result = identify(args.setup, lengths=args.lengths, method=args.method, seed=args.seed, walkers=args.walkers,
                      max_steps=args.max_steps, check_every=args.check_every, ess_min=args.ess_min,
                      checkpoint_interval=args.checkpoint_interval, band=args.band,
                      spindle_samples=args.spindle_uncertainty, allow_no_resonance=args.allow_no_resonance,
                      tail_check=args.tail_check, library=args.library, no_taps=args.no_taps, cuts=cuts,
                      out=args.out, resume=args.resume, force=args.force, progress=not args.quiet,
                      plots=not args.no_plots, sampler=args.sampler)
    out = args.out
    data = {"out": str(out), **result.summary_data(), "summary": str(out / "summary.json"),
            "posterior": None if result.path is None else str(out / "posterior.nc")}
    return Summary(result.summary_line(), data, warnings=result.warnings)
