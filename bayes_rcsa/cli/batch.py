"""``bayes-rcsa batch``: identify, predict and lobes for every setup of a tool library, in parallel, resumably."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import Summary, positive_int

__all__ = ["register", "run"]

DESCRIPTION = """\
Run 'bayes-rcsa identify', 'predict' and 'lobes' for every setup listed in MANIFEST (a TOML file:
[defaults] and one [[setup]] entry per tool-holder combination with name, file and options; see
docs/scaling-out.md), one setup per task, and collect one table across the library.

Parallel: setups run at the same time in --workers local processes (default: the number of CPU
cores), or on a Dask cluster with --scheduler ADDRESS (pip install 'bayes-rcsa[cluster]'). Each
worker uses one BLAS thread.

Resumable: a setup finished by an earlier run with the same options and setup file is not
recomputed; a half-done one (interrupted, killed, failed) is run again.  --force recomputes all.

Writes to --out: setups/<name>/{identify,predict,lobes,log.txt,result.json} per setup and
summary.csv, summary.html, summary.json across the library (a warnings column: every step's
warnings).  Exit status 1 when a setup failed.  A setup file outside the manifest's folder is used
with a warning.  A full disk or read-only --out ends the batch with one line (exit status 2) and
removes what this run made there.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("batch", help="identify + predict + lobes for every setup of a tool library (parallel, "
                              "resumable)", description=DESCRIPTION)
    p.add_argument("manifest", type=Path, metavar="MANIFEST", help="manifest TOML file")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory (resumed when it holds "
                   "an earlier batch run)")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="local worker processes (default: the number of CPU cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address, e.g. tcp://10.0.0.5:8786: run the setups on that cluster instead")
    p.add_argument("--force", action="store_true", help="recompute every setup, finished or not")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.batch_run import run_batch

    result = run_batch(args.manifest, args.out, workers=args.workers, scheduler=args.scheduler, force=args.force,
                   progress=not args.quiet)
    out = result.folder
    return Summary(result.summary_line(), {"out": str(out), "summary_csv": str(out / "summary.csv"),
                                           "summary_html": str(out / "summary.html"), **result.summary_data()},
                   warnings=result.warnings, status=1 if result.failed else 0)
