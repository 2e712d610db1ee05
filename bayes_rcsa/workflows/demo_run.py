"""The main job end to end on the bundled example campaign: :func:`demo` -> :class:`Demo`.

The demo is a scripted sequence of the ordinary jobs, so everything it writes
is exactly what a user gets from running them by hand:

1. ``identify``  multi-length Bayesian identification from the 25 mm and 40 mm
   hammer tests (the paper's Method II protocol);
2. ``predict``   credible intervals of the tool-point FRF and natural
   frequencies at 25, 30, 35 and 40 mm, the 30 and 35 mm tests held out;
3. ``lobes``     probabilistic stability lobes at 30 mm clamping for the
   paper's cutting case b (4 flutes, Al 7050, Kt = 790 MPa, Kr = 230 MPa,
   95 % radial immersion, feed in y);
4. ``discrepancy`` the model check: does the model miss a known effect?

and finally ``report.html`` (the self-contained report over the four
folders), ``index.html`` (the landing page) and ``summary.md``, which open
with the same summary block: recommended speed and depth, tool-point
frequencies with their 90 % intervals, the model check, convergence and the
warnings that change the decision.
"""

from __future__ import annotations

import contextlib
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar

from ..errors import SetupError
from ..messages import warning_log
from .result import Result, check_output_directory

__all__ = ["demo", "Demo", "FIT_LENGTHS", "PREDICT_LENGTHS", "LOBES_CASE"]

#: m, the clamping lengths the contact is identified from
FIT_LENGTHS = (0.025, 0.040)
#: m, the clamping lengths predicted (30 and 35 mm held out)
PREDICT_LENGTHS = (0.025, 0.030, 0.035, 0.040)
#: The cutting case of the lobes step (command-line options of ``lobes``)
LOBES_CASE = ["--clamping-length", "0.030", "--flutes", "4", "--kt", "790e6", "--kr", "230e6",
              "--immersion", "0.95", "--milling", "down", "--feed", "y", "--speeds", "5000:30000:400"]

_STEPS = ("identify", "predict", "lobes", "discrepancy")
_PAGES = ("report.html", "index.html", "summary.md")


def _text(lengths) -> str:
    return ",".join(f"{v:.3f}" for v in lengths)


@dataclass(eq=False)
class Demo(Result):
    """The demo's folder: the four jobs' folders, report.html, index.html and summary.md.

    Attributes
    ----------
    folder : Path, the demo folder
    seed : int
    warnings : tuple of str
    """

    title: ClassVar[str] = "bayes_rcsa demo"
    files: ClassVar[tuple[str, ...]] = _PAGES

    folder: Path
    seed: int = 0
    warnings: tuple[str, ...] = ()

    @property
    def report(self) -> Path:
        return Path(self.folder) / "report.html"

    @property
    def index(self) -> Path:
        return Path(self.folder) / "index.html"

    @property
    def summary_md(self) -> Path:
        return Path(self.folder) / "summary.md"

    @property
    def posterior(self):
        """The identified contact (:class:`~bayes_rcsa.workflows.identification.Posterior` of ``folder/identify``)."""
        from .identification import Posterior

        return Posterior.load(Path(self.folder) / "identify")

    def to_dict(self) -> dict:
        return {"out": str(self.folder), "report": str(self.report), "index": str(self.index),
                "summary": str(self.summary_md)}

    def headline(self) -> list[tuple[str, str]]:
        return [("report", str(self.report)), ("landing page", str(self.index)), ("answer", str(self.summary_md))]

    def summary_line(self) -> str:
        return f"demo finished: open {self.report} (links: {self.index}; the answer: {self.summary_md})"

    def summary_data(self) -> dict:
        return {"report": str(self.report), "index": str(self.index), "summary": str(self.summary_md)}

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """The demo writes its folder while it runs; saving it elsewhere is refused (run :func:`demo` there)."""
        if Path(folder).resolve() != Path(self.folder).resolve():
            raise SetupError(f"--out {folder}: the demo writes its folder while it runs; run demo(out={str(folder)!r})")
        return self.index

    @classmethod
    def load(cls, folder) -> "Demo":
        from ..errors import DataError

        folder = Path(folder)
        missing = [n for n in _PAGES if not (folder / n).is_file()]
        if missing:
            raise DataError(f"{folder}: not a demo folder ({', '.join(missing)} missing)")
        return cls(folder=folder)

    def figures(self) -> dict:
        return self.posterior.figures()


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


def _step_failed(step: str, why: str, output: bool = False):
    from ..errors import BayesRCSAError, OutputError

    # a full disk or read-only folder stays an output error (the same one line, exit status 2)
    kind = OutputError if output or re.search(r"\(E[A-Z]+\)$", why) else BayesRCSAError
    return kind(f"step '{step}' failed: {why}")


