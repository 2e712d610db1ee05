"""Figures of the self-contained report, returned as PNG data URIs (nothing written next to the page).

* :func:`geometry_figure`: schematic of spindle flange, holder and tool with
  the clamping length and the overhang;
* :func:`frf_zoom_figure`: posterior-predictive bands of ``|H|`` and of the
  phase around each mode of one configuration, with the measurement;
* :func:`p_stable_figure`: the P(stable) map of probabilistic lobes with
  the required-probability contour and the recommended operating point;
* :func:`png_data_uri`: an existing PNG file embedded as a data URI.
"""

from __future__ import annotations

import base64
import io
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DataError
from ..io.figures import finish, new_figure, write_png

__all__ = ["png_data_uri", "figure_data_uri", "geometry_figure", "frf_zoom_figure", "p_stable_figure"]

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def png_data_uri(path) -> str:
    """``data:image/png;base64,...`` of a PNG file (:class:`DataError` if it is not a PNG)."""
    data = Path(path).read_bytes()
    if not data.startswith(_PNG_MAGIC):
        raise DataError(f"{path}: not a PNG image")
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def figure_data_uri(fig, dpi: int = 90) -> str:
    """Render a matplotlib figure (from :func:`bayes_rcsa.io.figures.new_figure`, no pyplot state, laid out by
    :func:`bayes_rcsa.io.figures.finish`) to a PNG data URI.

    Saved as laid out, like the package's PNG files: ``bbox_inches="tight"`` would draw every figure once more
    only to trim the few pixels of margin ``finish``'s tight layout leaves (measured: the demo report's 16
    figures 10.4 s -> 6.7 s to build).
    """
    buf = io.BytesIO()
    write_png(fig, buf, dpi=dpi)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def geometry_figure(holder, tool, clamping_length: float, clamping_range: tuple[float, float] | None = None) -> str:
    """Side view of flange, holder and tool at ``clamping_length`` (m), as a data URI.

    Parameters
    ----------
    holder : bayes_rcsa.model.geometry.Holder
        Segments from the spindle flange to the holder's free end.
    tool : bayes_rcsa.model.geometry.Tool
        Segments from the tip towards the shank end.
    clamping_length : float, m
        Length of the tool inside the holder bore.
    clamping_range : (lo, hi) m, optional
        Feasible range, marked on the tool.
    """
    from matplotlib.patches import Rectangle

    mm = 1e3
    fig = new_figure(9, 3.2)
    ax = fig.add_subplot(1, 1, 1)
    d_max = max(s.outer_diameter for s in holder.segments) * mm
    ax.add_patch(Rectangle((-8, -0.75 * d_max), 8, 1.5 * d_max, facecolor="0.85", edgecolor="k", hatch="//"))
    ax.text(-4, 0.8 * d_max, "spindle flange\n(measured receptance)", ha="left", va="bottom", fontsize=8)
    x = 0.0
    for s in holder.segments:
        r = s.outer_diameter * mm / 2
        ax.add_patch(Rectangle((x, -r), s.length * mm, 2 * r, facecolor="#9ab", edgecolor="k"))
        if s.inner_diameter > 0:
            ri = s.inner_diameter * mm / 2
            ax.add_patch(Rectangle((x, -ri), s.length * mm, 2 * ri, facecolor="white", edgecolor="0.4", ls=":"))
        x += s.length * mm
    holder_end = x
    base = holder_end - clamping_length * mm  # tool's shank end inside the bore
    tip = base + tool.total_length * mm
    xs = tip
    for s in tool.segments:  # from the tip towards the shank
        r = s.effective_diameter * mm / 2
        ax.add_patch(Rectangle((xs - s.length * mm, -r), s.length * mm, 2 * r, facecolor="#d94", edgecolor="k",
                               alpha=0.9))
        xs -= s.length * mm
    y = -0.95 * d_max / 2 - 6
    ax.annotate("", (base, y), (holder_end, y), arrowprops=dict(arrowstyle="<->"))
    ax.text((base + holder_end) / 2, y - 1, f"clamping length {clamping_length * mm:.1f} mm", ha="center", va="top",
            fontsize=8)
    y2 = y + 3.5
    ax.annotate("", (holder_end, y2), (tip, y2), arrowprops=dict(arrowstyle="<->", color="#a52"))
    ax.text((holder_end + tip) / 2, y2 + 0.5, f"overhang {(tool.total_length - clamping_length) * mm:.1f} mm",
            ha="center", va="bottom", fontsize=8, color="#a52")
    ax.plot([tip], [0], "kv")
    ax.text(tip, 2, "tool point\n(hammer test)", ha="center", va="bottom", fontsize=8)
    if clamping_range is not None:
        lo, hi = clamping_range
        ax.text(holder_end, 0.75 * d_max, f"feasible clamping {lo * mm:g}-{hi * mm:g} mm", ha="center", fontsize=8)
    ax.set_xlim(-10, tip + 12)
    ax.set_ylim(-0.95 * d_max / 2 - 14, 1.1 * d_max)
    ax.set_aspect("equal")
    ax.set_xlabel("axial position from the spindle flange (mm)")
    ax.set_yticks([])
    ax.set_title("spindle - holder - tool (schematic, to scale)", fontsize=9)
    finish(fig)
    return figure_data_uri(fig)


