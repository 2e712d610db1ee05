"""PNG plots of predictions and identifiability, each returning the numbers it drew.

Every function draws with matplotlib's Agg canvas (no pyplot state), writes
the PNG atomically and returns a JSON-able dict of the numbers shown (mode
intervals, plotted quantiles, axis ranges).  The same dict is stored in the
PNG as a text chunk under the key :data:`METADATA_KEY`, so a figure can be
checked against the JSON reports of the same run later
(:func:`read_plot_numbers`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..io.atomic import atomic_path
from ..io.jsonable import dumps_strict
from ..io.figures import finish, lower_triangle, new_figure as _figure, write_png

__all__ = [
    "METADATA_KEY",
    "read_plot_numbers",
    "frf_band_plot",
    "frf_zoom_plot",
    "natural_frequency_plot",
    "corner_overlay",
    "forest_plot",
    "corner_overlay_figure",
    "forest_figure",
    "save_plot",
]

METADATA_KEY = "bayes_rcsa.numbers"
FIT_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink",
              "tab:olive", "tab:cyan", "tab:gray")


def save_plot(fig, path, numbers: dict) -> dict:
    """Write ``fig`` to ``path`` as PNG (atomically) with ``numbers`` in its metadata; returns ``numbers``."""
    return _save(fig, path, numbers)


def _save(fig, path, numbers: dict) -> dict:
    """Write ``fig`` with ``numbers`` in its metadata; with ``path`` None write nothing and return the figure too
    (under ``"figure"``: the workflows' ``Result.figures``)."""
    if path is None:
        return {**numbers, "figure": fig}
    path = Path(path)
    text = dumps_strict(numbers)
    with atomic_path(path) as tmp:
        write_png(fig, tmp, metadata={METADATA_KEY: text})
    return numbers


def read_plot_numbers(path) -> dict:
    """The numbers stored in a PNG written by this module."""
    from PIL import Image

    with Image.open(path) as im:
        text = im.text.get(METADATA_KEY) if hasattr(im, "text") else im.info.get(METADATA_KEY)
    if text is None:
        from ..errors import DataError

        raise DataError(f"{path}: no {METADATA_KEY!r} text chunk (not written by bayes_rcsa.posterior.plots)")
    return json.loads(text)


def _mm(length: float) -> str:
    return f"{length * 1e3:g} mm"


# -- predictions ---------------------------------------------------------------


def frf_band_plot(bands: Sequence, modes: Sequence, path, title: str = "") -> dict:
    """Predictive |H| bands (median, 50 %, 90 %) per configuration with mode intervals.

    Parameters
    ----------
    bands : sequence of FRFBands
    modes : sequence of ModePrediction
        Drawn as a vertical line at the median natural frequency, a shaded
        90 % interval and a label with the numbers.
    path : output PNG

    Returns
    -------
    dict ``{"panels": [{"clamping_length", "direction", "tool", "modes":
    [{"mode", "dominant", "q05_hz", ..., "q95_hz", "measured_hz"}]}]}``
    """
    n = len(bands)
    cols = 2 if n > 1 else 1
    rows = int(np.ceil(n / cols))
    per_panel = max([sum(m.configuration == b.configuration for m in modes) for b in bands] + [0])
    # each panel's mode list sits under it (a legend inside would cover the curves), the common keys on top
    fig = _figure(6.0 * cols, (3.6 + 0.2 * per_panel) * rows + 0.4 + (0.3 if title else 0))
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    panels = []
    for ax, b in zip(axes, bands):
        f = b.frequency_hz
        q = b.magnitude
        ax.fill_between(f, q[0], q[4], color="tab:blue", alpha=0.2, lw=0, label="90 % band")
        ax.fill_between(f, q[1], q[3], color="tab:blue", alpha=0.4, lw=0, label="50 % band")
        ax.semilogy(f, q[2], color="tab:blue", lw=1.0, label="median")
        if b.measured is not None:
            fm = b.measured.frequency_hz
            keep = (fm >= f[0]) & (fm <= f[-1])
            ax.semilogy(fm[keep], np.abs(b.measured.values[keep]), ".", ms=1.5, color="k", label="measured")
        c = b.configuration
        drawn = []
        ymin, ymax = ax.get_ylim()
        if b.measured is not None and np.any(keep):
            ymax = max(ymax, float(np.max(np.abs(b.measured.values[keep]))))
        # a strip above every curve for the mode numbers (log axis: 0.15 of the decades shown), so that no label
        # covers the data; the intervals themselves are listed under the panel
        ax.set_ylim(ymin, ymax * (ymax / ymin) ** 0.15)
        mode_handles = []
        for m in (m for m in modes if m.configuration == c):
            nf = m.natural_frequency_hz
            if nf["q50"] is None:
                continue
            text = f"mode {m.mode}: {nf['q50']:.1f} Hz, 90 % [{nf['q05']:.1f}, {nf['q95']:.1f}]"
            if m.has_measurement and m.measured_hz is not None:
                ax.axvline(m.measured_hz, color="k", lw=0.8, ls="--")
                text += f", measured {m.measured_hz:.1f}"
            mode_handles.append(ax.axvspan(nf["q05"], nf["q95"], color="tab:red", alpha=0.25, lw=0, label=text))
            ax.axvline(nf["q50"], color="tab:red", lw=0.8)
            ax.annotate(str(m.mode), (nf["q50"], 1.0), xycoords=("data", "axes fraction"), textcoords="offset points",
                        xytext=(2, -3), ha="left", va="top", color="tab:red")
            drawn.append({"mode": m.mode, "dominant": m.dominant,
                          **{f"{k}_hz": v for k, v in nf.items()},
                          "measured_hz": m.measured_hz if m.has_measurement else None})
        fitted = " (fitted)" if any(m.fitted for m in modes if m.configuration == c) else ""
        ax.set_title(f"{c.tool} {c.direction}, clamping {_mm(c.clamping_length)}{fitted}", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("|H| (m/N)")
        if mode_handles:
            ax.legend(handles=mode_handles, loc="upper left", bbox_to_anchor=(0.0, -0.2), frameon=False,
                      borderaxespad=0.0, handlelength=1.2)
        panels.append({"clamping_length": c.clamping_length, "direction": c.direction, "tool": c.tool,
                       "frequency_range_hz": [float(f[0]), float(f[-1])],
                       "median_peak_magnitude": float(np.max(q[2])), "modes": drawn})
    for ax in axes[n:]:
        ax.set_visible(False)
    inch = 1.0 / fig.get_figheight()  # figure fraction of an inch: the strips on top keep their height
    if title:
        fig.suptitle(title, fontsize=10, y=1.0 - 0.08 * inch, va="top")
    keys, labels = axes[0].get_legend_handles_labels()
    common = [(h, lab) for h, lab in zip(keys, labels) if not lab.startswith("mode ")]
    top = 1.0 - (0.32 if title else 0.02) * inch
    fig.legend([h for h, _ in common], [lab for _, lab in common], loc="upper center", ncol=len(common),
               frameon=False, bbox_to_anchor=(0.5, top))
    finish(fig, rect=(0, 0, 1, top - 0.35 * inch))
    return _save(fig, path, {"kind": "frf_bands", "panels": panels})


def frf_zoom_plot(bands: Sequence, modes: Sequence, path, rel_window: float = 0.04) -> dict:
    """Linear-scale zoom of every configuration's dominant mode with the 50/90 % bands.

    The window is the median natural frequency +- ``rel_window`` (relative),
    widened to three 90 % interval widths if those are larger.

    Returns
    -------
    dict ``{"panels": [{"clamping_length", "direction", "tool", "window_hz",
    "mode", "q05_hz", ..., "q95_hz", "measured_hz"}]}``
    """
    dom = {m.configuration: m for m in modes if m.dominant and m.natural_frequency_hz["q50"] is not None}
    shown = [b for b in bands if b.configuration in dom]
    n = max(len(shown), 1)
    cols = min(n, 4)
    rows = int(np.ceil(n / cols))
    fig = _figure(3.6 * cols, 3.0 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    panels = []
    for ax, b in zip(axes, shown):
        m = dom[b.configuration]
        nf = m.natural_frequency_hz
        half = max(rel_window * nf["q50"], 3.0 * (nf["q95"] - nf["q05"]))
        lo, hi = nf["q50"] - half, nf["q50"] + half
        f = b.frequency_hz
        k = (f >= lo) & (f <= hi)
        q = b.magnitude
        ax.fill_between(f[k], q[0][k], q[4][k], color="tab:blue", alpha=0.2, lw=0, label="90 %")
        ax.fill_between(f[k], q[1][k], q[3][k], color="tab:blue", alpha=0.4, lw=0, label="50 %")
        ax.plot(f[k], q[2][k], color="tab:blue", lw=1.0, label="median")
        if b.measured is not None:
            fm = b.measured.frequency_hz
            km = (fm >= lo) & (fm <= hi)
            ax.plot(fm[km], np.abs(b.measured.values[km]), ".", ms=2.5, color="k", label="measured")
        ax.axvspan(nf["q05"], nf["q95"], color="tab:red", alpha=0.25, lw=0)
        ax.axvline(nf["q50"], color="tab:red", lw=0.8)
        meas = m.measured_hz if m.has_measurement else None
        if meas is not None:
            ax.axvline(meas, color="k", lw=0.8, ls="--")
        c = b.configuration
        ax.set_title(f"{c.direction} {_mm(c.clamping_length)}: {nf['q50']:.1f} [{nf['q05']:.1f}, {nf['q95']:.1f}] Hz",
                     fontsize=8)
        ax.set_xlim(lo, hi)
        ax.set_xlabel("frequency (Hz)", fontsize=8)
        ax.set_ylabel("|H| (m/N)", fontsize=8)
        panels.append({"clamping_length": c.clamping_length, "direction": c.direction, "tool": c.tool,
                       "window_hz": [lo, hi], "mode": m.mode, **{f"{key}_hz": v for key, v in nf.items()},
                       "measured_hz": meas})
    if shown:
        axes[0].legend(fontsize=8)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    finish(fig)
    return _save(fig, path, {"kind": "frf_zoom", "panels": panels})


def natural_frequency_plot(modes: Sequence, path) -> dict:
    """Dominant natural frequency against clamping length, and its error against the measurements.

    Left: predicted median with 50 % (thick) and 90 % (thin) intervals and
    the measured values.  Right, where a measurement exists: the same
    intervals as errors relative to the measurement (%).

    Returns
    -------
    dict ``{"series": [{"direction", "tool", "points": [{"clamping_length",
    "q05_hz", ..., "q95_hz", "measured_hz"}]}]}``
    """
    fig = _figure(11.0, 4.2)
    ax, ax_err = fig.subplots(1, 2)
    series: dict = {}
    for m in modes:
        if m.dominant and m.natural_frequency_hz["q50"] is not None:
            series.setdefault((m.configuration.direction, m.configuration.tool), []).append(m)
    out = []
    keys = ("q05", "q25", "q50", "q75", "q95")
    for i, (key, ms) in enumerate(sorted(series.items())):
        ms = sorted(ms, key=lambda m: m.configuration.clamping_length)
        color = FIT_COLORS[i % len(FIT_COLORS)]
        x = np.array([m.configuration.clamping_length * 1e3 for m in ms])
        q = {k: np.array([m.natural_frequency_hz[k] for m in ms]) for k in keys}
        off = (i - 0.5 * (len(series) - 1)) * 0.15  # mm: directions side by side
        ax.errorbar(x + off, q["q50"], yerr=[q["q50"] - q["q05"], q["q95"] - q["q50"]], fmt="o", ms=3, color=color,
                    capsize=3, lw=0.8, label=f"{key[0]} predicted (50/90 %)")
        ax.errorbar(x + off, q["q50"], yerr=[q["q50"] - q["q25"], q["q75"] - q["q50"]], fmt="none", color=color, lw=2.5)
        meas = [(xx, m) for xx, m in zip(x, ms) if m.has_measurement and m.measured_hz is not None]
        if meas:
            ax.plot([a for a, _ in meas], [m.measured_hz for _, m in meas], "x", color=color, ms=6,
                    label=f"{key[0]} measured")
            xe = np.array([a for a, _ in meas]) + off
            e = {k: np.array([100.0 * (m.natural_frequency_hz[k] - m.measured_hz) / m.measured_hz for _, m in meas])
                 for k in keys}
            ax_err.errorbar(xe, e["q50"], yerr=[e["q50"] - e["q05"], e["q95"] - e["q50"]], fmt="o", ms=3, color=color,
                            capsize=3, lw=0.8, label=key[0])
            ax_err.errorbar(xe, e["q50"], yerr=[e["q50"] - e["q25"], e["q75"] - e["q50"]], fmt="none", color=color,
                            lw=2.5)
        out.append({"direction": key[0], "tool": key[1], "points": [
            {"clamping_length": m.configuration.clamping_length, **{f"{k}_hz": v for k, v in m.natural_frequency_hz.items()},
             "measured_hz": m.measured_hz if m.has_measurement else None} for m in ms]})
    ax.set_xlabel("clamping length (mm)")
    ax.set_ylabel("natural frequency (Hz)")
    ax.set_title("Dominant mode: predicted vs measured", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax_err.axhline(0.0, color="k", lw=0.8)
    ax_err.set_xlabel("clamping length (mm)")
    ax_err.set_ylabel("(predicted - measured) / measured (%)")
    ax_err.set_title("Prediction error where measured", fontsize=9)
    ax_err.grid(alpha=0.3)
    if any(line.get_label() and not line.get_label().startswith("_") for line in ax_err.get_lines()) or ax_err.containers:
        ax_err.legend(fontsize=8)
    finish(fig)
    return _save(fig, path, {"kind": "natural_frequencies", "series": out})


# -- identifiability ---------------------------------------------------------------


def _hpd_thresholds(hist: np.ndarray, masses: Sequence[float]) -> list[float]:
    """Histogram heights enclosing the given probability masses (highest-density regions)."""
    flat = np.sort(hist.ravel())[::-1]
    cum = np.cumsum(flat)
    total = cum[-1]
    out = []
    for m in masses:
        k = int(np.searchsorted(cum, m * total))
        out.append(float(flat[min(k, flat.size - 1)]))
    return out


def corner_overlay(groups: Sequence[Mapping], labels: Sequence[str], path, levels: Sequence[float] = (0.5, 0.9),
                   bins: int = 40, fit_order: Sequence[str] | None = None) -> dict:
    """:func:`corner_overlay_figure` written to ``path`` (PNG, its numbers in the metadata); returns the numbers."""
    fig, numbers = corner_overlay_figure(groups, labels, levels, bins, fit_order)
    return save_plot(fig, path, numbers)


def corner_overlay_figure(groups: Sequence[Mapping], labels: Sequence[str], levels: Sequence[float] = (0.5, 0.9),
                          bins: int = 40, fit_order: Sequence[str] | None = None) -> tuple:
    """Corner plots of several posteriors overlaid, one corner per group, identical axes and levels.

    Parameters
    ----------
    groups : sequence of {"title": str, "datasets": {fit name: (n, p) array}}
    labels : p axis labels
    levels : credible masses of the 2-D contours (highest-density regions,
        the same for every fit and group)
    bins : histogram bins per axis (the same edges for every fit)
    fit_order : fit names in legend/colour order

    Returns
    -------
    (Figure, dict): the figure and the numbers drawn: the common ``ranges`` (p, 2), ``levels`` and per group
    and fit the posterior ``q05``/``q50``/``q95`` of every coordinate.
    """
    p = len(labels)
    names = list(fit_order) if fit_order else sorted({n for g in groups for n in g["datasets"]})
    colors = {n: FIT_COLORS[i % len(FIT_COLORS)] for i, n in enumerate(names)}
    allz = np.concatenate([np.asarray(d, dtype=float) for g in groups for d in g["datasets"].values()])
    lo = np.quantile(allz, 0.002, axis=0)
    hi = np.quantile(allz, 0.998, axis=0)
    pad = 0.05 * np.maximum(hi - lo, 1e-6)
    ranges = np.column_stack([lo - pad, hi + pad])
    edges = [np.linspace(ranges[j, 0], ranges[j, 1], bins + 1) for j in range(p)]
    ng = len(groups)
    fig = _figure(2.6 * p * ng + 0.5, 2.6 * p + 0.8)
    subs = np.atleast_1d(fig.subfigures(1, ng, squeeze=False).ravel())
    out_groups = []
    for sub, g in zip(subs, groups):
        axes = sub.subplots(p, p, squeeze=False)
        stats = {}
        for name in names:
            if name not in g["datasets"]:
                continue
            z = np.asarray(g["datasets"][name], dtype=float)
            color = colors[name]
            q = np.quantile(z, [0.05, 0.5, 0.95], axis=0)
            stats[name] = {"q05": q[0].tolist(), "q50": q[1].tolist(), "q95": q[2].tolist()}
            for i in range(p):
                hist, _ = np.histogram(z[:, i], bins=edges[i])
                if hist.max() > 0:
                    axes[i, i].stairs(hist / hist.max(), edges[i], color=color, lw=1.0)
                for j in range(i):
                    ax = axes[i, j]
                    h2, _, _ = np.histogram2d(z[:, j], z[:, i], bins=[edges[j], edges[i]])
                    if np.count_nonzero(h2) < 4:
                        # too concentrated for contours at this common scale: show the draws
                        k = z[:: max(1, z.shape[0] // 200)]
                        ax.plot(k[:, j], k[:, i], ".", ms=1.5, color=color, alpha=0.6)
                        continue
                    th = sorted(set(_hpd_thresholds(h2, sorted(levels, reverse=True))))
                    th = [t for t in th if t > 0]
                    cx = 0.5 * (edges[j][1:] + edges[j][:-1])
                    cy = 0.5 * (edges[i][1:] + edges[i][:-1])
                    if len(th) >= 1:
                        ax.contour(cx, cy, h2.T, levels=th + [h2.max() + 1], colors=[color], linewidths=0.9)
        for i, j, ax in lower_triangle(axes):
            ax.set_xlim(*ranges[j])
            if i != j:
                ax.set_ylim(*ranges[i])
            else:
                ax.set_ylim(0, 1.1)
                ax.set_yticks([])
            if i == p - 1:
                ax.set_xlabel(labels[j])
            if j == 0 and i > 0:
                ax.set_ylabel(labels[i])
        sub.suptitle(g["title"], fontsize=9)
        out_groups.append({"title": g["title"], "fits": stats})
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=colors[n], label=n) for n in names]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(names), 6), fontsize=8, frameon=False)
    finish(fig, layout=False)
    return fig, {"kind": "corner_overlay", "labels": list(labels), "ranges": ranges.tolist(), "levels": list(levels),
                 "groups": out_groups}


def forest_plot(panels: Sequence[Mapping], path, fit_order: Sequence[str] | None = None, title: str = "") -> dict:
    """:func:`forest_figure` written to ``path`` (PNG, its numbers in the metadata); returns the numbers."""
    fig, numbers = forest_figure(panels, fit_order, title)
    return save_plot(fig, path, numbers)


def forest_figure(panels: Sequence[Mapping], fit_order: Sequence[str] | None = None, title: str = "") -> tuple:
    """Forest plot: per row, each fit's median with 50 % (thick) and 90 % (thin) intervals.

    Parameters
    ----------
    panels : sequence of {"title", "xlabel", "rows": [{"label", "fits": {name:
        {"q05", "q25", "q50", "q75", "q95"}}, "reference": float or None}]}
        ``reference`` (e.g. a measurement or 0 % error) is drawn as a mark.

    Returns
    -------
    (Figure, dict): the figure and the panels as drawn.
    """
    names = list(fit_order) if fit_order else sorted({n for pnl in panels for r in pnl["rows"] for n in r["fits"]})
    colors = {n: FIT_COLORS[i % len(FIT_COLORS)] for i, n in enumerate(names)}
    n_rows = max(len(pnl["rows"]) for pnl in panels)
    fig = _figure(4.2 * len(panels) + 0.6, 0.45 * n_rows * max(1, len(names)) * 0.6 + 1.8)
    axes = np.atleast_1d(fig.subplots(1, len(panels), squeeze=False).ravel())
    drawn = []
    for ax, pnl in zip(axes, panels):
        rows = pnl["rows"]
        yt, yl = [], []
        for r_i, row in enumerate(rows):
            base = len(rows) - 1 - r_i
            present = [n for n in names if n in row["fits"] and row["fits"][n].get("q50") is not None]
            for k, name in enumerate(present):
                q = row["fits"][name]
                y = base + (k - 0.5 * (len(present) - 1)) * (0.7 / max(len(present), 1))
                ax.plot([q["q05"], q["q95"]], [y, y], color=colors[name], lw=1.0)
                if q.get("q25") is not None:
                    ax.plot([q["q25"], q["q75"]], [y, y], color=colors[name], lw=3.0)
                ax.plot([q["q50"]], [y], "o", color=colors[name], ms=3)
            if row.get("reference") is not None:
                ax.plot([row["reference"]], [base], "kx", ms=6)
            yt.append(base)
            yl.append(row["label"])
        ax.set_yticks(yt)
        ax.set_yticklabels(yl, fontsize=8)
        ax.set_xlabel(pnl.get("xlabel", ""), fontsize=8)
        ax.set_title(pnl.get("title", ""), fontsize=9)
        ax.tick_params(axis="x", labelsize=8)
        ax.grid(axis="x", alpha=0.3)
        drawn.append({"title": pnl.get("title", ""), "rows": [dict(r) for r in rows]})
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=colors[n], marker="o", label=n) for n in names]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(names), 6), fontsize=8, frameon=False)
    if title:
        fig.suptitle(title, fontsize=10)
    finish(fig, rect=(0, 0.08, 1, 0.95 if title else 1))
    return fig, {"kind": "forest", "panels": drawn}
