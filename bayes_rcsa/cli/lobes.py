"""``bayes-rcsa lobes``: stability lobes and a robust operating point from measured FRFs or posterior draws.

Parsing and printing only; the job lives in :mod:`bayes_rcsa.stability`
(:func:`~bayes_rcsa.stability.probabilistic.lobes_from_frf_draws`, the FRF
inputs in :mod:`~bayes_rcsa.stability.posterior_frf`, the files in
:mod:`~bayes_rcsa.stability.outputs`).  See docs/stability.md.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..errors import SetupError
from ._arguments import (DEFAULT_SPEED_POINTS, add_cutting_arguments, cutting_from_arguments, parse_fraction,
                         parse_speeds)
from ._common import (Summary, add_force_argument, check_output_directory, command_warnings, merge_warnings,
                      nonnegative_int, parse_float, positive_int)

__all__ = ["register", "run"]

DEFAULT_BUDGET_S = 120.0


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
    grid.add_argument("--level", metavar="P", help="P(stable) required over the neighbourhood (default 0.95)")
    grid.add_argument("--confidence", metavar="C",
                      help="confidence of the robust envelope (the depth below which P(stable) >= C at each speed, "
                      "written to lobes.json and drawn) and of the recommendation; sets --level (default: --level)")
    grid.add_argument("--budget", default=str(DEFAULT_BUDGET_S), metavar="S",
                      help=f"run time in s above which the estimate printed before the job comes with advice on "
                      f"cutting it (default {DEFAULT_BUDGET_S:g})")
    p.add_argument("--tests", metavar="CSV", help="cutting tests: spindle_speed_rpm,depth_m,outcome (stable|chatter)")
    p.add_argument("--quiet", action="store_true", help="no run-time estimate or progress bar on stderr")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    add_force_argument(p)
    p.set_defaults(func=run)


def _posterior_coefficients(args):
    """``args`` with --kt/--kr set to the medians of an updated posterior's per-draw coefficients, or unchanged."""
    if args.kt is not None and args.kr is not None:
        return args, False
    if (args.kt is None) != (args.kr is None):
        raise SetupError("give both --kt and --kr, or neither (an updated posterior's per-draw coefficients)")
    if args.posterior is None:
        raise SetupError("--kt and --kr are required (only a posterior written by 'bayes-rcsa update' carries "
                         "per-draw cutting coefficients)")
    from ..stability.coefficients import read_coefficient_draws

    coef = read_coefficient_draws(args.posterior)
    if coef is None:
        raise SetupError(f"--kt and --kr are required: {args.posterior} carries no cutting-coefficient draws (only "
                         "'bayes-rcsa update' writes them)")
    return argparse.Namespace(**{**vars(args), "kt": repr(float(np.median(coef[0]))),
                                 "kr": repr(float(np.median(coef[1])))}), True


def _dynamics(args):
    """FRF draws in X and Y (FRFInput)."""
    from ..stability.measured import interpolate_lines
    from ..stability.posterior_frf import measured_frf_draws, posterior_frf_draws

    measured = args.measured_x is not None or args.measured_y is not None
    posterior = args.setup is not None or args.posterior is not None or args.clamping_length is not None
    if measured and posterior:
        raise SetupError("give either --measured-x/--measured-y or SETUP --posterior --clamping-length, not both")
    if measured:
        if args.measured_x is None or args.measured_y is None:
            raise SetupError("measured mode needs both --measured-x and --measured-y")
        from pathlib import Path

        from ..io.checks import warn_all, xy_pair_warnings

        averages = None
        if args.averages is not None:
            try:
                averages = int(args.averages)
            except ValueError:
                raise SetupError(f"--averages {args.averages!r}: expected a whole number >= 1 (impacts averaged "
                                 "per FRF)") from None
            if averages < 1:
                raise SetupError(f"--averages {args.averages!r}: expected a whole number >= 1 (impacts averaged "
                                 "per FRF)")
        if args.deterministic and averages is not None:
            raise SetupError(f"--averages {args.averages} and --deterministic contradict each other (averages give the "
                             "FRF's random error, --deterministic ignores it); give one of them")
        pair = measured_frf_draws(args.measured_x, args.measured_y, averages, args.draws,
                                  np.random.default_rng(args.seed), exact=args.deterministic)
        mx, my = pair.measured
        warn_all(pair.source["notes"])
        warn_all(xy_pair_warnings(Path(mx.files[0]).name, Path(my.files[0]).name, mx.frequency_hz, mx.mean,
                                  interpolate_lines(my.mean, my.frequency_hz, mx.frequency_hz)[0]
                                  if mx.frequency_hz.shape != my.frequency_hz.shape
                                  or not np.allclose(mx.frequency_hz, my.frequency_hz) else my.mean))
        return pair
    if args.setup is None or args.posterior is None or args.clamping_length is None:
        raise SetupError(
            "give --measured-x FX --measured-y FY, or SETUP --posterior FILE --clamping-length M for posterior draws"
        )
    if args.averages is not None:
        raise SetupError(f"--averages {args.averages}: only for measured FRFs (--measured-x/--measured-y)")
    if args.deterministic:
        raise SetupError("--deterministic: only for measured FRFs (--measured-x/--measured-y)")
    clamping = parse_float(args.clamping_length, "--clamping-length", positive=True)
    if args.draws < 1:
        raise SetupError(f"--draws {args.draws}: expected >= 1")
    from ..io.checks import warn_all
    from ..io.setup import load_setup
    from ..posterior.setup_match import posterior_setup_warnings

    # a posterior identified for another geometry or material says so (the setup's files are read later)
    warn_all(posterior_setup_warnings(args.posterior, load_setup(args.setup, load_data=False, load_spindle=False)))
    return posterior_frf_draws(args.setup, args.posterior, clamping, args.draws, np.random.default_rng(args.seed),
                               tool=getattr(args, "tool", None))