def frf_zoom_figure(label: str, frequency_hz: np.ndarray, h: np.ndarray, modes: Sequence[dict],
                    measured=None) -> str:
    """Bands of ``|H|`` and phase around each mode of one configuration, as a data URI.

    Three rows per mode: ``|H|`` itself; ``|H|`` relative to the posterior
    median (%); the phase minus the median phase (deg).  The credible bands
    of a well-identified contact are a fraction of a per cent wide, so only
    the two relative rows make them (and the measurement's scatter about
    them) visible.

    Parameters
    ----------
    label : str
        Configuration, for the title.
    frequency_hz : (n_freq,) Hz
        Dense lines covering every mode's zoom window.
    h : (n_draws, n_freq) complex, m/N
        Posterior draws of the FRF (noise-free model).
    modes : sequence of dict
        ``frequencies.json`` entries of the configuration's modes (their
        ``zoom_lo_hz``/``zoom_hi_hz`` set by the caller).
    measured : FRF, optional
        The measurement, drawn as points.
    """
    n = max(len(modes), 1)
    fig = new_figure(4.2 * n, 7.0)
    axes = fig.subplots(3, n, squeeze=False, sharex="col")
    levels = [0.05, 0.25, 0.5, 0.75, 0.95]
    mag = np.abs(h)
    q_mag = np.quantile(mag, levels, axis=0)
    med = np.median(h.real, axis=0) + 1j * np.median(h.imag, axis=0)
    rel = 100.0 * (mag / q_mag[2] - 1.0)
    # phase relative to the median FRF: small angles, no wrap (passive receptance: phase in [-180, 0] deg)
    dph = np.degrees(np.angle(h * np.conj(med)))
    q_rel = np.quantile(rel, levels, axis=0)
    q_dph = np.quantile(dph, levels, axis=0)
    meas_rows = None
    if measured is not None:
        fm = measured.frequency_hz
        inside = (fm >= frequency_hz[0]) & (fm <= frequency_hz[-1])
        fm = fm[inside]
        hm = measured.values[inside]
        med_m = np.interp(fm, frequency_hz, med.real) + 1j * np.interp(fm, frequency_hz, med.imag)
        mag_m = np.interp(fm, frequency_hz, q_mag[2])
        meas_rows = (fm, np.abs(hm) * 1e6, 100.0 * (np.abs(hm) / mag_m - 1.0), np.degrees(np.angle(hm * np.conj(med_m))))
    rows = ((q_mag * 1e6, "|H| (µm/N)"), (q_rel, "|H| / median - 1 (%)"), (q_dph, "phase - median phase (deg)"))
    for k, m in enumerate(modes):
        lo, hi = m["zoom_lo_hz"], m["zoom_hi_hz"]
        sel = (frequency_hz >= lo) & (frequency_hz <= hi)
        f = frequency_hz[sel]
        for r, (q, ylab) in enumerate(rows):
            ax = axes[r, k]
            ax.fill_between(f, q[0, sel], q[4, sel], color="C0", alpha=0.25, lw=0, label="90 % band")
            ax.fill_between(f, q[1, sel], q[3, sel], color="C0", alpha=0.5, lw=0, label="50 % band")
            ax.plot(f, q[2, sel], "C0", lw=1, label="median")
            if meas_rows is not None:
                sm = (meas_rows[0] >= lo) & (meas_rows[0] <= hi)
                ax.plot(meas_rows[0][sm], meas_rows[r + 1][sm], "ko", ms=3, label="measured")
            ax.set_ylabel(ylab, fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, k].set_title(f"{label}, mode {m['mode']}", fontsize=9)
        axes[2, k].set_xlabel("frequency (Hz)")
    axes[0, 0].legend(fontsize=8)
    finish(fig)
    return figure_data_uri(fig, dpi=75)


def p_stable_figure(speed_rpm: np.ndarray, depth_m: np.ndarray, p_stable: np.ndarray, level: float,
                    recommended: dict | None) -> str:
    """P(stable) over spindle speed and axial depth with the ``level`` contour and the recommended point.

    Parameters
    ----------
    speed_rpm : (n_speed,) rpm
    depth_m : (n_depth,) m
    p_stable : (n_speed, n_depth)
    level : float
        Required probability of stability.
    recommended : dict or None
        ``lobes.json`` ``recommended`` (``spindle_speed_rpm``, ``depth_m``).
    """
    fig = new_figure(8, 4)
    ax = fig.add_subplot(1, 1, 1)
    pc = ax.pcolormesh(speed_rpm, depth_m * 1e3, p_stable.T, cmap="RdYlGn", vmin=0, vmax=1, shading="auto")
    fig.colorbar(pc, ax=ax, label="P(stable)")
    ax.contour(speed_rpm, depth_m * 1e3, p_stable.T, levels=[level], colors="k", linewidths=1)
    if recommended:
        ax.plot(recommended["spindle_speed_rpm"], recommended["depth_m"] * 1e3, "w*", ms=14, mec="k",
                label="recommended")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth of cut (mm)")
    ax.set_title(f"probability of stable cutting; black line: P(stable) = {level:g}", fontsize=9)
    finish(fig)
    return figure_data_uri(fig)
