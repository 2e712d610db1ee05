"""Trace, corner and FRF-fit plots (PNG), written atomically.

Plots use matplotlib's non-interactive Agg canvas directly (no pyplot
state), so they work on headless machines and never leak figures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..io.figures import new_figure as _figure, save_png as _save

__all__ = ["trace_plot", "corner_plot", "frf_plot", "trace_figure", "corner_figure", "frf_figure"]


def trace_plot(chain: np.ndarray, labels: Sequence[str], burn: int, path, max_walkers: int = 32) -> Path:
    """:func:`trace_figure` written to ``path`` (PNG)."""
    return _save(trace_figure(chain, labels, burn, max_walkers), path)


def trace_figure(chain: np.ndarray, labels: Sequence[str], burn: int, max_walkers: int = 32):
    """Walker traces of every parameter, burn-in shaded (a matplotlib Figure).

    Parameters
    ----------
    chain : (n_steps, n_walkers, ndim) sampling coordinates
    labels : ndim axis labels
    burn : int
        Steps discarded as burn-in.
    """
    n, nw, nd = chain.shape
    fig = _figure(9, 1.6 * nd + 0.6)
    axes = fig.subplots(nd, 1, sharex=True, squeeze=False)[:, 0]
    steps = np.arange(n)
    for j, ax in enumerate(axes):
        ax.plot(steps, chain[:, : min(nw, max_walkers), j], lw=0.4, alpha=0.5, color="k")
        ax.axvspan(0, burn, color="tab:red", alpha=0.1, lw=0)
        ax.set_ylabel(labels[j], fontsize=8)
    axes[-1].set_xlabel("step")
    fig.tight_layout()
    return fig


def corner_plot(samples: np.ndarray, labels: Sequence[str], path, truths: Sequence[float] | None = None) -> Path:
    """:func:`corner_figure` written to ``path`` (PNG)."""
    return _save(corner_figure(samples, labels, truths), path)


def corner_figure(samples: np.ndarray, labels: Sequence[str], truths: Sequence[float] | None = None):
    """Corner plot of kept samples (n, ndim) with the ``corner`` package (a matplotlib Figure)."""
    import corner

    nd = samples.shape[1]
    fig = _figure(2.0 * nd + 1, 2.0 * nd + 1)
    corner.corner(samples, labels=list(labels), truths=truths, fig=fig, quantiles=[0.05, 0.5, 0.95],
                  show_titles=True, title_fmt=".4g", title_kwargs={"fontsize": 8}, label_kwargs={"fontsize": 8})
    return fig


def frf_plot(panels: Sequence[dict], path) -> Path:
    """:func:`frf_figure` written to ``path`` (PNG)."""
    return _save(frf_figure(panels), path)


def frf_figure(panels: Sequence[dict]):
    """Measured |H| against the predicted median and 90 % band, one panel per measurement (a matplotlib Figure).

    Parameters
    ----------
    panels : sequence of dict
        Keys ``title``, ``frequency_hz`` (n,), ``measured`` (n,) complex,
        ``q05``, ``q50``, ``q95`` (n,) of the predicted |H| (m/N).
    """
    n = len(panels)
    cols = min(n, 2)
    rows = int(np.ceil(n / cols))
    fig = _figure(5.5 * cols, 3.2 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    for ax, p in zip(axes, panels):
        f = p["frequency_hz"]
        ax.semilogy(f, np.abs(p["measured"]), ".", ms=2, color="k", label="measured")
        ax.fill_between(f, p["q05"], p["q95"], color="tab:blue", alpha=0.3, lw=0, label="90 % predicted")
        ax.semilogy(f, p["q50"], color="tab:blue", lw=1, label="median")
        ax.set_title(p["title"], fontsize=9)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("|H| (m/N)")
        ax.legend(fontsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig
