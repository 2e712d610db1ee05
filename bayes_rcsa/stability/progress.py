"""A small text progress bar for long stability jobs (written to a stream, normally stderr).

Library functions take ``progress=None`` (silent) or a callable
``progress(fraction)``; the command line passes a :class:`ProgressBar`.  The
bar stays silent for jobs that finish within ``quiet_seconds`` and redraws at
most every ``interval`` seconds, so short runs print nothing but their result.
"""

from __future__ import annotations

import sys
import time

__all__ = ["ProgressBar", "format_seconds"]


def format_seconds(seconds: float) -> str:
    """'12 s', '3.5 min', '1.2 h'."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


class ProgressBar:
    """``bar(fraction)`` draws ``label [#####-----]  50 %  12 s`` on one line; ``bar.close()`` ends it.

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

    def __call__(self, fraction: float) -> None:
        now = time.monotonic()
        if now - self.start < self.quiet_seconds or now - self._last < self.interval:
            return
        self._last = now
        f = min(max(float(fraction), 0.0), 1.0)
        fill = int(round(f * self.width))
        self.stream.write(f"\r{self.label} [{'#' * fill}{'-' * (self.width - fill)}] {100 * f:3.0f} % "
                          f"{format_seconds(now - self.start)}")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """Finish the line (only when something was drawn): the final state, then a newline."""
        if self._drawn:
            self._last = -1e9
            self.quiet_seconds = 0.0
            self(1.0)
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False
