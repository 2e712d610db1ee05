"""A log axis' tick locator that makes only the ticks inside the view (see :func:`bayes_rcsa.io.figures.finish`).

Its own module so that matplotlib is imported only where a figure is finished.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.ticker import LogLocator

__all__ = ["InViewLogLocator", "in_view"]


class InViewLogLocator(LogLocator):
    """:class:`~matplotlib.ticker.LogLocator` without the ticks outside ``[vmin, vmax]``.

    A log axis' locator returns a decade beyond each view limit (with a minor tick at every 2..9 of it) and the
    axis makes a tick (two lines, two texts) for each before it drops those outside the view; making ticks is
    most of a log panel's layout time.  The ticks inside the view are the same, so the figure is the same.
    """

    def tick_values(self, vmin, vmax):
        """The ticks of ``LogLocator.tick_values`` within the view, in the same order (axis units)."""
        ticks = super().tick_values(vmin, vmax)
        if self.axis is None or ticks.size == 0 or not (vmin > 0 and vmax > 0):
            return ticks
        lo, hi = sorted((math.log(vmin), math.log(vmax)))
        # looser than the axis' own in-view test (1e-10 of the span), so no tick it would draw is dropped
        tol = 1e-6 * (hi - lo) + 1e-12
        with np.errstate(divide="ignore", invalid="ignore"):
            logs = np.log(ticks)
        return ticks[(logs >= lo - tol) & (logs <= hi + tol)]


def in_view(locator: LogLocator) -> InViewLogLocator:
    """An :class:`InViewLogLocator` with the base, subs and numticks of ``locator``."""
    return InViewLogLocator(locator._base, locator._subs, numticks=locator.numticks)
