"""Each setup's printed lines into its own log file, also when setups run on threads of one process.

:func:`contextlib.redirect_stdout` and :func:`~contextlib.redirect_stderr` replace the process's
``sys.stdout``/``sys.stderr``; two setups running at once on threads of one process (a Dask worker with
several threads, a ``processes=False`` cluster, a thread pool) would then write into each other's logs, and the
thread that finishes last would restore the stream the other had installed, leaving the process printing into
a closed file.  :func:`output_to` instead installs, once for as long as any setup runs, stand-ins that send
each thread's writes to the file that thread named, and everything else (other threads, the caller's heartbeat)
to the streams that were there before.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from typing import IO, Iterator

__all__ = ["output_to"]

_LOCK = threading.Lock()
_TARGET = threading.local()
_USERS = 0
_SAVED: tuple = ()


class _Routed:
    """A ``sys.stdout``/``sys.stderr`` stand-in writing to the calling thread's log file, else to ``fallback``."""

    def __init__(self, fallback):
        self._fallback = fallback

    def _stream(self):
        return getattr(_TARGET, "stream", None) or self._fallback

    def write(self, text: str) -> int:
        return self._stream().write(text)

    def writelines(self, lines) -> None:
        self._stream().writelines(lines)

    def flush(self) -> None:
        self._stream().flush()

    def isatty(self) -> bool:
        return self._stream().isatty()

    def __getattr__(self, name):
        return getattr(self._stream(), name)


@contextlib.contextmanager
def output_to(stream: IO[str]) -> Iterator[None]:
    """Send what the calling thread prints (stdout and stderr) to ``stream`` inside the block.

    Other threads keep printing where they did.  The process's streams are
    put back when the last block on any thread ends, unless someone else has
    replaced them meanwhile (theirs is then left in place).
    """
    global _USERS, _SAVED
    with _LOCK:
        if _USERS == 0:
            _SAVED = (sys.stdout, sys.stderr)
            sys.stdout, sys.stderr = _Routed(sys.stdout), _Routed(sys.stderr)
        _USERS += 1
    previous = getattr(_TARGET, "stream", None)
    _TARGET.stream = stream
    try:
        yield
    finally:
        _TARGET.stream = previous
        with _LOCK:
            _USERS -= 1
            if _USERS == 0:
                if isinstance(sys.stdout, _Routed):
                    sys.stdout = _SAVED[0]
                if isinstance(sys.stderr, _Routed):
                    sys.stderr = _SAVED[1]
                _SAVED = ()
