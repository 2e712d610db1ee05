"""A small text progress bar for long stability jobs (written to a stream, normally stderr).

Library functions take ``progress=None`` (silent) or a callable
``progress(fraction)``; the command line passes a :class:`ProgressBar`.  The
bar stays silent for jobs that finish within ``quiet_seconds`` and redraws at
most every ``interval`` seconds, so short runs print nothing but their result.
"""

from __future__ import annotations

import sys
import time

__all__ = ["ProgressBar", "format_seconds", "is_terminal"]


def is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal (where a line may be redrawn with carriage returns)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or a closed stream
        return False


def format_seconds(seconds: float) -> str:
    """'12 s', '3.5 min', '1.2 h'."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


class ProgressBar:
    """``bar(fraction)`` draws ``label [#####-----]  50 %  12 s`` on one line; ``bar.close()`` ends it.

    On a stream that is not a terminal the bar is not drawn; ``close()`` then writes the final state as one
    line, only for a job that took longer than ``quiet_seconds``.

    Parameters
    ----------
    label : str
    stream : text stream (default ``sys.stderr``)
    quiet_seconds : float, nothing is drawn before this much time has passed
    interval : float, s between redraws
    width : int, characters of the bar
    """

    def __init__(self, label: str, stream=None, quiet_seconds: float = 2.0, interval: float = 0.5, width: int = 30):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.quiet_seconds = quiet_seconds
        self.interval = interval
        self.width = width
        self.start = time.monotonic()
        self._last = -1e9
        self._drawn = False
        self.terminal = is_terminal(self.stream)

    def _line(self, fraction: float, elapsed: float) -> str:
        fill = int(round(fraction * self.width))
        return (f"{self.label} [{'#' * fill}{'-' * (self.width - fill)}] {100 * fraction:3.0f} % "
                f"{format_seconds(elapsed)}")

    def __call__(self, fraction: float) -> None:
        now = time.monotonic()
        if now - self.start < self.quiet_seconds or now - self._last < self.interval:
            return
        self._last = now
        self._drawn = True
        if not self.terminal:
            return  # no redrawn lines in a log: close() writes the one final line
        f = min(max(float(fraction), 0.0), 1.0)
        self.stream.write("\r" + self._line(f, now - self.start))
        self.stream.flush()

    def close(self) -> None:
        """Finish the line (only when something was drawn): the final state, then a newline.

        Not on a terminal: one line with the final state when the job took longer than ``quiet_seconds``.
        """
        if not self.terminal:
            elapsed = time.monotonic() - self.start
            if self._drawn or elapsed >= self.quiet_seconds:
                self.stream.write(self._line(1.0, elapsed) + "\n")
                self.stream.flush()
            self._drawn = False
            return
        if self._drawn:
            self._last = -1e9
            self.quiet_seconds = 0.0
            self(1.0)
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False
