"""``bayes-rcsa demo``: the main job end to end on the bundled example campaign.

Parsing and printing only; the steps (identify, predict, lobes, the model
check, report.html, index.html, summary.md) are
:func:`bayes_rcsa.workflows.demo_run.demo`.
"""

from __future__ import annotations

import argparse

from ._common import Summary, nonnegative_int, positive_int

ORDER = 10


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo",
        help="run the main job end to end on the bundled example data",
        description="Run bayes_rcsa end to end on the bundled example campaign (synthetic hammer tests of an "
        "ER32 collet chuck with a 7.94 mm carbide end mill at 25-40 mm clamping, made by the project's "
        "independent finite-element bench): identify the tool-holder contact from the 25 and 40 mm tests, "
        "predict the tool point with credible intervals at 25-40 mm (30 and 35 mm held out), and compute "
        "probabilistic stability lobes at 30 mm, and check the model for missing effects (discrepancy).  "
        "Writes DIR/identify, DIR/predict, DIR/lobes, DIR/discrepancy, the "
        "self-contained report DIR/report.html, the landing page DIR/index.html and DIR/summary.md (all three "
        "open with the answer: recommended speed and depth, tool-point frequencies, model check).  Takes one to "
        "two minutes.",
    )
    p.add_argument("--out", default=".", metavar="DIR", help="output directory (default: current directory)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed of the whole run (default 0)")
    p.add_argument("--max-steps", type=positive_int, default=20000, metavar="N", help="sampler step cap (default 20000)")
    p.add_argument("--force", action="store_true",
                   help="replace the outputs of an earlier demo in DIR (identify/, predict/, lobes/, report.html, "
                        "index.html, summary.md); default: refuse")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.demo_run import demo

    result = demo(args.out, seed=args.seed, max_steps=args.max_steps, force=args.force)
    return Summary(result.summary_line(), {"out": str(result.folder), **result.summary_data()})
