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
        "byte-identical files.  DIR is written atomically.",
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
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    import numpy as np

    from pathlib import Path

    from ..errors import SetupError
    from ..io.atomic import directory_lock
    from ..synthetic import generate_campaign, load_bench_config, write_campaign

    check_output_directory(Path(args.out), args.force)  # before anything is generated
    config = load_bench_config(args.config)
    seed = config.seed if args.seed is None else args.seed
    if seed < 0:
        raise SetupError(f"--seed {seed}: expected an integer >= 0")
    if args.artifact:
        from ..synthetic.artifact import default_bench_artifact, generate_artifact_tests, write_artifact_tests

        tests = generate_artifact_tests(config, default_bench_artifact(), np.random.default_rng(seed))
        with directory_lock(args.out):
            path = write_artifact_tests(tests, args.out, overwrite=args.force, seed=seed)
        return Summary(f"wrote {len(tests.frfs)} artifact FRFs, the true flange receptances and {path.name} to "
                       f"{path.parent} (seed {seed})",
                       {"out": str(path.parent), "artifact": str(path), "n_frfs": len(tests.frfs), "seed": seed})
    campaign = generate_campaign(config, np.random.default_rng(seed))
    campaign = dataclasses.replace(campaign, truth={**campaign.truth, "seed": seed})
    with directory_lock(args.out):
        setup_path = write_campaign(campaign, args.out, overwrite=args.force)
    effects = ", ".join(f"{k}={v:g}" for k, v in campaign.truth["hidden_effects"].items()) or "none"
    return Summary(
        f"wrote {len(campaign.measurements)} tool-point FRFs, {len(campaign.spindle)} spindle file(s), "
        f"{setup_path.name} and truth.json to {setup_path.parent} (seed {seed}; hidden effects: {effects})",
        {"out": str(setup_path.parent), "setup": str(setup_path), "n_measurements": len(campaign.measurements),
         "seed": seed, "hidden_effects": dict(campaign.truth["hidden_effects"])},
    )
