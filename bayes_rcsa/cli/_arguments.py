"""Argument groups and parsers shared by several sub-commands (no command module imports another).

The cutting conditions of ``lobes``, ``update`` and ``design --next-cut``, the
``--cuts`` group of ``identify``, spindle-speed grids, fractions and
coefficients with tolerances, and the executor options of ``batch`` and
``library``.  Parsing only: numbers and names go to the workflows
(:mod:`bayes_rcsa.workflows`), which build the domain objects.
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import SetupError
from ._common import parse_float, parse_float_list, positive_int

__all__ = ["DEFAULT_SPEED_POINTS", "KT_HELP", "KR_HELP", "add_cutting_arguments", "parse_speeds", "parse_fraction",
           "add_sampler_argument", "parse_coefficient", "cutting_keywords", "parse_averages", "optional_float", "parse_directions",
           "boundary_width_numbers", "CUT_FLAGS", "add_cut_arguments", "cut_test_numbers", "join_negative_values",
           "check_lengths_in_metres", "MM_SUSPECT_M", "LENGTH_OPTIONS"]

DEFAULT_SPEED_POINTS = 400

KT_HELP = ("tangential cutting-force coefficient in Pa (e.g. 790e6); an optional tolerance of the cutting-force level, "
           "790e6±5%% (or +-5%%, or ±40e6), scales Kt and Kr together and is part of the recommendation's "
           "neighbourhood; default with an updated posterior (bayes-rcsa update): its per-draw Kt and Kr")
KR_HELP = "radial cutting-force coefficient in Pa (e.g. 230e6); default as --kt"


def add_cutting_arguments(p, kt_help: str = KT_HELP, kr_help: str = KR_HELP, required: bool = False):
    """The cutting-condition options of ``lobes`` (also used by ``update``); returns the argument group."""
    cut = p.add_argument_group("cutting conditions")
    cut.add_argument("--flutes", type=positive_int, required=True, metavar="N", help="number of teeth")
    cut.add_argument("--kt", required=required, metavar="PA[±TOL]", help=kt_help)
    cut.add_argument("--kr", required=required, metavar="PA[±TOL]" if required else "PA", help=kr_help)
    cut.add_argument("--allow-unusual", action="store_true",
                     help="proceed (with a warning) when Kt is outside 1e8-1e10 Pa or Kr/Kt outside 0.05-2, "
                     "the ranges for metals that otherwise stop the run as a likely unit slip")
    cut.add_argument("--immersion", metavar="R", help="radial depth / tool diameter in (0, 1], 1 = slotting")
    cut.add_argument("--angles", metavar="ENTRY,EXIT", help="entry and exit angles in degrees instead of --immersion")
    cut.add_argument("--milling", choices=("down", "up"), default="down", help="down (climb) or up milling (default down)")
    cut.add_argument("--feed", choices=("x", "y"), default="x", help="feed direction (default x; the paper feeds in y)")
    cut.add_argument("--pitch", metavar="DEG,...", help="variable pitch: angle (deg) from each tooth to the one ahead")
    return cut


def parse_speeds(text: str, option: str = "--speeds") -> np.ndarray:
    """``START:STOP[:COUNT]`` rpm -> increasing grid of COUNT speeds (default 400).

    Each malformed range gets its own one-line message: not two or three parts, a part that is not a number, a
    speed <= 0 (also ``--speeds -5000:30000``, which :func:`join_negative_values` hands over as a value),
    STOP <= START, a COUNT that is not an integer >= 2.
    """
    example = "e.g. 5000:30000 or 5000:30000:400"
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise SetupError(f"{option} {text!r}: expected START:STOP[:COUNT] in rpm, {example}")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise SetupError(f"{option} {text!r}: START and STOP must be numbers in rpm, {example}") from None
    if not (np.isfinite(start) and np.isfinite(stop)) or start <= 0 or stop <= 0:
        raise SetupError(f"{option} {text!r}: spindle speeds are in rpm and must be > 0, {example}")
    count = DEFAULT_SPEED_POINTS
    if len(parts) == 3:
        try:
            count = int(parts[2])
        except ValueError:
            raise SetupError(f"{option} {text!r}: COUNT must be an integer >= 2") from None
    if stop <= start:
        raise SetupError(f"{option} {text!r}: STOP must be above START (speeds in rpm, {example})")
    if count < 2:
        raise SetupError(f"{option} {text!r}: COUNT must be an integer >= 2")
    from ..io.limits import check_count

    check_count("speed_points", count, f"{option} {text!r}: COUNT")
    return np.linspace(start, stop, count)


def join_negative_values(argv: list[str]) -> list[str]:
    """``--speeds -5000:30000`` -> ``--speeds=-5000:30000``, so that the option's own check names the problem.

    argparse takes a value starting with ``-`` for an option (unless it is a plain negative number) and answers
    only "expected one argument"; joined with ``=``, the value reaches the option's parser, which says what is
    wrong with it.  Tokens after ``--`` are left alone.
    """
    out, i = [], 0
    argv = list(argv)
    while i < len(argv):
        tok = argv[i]
        if tok == "--":
            out.extend(argv[i:])
            break
        nxt = argv[i + 1] if i + 1 < len(argv) else ""
        if tok.startswith("--") and "=" not in tok and _NEGATIVE_VALUE.match(nxt):
            out.append(f"{tok}={nxt}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


_NEGATIVE_VALUE = re.compile(r"^-\.?\d")

#: Lengths (m) at or above which a command-line or setup length is taken for millimetres: no clamping length,
#: tool, holder, flute or depth of cut reaches 1 m.
MM_SUSPECT_M = 1.0

#: The options holding lengths in metres (argparse dest -> option).
LENGTH_OPTIONS = {"lengths": "--lengths", "clamping_length": "--clamping-length",
                  "cut_clamping_length": "--cut-clamping-length", "cut_length": "--cut-length",
                  "flute_length": "--flute-length", "max_depth": "--max-depth", "depths": "--depths"}


def _length_values(value) -> list[float]:
    """The lengths in an option's value: ``0.025``, ``'0.025,0.04'``, a tuple, or a ``C:D[:N]`` range (not N)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [float(value)]
    if isinstance(value, (tuple, list)):
        return [v for item in value for v in _length_values(item)]
    if not isinstance(value, str):
        return []
    out = []
    for part in value.split(","):
        for piece in part.split(":")[:2]:
            try:
                out.append(float(piece))
            except ValueError:
                pass  # not a number: the option's own parser says so
    return out


