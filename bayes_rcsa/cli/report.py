"""``bayes-rcsa report``: one self-contained HTML report from the output directories of the other commands."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import SetupError
from ._common import Summary, check_output_path, nonnegative_int

DESCRIPTION = """\
Build ONE self-contained HTML file (figures embedded, no external files) from the output directories
of identify, predict, identifiability, discrepancy, design and lobes; each directory's kind is
recognised by the files in it, and a 'bayes-rcsa demo' directory stands for its sub-directories.

The page opens with the answer: a summary block on its first screen (1400x900) with the recommended
spindle speed and depth (their margins and the confidence they hold at), the tool-point natural
frequency at each predicted clamping length with its 90 % interval, the model check's verdict in one
sentence, convergence in one word and the warnings that change the decision (unconverged, prior
pile-up, not usable for prediction). --summary MD writes the same block as Markdown.

Then: stability lobes with the P(stable) map and the recommended point, tool-point predictions
(natural frequencies with both the model's credible interval and the predictive interval of a new
measured peak; FRF bands against the measurements in magnitude and phase around each mode,
collapsed), identifiability, discrepancy findings, the design recommendation, the setup (geometry
drawing with the clamping length; which parameters were sampled and which fixed), and last the
sampler: convergence verdict and warnings, identified parameters, and the diagnostics collapsed
(R-hat, ESS, autocorrelation time, steps; corner and trace plots). The zoomed FRF bands need the
setup and posterior files the predict run names.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("report", help="one self-contained HTML report from run directories",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", type=Path, metavar="RUN_DIR", help="output directory of a bayes-rcsa command")
    p.add_argument("--out", type=Path, required=True, metavar="FILE", help="the HTML file to write")
    p.add_argument("--title", default=None, help="page title (default: 'bayes_rcsa report')")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the draws behind the FRF bands (default 0)")
    p.add_argument("--summary", type=Path, default=None, metavar="MD",
                   help="also write the report's summary block (recommended point, tool-point frequencies, model "
                        "check, convergence, decisive warnings) as Markdown to MD")
    p.add_argument("--force", action="store_true", help="replace an existing FILE (and MD) (default: refuse)")
    p.set_defaults(func=run, out_kind="file")


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.reporting import make_report

    out = check_output_path(args.out, "--out", kind="file")
    if out.exists() and not args.force:
        raise SetupError(f"--out {out}: exists; use --force to replace it")  # before the report is built
    md = None if args.summary is None else check_output_path(args.summary, "--summary", kind="file")
    if md is not None and md.exists() and not args.force:
        raise SetupError(f"--summary {md}: exists; use --force to replace it")
    result = make_report(args.runs, title=args.title, seed=args.seed)
    result.save(out, force=args.force, summary_md=md)
    return Summary(result.summary_line(), result.summary_data(), warnings=result.warnings)
