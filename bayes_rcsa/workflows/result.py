"""The base of every result object a workflow returns.

A workflow (``bayes_rcsa.identify``, ``bayes_rcsa.lobes``, ...) computes and
returns a :class:`Result`; it writes nothing unless asked.  The command line
is a thin shell over the same call: it parses, calls the workflow, calls
``result.save(out)`` and prints ``result.summary_line()``.  So a script, a
notebook and the command line get the same numbers and the same files.

Every result

- holds its numbers as attributes and as :meth:`Result.to_dict`, the
  document that becomes its JSON file (one source for both);
- writes exactly the files of its command with :meth:`Result.save` (atomically,
  under the output-directory lock: a failure leaves no partial output) and
  reads them back with :meth:`Result.load`;
- draws its matplotlib figures on request (:meth:`Result.figures`);
- shows a concise table in a notebook (``_repr_html_``, from
  :meth:`Result.headline`);
- carries the warnings issued while it was computed (:attr:`Result.warnings`),
  which every JSON file it writes lists too.

Subclasses are dataclasses; see docs/api.md.
"""

from __future__ import annotations

import contextlib
import html
from pathlib import Path
from typing import ClassVar, Iterator

from ..errors import SetupError

__all__ = ["Result", "saving", "check_output_directory"]


def check_output_directory(path, force: bool = False, resume: bool = False, resumable: bool = False,
                           option: str = "--out") -> Path:
    """Refuse to write into an existing non-empty output directory unless ``force`` (or ``resume``).

    The one rule of every result that writes a folder: a new or empty folder
    is used; a non-empty one only with ``force`` (replace the earlier run's
    files) or, for resumable runs, ``resume`` (continue it).  Called under
    :func:`bayes_rcsa.io.atomic.directory_lock` so that the answer cannot
    change before the files are written.

    Raises
    ------
    SetupError
        ``"--out DIR: exists and is not empty; use --force to replace its contents"``.
    """
    from ..io.atomic import directory_is_empty

    path = Path(path)
    if force or resume or directory_is_empty(path):
        return path
    raise SetupError(f"{option} {path}: exists and is not empty; use --force to replace its contents"
                     + (" or --resume to continue the run in it" if resumable else ""))


@contextlib.contextmanager
def saving(folder, force: bool = False, earlier_outputs: tuple[str, ...] = (), option: str = "--out",
           keep_on_interrupt: tuple[str, ...] = ()) -> Iterator[Path]:
    """The block in which a result writes its folder: locked, checked, and removed again on failure.

    Parameters
    ----------
    folder : path-like, the output folder (created if missing)
    force : bool, replace the files of an earlier run in a non-empty folder
    earlier_outputs : names of files removed first with ``force`` (an earlier run's results must not survive
        beside the new ones)
    option : str, the option named in messages (``--out``)
    keep_on_interrupt : names kept when the block is interrupted (a resumable checkpoint)
    """
    from ..io.atomic import directory_lock, new_output_directory

    folder = Path(folder)
    with directory_lock(folder, option):
        check_output_directory(folder, force, option=option)
        if force:
            for name in earlier_outputs:
                (folder / name).unlink(missing_ok=True)
        with new_output_directory(folder, option, keep_on_interrupt=keep_on_interrupt):
            yield folder


class Result:
    """Base class of the workflows' result objects (subclasses are dataclasses).

    Class attributes
    ----------------
    title : str
        What the result is, for people ("Stability lobes").
    files : tuple of str
        The files :meth:`save` writes (those present depend on the run; see each subclass).
    """

    title: ClassVar[str] = "result"
    files: ClassVar[tuple[str, ...]] = ()

    #: One-line warnings issued while the result was computed (also in every JSON file it writes).
    warnings: tuple[str, ...]

    # -- numbers ---------------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The result's numbers as the JSON document its command writes (SI units, stable keys)."""
        raise NotImplementedError

    def headline(self) -> list[tuple[str, str]]:
        """The few numbers a person reads first, as (printed name, formatted value with unit) pairs."""
        return []

    def summary_line(self) -> str:
        """One line for a person (what the command line prints at the end)."""
        return self.title

    def summary_data(self) -> dict:
        """The facts the command line prints with ``--json`` (paths added by the command)."""
        return {}

    # -- files -----------------------------------------------------------------------------------------------
    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the command's files into ``folder``; returns the main file's path."""
        raise NotImplementedError

    @classmethod
    def load(cls, folder) -> "Result":
        """Read a folder written by :meth:`save` (or by the command line) back into a result."""
        raise NotImplementedError

    # -- pictures --------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``{name: matplotlib.figure.Figure}`` of the result's plots (made on request, not stored)."""
        return {}

    def _repr_html_(self) -> str:
        rows = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
                       for k, v in self.headline())
        from ..vocabulary import in_words

        warn = "".join(f"<li>{html.escape(in_words(w))}</li>" for w in getattr(self, "warnings", ()) or ())
        return (f"<div><strong>{html.escape(self.title)}</strong>"
                + (f"<table>{rows}</table>" if rows else "")
                + (f"<p>Warnings:</p><ul>{warn}</ul>" if warn else "") + "</div>")
