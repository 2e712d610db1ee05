"""``bayes-rcsa demo``: the main job end to end on the bundled example campaign.

The demo is a scripted sequence of the ordinary sub-commands, so everything
it writes is exactly what a user gets from running them by hand:

1. ``identify``  multi-length Bayesian identification from the 25 mm and 40 mm
   hammer tests (the paper's Method II protocol);
2. ``predict``   credible intervals of the tool-point FRF and natural
   frequencies at 25, 30, 35 and 40 mm, the 30 and 35 mm tests held out;
3. ``lobes``     probabilistic stability lobes at 30 mm clamping for the
   paper's cutting case b (4 flutes, Al 7050, Kt = 790 MPa, Kr = 230 MPa,
   95 % radial immersion, feed in y);
4. ``discrepancy`` the model check: does the model miss a known effect
   (tip mass, joint damping, ...)? Named, added and shown, or "adequate";

and finally ``report.html``, the self-contained report of ``bayes-rcsa
report`` over the four directories (figures embedded; the page to open or
mail), an ``index.html`` landing page that links it and the sub-commands'
own files (:mod:`bayes_rcsa.report.index_html`), and ``summary.md``.  The
report, the landing page and ``summary.md`` open with the same summary block
(:mod:`bayes_rcsa.report.answer`): the recommended speed and depth, the
tool-point frequencies with their 90 % intervals, the model check,
convergence and the warnings that change the decision.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import sys
from pathlib import Path

from ..errors import SetupError
from ._common import Summary, check_output_directory, nonnegative_int, positive_int

ORDER = 10

FIT_LENGTHS = "0.025,0.040"
PREDICT_LENGTHS = "0.025,0.030,0.035,0.040"
LOBES_CASE = ["--clamping-length", "0.030", "--flutes", "4", "--kt", "790e6", "--kr", "230e6",
              "--immersion", "0.95", "--milling", "down", "--feed", "y", "--speeds", "5000:30000:400"]


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


class _HoldErrorLines:
    """A stderr that passes every line through except a step's ``error:`` line, which it keeps.

    A failed step's error becomes the demo's one error line (naming the step) instead of a second line.
    """

    def __init__(self, stream):
        self.stream, self.pending, self.errors = stream, "", []

    def write(self, text: str) -> int:
        self.pending += text
        *lines, self.pending = self.pending.split("\n")
        for line in lines:
            if re.match(r"^bayes-rcsa \w+: error: ", line):
                self.errors.append(line.split(": error: ", 1)[1])
            else:
                self.stream.write(line + "\n")
        return len(text)

    def __getattr__(self, name):  # isatty, encoding, fileno, ...: the wrapped stream's
        return getattr(self.stream, name)

    def flush(self) -> None:
        if self.pending:
            self.stream.write(self.pending)
            self.pending = ""
        self.stream.flush()


def _step(title: str, argv: list[str]) -> None:
    from .main import main

    print(f"\n== {title}\n$ bayes-rcsa {' '.join(argv)}", file=sys.stderr)
    held = _HoldErrorLines(sys.stderr)
    with contextlib.redirect_stderr(held):
        status = main(argv)
    held.flush()
    if status != 0:
        from ..errors import BayesRCSAError, OutputError

        why = held.errors[-1] if held.errors else f"exit status {status}"
        # a full disk or read-only folder stays an output error (the same one line, exit status 2)
        kind = OutputError if re.search(r"\(E[A-Z]+\)$", why) else BayesRCSAError
        raise kind(f"step '{argv[0]}' failed: {why}")


def run(args: argparse.Namespace) -> Summary:
    from ..data import example_setup
    from ..report import write_demo_index, write_report_html

    out = Path(args.out)
    # the overwrite rule of every command, checked for all steps before the first one runs
    for name in ("identify", "predict", "lobes", "discrepancy"):
        check_output_directory(out / name, args.force)
    for name in ("report.html", "index.html", "summary.md"):
        if (out / name).exists() and not args.force:
            raise SetupError(f"--out {out}: {name} of an earlier run exists; use --force to replace it")
    force = ["--force"] if args.force else []
    setup = str(example_setup())
    seed = str(args.seed)
    _step("1/4 identify the contact from the 25 and 40 mm tests",
          ["identify", setup, "--out", str(out / "identify"), "--lengths", FIT_LENGTHS, "--seed", seed,
           "--max-steps", str(args.max_steps), *force])
    posterior = str(out / "identify" / "posterior.nc")
    _step("2/4 predict 25-40 mm with credible intervals",
          ["predict", setup, "--posterior", posterior, "--lengths", PREDICT_LENGTHS, "--seed", seed,
           "--out", str(out / "predict"), *force])
    _step("3/4 probabilistic stability lobes at 30 mm",
          ["lobes", setup, "--posterior", posterior, *LOBES_CASE, "--draws", "300", "--seed", seed,
           "--out", str(out / "lobes"), *force])
    _step("4/4 model check: is anything missing from the model? (discrepancy workflow)",
          ["discrepancy", setup, "--lengths", FIT_LENGTHS, "--seed", seed, "--out", str(out / "discrepancy"), *force])
    print("\n== report.html: one self-contained page of all four", file=sys.stderr)
    report = write_report_html([out / "identify", out / "predict", out / "lobes", out / "discrepancy"],
                               out / "report.html", seed=args.seed,
                               title="bayes_rcsa demo: ER32 collet + 7.94 mm end mill")
    index = write_demo_index(out)
    return Summary(f"demo finished: open {report} (links: {index}; the answer: {out / 'summary.md'})",
                   {"out": str(out), "report": str(report), "index": str(index), "summary": str(out / "summary.md")})
