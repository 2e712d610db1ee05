"""One self-contained HTML report from the output directories of the other commands (``bayes-rcsa report``).

:func:`report` recognises each directory's kind by its files (identify, predict, identifiability, discrepancy,
design, lobes; a ``demo`` directory stands for its sub-directories) and builds ONE HTML page with the figures
embedded (:func:`bayes_rcsa.report.build_report`).  :meth:`Report.save` writes it, and optionally the page's
summary block as Markdown.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Sequence

from ..errors import SetupError
from ..messages import merge_warnings, warning_log
from .result import Result

__all__ = ["make_report", "Report"]


@dataclass
class Report(Result):
    """The HTML report of a set of run directories.

    Attributes
    ----------
    html : str, the self-contained page (figures embedded)
    runs : tuple of str, the run directories it was built from
    warnings : tuple of str
    path : Path or None, the HTML file written or read (None until saved)
    summary_path : Path or None, the Markdown summary written with it (None if none)
    """

    title: ClassVar[str] = "Report"
    files: ClassVar[tuple[str, ...]] = ("report.html",)

    html: str
    runs: tuple[str, ...]
    warnings: tuple[str, ...] = ()
    path: Path | None = None
    summary_path: Path | None = None

    def to_dict(self) -> dict:
        """The HTML file, the run directories and the Markdown summary (the command writes no JSON)."""
        out = {"report": None if self.path is None else str(self.path), "runs": list(self.runs)}
        if self.summary_path is not None:
            out["summary"] = str(self.summary_path)
        return out

    def headline(self) -> list[tuple[str, str]]:
        return [("run directories", str(len(self.runs))), ("report", str(self.path or "not saved")),
                ("size", f"{len(self.html.encode('utf-8')) / 1e6:.2f} MB")]

    def summary_line(self) -> str:
        return f"wrote {self.path}" + (f" and {self.summary_path}" if self.summary_path is not None else "")

    def summary_data(self) -> dict:
        return self.to_dict()

    def save(self, path, *, force: bool = False, plots: bool = True, summary_md=None) -> Path:
        """Write the page to the file ``path`` (and its summary block as Markdown to ``summary_md``).

        Existing files are replaced only with ``force``.  ``plots`` has no effect (the figures are part of the
        page).  Returns the path of the page.
        """
        from ..io.atomic import atomic_write_text
        from ..report.html_report import write_summary_markdown

        path = Path(path)
        for option, p in (("--out", path), ("--summary", summary_md)):
            if p is not None and Path(p).exists() and not force:
                raise SetupError(f"{option} {p}: exists; use --force to replace it")
        atomic_write_text(path, self.html)  # makes the missing folders, and removes them again if the write fails
        self.path = path
        if summary_md is not None:
            self.summary_path = write_summary_markdown(self.runs, path, summary_md)
        return path

    @classmethod
    def load(cls, path) -> "Report":
        """Read a page written by :meth:`save` (the run directories are not recorded in it: ``runs`` is empty)."""
        from ..errors import DataError

        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise DataError(f"{path}: cannot read the report ({exc})") from None
        return cls(text, (), (), path)


def make_report(run_dirs: Sequence, *, title: str | None = None, seed: int = 0) -> Report:
    """Build the HTML report of ``run_dirs`` (output directories of the other commands).

    Parameters
    ----------
    run_dirs : sequence of path-like
    title : str or None, page title (default "bayes_rcsa report")
    seed : int, seed of the draws behind the FRF bands

    Returns
    -------
    Report (not yet written: :meth:`Report.save`)
    """
    from ..report import build_report

    with warning_log() as log:
        runs = tuple(str(r) for r in run_dirs)
        html = build_report(list(run_dirs), seed=seed, title=title)
        return Report(html, runs, tuple(merge_warnings(log)))
