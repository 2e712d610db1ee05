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

import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar

import numpy as np

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

#: The same case as keywords of :func:`bayes_rcsa.lobes`
LOBES_KW = dict(clamping_length=0.030, flutes=4, kt=790e6, kr=230e6, radial_immersion=0.95, milling="down", feed="y",
                speeds_rpm=np.linspace(5000.0, 30000.0, 400))

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


def _step_failed(step: str, why: str, output: bool = False):
    from ..errors import BayesRCSAError, OutputError

    # a full disk or read-only folder stays an output error (the same one line, exit status 2)
    kind = OutputError if output or re.search(r"\(E[A-Z]+\)$", why) else BayesRCSAError
    return kind(f"step '{step}' failed: {why}")


def _saved(result: Result, folder: Path, force: bool) -> Result:
    result.save(folder, force=force)
    return result


def _step(title: str, argv: list[str], job: Callable[[], Result]) -> Result:
    """One step through its workflow, printed as its command line would print it; its error is the demo's."""
    from ..errors import BayesRCSAError, OutputError
    from ..messages import current_warnings, merge_warnings

    print(f"\n== {title}\n$ bayes-rcsa {' '.join(argv)}", file=sys.stderr)
    with warning_log(echo=False):
        try:
            result = job()
        except BayesRCSAError as exc:
            raise _step_failed(argv[0], " ".join(str(exc).split()), isinstance(exc, OutputError)) from None
        for w in merge_warnings(current_warnings(), result.warnings):
            print(f"bayes-rcsa {argv[0]}: warning: {w}", file=sys.stderr)
    print(f"bayes-rcsa {argv[0]}: {' '.join(result.summary_line().split())}", file=sys.stderr)
    return result


def demo(out=".", *, seed: int = 0, max_steps: int = 20000, force: bool = False) -> Demo:
    """Run identify, predict, lobes and the model check on the bundled example campaign into ``out``.

    Parameters
    ----------
    out : path of the demo folder (``identify/``, ``predict/``, ``lobes/``, ``discrepancy/``, report.html,
        index.html, summary.md)
    seed : int, random seed of the whole run
    max_steps : int, sampler step cap of the identification
    force : bool, replace the outputs of an earlier demo in ``out``

    Returns
    -------
    Demo
    """
    from ..data import example_setup
    from ..report import write_demo_index, write_report_html
    from ..io.setup import load_setup
    from .identification import identify
    from .model_check import check_model
    from .prediction import predict
    from .stability_lobes import lobes

    out = Path(out)
    # the overwrite rule of every command, checked for all steps before the first one runs
    for name in _STEPS:
        check_output_directory(out / name, force)
    for name in _PAGES:
        if (out / name).exists() and not force:
            raise SetupError(f"--out {out}: {name} of an earlier run exists; use --force to replace it")
    with warning_log() as log:
        flag = ["--force"] if force else []
        setup = load_setup(example_setup())  # read once, used by every step
        name = str(setup.path)
        post = _step("1/4 identify the contact from the 25 and 40 mm tests",
                     ["identify", name, "--out", str(out / "identify"), "--lengths", _text(FIT_LENGTHS), "--seed",
                      str(seed), "--max-steps", str(max_steps), *flag],
                     lambda: identify(setup, lengths=FIT_LENGTHS, seed=seed, max_steps=max_steps, out=out / "identify",
                                      force=force, progress=True))
        posterior = str(out / "identify" / "posterior.nc")
        _step("2/4 predict 25-40 mm with credible intervals",
              ["predict", name, "--posterior", posterior, "--lengths", _text(PREDICT_LENGTHS), "--seed", str(seed),
               "--out", str(out / "predict"), *flag],
              lambda: _saved(predict(setup, post, PREDICT_LENGTHS, seed=seed, progress=True), out / "predict", force))
        _step("3/4 probabilistic stability lobes at 30 mm",
              ["lobes", name, "--posterior", posterior, *LOBES_CASE, "--draws", "300", "--seed", str(seed),
               "--out", str(out / "lobes"), *flag],
              lambda: _saved(lobes(posterior=post, setup=setup, draws=300, seed=seed, progress=True, **LOBES_KW),
                             out / "lobes", force))
        _step("4/4 model check: is anything missing from the model? (discrepancy workflow)",
              ["discrepancy", name, "--lengths", _text(FIT_LENGTHS), "--seed", str(seed), "--out",
               str(out / "discrepancy"), *flag],
              lambda: _saved(check_model(setup, lengths=FIT_LENGTHS, seed=seed), out / "discrepancy", force))
        print("\n== report.html: one self-contained page of all four", file=sys.stderr)
        write_report_html([out / n for n in _STEPS], out / "report.html", seed=seed,
                          title="bayes_rcsa demo: ER32 collet + 7.94 mm end mill")
        write_demo_index(out)
    return Demo(folder=out, seed=seed, warnings=tuple(log))
