"""identify, predict and lobes for every setup of a tool library: :func:`batch` -> :class:`BatchRun`.

The job of ``bayes-rcsa batch``: one task per setup of a manifest (local
worker processes or a Dask cluster), resumable (a setup finished by an
earlier run with the same options and setup file is reused), and one table
across the library (summary.csv, summary.html, summary.json).  Each setup's
steps are command lines (the manifest's options are command-line options), run
in the worker process by a *runner* ``runner(argv) -> exit status``; the
default is the ``bayes-rcsa`` entry point itself (:class:`CommandLine`).
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, ClassVar

from ..errors import SetupError
from ..messages import current_warnings, merge_warnings, warning_log
from .result import Result

__all__ = ["run_batch", "BatchRun", "CommandLine", "executor_for", "check_run_folder"]


@dataclass(frozen=True)
class CommandLine:
    """``runner(argv) -> exit status``: one ``bayes-rcsa`` command line run in this (worker) process.

    Picklable, so that it travels to local worker processes and Dask workers.  The entry point is looked up by
    name when a task runs: the setups' steps are command lines, and the workflows layer does not import the
    command line (which is built on it).
    """

    entry_point: str = "bayes_rcsa.cli.main"

    def __call__(self, argv: list[str]) -> int:
        import importlib

        return importlib.import_module(self.entry_point).main(argv)


def check_run_folder(out, marker: str, what: str, force: bool) -> Path:
    """``out`` must be new, empty, or hold an earlier run of this job (its file ``marker``) unless ``force``.

    Raises
    ------
    SetupError
        ``"--out DIR: exists, is not empty and holds no earlier <what> run; use --force to write into it"``.
    """
    from ..io.atomic import directory_is_empty

    out = Path(out)
    if not directory_is_empty(out) and not (out / marker).is_file() and not force:
        raise SetupError(f"--out {out}: exists, is not empty and holds no earlier {what} run; use --force to "
                         "write into it")
    return out


def executor_for(scheduler: str | None):
    """``(client, executor)`` of a Dask scheduler address (``(None, None)``: a local process pool is used).

    Raises
    ------
    SetupError
        Dask distributed is not installed, or the scheduler cannot be reached.
    """
    if scheduler is None:
        return None, None
    try:
        from distributed import Client
    except ImportError:
        raise SetupError(f"--scheduler {scheduler}: Dask distributed is not installed "
                         "(pip install 'bayes-rcsa[cluster]')") from None
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise SetupError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    return client, client.get_executor()


def progress_printer(progress, command: str, prefix: str = "", converged: bool = True):
    """``progress(k, n, row)`` of :func:`bayes_rcsa.batch.run_batch`: a callable as given, ``True``: the line the
    command prints on stderr, ``False``/None: nothing."""
    if callable(progress):
        return progress
    if not progress:
        return None

    def show(k, n, row):
        conv = {True: ", converged", False: ", NOT converged"}.get(row.get("converged"), "") if converged else ""
        print(f"bayes-rcsa {command}: {prefix}[{k}/{n}] {row['name']}: {row['status']}{conv}"
              + (f" ({row['error']})" if row.get("error") else ""), file=sys.stderr, flush=True)

    return show


@dataclass(eq=False)
class BatchRun(Result):
    """The rows of every setup of a batch run and what this run did.

    Attributes
    ----------
    rows : list of dict, one per setup in manifest order (status ``done``, ``failed`` or ``lost``, natural
        frequencies in Hz, recommended speed in rpm and depth in m, warnings, ...)
    ran : list of str, setups computed in this run; reused : list of str, finished setups taken over
    folder : Path, the batch folder (setups/<name>/..., summary.csv, summary.html, summary.json)
    table_title : str, the table's title (the manifest's file name)
    warnings : tuple of str
    """

    title: ClassVar[str] = "Batch run"
    files: ClassVar[tuple[str, ...]] = ("batch.json", "summary.csv", "summary.html", "summary.json")

    rows: list
    ran: list = field(default_factory=list)
    reused: list = field(default_factory=list)
    folder: Path | None = None
    table_title: str = "Batch run"
    warnings: tuple[str, ...] = ()

    def count(self, status: str) -> int:
        return sum(1 for r in self.rows if r["status"] == status)

    @property
    def failed(self) -> bool:
        """True when a setup is not done (the command's exit status 1)."""
        return self.count("done") < len(self.rows)

    def to_dict(self) -> dict:
        from ..batch.table import summary_columns

        return {"columns": summary_columns(self.rows), "rows": list(self.rows), "warnings": list(self.warnings)}

    def headline(self) -> list[tuple[str, str]]:
        return [("setups", str(len(self.rows))), ("done", f"{self.count('done')} ({len(self.reused)} from an "
                                                           "earlier run)"),
                ("failed", str(self.count("failed"))), ("lost", str(self.count("lost")))]

    def summary_line(self) -> str:
        html = None if self.folder is None else Path(self.folder) / "summary.html"
        return (f"{len(self.rows)} setup(s): {self.count('done')} done ({len(self.reused)} from an earlier run), "
                f"{self.count('failed')} failed, {self.count('lost')} lost; table in {html}")

    def summary_data(self) -> dict:
        return {"done": self.count("done"), "failed": self.count("failed"), "lost": self.count("lost"),
                "ran": self.ran, "reused": self.reused}

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the table across the library (summary.csv, summary.html, summary.json) into ``folder``; returns
        summary.html.  The setups' own folders are written by :func:`batch` while it runs."""
        from ..batch import write_summary
        from .result import saving

        folder = Path(folder)
        if self.folder is not None and folder.resolve() == Path(self.folder).resolve():
            return write_summary(self.rows, folder, title=self.table_title, warnings=self.warnings)["html"]
        with saving(folder, force):
            return write_summary(self.rows, folder, title=self.table_title, warnings=self.warnings)["html"]

    @classmethod
    def load(cls, folder) -> "BatchRun":
        """Read summary.json (and the manifest's name from batch.json) of a batch folder."""
        from ..errors import DataError

        folder = Path(folder)
        try:
            doc = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
            run = json.loads((folder / "batch.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise DataError(f"{folder}: cannot read the batch run's summary.json and batch.json ({exc})") from None
        rows = list(doc["rows"])
        return cls(rows=rows, ran=[r["name"] for r in rows if not r.get("reused")],
                   reused=[r["name"] for r in rows if r.get("reused")], folder=folder,
                   table_title=Path(run["manifest"]).name, warnings=tuple(doc.get("warnings", [])))


def run_batch(manifest, out, *, workers: int | None = None, scheduler: str | None = None, force: bool = False,
          progress=None, runner: Callable[[list[str]], int] | None = None) -> BatchRun:
    """Run identify, predict and lobes for every setup of ``manifest`` into ``out``, in parallel and resumably.

    Parameters
    ----------
    manifest : path of the manifest TOML ([defaults] and one [[setup]] per tool-holder combination)
    out : path of the batch folder (an earlier batch run's folder is resumed)
    workers : int or None, local worker processes (None: the number of CPU cores)
    scheduler : str or None, a Dask scheduler address (``tcp://host:8786``): run the setups on that cluster
    force : bool, recompute every setup, finished or not
    progress : bool or callable ``(k, n, row)``: True prints one line per finished setup on stderr
    runner : callable ``argv -> exit status`` or None (the ``bayes-rcsa`` entry point, :class:`CommandLine`)

    Returns
    -------
    BatchRun (also written: ``out/batch.json``, ``out/setups/<name>/``, summary.csv/html/json)
    """
    with warning_log():
        from ..batch import load_manifest, run_batch, write_summary
        from ..io.atomic import atomic_write_text, directory_lock, new_output_directory

        manifest = Path(manifest)
        jobs = load_manifest(manifest)
        out = check_run_folder(out, "batch.json", "batch", force)
        client, executor = executor_for(scheduler)
        try:
            # a full disk or read-only folder: one line, and what this run made in out goes again (an earlier
            # batch run's files stay, so a resumed library keeps its finished setups)
            with directory_lock(out), new_output_directory(out):
                atomic_write_text(out / "batch.json", json.dumps({"manifest": str(manifest.resolve()),
                                                                  "setups": [j.name for j in jobs]}, indent=1))
                result = run_batch(jobs, out, runner or CommandLine(), executor=executor,
                                   workers=workers or os.cpu_count() or 1, force=force,
                                   progress=progress_printer(progress, "batch"))
                not_conv = [r["name"] for r in result.rows if r.get("converged") is False]
                warns = merge_warnings(
                    current_warnings(),  # the manifest's (a setup file outside its folder)
                    (f"{n}: the posterior did not converge" for n in not_conv),
                    (f"{r['name']}: {r['status']}: {r['error']}" for r in result.rows if r["status"] != "done"),
                    (f"{r['name']}: {r['n_warnings']} warning(s) (see the warnings column)" for r in result.rows
                     if r.get("n_warnings")))
                write_summary(result.rows, out, title=manifest.name, warnings=warns)
        finally:
            if client is not None:
                client.close()
        return BatchRun(rows=result.rows, ran=result.ran, reused=result.reused, folder=out, table_title=manifest.name,
                        warnings=tuple(warns))
