"""``bayes-rcsa batch``: identify, predict and lobes for every setup of a tool library, in parallel, resumably."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ._arguments import prepare_run
from ._common import Summary, command_warnings, merge_warnings, positive_int

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
    from ..batch import load_manifest, run_batch, write_summary
    from ..io.atomic import atomic_write_text, directory_lock, new_output_directory
    from .main import main as run_command

    jobs = load_manifest(args.manifest)
    out, workers, client, executor = prepare_run(args, "batch.json", "batch")

    def progress(k, n, row):
        if not args.quiet:
            conv = {True: ", converged", False: ", NOT converged"}.get(row.get("converged"), "")
            print(f"bayes-rcsa batch: [{k}/{n}] {row['name']}: {row['status']}{conv}"
                  + (f" ({row['error']})" if row.get("error") else ""), file=sys.stderr, flush=True)

    try:
        # a full disk or read-only folder: one line, and what this run made in --out goes again (an earlier
        # batch run's files stay, so a resumed library keeps its finished setups)
        with directory_lock(out), new_output_directory(out):
            atomic_write_text(out / "batch.json", json.dumps({"manifest": str(args.manifest.resolve()),
                                                              "setups": [j.name for j in jobs]}, indent=1))
            result = run_batch(jobs, out, run_command, executor=executor, workers=workers, force=args.force,
                               progress=progress)
            not_conv = [r["name"] for r in result.rows if r.get("converged") is False]
            warns = merge_warnings(
                command_warnings(),  # the manifest's (a setup file outside its folder)
                (f"{n}: the posterior did not converge" for n in not_conv),
                (f"{r['name']}: {r['status']}: {r['error']}" for r in result.rows if r["status"] != "done"),
                (f"{r['name']}: {r['n_warnings']} warning(s) (see the warnings column)" for r in result.rows
                 if r.get("n_warnings")))
            paths = write_summary(result.rows, out, title=args.manifest.name, warnings=warns)
    finally:
        if client is not None:
            client.close()
    n_bad = len(jobs) - result.count("done")
    human = (f"{len(jobs)} setup(s): {result.count('done')} done ({len(result.reused)} from an earlier run), "
             f"{result.count('failed')} failed, {result.count('lost')} lost; table in {paths['html']}")
    return Summary(
        human,
        {"out": str(out), "summary_csv": str(paths["csv"]), "summary_html": str(paths["html"]),
         "done": result.count("done"), "failed": result.count("failed"), "lost": result.count("lost"),
         "ran": result.ran, "reused": result.reused},
        warnings=tuple(warns),
        status=1 if n_bad else 0,
    )
