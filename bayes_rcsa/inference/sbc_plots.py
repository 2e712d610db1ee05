"""Plots of a simulation-based calibration (:mod:`bayes_rcsa.stats.sbc`): rank histograms and ECDF differences.

matplotlib is imported only when a figure is drawn (through :mod:`bayes_rcsa.io.figures`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..io.figures import finish, new_figure, save_png
from ..stats.sbc import ecdf_difference, simultaneous_band

__all__ = ["sbc_figure", "sbc_plot"]


def sbc_figure(ranks: np.ndarray, n_draws: int, names: Sequence[str], rng: np.random.Generator, alpha: float = 0.01,
               n_bins: int = 20, title: str = "", p_values: Sequence[float] | None = None):
    """Per parameter: the rank histogram and the rank ECDF difference with its simultaneous ``1 - alpha`` band.

    Parameters
    ----------
    ranks : (n_replicates, n_params) int in ``[0, n_draws]``
    n_draws : int, posterior draws per replicate L
    names : (n_params,) parameter names
    rng : numpy.random.Generator, for the band's null simulation
    alpha : float
        Level of each parameter's band (e.g. the family-wise level divided by the number of parameters).
    n_bins : int, histogram bins (a divisor of L + 1)
    title : str
    p_values : (n_params,), optional, written into each panel

    Returns
    -------
    matplotlib Figure
    """
    ranks = np.asarray(ranks)
    n, p = ranks.shape
    z, diff = ecdf_difference(ranks, n_draws)
    band = simultaneous_band(n, n_draws + 1, alpha, rng)
    fig = new_figure(3.0 * p, 5.2)
    axes = fig.subplots(2, p, squeeze=False)
    edges = np.arange(n_bins + 1) * (n_draws + 1) / n_bins - 0.5
    from scipy.stats import binom

    lo, hi = binom.ppf([0.005, 0.995], n, 1.0 / n_bins)
    for j, name in enumerate(names):
        ax = axes[0, j]
        ax.axhspan(lo, hi, color="0.85", lw=0, label="99 % per bin")
        ax.hist(ranks[:, j], bins=edges, color="tab:blue", edgecolor="white")
        ax.axhline(n / n_bins, color="k", lw=0.8)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("rank", fontsize=8)
        ax = axes[1, j]
        ax.fill_between(band.z, band.lower, band.upper, color="0.85", lw=0, step="mid",
                        label=f"{100 * (1 - alpha):.4g} % simultaneous")
        ax.plot(z, diff[:, j], color="tab:blue", lw=1.0, drawstyle="steps-mid")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xlabel("fractional rank", fontsize=8)
        if p_values is not None:
            ax.text(0.03, 0.04, f"p = {p_values[j]:.3g}", transform=ax.transAxes, fontsize=8)
    axes[0, 0].set_ylabel("replicates", fontsize=8)
    axes[1, 0].set_ylabel("ECDF - uniform", fontsize=8)
    axes[1, 0].legend(fontsize=8, loc="upper left")
    if title:
        fig.suptitle(title, fontsize=10)
    finish(fig)
    return fig


def sbc_plot(ranks: np.ndarray, n_draws: int, names: Sequence[str], path, rng: np.random.Generator,
             alpha: float = 0.01, **kwargs) -> Path:
    """:func:`sbc_figure` written to ``path`` (PNG)."""
    return save_png(sbc_figure(ranks, n_draws, names, rng, alpha, **kwargs), path)