def check_lengths_in_metres(args) -> None:
    """Refuse, before any computation, a length option whose value looks like millimetres.

    ``--lengths 25,40`` -> ``--lengths '25,40': lengths are in metres; did you mean 0.025,0.04?``.
    """
    for dest, option in LENGTH_OPTIONS.items():
        value = getattr(args, dest, None)
        values = _length_values(value)
        if any(v >= MM_SUSPECT_M for v in values if np.isfinite(v)):
            shown = value if isinstance(value, str) else ",".join(f"{v:g}" for v in values)
            guess = ",".join(f"{v * 1e-3:g}" for v in values)
            raise SetupError(f"{option} {shown!r}: lengths are in metres; did you mean {guess}?")


def parse_fraction(text: str, option: str, lo: float, hi: float) -> float:
    """``'2%'`` or ``'0.02'`` -> 0.02, required in [lo, hi]."""
    t = text.strip()
    value = parse_float(t[:-1], option) / 100 if t.endswith("%") else parse_float(t, option)
    if not (lo <= value <= hi):
        raise SetupError(f"{option} {text!r}: expected a fraction in [{lo:g}, {hi:g}] (e.g. 2% or 0.02)")
    return value


def parse_coefficient(text: str, option: str) -> tuple[float, float]:
    """``'790e6'``, ``'790e6±5%'``, ``'790e6+-5%'`` or ``'790e6±40e6'`` -> (value Pa, relative tolerance)."""
    t = text.strip().replace("+-", "±")
    if "±" not in t:
        return parse_float(t, option), 0.0
    base, tol = t.split("±", 1)
    value = parse_float(base, option)
    if tol.strip().endswith("%"):
        rel = parse_float(tol.strip()[:-1], option) / 100
    else:
        rel = parse_float(tol, option) / abs(value) if value else float("inf")
    if not (0 <= rel < 0.5):
        raise SetupError(f"{option} {text!r}: expected a tolerance below ±50 % (e.g. 790e6±5%)")
    return value, rel


