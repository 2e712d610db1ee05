"""Trace, corner and FRF-fit plots (PNG), written atomically.

Plots use matplotlib's non-interactive Agg canvas directly (no pyplot
state), so they work on headless machines and never leak figures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..io.figures import finish, lower_triangle, new_figure as _figure, save_png as _save

__all__ = ["trace_plot", "corner_plot", "frf_plot", "trace_figure", "corner_figure", "frf_figure", "TRACE_POINTS"]

#: Most points drawn per walker and parameter in the trace plot.
TRACE_POINTS = 1000
#: Most points of each pair panel of the corner plot.
CORNER_POINTS = 3000


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
    # at most TRACE_POINTS points per walker: the axes are about 800 pixels wide, so more points draw the same
    # picture (20000 steps x 32 walkers x every parameter took 3 s of a 25 s identify)
    stride = max(1, -(-n // TRACE_POINTS))
    steps = np.arange(0, n, stride)
    for j, ax in enumerate(axes):
        ax.plot(steps, chain[::stride, : min(nw, max_walkers), j], lw=0.4, alpha=0.5, color="k")
        ax.axvspan(0, burn, color="tab:red", alpha=0.1, lw=0)
        ax.set_ylabel(labels[j], fontsize=8)
    axes[-1].set_xlabel("step")
    finish(fig)
    return fig


def corner_plot(samples: np.ndarray, labels: Sequence[str], path, truths: Sequence[float] | None = None) -> Path:
    """:func:`corner_figure` written to ``path`` (PNG)."""
    return _save(corner_figure(samples, labels, truths), path)


def corner_figure(samples: np.ndarray, labels: Sequence[str], truths: Sequence[float] | None = None):
    """Corner plot of kept samples (a matplotlib Figure): histograms with the 5/50/95 % quantiles on the
    diagonal (their values in the titles), pairs of parameters below it.

    Drawn here rather than with the ``corner`` package, whose import (ArviZ's plotting modules) took longer than
    the figure.

    Parameters
    ----------
    samples : (n, ndim) kept draws (sampling coordinates)
    labels : ndim axis labels
    truths : ndim values to mark (synthetic checks), optional
    """
    samples = np.asarray(samples, dtype=float)
    nd = samples.shape[1]
    fig = _figure(2.0 * nd + 1, 2.0 * nd + 1)
    axes = fig.subplots(nd, nd, squeeze=False)
    q = np.quantile(samples, [0.05, 0.5, 0.95], axis=0)
    lo, hi = np.quantile(samples, [0.002, 0.998], axis=0)
    pad = 0.05 * np.maximum(hi - lo, 1e-12 * np.maximum(np.abs(hi), 1.0))
    lims = np.column_stack([lo - pad, hi + pad])
    shown = samples[:: max(1, samples.shape[0] // CORNER_POINTS)]  # a cloud of points; more hide each other
    for i, j, ax in lower_triangle(axes):
        ax.set_xlim(*lims[j])
        if i == j:
            ax.hist(samples[:, i], bins=30, range=tuple(lims[i]), histtype="step", color="k")
            for v in q[:, i]:
                ax.axvline(v, color="k", ls="--", lw=0.8)
            ax.set_yticks([])
            ax.set_title(f"{labels[i]}\n" + _interval_text(q[:, i]), fontsize=8)
        else:
            ax.plot(shown[:, j], shown[:, i], ".", ms=1.5, color="k", alpha=0.3)
            ax.set_ylim(*lims[i])
        if truths is not None:
            ax.axvline(truths[j], color="tab:blue", lw=1.0)
            if i != j:
                ax.axhline(truths[i], color="tab:blue", lw=1.0)
        if i == nd - 1:
            ax.set_xlabel(labels[j], fontsize=8)
            ax.tick_params(axis="x", labelrotation=45)
        else:
            ax.set_xticklabels([])
        if j == 0 and i > 0:
            ax.set_ylabel(labels[i], fontsize=8)
        elif i != j:
            ax.set_yticklabels([])
    finish(fig)
    return fig


def _interval_text(q) -> str:
    """``median [q05, q95]`` with the decimals the interval's width justifies (a narrow posterior of a log10
    stiffness needs five: 6.25503 [6.25475, 6.25531], where four significant digits gave 6.255 [6.255, 6.255])."""
    half = 0.5 * abs(float(q[2]) - float(q[0]))
    d = 3 if not half > 0 else int(min(8, max(0, 1 - np.floor(np.log10(half)))))
    return f"{q[1]:.{d}f} [{q[0]:.{d}f}, {q[2]:.{d}f}]"


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
        ax.legend(fontsize=8)
    for ax in axes[n:]:
        ax.set_visible(False)
    finish(fig)
    return fig
