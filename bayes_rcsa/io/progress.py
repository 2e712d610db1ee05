"""Progress indication for jobs whose library call has no progress hook (written to stderr).

:class:`Heartbeat` shows that a job is alive and how long it has run
(``predict: 1000 draws x 8 configurations ... 12 s``) while a single library
call works, without knowing its fraction done.  It stays silent for jobs that
finish within ``quiet_seconds``, so short runs print nothing but their
result.  Jobs that can report a fraction use
:class:`bayes_rcsa.stability.progress.ProgressBar` instead.  The line is
redrawn with carriage returns on a terminal only; on any other stream (a log,
a pipe) a job longer than ``quiet_seconds`` ends with one plain line.
"""

from __future__ import annotations

import sys
import threading
import time

__all__ = ["Heartbeat"]


def _seconds(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.1f} min"


class Heartbeat:
    """Context manager redrawing ``label ... 12 s`` on one stderr line while its block runs.

    Parameters
    ----------
    label : str
    stream : text stream (default ``sys.stderr``)
    quiet_seconds : float, s before the first line (shorter jobs print nothing)
    interval : float, s between redraws
    enabled : bool, ``False`` makes it a no-op (``--quiet``)
    """

    def __init__(self, label: str, stream=None, quiet_seconds: float = 2.0, interval: float = 1.0,
                 enabled: bool = True):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.quiet_seconds = quiet_seconds
        self.interval = interval
        self.enabled = enabled
        self.drawn = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._start = 0.0
        self.terminal = False

    def _draw(self, final: bool = False) -> None:
        elapsed = time.monotonic() - self._start
        prefix = "\r" if self.terminal else ""  # a redrawn line on a terminal only
        self.stream.write(f"{prefix}{self.label} ... {_seconds(elapsed)}{' done' if final else ''}")
        self.stream.flush()
        self.drawn = True

    def _loop(self) -> None:
        if self._stop.wait(self.quiet_seconds):
            return
        while True:
            self._draw()
            if self._stop.wait(self.interval):
                return

    def __enter__(self) -> "Heartbeat":
        self._start = time.monotonic()
        try:
            self.terminal = bool(self.stream.isatty())
        except (AttributeError, ValueError, OSError):
            self.terminal = False
        if self.enabled and self.terminal:
            # a daemon thread: an interrupted job never waits for its progress line
            self._thread = threading.Thread(target=self._loop, name="bayes-rcsa-heartbeat", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            if self.drawn:
                self._draw(final=exc[0] is None)
                self.stream.write("\n")
                self.stream.flush()
        elif self.enabled and time.monotonic() - self._start >= self.quiet_seconds:
            self._draw(final=exc[0] is None)  # not a terminal: one plain line for a long job
            self.stream.write("\n")
            self.stream.flush()