def cutting_keywords(args, kr_tolerance: bool = False) -> dict:
    """The cutting options as keyword arguments of the workflows: numbers in SI units, angles in rad.

    ``kt``/``kr`` are None when not given (a workflow may take them from an updated posterior);
    ``kt_tolerance`` (and ``kr_tolerance`` if ``kr_tolerance``) are relative.  The workflow checks the
    values and builds the :class:`~bayes_rcsa.stability.CuttingConditions`.
    """
    kt, kt_tol = parse_coefficient(args.kt, "--kt") if args.kt is not None else (None, 0.0)
    kr, kr_tol = parse_coefficient(args.kr, "--kr") if args.kr is not None else (None, 0.0)
    if kr_tol and not kr_tolerance:
        raise SetupError(f"--kr {args.kr!r}: give the tolerance on --kt; it scales the cutting-force level (Kt and "
                         "Kr together, Kr/Kt fixed)")
    kw = {"flutes": args.flutes, "kt": kt, "kr": kr, "kt_tolerance": kt_tol, "milling": args.milling,
          "feed": args.feed, "allow_unusual": args.allow_unusual}
    if kr_tolerance:
        kw["kr_tolerance"] = kr_tol
    kw.update(_geometry_numbers(args.immersion, args.angles, args.pitch))
    return kw


def _geometry_numbers(immersion: str | None, angles: str | None, pitch: str | None) -> dict:
    """``--immersion``, ``--angles`` (deg) and ``--pitch`` (deg) -> radial_immersion, entry_angle, exit_angle,
    pitch_angles (rad); only those given."""
    out = {}
    if immersion is not None:
        out["radial_immersion"] = parse_float(immersion, "--immersion", positive=True)
    if angles is not None:
        ang = parse_float_list(angles, "--angles")
        if len(ang) != 2:
            raise SetupError(f"--angles {angles!r}: expected ENTRY,EXIT in degrees")
        out["entry_angle"], out["exit_angle"] = (np.radians(a) for a in ang)
    if pitch is not None:
        out["pitch_angles"] = tuple(float(np.radians(a)) for a in parse_float_list(pitch, "--pitch", positive=True))
    return out


