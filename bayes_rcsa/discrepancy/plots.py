"""Plots of the discrepancy workflow: the gap before and after, on the same axes.

Every plot is drawn from the evaluation of the baseline and the final model (``evaluation["before"]`` and
``["after"]`` of a :class:`~.workflow.DiscrepancyResult`): the natural-frequency and stiffness plots need only
what discrepancy.json holds (``measurements``, ``stiffness``), the FRF and residual plots also the FRFs
(``frf``), which only a computed result has.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..io.figures import finish, new_figure, save_png
from ..vocabulary import parameter_name, parameter_symbol

#: The plots' names (their files are NAME.png), in the order they are written.
PLOT_NAMES = ("frf_before_after", "residuals_before_after", "frequency_errors", "stiffness_before_after")

__all__ = ["write_plots", "plot_figures", "PLOT_NAMES"]


def _grid(n: int):
    cols = min(4, n)
    rows = int(math.ceil(n / cols))
    return rows, cols


def _panels(evaluation: dict, label_after: str, height: float, draw, ylabel: str):
    """One panel per measurement: ``draw(ax, j, f, measured, before, after)``; shared layout and labels."""
    b, a = evaluation["before"], evaluation["after"]
    n = len(b["measurements"])
    rows, cols = _grid(n)
    fig = new_figure(3.6 * cols, height * rows)
    for j, m in enumerate(b["measurements"]):
        ax = fig.add_subplot(rows, cols, j + 1)
        draw(ax, b["frf"]["frequency_hz"][j], b["frf"]["measured"][j], b["frf"]["predicted"][j], a["frf"]["predicted"][j])
        ax.set_title(f"{m['direction']} {m['clamping_length'] * 1e3:g} mm" + ("" if m["fitted"] else " (held out)"),
                     fontsize=8)
        ax.set_xlabel("frequency [Hz]", fontsize=8)
        ax.set_ylabel(ylabel, fontsize=8)
        if j == 0:
            ax.legend(fontsize=8)
    finish(fig)
    return fig


def _frf_plot(evaluation: dict, label_after: str):
    def draw(ax, f, meas, before, after):
        ax.semilogy(f, np.abs(meas), "k.", ms=2, label="measured")
        ax.semilogy(f, np.abs(before), "C3-", lw=1, label="baseline")
        ax.semilogy(f, np.abs(after), "C0-", lw=1, label=label_after)

    return _panels(evaluation, label_after, 2.8, draw, "|H| [m/N]")


def _residual_plot(evaluation: dict, label_after: str):
    def draw(ax, f, meas, before, after):
        scale = np.abs(meas).max()
        ax.plot(f, np.abs(before - meas) / scale, "C3-", lw=1, label="baseline")
        ax.plot(f, np.abs(after - meas) / scale, "C0-", lw=1, label=label_after)

    return _panels(evaluation, label_after, 2.4, draw, "|H_model - H_meas| / max|H_meas|")


def _frequency_plot(evaluation: dict, label_after: str):
    """Natural-frequency error of every matched mode of every measurement, with its 90 % interval.

    Errors are model mode k minus measured mode k (never two different modes), relative to the measured
    frequency; the bar spans the model's 90 % interval of that mode relative to it, so a bar that crosses 0
    covers the measurement.  The bar is drawn from its two ends (not as an error around the point), so a
    point and interval are shown as computed.  Before and after are offset slightly in clamping length, and
    the modes of one measurement fan out to the right.
    """
    fig = new_figure(6.6, 3.6)
    ax = fig.add_subplot(1, 1, 1)
    for k, (key, colour, lab) in enumerate((("before", "C3", "baseline"), ("after", "C0", label_after))):
        for m in evaluation[key]["measurements"]:
            for r, md in enumerate(m["modes"]):
                q, fm = md["model_interval"], md["measured_hz"]
                lo, hi = (100 * (q[c] - fm) / fm for c in ("q05", "q95"))
                x = m["clamping_length"] * 1e3 + (k - 0.5) * 0.5 + (0.15 if m["direction"] == "y" else 0.0) + 0.1 * r
                style = dict(color=colour, lw=0.8)
                if math.isfinite(lo) and math.isfinite(hi):
                    ax.vlines(x, lo, hi, **style)
                    ax.hlines([lo, hi], x - 0.08, x + 0.08, **style)
                ax.plot(x, md["error_pct"], "o" if m["fitted"] else "s", color=colour,
                        mfc=colour if m["fitted"] else "none", ms=4)
        ax.plot([], [], "o", color=colour, label=lab)
    ax.plot([], [], "ks", mfc="none", label="held out")
    ax.axhline(0, color="k", lw=0.5)
    # linear within +-0.5 % (the errors of a good fit), logarithmic beyond (the intervals of an unexplained remainder)
    ax.set_yscale("symlog", linthresh=0.5)
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo * 1.5 if lo < 0 else lo, hi * 1.5 if hi > 0 else hi)  # room for the end markers
    ax.set_xlabel("clamping length [mm]")
    ax.set_ylabel("mode k error [%], model - measured\n(bars: model 90 % interval)", fontsize=8)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)  # beside the axes: no bar hidden
    finish(fig)
    return fig


def _stiffness_plot(evaluation: dict, label_after: str):
    fig = new_figure(8.0, 3.2)
    for i, name in enumerate(("k_xf", "k_thetaM")):
        ax = fig.add_subplot(1, 2, i + 1)
        for k, (key, colour, lab) in enumerate((("before", "C3", "baseline"), ("after", "C0", label_after))):
            st = evaluation[key]["stiffness"][name]
            x = np.array([float(l) for l in st]) + (k - 0.5) * 0.3
            q = np.array([[v["q05"], v["q50"], v["q95"]] for v in st.values()])
            ax.errorbar(x, q[:, 1], yerr=[q[:, 1] - q[:, 0], q[:, 2] - q[:, 1]], fmt="o", color=colour, label=lab,
                        capsize=3)
        ax.set_yscale("log")
        ax.set_xlabel("clamping length [mm]")
        ax.set_ylabel(f"{parameter_symbol(name) or parameter_name(name)} [{'N/m' if name == 'k_xf' else 'N m/rad'}] (90 % interval)")
    # one key above both panels: inside either it would hide a length's interval
    fig.legend(*fig.axes[0].get_legend_handles_labels(), loc="upper center", ncol=2, frameon=False)
    finish(fig, rect=(0, 0, 1, 1 - 0.35 / fig.get_figheight()))
    return fig


_DRAW = {"frf_before_after": _frf_plot, "residuals_before_after": _residual_plot,
         "frequency_errors": _frequency_plot, "stiffness_before_after": _stiffness_plot}


def plot_figures(evaluation: dict, final_model: str) -> dict:
    """``{name: Figure}`` of the plots that ``evaluation`` can draw (all four when it holds the FRFs).

    Parameters
    ----------
    evaluation : dict with ``"before"`` and ``"after"``, each with ``measurements`` and ``stiffness`` (as in
        discrepancy.json) and, for the FRF and residual plots, ``frf``
    final_model : str, the final model's label (``"baseline"`` when nothing was added)
    """
    label = final_model if final_model != "baseline" else "baseline (unchanged)"
    with_frf = all("frf" in evaluation[k] for k in ("before", "after"))
    return {name: _DRAW[name](evaluation, label) for name in PLOT_NAMES
            if with_frf or name not in ("frf_before_after", "residuals_before_after")}


def write_plots(res, out_dir: Path) -> list[str]:
    """Write the four plots of a computed result (:class:`~.workflow.DiscrepancyResult`) into ``out_dir``;
    returns the file names."""
    out = []
    for name, fig in plot_figures(res.evaluation, res.final_label).items():
        save_png(fig, Path(out_dir) / f"{name}.png")
        out.append(f"{name}.png")
    return out
