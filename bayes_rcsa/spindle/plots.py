"""Plots of the spindle identification (PNG, written atomically, no pyplot state)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .identification import SpindleIdentification
from ..io.figures import finish, new_figure as _figure, save_png as _save

__all__ = ["receptance_plot", "reproduction_plot", "receptance_figure", "reproduction_figure"]

_ENTRIES = (("h", 0, 0, "m/N"), ("l = n", 0, 1, "1/N"), ("p", 1, 1, "rad/(N m)"))


def _phase(values) -> np.ndarray:
    """Phase in degrees on (-270, 90]: a passive receptance lies in [-180, 0], so noise does not wrap."""
    deg = np.degrees(np.angle(values))
    return np.where(deg > 90, deg - 360, deg)


def _shade(ax, bands) -> None:
    for lo, hi in bands:
        ax.axvspan(lo, hi, color="tab:red", alpha=0.12, lw=0)


def receptance_plot(result: SpindleIdentification, path, truth: np.ndarray | None = None) -> Path:
    """:func:`receptance_figure` written to ``path`` (PNG)."""
    return _save(receptance_figure(result, truth), path)


def reproduction_plot(result: SpindleIdentification, path) -> Path:
    """:func:`reproduction_figure` written to ``path`` (PNG)."""
    return _save(reproduction_figure(result), path)


def receptance_figure(result: SpindleIdentification, truth: np.ndarray | None = None):
    """Raw (line-by-line) vs smoothed flange receptances, magnitude and phase (a matplotlib Figure).

    Parameters
    ----------
    result : SpindleIdentification
    truth : (n_freq, 2, 2) complex, optional
        A known flange block to overlay (synthetic checks).

    Shaded in red: lines flagged unreliable.  Grey band: 2.5-97.5 %
    quantiles of the bootstrap samples' magnitude, when present.
    """
    f = result.frequency_hz
    fig = _figure(11, 9)
    axes = fig.subplots(3, 2, sharex=True)
    for row, (name, i, j, unit) in enumerate(_ENTRIES):
        am, ap = axes[row]
        raw = result.raw[:, i, j] if i == j else 0.5 * (result.raw[:, 0, 1] + result.raw[:, 1, 0])
        sm = result.smoothed[:, i, j]
        _shade(am, result.bands)
        _shade(ap, result.bands)
        if result.samples is not None:
            mag = np.abs(result.samples[:, :, i, j])
            lo, hi = np.quantile(mag, [0.025, 0.975], axis=0)
            am.fill_between(f, lo, hi, color="0.6", alpha=0.5, lw=0, label="bootstrap 95 %")
        am.semilogy(f, np.abs(raw), ".", ms=1.5, color="0.45", label="raw (inverse coupling)")
        am.semilogy(f, np.abs(sm), color="tab:blue", lw=1.2, label=f"modal model ({result.fit.model.n_modes} modes)")
        ap.plot(f, _phase(raw), ".", ms=1.5, color="0.45")
        ap.plot(f, _phase(sm), color="tab:blue", lw=1.2)
        if truth is not None:
            am.semilogy(f, np.abs(truth[:, i, j]), "--", color="k", lw=0.9, label="truth")
            ap.plot(f, _phase(truth[:, i, j]), "--", color="k", lw=0.9)
        am.set_ylabel(f"|{name}| [{unit}]")
        ap.set_ylabel(f"phase {name} [deg]")
        ap.set_ylim(-280, 100)
        raw_mag = np.abs(raw[np.isfinite(raw)])
        if raw_mag.size:
            # keep the axes on the smoothed curve; raw outliers in flagged bands would squash it
            top = max(np.max(np.abs(sm)), np.quantile(raw_mag, 0.99)) * 3
            am.set_ylim(np.min(np.abs(sm)) / 3, top)
    axes[0][0].legend(fontsize=8, loc="best")
    axes[-1][0].set_xlabel("frequency [Hz]")
    axes[-1][1].set_xlabel("frequency [Hz]")
    fig.suptitle(f"flange receptance, direction {result.direction} (red: unreliable inversion, "
                 f"relative std > {result.threshold:g})", fontsize=10)
    finish(fig)
    return fig


def reproduction_figure(result: SpindleIdentification):
    """Measured hammer tests vs those predicted by coupling the smoothed block to the artifact (a Figure)."""
    f = result.frequency_hz
    fig = _figure(9, 7)
    axes = fig.subplots(3, 1, sharex=True)
    for ax, k, name in zip(axes, range(3), ("H11", "H12 (= H21)", "H22")):
        _shade(ax, result.bands)
        ax.semilogy(f, np.abs(result.measured[:, k]), ".", ms=1.5, color="0.45", label="measured")
        ax.semilogy(f, np.abs(result.reproduced[:, k]), color="tab:orange", lw=1.0, label="artifact + smoothed spindle")
        ax.set_ylabel(f"|{name}| [m/N]")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("frequency [Hz]")
    fig.suptitle(f"artifact hammer tests, direction {result.direction}", fontsize=10)
    finish(fig)
    return fig
