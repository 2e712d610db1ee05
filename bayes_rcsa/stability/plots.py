"""The lobe diagram figure: P(stable) map, quantile lobes, recommended point, alternatives, tests."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_lobes"]


def plot_lobes(path, res, tests=None, title: str = "", max_depth: float | None = None) -> None:
    """Write the lobe diagram of a :class:`~bayes_rcsa.stability.probabilistic.ProbabilisticLobes` as PNG.

    Marks: the robust recommended point (gold star) with its checked neighbourhood (speed window x
    depth margin, dashed box), the point-wise optimum (open diamond), the best point of each of the
    largest stable pockets (numbered triangles), a user depth limit (dotted line) and the cutting tests
    (circles stable, crosses chatter).

    Parameters
    ----------
    path : output path (written atomically)
    res : ProbabilisticLobes
    tests : (speed (n,), depth (n,), stable (n,)) or None
    title : str
    max_depth : float or None, m
    """
    from ..io.figures import new_figure, save_png

    n = res.speed_rpm
    a_mm = res.depth_m * 1e3
    q = res.quantiles
    deterministic = res.depth_limit_m.shape[0] == 1
    fig = new_figure(9, 5.5)
    ax = fig.add_subplot(1, 1, 1)
    mesh = ax.pcolormesh(n, a_mm, res.p_stable.T, shading="nearest", cmap="RdYlGn", vmin=0, vmax=1, alpha=0.75)
    fig.colorbar(mesh, ax=ax, label="P(stable)")
    top = a_mm[-1]
    levels = [v for v in (0.05, 0.5, 0.95) if res.p_stable.min() < v < res.p_stable.max()]
    if not deterministic and levels:
        cs = ax.contour(n, a_mm, res.p_stable.T, levels=levels, colors="k", linewidths=0.8)
        ax.clabel(cs, fmt={v: f"P={v:g}" for v in levels}, fontsize=7)
    for key, style in ((0.5, "-"), (0.05, "--"), (0.95, ":")):
        y = np.where(np.isfinite(q[key]), q[key] * 1e3, np.nan)
        ax.plot(n, np.minimum(y, top * 1.05), style, color="navy", lw=1.2,
                label=("lobe" if deterministic else f"a_lim q{int(key * 100):02d}"))
        if deterministic:
            break
    if not deterministic:
        lo = np.where(np.isfinite(q[0.05]), q[0.05] * 1e3, np.nan)
        hi = np.where(np.isfinite(q[0.95]), q[0.95] * 1e3, np.nan)
        ax.fill_between(n, np.minimum(lo, top), np.minimum(hi, top), color="navy", alpha=0.15, label="5-95 % band")
    if max_depth is not None and max_depth * 1e3 < top:
        ax.axhline(max_depth * 1e3, color="k", ls=":", lw=1.0, label="--max-depth")
    for k, alt in enumerate(res.alternatives, start=1):
        ax.plot(alt["spindle_speed_rpm"], alt["depth_m"] * 1e3, "^", ms=8, color="deepskyblue", mec="k",
                label="best point per pocket" if k == 1 else None)
        ax.annotate(str(k), (alt["spindle_speed_rpm"], alt["depth_m"] * 1e3), textcoords="offset points",
                    xytext=(5, -10), fontsize=8)
    if res.pointwise is not None:
        ax.plot(res.pointwise.spindle_speed_rpm, res.pointwise.depth_m * 1e3, "D", ms=7, mfc="none", mec="k",
                label="point-wise optimum (no tolerance)")
    rec = res.recommended
    if rec is not None:
        lo_n, hi_n = rec.speed_window_rpm
        ax.plot([lo_n, hi_n, hi_n, lo_n, lo_n], np.array([0, 0, 1, 1, 0]) * rec.depth_checked_m * 1e3, "--",
                color="k", lw=0.9, label="checked neighbourhood")
        ax.plot(rec.spindle_speed_rpm, rec.depth_m * 1e3, "*", ms=15, color="gold", mec="k", label="recommended")
    if tests is not None:
        s, d, st = tests
        ax.plot(s[st], d[st] * 1e3, "o", mfc="none", mec="darkgreen", ms=7, label="test: stable")
        ax.plot(s[~st], d[~st] * 1e3, "x", color="darkred", ms=7, label="test: chatter")
    ax.set_xlim(n[0], n[-1])
    ax.set_ylim(0, top)
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth of cut (mm)")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    save_png(fig, path)