def _estimate(impl, frf, speeds, method, budget, quiet: bool) -> None:
    from ..stability.progress import format_seconds

    est = impl.estimate_seconds(frf.n_draws, speeds.size, frf.frequency_hz.size)
    if quiet:
        return
    print(f"lobes: {method}, {frf.n_draws} draw(s) x {speeds.size} speeds: estimated {format_seconds(est)}",
          file=sys.stderr)
    if est > budget:
        print(f"lobes: that is more than --budget {budget:g} s; to cut it use fewer draws (--draws "
              f"{max(1, frf.n_draws // 4)} is about 4x faster), a coarser speed grid (START:STOP:{max(2, speeds.size // 2)} "
              f"halves it)" + ("" if method == "zoa" else ", or --method zoa (seconds; accurate at moderate to "
                               "full radial immersion, SDM is needed below about 0.3)"), file=sys.stderr)


def run(args: argparse.Namespace) -> Summary:
    from ..stability import Tolerances, lobes_from_frf_draws
    from ..stability.methods import STABILITY_METHODS, MethodOptions
    from ..stability.outputs import lobes_document, write_lobes_outputs
    from ..stability.progress import ProgressBar
    from ..stability.tests_io import read_cutting_tests
    from ..io.atomic import directory_is_empty, directory_lock, new_output_directory

    args, per_draw = _posterior_coefficients(args)
    cutting, kt_tol, warnings = cutting_from_arguments(args)
    speeds = parse_speeds(args.speeds)
    level = parse_float(args.level if args.level is not None else "0.95", "--level", positive=True)
    if level > 1:
        raise SetupError(f"--level {args.level}: expected a probability in (0, 1]")
    if args.confidence is not None:
        confidence = parse_float(args.confidence, "--confidence", positive=True)
        if not (0.5 <= confidence < 1):
            raise SetupError(f"--confidence {args.confidence}: expected a probability in [0.5, 1) (e.g. 0.95)")
        if args.level is not None and abs(confidence - level) > 1e-12:
            raise SetupError(f"--confidence {args.confidence} and --level {args.level} differ; give one of them")
        level = confidence
    max_depth = parse_float(args.max_depth, "--max-depth", positive=True) if args.max_depth is not None else None
    flute = parse_float(args.flute_length, "--flute-length", positive=True) if args.flute_length is not None else None
    tol = Tolerances(parse_fraction(args.speed_tolerance, "--speed-tolerance", 0.0, 0.2),
                     parse_fraction(args.depth_margin, "--depth-margin", 1e-3, 1.0), kt_tol)
    budget = parse_float(args.budget, "--budget", positive=True)
    if args.depth_points < 2:
        raise SetupError(f"--depth-points {args.depth_points}: expected >= 2")
    if args.max_modes < 1:
        raise SetupError(f"--max-modes {args.max_modes}: expected >= 1 (the modal fit needs at least one mode)")
    impl = STABILITY_METHODS.get(args.method, "--method")
    impl.check(MethodOptions(intervals=args.intervals, max_modes=args.max_modes))
    tests = read_cutting_tests(args.tests) if args.tests is not None else None
    from ..io.limits import check_memory

    n_cells = speeds.size * args.depth_points
    check_memory(8.0 * (8 * args.draws * speeds.size + 4 * n_cells), f"--draws {args.draws} x --speeds "
                 f"{speeds.size} x --depth-points {args.depth_points}", "use fewer draws, speeds or depth points, or "
                 "split the speed range into several runs")
    frf = _dynamics(args)  # validates before any output is written
    check_memory(8.0 * (8 * frf.n_draws * speeds.size + 4 * n_cells) + 16.0 * 6 * frf.n_draws * frf.frequency_hz.size,
                 f"{frf.n_draws} draw(s) x {frf.frequency_hz.size} frequency lines x --speeds {speeds.size}",
                 "use fewer --draws or a coarser speed grid, or split the speed range into several runs")
    if not args.force and not directory_is_empty(args.out):
        check_output_directory(args.out)  # refused before the lobes are computed (checked again under the lock)
    flute = flute if flute is not None else frf.flute_length_m
    status = frf.source.get("posterior_status") or {}
    if status.get("converged") is False:
        warnings.append(f"the posterior {frf.source['posterior']} did not converge (see its summary.json): "
                        "the P(stable) map inherits its uncertainty estimate")
    warnings += [n.removeprefix("warning:").strip() for n in frf.source.get("parameter_model_notes", [])
                 if n.startswith("warning:")]

    _estimate(impl, frf, speeds, args.method, budget, args.quiet)
    bar = None if args.quiet else ProgressBar(f"lobes: {args.method}")
    try:
        res = lobes_from_frf_draws(
            frf.frf_x, frf.frf_y, frf.frequency_hz, cutting, speeds, method=args.method, level=level,
            max_depth=max_depth, depth_points=args.depth_points, intervals=args.intervals, max_modes=args.max_modes,
            tolerances=tol, flute_length=flute, progress=bar,
            coefficients=frf.coefficients if per_draw else None,
        )
    finally:
        if bar is not None:
            bar.close()
    fit_report = None
    if args.method == "sdm" and frf.measured is not None:
        from ..io.checks import warn_all
        from ..stability.modal_quality import measured_fit_report

        fit_report, fit_warnings = measured_fit_report(frf.measured, res.modal_fits, args.max_modes)
        warn_all(fit_warnings)
    warnings = merge_warnings(command_warnings(), warnings)  # the data warnings printed on stderr go into lobes.json
    doc = lobes_document(res, cutting, frf.source, tests, warnings, max_depth=max_depth, flute_length=flute)
    if per_draw:
        kt_q, kr_q = (np.quantile(c, [0.05, 0.5, 0.95]).tolist() for c in frf.coefficients)
        doc["cutting_coefficients"] = {"source": "per-draw K_t/K_r of the updated posterior (bayes-rcsa update); "
                                       "the cutting block gives their medians", "kt_pa_q05_q50_q95": kt_q,
                                       "kr_pa_q05_q50_q95": kr_q}
    if fit_report is not None:
        doc["modal_fit"] = fit_report
    title = f"{cutting.flutes} flutes, {res.method.upper()}, " + (
        "measured FRFs" if frf.source["mode"] == "measured" else f"{frf.n_draws} draws"
    )
    with directory_lock(args.out), new_output_directory(check_output_directory(args.out, args.force)):
        path = write_lobes_outputs(args.out, res, doc, tests, title, max_depth=max_depth)
    rec = res.recommended
    msg = f"wrote {path}, p_stable.npz, lobes.png"
    if rec is not None:
        below, above = rec.margin_speed_rpm
        msg += (f"; recommended {rec.spindle_speed_rpm:.0f} rpm, {rec.depth_m * 1e3:.3f} mm (P(stable) >= "
                f"{rec.p_stable_neighbourhood:.2f} over ±{100 * tol.speed_rel:g} % speed and +{100 * tol.depth_margin:g} % "
                f"depth; margins {'-' if below is None else f'{below:.0f}'}/{'-' if above is None else f'{above:.0f}'} rpm, "
                f"{rec.margin_depth_m * 1e3:.3f} mm; limited by {rec.binding})")
    else:
        msg += f"; no recommendation: {res.note}"
    med = res.median_recommended
    if rec is not None and med is not None and res.depth_limit_m.shape[0] > 1:
        msg += (f"; at P(stable) >= 0.5 it would be {med.spindle_speed_rpm:.0f} rpm, {med.depth_m * 1e3:.3f} mm "
                f"(confidence {res.level:g} costs {(med.depth_m - rec.depth_m) * 1e3:.3f} mm)")
    if frf.source.get("deterministic"):
        msg += "; " + frf.source["deterministic_note"]
    elif frf.measured is not None:
        msg += "; FRF random error: " + ", ".join(
            f"{d} {m.model} ({len(m.files)} file(s){'' if m.averages is None else f', {m.averages} averages'})"
            for d, m in zip("XY", frf.measured)) + f", {frf.n_draws} realisations"
    recommended = None if rec is None else {
        "spindle_speed_rpm": rec.spindle_speed_rpm, "depth_m": rec.depth_m,
        "p_stable": rec.p_stable_neighbourhood, "binding": rec.binding}
    return Summary(msg, {"out": str(args.out), "lobes": str(path), "recommended": recommended,
                         "robust_envelope_confidence": res.level,
                         "deterministic": bool(res.depth_limit_m.shape[0] == 1),
                         "uncertainty": doc.get("uncertainty"),
                         "posterior_converged": status.get("converged")}, warnings=tuple(warnings))