def parse_averages(text: str, option: str = "--averages") -> int:
    """A whole number >= 1 of impacts averaged per measured FRF."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise SetupError(f"{option} {text!r}: expected a whole number >= 1 (impacts averaged per FRF)")
    return value


def parse_directions(text: str, option: str = "--directions") -> list[str]:
    """``'x,y'`` -> ``["x", "y"]`` (directions of the tool-point FRF)."""
    directions = [d.strip() for d in text.split(",") if d.strip()]
    if not directions or any(d not in ("x", "y") for d in directions):
        raise SetupError(f"{option} {text!r}: expected a comma-separated list of x and y")
    return directions


def optional_float(text, option: str, positive: bool = True):
    """:func:`parse_float` of ``text``, or None when the option was not given."""
    return None if text is None else parse_float(text, option, positive=positive)


def boundary_width_numbers(text: str, option: str = "--boundary-width") -> float | tuple[float, float]:
    """``'W'`` -> W, ``'LO:HI'`` -> (LO, HI): the probit boundary width, fixed or log-uniform."""
    if ":" in text:
        lo, hi = text.split(":", 1)
        return parse_float(lo, option, positive=True), parse_float(hi, option, positive=True)
    return parse_float(text, option, positive=True)


# ------------------------------------------------------------------------------------------
# identify --cuts: the cut outcomes as an extra likelihood term of the identification
CUT_FLAGS = ("cut_clamping_length", "cut_tool", "cut_flutes", "cut_kt", "cut_kr", "cut_immersion", "cut_angles",
              "cut_pitch", "cut_boundary_width", "cut_label_error")


def add_cut_arguments(p) -> None:
    """The ``--cuts`` group of ``identify`` (joint fit of hammer FRFs and cut outcomes)."""
    from ..cuts import DEFAULT_BOUNDARY_WIDTH, DEFAULT_LABEL_ERROR

    g = p.add_argument_group("cutting tests (joint fit with the hammer data; docs/stability.md)")
    g.add_argument("--cuts", metavar="CSV", help="cut outcomes sampled together with the FRFs: "
                   "spindle_speed_rpm,depth_m,outcome[,clamping_length_m,radial_immersion,feed_direction,tool]")
    g.add_argument("--cut-clamping-length", metavar="M", help="clamping length of cuts without their own")
    g.add_argument("--cut-tool", metavar="NAME", help="tool of cuts without their own")
    g.add_argument("--cut-flutes", type=positive_int, metavar="N", help="number of teeth (required with --cuts)")
    g.add_argument("--cut-kt", metavar="PA[±TOL]", help="K_t and the prior spread of the force level, e.g. 560e6±30%%")
    g.add_argument("--cut-kr", metavar="PA[±TOL]", help="K_r and the prior spread of K_r/K_t, e.g. 170e6")
    g.add_argument("--cut-immersion", metavar="R", help="radial immersion of cuts without their own, in (0, 1]")
    g.add_argument("--cut-angles", metavar="ENTRY,EXIT", help="entry and exit angles in degrees instead")
    g.add_argument("--cut-milling", choices=("down", "up"), default="down", help="down or up milling (default down)")
    g.add_argument("--cut-feed", choices=("x", "y"), default="x", help="feed direction of cuts without their own")
    g.add_argument("--cut-pitch", metavar="DEG,...", help="variable pitch (deg)")
    g.add_argument("--cut-boundary-width", metavar="W|LO:HI", help=f"probit width (default {DEFAULT_BOUNDARY_WIDTH:g})")
    g.add_argument("--cut-label-error", metavar="P", help=f"label error (default {DEFAULT_LABEL_ERROR:g})")


def cut_test_numbers(args) -> dict | None:
    """The ``--cuts`` group of ``identify`` as numbers (None without ``--cuts``): the keywords of
    :class:`bayes_rcsa.workflows.identification.CutTestOptions` (a missing ``--cut-kt``/``--cut-kr``/``--cut-flutes``
    is None; the workflow names it)."""
    if args.cuts is None:
        given = [f"--{n.replace('_', '-')}" for n in CUT_FLAGS if getattr(args, n, None) is not None]
        if given:
            raise SetupError(f"{', '.join(given)} need(s) --cuts CSV")
        return None
    out = {"path": args.cuts, "flutes": args.cut_flutes, "kt": None, "kt_tolerance": 0.0, "kr": None,
           "kr_tolerance": 0.0, "milling": args.cut_milling, "feed": args.cut_feed, "tool": args.cut_tool}
    if args.cut_kt is not None:
        out["kt"], out["kt_tolerance"] = parse_coefficient(args.cut_kt, "--kt")
    if args.cut_kr is not None:
        out["kr"], out["kr_tolerance"] = parse_coefficient(args.cut_kr, "--kr")
    out.update(_geometry_numbers(args.cut_immersion, args.cut_angles, args.cut_pitch))
    out["boundary_width"] = boundary_width_numbers(args.cut_boundary_width or "0.1", "--boundary-width")
    if args.cut_label_error is not None:
        out["label_error"] = parse_float(args.cut_label_error, "--cut-label-error")
    if args.cut_clamping_length is not None:
        out["clamping_length"] = parse_float(args.cut_clamping_length, "--cut-clamping-length", positive=True)
    return out


def add_sampler_argument(p, chain_options: str) -> None:
    """``--sampler`` of the commands that identify (identify, identifiability); ``chain_options`` names the
    command's options that act on an emcee chain only."""
    p.add_argument("--sampler", choices=("auto", "importance", "mcmc"), default="auto",
                   help="auto (default): importance-sample the exact posterior around its optimum, kept when Pareto "
                        "k <= 0.7 and ESS >= 1000, else the emcee chain runs and summary.json's sampler block says "
                        "why; importance: the same, the fall-back also a warning; mcmc: always the emcee chain "
                        f"({chain_options} act on a chain only)")
