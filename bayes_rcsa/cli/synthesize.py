"""``bayes-rcsa synthesize``: a synthetic impact-hammer campaign with optional hidden effects."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import SetupError
from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int, parse_float


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "synthesize",
        help="generate a synthetic multi-clamping-length campaign (test bench with hidden effects)",
        description="Simulate impact-hammer tests of a spindle-holder-tool assembly with an independent "
        "finite-element model (richer than the RCSA model: optional distributed contact and hidden effects "
        "such as contact_damping, tip_mass, fluted_section, extra_mode, nonlinear_stiffness_law), and write "
        "DIR with spindle_x.csv (+ y), tip_<dir>_<mm>mm.csv, setup.toml (what the user believes) and "
        "truth.json (what is true).  CONFIG is a bench TOML file; every key is optional (see "
        "docs/synthetic.md and bayes_rcsa/synthetic/example_bench.toml).  The same CONFIG and seed give "
        "byte-identical files.  DIR is written atomically.  With a [library] table CONFIG describes a "
        "tool library instead: one campaign per holder-tool combination, laws drawn from per-holder-type "
        "populations, and DIR/manifest.toml for `bayes-rcsa batch` / `bayes-rcsa library` (docs/synthetic.md, "
        "Tool libraries).",
    )
    p.add_argument("config", metavar="CONFIG", help="bench configuration TOML file")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (new or empty unless --force)")
    p.add_argument("--seed", type=nonnegative_int, default=None, metavar="N",
                   help="seed of the measurement noise (default: [noise] seed of CONFIG, else 0)")
    add_force_argument(p)
    p.add_argument("--artifact", action="store_true",
                   help="instead of the tool-point campaign, write standard-artifact hammer tests of the bench's "
                        "spindle (artifact.toml, h11/h12/h21/h22 per direction, the true flange receptance) for "
                        "`bayes-rcsa spindle` (docs/spindle.md)")
    _add_cut_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.synthesis import synthesize

    check_output_directory(Path(args.out), args.force)  # before anything is generated
    cut = {} if not args.cuts else dict(  # parsed only with --cuts (the cut options have no effect without it)
        cut_length=None if args.cut_length is None else parse_float(args.cut_length, "--cut-length", positive=True),
        cut_speeds=_cut_range(args.cut_speeds, "--cut-speeds"), cut_depths=_cut_range(args.cut_depths, "--cut-depths"),
        cut_kt=parse_float(args.cut_kt, "--cut-kt", positive=True),
        cut_kr=parse_float(args.cut_kr, "--cut-kr", positive=True),
        cut_kt_error=parse_float(args.cut_kt_error, "--cut-kt-error"),
        cut_kr_error=parse_float(args.cut_kr_error, "--cut-kr-error"), cut_flutes=args.cut_flutes,
        cut_immersion=parse_float(args.cut_immersion, "--cut-immersion", positive=True), cut_milling=args.cut_milling,
        cut_feed=args.cut_feed, cut_label_noise=parse_float(args.cut_label_noise, "--cut-label-noise"),
        cut_truth=args.cut_truth, cut_layout=args.cut_layout)
    result = synthesize(args.config, seed=args.seed, artifact=args.artifact, cuts=args.cuts, **cut)
    path = result.save(args.out, force=args.force)
    key = {"campaign": "setup", "artifact": "artifact", "library": "manifest"}[result.kind]
    return Summary(result.summary_line(), {"out": str(path.parent), key: str(path), **result.summary_data()},
                   warnings=result.warnings)


# --------------------------------------------------------- cutting tests (issue #23) --
def _add_cut_arguments(p) -> None:
    g = p.add_argument_group("cutting tests from the truth (cuts.csv + cuts_truth.json; docs/synthetic.md)")
    g.add_argument("--cuts", type=nonnegative_int, default=0, metavar="N",
                   help="also write N test cuts labelled stable/chatter by the true structure's ZOA limit with the "
                        "TRUE cutting coefficients (default 0: none)")
    g.add_argument("--cut-length", default=None, metavar="L",
                   help="clamping length of the cuts in m (default: the first clamping length of CONFIG)")
    g.add_argument("--cut-speeds", default="5000:30000", metavar="A:B", help="spindle-speed range in rpm")
    g.add_argument("--cut-depths", default="1e-5:1.5e-4", metavar="C:D",
                   help="axial-depth range in m of the cuts and the truth map")
    g.add_argument("--cut-kt", default="790e6", metavar="PA", help="tangential coefficient the user assumes, Pa")
    g.add_argument("--cut-kr", default="230e6", metavar="PA", help="radial coefficient the user assumes, Pa")
    g.add_argument("--cut-kt-error", default="0.2", metavar="E", help="true K_t = assumed x (1 + E) (default 0.2)")
    g.add_argument("--cut-kr-error", default="0.2", metavar="E", help="true K_r = assumed x (1 + E) (default 0.2)")
    g.add_argument("--cut-flutes", type=nonnegative_int, default=4, metavar="N", help="flutes (default 4)")
    g.add_argument("--cut-immersion", default="0.95", metavar="R", help="radial immersion in (0, 1] (default 0.95)")
    g.add_argument("--cut-milling", choices=("down", "up"), default="down", help="default down")
    g.add_argument("--cut-feed", choices=("x", "y"), default="y", help="feed direction (default y)")
    g.add_argument("--cut-label-noise", default="0", metavar="S",
                   help="sigma of a probit in ln(depth/limit): cuts near the boundary may get either label "
                        "(default 0: exact labels)")
    g.add_argument("--cut-truth", choices=("sdm", "zoa"), default="sdm",
                   help="stability method of the true limit on the noise-free FRFs: the project's SDM (default; "
                        "not the ZOA the cut likelihood uses) or the bench's own ZOA root finder")
    g.add_argument("--cut-layout", choices=("random", "grid"), default="random",
                   help="cuts uniform at random in the speed x depth box, or on a grid (default random)")


def _cut_range(text: str, option: str) -> tuple[float, float]:
    """``LO:HI`` -> (lo, hi) with 0 < lo < hi."""
    parts = text.split(":")
    if len(parts) != 2:
        raise SetupError(f"{option} {text!r}: expected LO:HI")
    lo, hi = (parse_float(v, option, positive=True) for v in parts)
    if hi <= lo:
        raise SetupError(f"{option} {text!r}: expected LO < HI")
    return lo, hi
