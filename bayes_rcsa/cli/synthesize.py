"""``bayes-rcsa synthesize``: a synthetic impact-hammer campaign with optional hidden effects."""

from __future__ import annotations

import argparse
import dataclasses

from ._common import Summary, add_force_argument, check_output_directory, nonnegative_int


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
    import numpy as np

    from pathlib import Path

    from ..errors import SetupError
    from ..io.atomic import directory_lock
    from ..synthetic import generate_campaign, load_bench_config, write_campaign

    check_output_directory(Path(args.out), args.force)  # before anything is generated
    from ..synthetic.library import load_library_config

    library = load_library_config(args.config)  # a [library] table: a tool library instead of one campaign
    if library is not None:
        return _run_library(args, *library)
    config = load_bench_config(args.config)
    seed = config.seed if args.seed is None else args.seed
    if seed < 0:
        raise SetupError(f"--seed {seed}: expected an integer >= 0")
    if args.artifact and args.cuts:
        raise SetupError("--cuts writes cutting tests of a tool-point campaign; it cannot be combined with --artifact")
    if args.artifact:
        from ..synthetic.artifact import default_bench_artifact, generate_artifact_tests, write_artifact_tests

        tests = generate_artifact_tests(config, default_bench_artifact(), np.random.default_rng(seed))
        with directory_lock(args.out):
            path = write_artifact_tests(tests, args.out, overwrite=args.force, seed=seed)
        return Summary(f"wrote {len(tests.frfs)} artifact FRFs, the true flange receptances and {path.name} to "
                       f"{path.parent} (seed {seed})",
                       {"out": str(path.parent), "artifact": str(path), "n_frfs": len(tests.frfs), "seed": seed})
    cuts = _generate_cuts(args, config, seed)  # before anything is written: a bad cut option leaves no output
    campaign = generate_campaign(config, np.random.default_rng(seed))
    campaign = dataclasses.replace(campaign, truth={**campaign.truth, "seed": seed})
    with directory_lock(args.out):
        setup_path = write_campaign(campaign, args.out, overwrite=args.force)
        if cuts is not None:
            from ..synthetic.cuts import write_cuts

            write_cuts(cuts, setup_path.parent, seed)
    effects = ", ".join(f"{k}={v:g}" for k, v in campaign.truth["hidden_effects"].items()) or "none"
    return Summary(
        f"wrote {len(campaign.measurements)} tool-point FRFs, {len(campaign.spindle)} spindle file(s), "
        f"{setup_path.name} and truth.json to {setup_path.parent} (seed {seed}; hidden effects: {effects})"
        + ("" if cuts is None else f"; {cuts.speed_rpm.size} cuts ({int(cuts.stable.sum())} stable) in cuts.csv, "
           f"their truth in cuts_truth.json"),
        {"out": str(setup_path.parent), "setup": str(setup_path), "n_measurements": len(campaign.measurements),
         "seed": seed, "hidden_effects": dict(campaign.truth["hidden_effects"]),
         "n_cuts": 0 if cuts is None else int(cuts.speed_rpm.size)},
    )


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
    from ..errors import SetupError
    from ._common import parse_float

    parts = text.split(":")
    if len(parts) != 2:
        raise SetupError(f"{option} {text!r}: expected LO:HI")
    lo, hi = (parse_float(v, option, positive=True) for v in parts)
    if hi <= lo:
        raise SetupError(f"{option} {text!r}: expected LO < HI")
    return lo, hi


def _generate_cuts(args, config, seed: int):
    """The cut campaign of the --cut-* options, or None without --cuts."""
    if not args.cuts:
        return None
    import numpy as np

    from ..errors import SetupError
    from ..synthetic.cuts import CutPlan, generate_cuts
    from ._common import parse_float

    length = config.clamping_lengths[0] if args.cut_length is None else parse_float(args.cut_length, "--cut-length",
                                                                                     positive=True)
    plan = CutPlan(
        n_cuts=args.cuts, clamping_length=length, speed_range=_cut_range(args.cut_speeds, "--cut-speeds"),
        depth_range=_cut_range(args.cut_depths, "--cut-depths"),
        kt_assumed=parse_float(args.cut_kt, "--cut-kt", positive=True),
        kr_assumed=parse_float(args.cut_kr, "--cut-kr", positive=True),
        kt_error=parse_float(args.cut_kt_error, "--cut-kt-error"), kr_error=parse_float(args.cut_kr_error,
                                                                                         "--cut-kr-error"),
        flutes=args.cut_flutes, radial_immersion=parse_float(args.cut_immersion, "--cut-immersion", positive=True),
        milling=args.cut_milling, feed=args.cut_feed,
        label_noise=parse_float(args.cut_label_noise, "--cut-label-noise"), layout=args.cut_layout)
    truth = {}
    if args.cut_truth == "sdm":
        from ..cuts.truth import SDM_TRUTH, sdm_true_limit

        truth = {"true_limit": sdm_true_limit(plan), "truth_method": SDM_TRUTH}
    # the cuts' own stream (seed + 1 spawned) so that --cuts does not change the hammer-test noise
    return generate_cuts(config, plan, np.random.default_rng([seed, 23]), **truth)


# --------------------------------------------------------- tool libraries (issue #20) --
def _run_library(args, base, spec) -> Summary:
    """``synthesize CONFIG`` with a ``[library]`` table: a whole synthetic tool library."""
    from ..errors import SetupError
    from ..io.atomic import directory_lock
    from ..synthetic.library import generate_library, write_library

    if args.artifact or args.cuts:
        raise SetupError(f"{args.config}: [library] writes a tool library; it cannot be combined with "
                         f"{'--artifact' if args.artifact else '--cuts'}")
    seed = base.seed if args.seed is None else args.seed
    library = generate_library(spec, base, seed)
    with directory_lock(args.out):
        manifest = write_library(library, args.out, overwrite=args.force)
    specials = [c.name for c in library.combinations if c.special is not None]
    types = ", ".join(spec.holder_types)
    return Summary(
        f"wrote a tool library of {len(library.combinations)} holder-tool combinations ({types}; "
        f"special: {', '.join(specials) or 'none'}), {manifest.name} and library.json to {manifest.parent} "
        f"(seed {seed})",
        {"out": str(manifest.parent), "manifest": str(manifest), "n_combinations": len(library.combinations),
         "holder_types": list(spec.holder_types), "special": specials, "seed": seed},
    )
