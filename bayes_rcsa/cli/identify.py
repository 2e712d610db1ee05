"""``bayes-rcsa identify``: Bayesian (or deterministic) identification of the tool-holder contact."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import SetupError
from ._common import (Summary, add_force_argument, check_output_directory, command_warnings, finite_float,
                      merge_warnings, nonnegative_int, positive_int, sampler_int)

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
The likelihood band, noise model and priors can be tuned in the setup's [likelihood], [priors] and
[sampler] tables (see docs/identification.md).
"""


#: Files of an identify run, removed by --force before a new run (other files in --out are left alone).
EARLIER_OUTPUTS = ("summary.json", "posterior.nc", "chain.h5", "chain.mirror.h5", "trace.png", "corner.png", "frf.png")


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
    p.add_argument("--resume", action="store_true", help="continue the run checkpointed in DIR/chain.h5")
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
    p.add_argument("--tail-check", action="store_true",
                   help="after sampling, compare every parameter's 90 %% interval ends with an importance-sampling "
                        "estimate of the same posterior (1e5 evaluations; docs/identification.md)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    lib = p.add_argument_group("tool library (docs/library.md)")
    lib.add_argument("--library", type=Path, default=None, metavar="FILE",
                     help="population.nc of 'bayes-rcsa library': the contact prior is the population predictive of "
                          "the setup's [holder] type and shank diameter (method multi)")
    lib.add_argument("--no-taps", action="store_true",
                     help="with --library: use no measurement; write a posterior.nc of population-predictive draws "
                          "(predict and lobes read it like any posterior)")
    from ._arguments import add_cut_arguments

    add_cut_arguments(p)
    p.set_defaults(func=run)


def _library(args):
    """The population of --library and the options it sets (None without --library); checks the combinations."""
    if args.library is None:
        if args.no_taps:
            raise SetupError("--no-taps needs --library (the population the prediction comes from)")
        return None
    if args.method != "multi":
        raise SetupError(f"--library: method {args.method!r}; a library prior is used with method 'multi'")
    if args.resume:
        raise SetupError("--library cannot be combined with --resume")
    if args.no_taps and (args.lengths is not None or args.spindle_uncertainty is not None):
        raise SetupError("--no-taps uses no measurement: drop --lengths and --spindle-uncertainty")
    from ..library.outputs import read_population

    return read_population(args.library)


def _run_zero_taps(args, population) -> Summary:
    import warnings

    import numpy as np

    from ..errors import DataWarning
    from ..io.atomic import directory_lock, new_output_directory
    from ..io.setup import load_setup
    from ..library.newsetup import write_zero_tap

    setup = load_setup(args.setup, load_data=False)
    with directory_lock(args.out):
        check_output_directory(args.out, args.force, False, resumable=False)
        if args.force:
            for name in EARLIER_OUTPUTS:
                (args.out / name).unlink(missing_ok=True)
        with new_output_directory(args.out):
            summary = write_zero_tap(args.out, population, setup, np.random.default_rng(args.seed),
                                     warnings=command_warnings())
    for w in summary["warnings"]:
        warnings.warn(w, DataWarning, stacklevel=2)
    return Summary(f"zero taps: population predictive of holder type {summary['holder_type']}; results in {args.out}",
                   {"out": str(args.out), "method": summary["method"], "converged": True,
                    "summary": str(args.out / "summary.json"), "posterior": str(args.out / "posterior.nc")},
                   warnings=tuple(summary["warnings"]))


def _check_resonances(problem, allow: bool) -> None:
    """Refuse (or, with ``allow``, warn about) a fitted measurement without a resonance in its band."""
    import warnings

    from ..errors import DataError, DataWarning
    from ..io.checks import resonance_problem

    for _, frf in problem.measurements:
        why = resonance_problem(frf.frequency_hz, frf.values)
        if why is None:
            continue
        if not allow:
            raise DataError(f"{frf.source}: {why}; --allow-no-resonance proceeds anyway")
        warnings.warn(f"{frf.source}: {why}; the posterior of the contact mostly restates its prior", DataWarning,
                      stacklevel=2)


def _tail_check_rng(seed: int):
    import numpy as np

    return np.random.default_rng([seed, 7])


def run(args) -> Summary:
    from ..inference.identify import identify
    from ..inference.outputs import write_outputs
    from ..inference.problem import IdentificationOptions, build_problem_from_setup
    from ..inference.sampler import SamplerSettings
    from ..inference.tail_check import check_identification
    from ..io.atomic import directory_lock, new_output_directory
    from ..io.setup import load_setup
    from ..posterior.setup_match import GEOMETRY_KEY, setup_geometry

    # Everything that can be checked without sampling is checked before --out is touched.
    if args.ess_min <= 0:
        raise SetupError(f"--ess-min {args.ess_min!r}: expected a number > 0")
    if args.checkpoint_interval < 0:
        raise SetupError(f"--checkpoint-interval {args.checkpoint_interval!r}: expected a number >= 0 (seconds)")
    bayesian = args.method != "deterministic"
    if args.resume and not bayesian:
        raise SetupError("--resume applies to the Bayesian methods only")
    if args.spindle_uncertainty is not None and not bayesian:
        raise SetupError("--spindle-uncertainty applies to the Bayesian methods only")
    population = _library(args)
    if args.no_taps:
        return _run_zero_taps(args, population)
    ckpt = args.out / "chain.h5"
    if args.resume and not (ckpt.exists() or ckpt.with_name("chain.mirror.h5").exists()):
        raise SetupError(f"--resume: no checkpoint found at {ckpt}")
    setup = load_setup(args.setup)
    library_kw = {}
    if population is not None:
        import warnings

        import numpy as np

        from ..errors import DataWarning
        from ..library.newsetup import library_options

        library_kw, lib_warnings = library_options(population, setup, np.random.default_rng(args.seed))
        for w in lib_warnings:
            warnings.warn(w, DataWarning, stacklevel=2)
    options = IdentificationOptions.from_setup(setup.extra, method=args.method, lengths=args.lengths, band=args.band,
                                               **library_kw)
    problem = build_problem_from_setup(setup, options)
    _check_resonances(problem, args.allow_no_resonance)
    from .update import cut_coefficients, cut_term_from_arguments, write_cut_coefficients

    cut_term = cut_term_from_arguments(args, problem, setup)  # None without --cuts
    if cut_term is not None:  # --cuts: a joint fit
        problem = problem.with_extra_terms(cut_term)
    sampler_extra = dict(setup.extra.get("sampler", {}) or {})
    pick = lambda cli, key, default: cli if cli is not None else sampler_int(sampler_extra, key, default, setup.path)  # noqa: E731
    settings = SamplerSettings(
        n_walkers=pick(args.walkers, "walkers", None),
        max_steps=pick(args.max_steps, "max_steps", 20000),
        check_every=pick(args.check_every, "check_every", 250),
        ess_min=args.ess_min,
        checkpoint_interval=args.checkpoint_interval,
        progress=not args.quiet,
    )
    if bayesian:
        from ..io.limits import check_memory

        n_walkers = settings.walkers(problem.priors.ndim)  # refuses an odd or too small walker count now
        # the chain is kept in memory (twice while it grows) until the run ends
        check_memory(2 * 8.0 * settings.max_steps * n_walkers * (problem.priors.ndim + 1),
                     f"--max-steps {settings.max_steps} x {n_walkers} walkers", "lower --max-steps or --walkers")
    spindle_samples = None
    if args.spindle_uncertainty is not None:
        from ..spindle.uncertainty import load_spindle_samples

        spindle_samples = load_spindle_samples(args.spindle_uncertainty)
        missing = sorted({m.direction for m in setup.measurements} - set(spindle_samples.directions))
        if missing:
            raise SetupError(f"--spindle-uncertainty {args.spindle_uncertainty}: no samples for direction(s) "
                             f"{missing}; the file has {spindle_samples.directions}")
    with directory_lock(args.out):
        check_output_directory(args.out, args.force, args.resume, resumable=bayesian)
        if args.force and not args.resume:
            # an earlier run's results must not survive beside the new ones (a deterministic rerun writes no
            # posterior.nc, and predict would read the old one)
            for name in EARLIER_OUTPUTS:
                (args.out / name).unlink(missing_ok=True)
        # a failure removes what this run wrote (a checkpoint too: a rerun must not be blocked by it), except the
        # checkpoint after Ctrl-C, which --resume continues
        with new_output_directory(args.out, keep_on_interrupt=("chain.h5", "chain.mirror.h5")):
            result = identify(problem, seed=args.seed, settings=settings,
                              checkpoint_path=ckpt if bayesian else None, resume=args.resume,
                              spindle_samples=spindle_samples)
            if args.tail_check and bayesian:
                # its own stream: the chain's seed stays the chain's
                result.summary["tail_check"] = check_identification(result, _tail_check_rng(args.seed))
            if cut_term is not None:
                cut_draws, result.summary["cuts"] = cut_coefficients(result, cut_term, args.seed)
            tc = result.summary.get("tail_check")
            if tc is not None and tc["verdict"] != "consistent":
                result.summary.setdefault("warnings", []).append(f"tail check {tc['verdict']}: {tc['reason']}")
            # the data-plausibility warnings printed on stderr travel with the results too
            result.summary["warnings"] = merge_warnings(command_warnings(), result.summary.get("warnings", []))
            # what predict and lobes compare their setup with (a changed tool length, diameter or modulus)
            result.summary[GEOMETRY_KEY] = setup_geometry(setup)
            if population is not None:  # which population was the prior
                result.summary["library"] = {"population": str(args.library), "model_version": population.version,
                                             "holder_type": setup.holder_type,
                                             "pooled_parameters": list(population.names)}
            write_outputs(result, args.out, plots=not args.no_plots)
            if cut_term is not None:
                write_cut_coefficients(args.out, cut_draws, result.summary["cuts"])
    s = result.summary
    status = "converged" if s["converged"] else "NOT converged"
    return Summary(
        f"{s['method']}: {status}; results in {args.out}",
        {"out": str(args.out), "method": s["method"], "converged": bool(s["converged"]),
         "summary": str(args.out / "summary.json"),
         "posterior": str(args.out / "posterior.nc") if bayesian else None},
        warnings=tuple(s.get("warnings", [])),
    )
