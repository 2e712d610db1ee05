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
"""

from __future__ import annotations

import contextlib
import warnings
from typing import Iterable, Iterator

__all__ = ["warning_log", "current_warnings", "merge_warnings", "one_line"]

#: The open logs, outermost first.
_LOGS: list[list[str]] = []


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
                new = False
                for log in _LOGS:
                    if text not in log:
                        log.append(text)
                        new = True
                if echo and new:
                    previous(message, category, filename, lineno, file, line)

            # entering catch_warnings invalidates the once-per-location registry, so a second workflow run in the
            # same process records its own warnings again; the filters themselves are left as the caller set them
            warnings.showwarning = show
            yield buffer
    finally:
        _LOGS.pop()
