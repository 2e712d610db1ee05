"""Matplotlib figures without pyplot state, saved atomically as PNG."""

from __future__ import annotations

from pathlib import Path

from .atomic import atomic_path

__all__ = ["new_figure", "save_png"]


def new_figure(width: float, height: float):
    """A Figure on its own Agg canvas (no global pyplot state), size in inches at 100 dpi."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig, path) -> Path:
    """Write ``fig`` to ``path`` as PNG atomically; returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path
