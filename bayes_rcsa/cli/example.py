"""``bayes-rcsa example``: write every file the documentation uses into one folder.

Parsing and printing only; the files are :func:`bayes_rcsa.workflows.example_files.write_example_files`.
"""

from __future__ import annotations

import argparse

from ._common import Summary, add_force_argument, nonnegative_int


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "example",
        help="write the example files the documentation uses (campaign, bench, artifact, library manifest)",
        description="Write into DIR every file the documentation's commands use, so that each page runs as "
        "written from that folder: the bundled example campaign (setup.toml, spindle_x.csv, spindle_y.csv, "
        "tip_<dir>_<mm>mm.csv, truth.json; the demo's data), bench.toml (the synthetic bench configuration for "
        "'bayes-rcsa synthesize'), artifact/artifact.toml with its standard-artifact hammer tests (for "
        "'bayes-rcsa spindle'), library.toml with the two set-ups of a small synthetic tool library in "
        "library/ (for 'bayes-rcsa batch' and 'bayes-rcsa library') and README.txt naming each file.  Takes a "
        "few seconds.  DIR must be new or empty unless --force.",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (new or empty unless --force)")
    p.add_argument("--seed", type=nonnegative_int, default=0, metavar="N",
                   help="seed of the synthetic artifact tests and tool library (default 0)")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.example_files import write_example_files

    result = write_example_files(args.out, force=args.force, seed=args.seed)
    return Summary(result.summary_line(), {"out": str(result.folder), **result.summary_data()},
                   warnings=result.warnings)