def _command(title: str, argv: list[str], runner: Callable[[list[str]], int]) -> None:
    """One step as a command line (its own closing lines on stderr; its error line kept for the demo's)."""
    print(f"\n== {title}\n$ bayes-rcsa {' '.join(argv)}", file=sys.stderr)
    held = _HoldErrorLines(sys.stderr)
    with contextlib.redirect_stderr(held):
        status = runner(argv)
    held.flush()
    if status != 0:
        raise _step_failed(argv[0], held.errors[-1] if held.errors else f"exit status {status}")


def _identify(title: str, setup, out: Path, seed: int, max_steps: int, force: bool) -> None:
    """Step 1 through the workflow, printed as the command line prints it."""
    from ..errors import BayesRCSAError, OutputError
    from ..messages import current_warnings, merge_warnings
    from .identification import identify

    argv = ["identify", str(setup), "--out", str(out), "--lengths", _text(FIT_LENGTHS), "--seed", str(seed),
            "--max-steps", str(max_steps), *(["--force"] if force else [])]
    print(f"\n== {title}\n$ bayes-rcsa {' '.join(argv)}", file=sys.stderr)
    with warning_log(echo=False):
        try:
            post = identify(setup, lengths=FIT_LENGTHS, seed=seed, max_steps=max_steps, out=out, force=force,
                            progress=True)
        except BayesRCSAError as exc:
            raise _step_failed("identify", " ".join(str(exc).split()), isinstance(exc, OutputError)) from None
        for w in merge_warnings(current_warnings(), post.warnings):
            print(f"bayes-rcsa identify: warning: {w}", file=sys.stderr)
    print(f"bayes-rcsa identify: {' '.join(post.summary_line().split())}", file=sys.stderr)


def demo(out=".", *, seed: int = 0, max_steps: int = 20000, force: bool = False,
         runner: Callable[[list[str]], int] | None = None) -> Demo:
    """Run identify, predict, lobes and the model check on the bundled example campaign into ``out``.

    Parameters
    ----------
    out : path of the demo folder (``identify/``, ``predict/``, ``lobes/``, ``discrepancy/``, report.html,
        index.html, summary.md)
    seed : int, random seed of the whole run
    max_steps : int, sampler step cap of the identification
    force : bool, replace the outputs of an earlier demo in ``out``
    runner : callable ``argv -> exit status`` or None, runs the steps given as command lines (None: the
        ``bayes-rcsa`` entry point)

    Returns
    -------
    Demo
    """
    from ..data import example_setup
    from ..report import write_demo_index, write_report_html
    from .batch_run import CommandLine

    out = Path(out)
    # the overwrite rule of every command, checked for all steps before the first one runs
    for name in _STEPS:
        check_output_directory(out / name, force)
    for name in _PAGES:
        if (out / name).exists() and not force:
            raise SetupError(f"--out {out}: {name} of an earlier run exists; use --force to replace it")
    runner = runner or CommandLine()
    with warning_log() as log:
        flag = ["--force"] if force else []
        setup = str(example_setup())
        _identify("1/4 identify the contact from the 25 and 40 mm tests", setup, out / "identify", seed, max_steps,
                  force)
        posterior = str(out / "identify" / "posterior.nc")
        # TODO(merge): workflows.prediction.predict, workflows.stability_lobes.lobes and workflows.model_check.discrepancy
        # (written by the other helpers) instead of their command lines
        _command("2/4 predict 25-40 mm with credible intervals",
                 ["predict", setup, "--posterior", posterior, "--lengths", _text(PREDICT_LENGTHS), "--seed", str(seed),
                  "--out", str(out / "predict"), *flag], runner)
        _command("3/4 probabilistic stability lobes at 30 mm",
                 ["lobes", setup, "--posterior", posterior, *LOBES_CASE, "--draws", "300", "--seed", str(seed),
                  "--out", str(out / "lobes"), *flag], runner)
        _command("4/4 model check: is anything missing from the model? (discrepancy workflow)",
                 ["discrepancy", setup, "--lengths", _text(FIT_LENGTHS), "--seed", str(seed), "--out",
                  str(out / "discrepancy"), *flag], runner)
        print("\n== report.html: one self-contained page of all four", file=sys.stderr)
        write_report_html([out / n for n in _STEPS], out / "report.html", seed=seed,
                          title="bayes_rcsa demo: ER32 collet + 7.94 mm end mill")
        write_demo_index(out)
    return Demo(folder=out, seed=seed, warnings=tuple(log))
