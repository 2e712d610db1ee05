"""Warnings as one-line messages that travel with the results.

Every workflow (:mod:`bayes_rcsa.workflows`) runs inside a :func:`warning_log`:
each warning issued while it runs (data plausibility, numerics, a posterior
that did not converge) is recorded as one line, so that the result object
carries it (``result.warnings``) and every file the result writes lists it.
Logs nest: the command line opens one around the whole command (``demo``
runs workflows inside a workflow) and every open log receives every warning.

Only the outermost log decides whether a warning is also shown the usual
way: a script or notebook (``echo=True``, the default) sees it at once; the
command line (``echo=False``) prints the collected lines itself when the
command succeeds, and nothing but the error line when it fails.

The package's own warnings are issued with :func:`warn`, which records the
line in every open log *before* handing it to :func:`warnings.warn`.  The log
learns of anything else (numpy, scipy) through :func:`warnings.showwarning`,
which is process-global state: before Python 3.14 any other thread that
enters :class:`warnings.catch_warnings` while a workflow runs (a user's
thread, a library compiling in the background) can restore a previous
``showwarning`` and so cut the log off from what follows.  Recording first
keeps the package's own warnings in ``result.warnings`` and the JSON outputs
whatever another thread does, and whatever filters the caller set.
"""

from __future__ import annotations

import contextlib
import warnings
from typing import Iterable, Iterator

__all__ = ["warning_log", "current_warnings", "merge_warnings", "one_line", "warn"]

#: The open logs, outermost first.
_LOGS: list[list[str]] = []
#: Lines :func:`warn` recorded that the echo of the outermost log has not shown yet.
_UNSHOWN: set[str] = set()


def _record(text: str) -> bool:
    """Add ``text`` to every open log that lacks it; whether the outermost lacked it (only it decides the echo)."""
    new = bool(_LOGS) and text not in _LOGS[0]
    for log in _LOGS:
        if text not in log:
            log.append(text)
    return new


def warn(message, category: type[Warning] = UserWarning, stacklevel: int = 1) -> None:
    """:func:`warnings.warn` for the package's own warnings, recorded in every open log first.

    Parameters
    ----------
    message : str
    category : Warning subclass (e.g. :class:`bayes_rcsa.errors.DataWarning`)
    stacklevel : int, as for :func:`warnings.warn`, counted from the caller of this function
    """
    text = one_line(message)
    if _LOGS and _record(text):
        _UNSHOWN.add(text)
    warnings.warn(message, category, stacklevel=stacklevel + 1)


def one_line(message) -> str:
    """``message`` as one line with single spaces (how every warning is stored and compared)."""
    return " ".join(str(message).split())


def current_warnings() -> list[str]:
    """The warnings recorded so far by the innermost open log (a copy; empty outside any log)."""
    return list(_LOGS[-1]) if _LOGS else []


def merge_warnings(*groups: Iterable) -> list[str]:
    """The warnings of ``groups`` in order, each once (compared as one-line text)."""
    out: list[str] = []
    for group in groups:
        for w in group:
            text = one_line(w)
            if text not in out:
                out.append(text)
    return out


@contextlib.contextmanager
def warning_log(echo: bool = True) -> Iterator[list[str]]:
    """Record every warning issued inside the block; yields the (growing) list of one-line messages.

    Parameters
    ----------
    echo : bool
        Outermost log only: also show each warning through the previous
        :func:`warnings.showwarning` (a script or notebook sees it at once).
        The command line passes ``False`` and prints the lines itself.
    """
    buffer: list[str] = []
    outermost = not _LOGS
    _LOGS.append(buffer)
    try:
        if not outermost:
            yield buffer
            return
        with warnings.catch_warnings():
            previous = warnings.showwarning

            def show(message, category, filename, lineno, file=None, line=None):
                text = one_line(message)
                new = _record(text) or text in _UNSHOWN
                _UNSHOWN.discard(text)
                if echo and new:
                    previous(message, category, filename, lineno, file, line)

            # entering catch_warnings invalidates the once-per-location registry, so a second workflow run in the
            # same process records its own warnings again; the filters themselves are left as the caller set them
            warnings.showwarning = show
            yield buffer
    finally:
        _LOGS.pop()
        if not _LOGS:
            _UNSHOWN.clear()
