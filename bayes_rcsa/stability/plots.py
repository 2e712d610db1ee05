"""The lobe diagram figure: P(stable) map, quantile lobes, robust envelope, recommended point, alternatives, tests.

Figures are drawn at display resolution: a speed grid finer than
:data:`MAX_COLUMNS` speeds (more than the axes have pixel columns) is reduced
in blocks of consecutive speeds before drawing -- P(stable) by the block
mean (an image, not one patch per cell), the depth-limit curves by the block
minimum (which keeps every lobe cusp, the conservative reading).  The JSON and
npz files keep every speed.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_lobes", "display_blocks", "display_map", "MAX_COLUMNS"]

MAX_COLUMNS = 1200


def display_blocks(n_speed: int, max_columns: int = MAX_COLUMNS) -> int:
    """Speeds per displayed column: 1 up to ``max_columns`` speeds, else ceil(n_speed / max_columns)."""
    return max(1, -(-int(n_speed) // int(max_columns)))


def display_map(speed_rpm, p_stable, max_columns: int = MAX_COLUMNS):
    """The P(stable) map as the figure shows it: block means over consecutive speeds.

    Parameters
    ----------
    speed_rpm : (n_speed,) rpm
    p_stable : (n_speed, n_depth)
    max_columns : int, most speed columns shown

    Returns
    -------
    speed_rpm : (n_columns,) rpm, the mean speed of each block
    p_stable : (n_columns, n_depth), the block mean of P(stable)
    block : int, speeds per column (:func:`display_blocks`)
    """
    block = display_blocks(np.size(speed_rpm), max_columns)
    return (_reduce(np.asarray(speed_rpm, dtype=float), block, "mean"), _reduce(np.asarray(p_stable, dtype=float),
                                                                                 block, "mean"), block)


def _reduce(a: np.ndarray, block: int, how: str) -> np.ndarray:
    """Block-reduce the first axis of ``a``: mean, or minimum ignoring NaN (the last block may be shorter)."""
    if block == 1:
        return a
    starts = np.arange(0, a.shape[0], block)
    if how == "mean":
        counts = np.diff(np.append(starts, a.shape[0])).reshape((-1,) + (1,) * (a.ndim - 1))
        return np.add.reduceat(a, starts, axis=0) / counts
    return np.fmin.reduceat(a, starts, axis=0)


def plot_lobes(path, res, tests=None, title: str = "", max_depth: float | None = None) -> None:
    """Write :func:`lobes_figure` of ``res`` to ``path`` as PNG (atomically)."""
    from ..io.figures import save_png

    save_png(lobes_figure(res, tests, title, max_depth), path)


def lobes_figure(res, tests=None, title: str = "", max_depth: float | None = None):
    """The lobe diagram of a :class:`~bayes_rcsa.stability.probabilistic.ProbabilisticLobes` as PNG.

    Marks: the robust recommended point (gold star) with its checked neighbourhood (speed window x
    depth margin, dashed box), the point-wise optimum (open diamond), the best point of each of the
    largest stable pockets (numbered triangles), a user depth limit (dotted line) and the cutting tests
    (circles stable, crosses chatter).

    Parameters
    ----------
    res : ProbabilisticLobes (or an object with its attributes: ``speed_rpm``, ``depth_m``, ``p_stable``,
        ``quantiles``, ``depth_limit_m``, ``envelope``, ``level``, ``alternatives``, ``pointwise``, ``recommended``)
    tests : (speed (n,), depth (n,), stable (n,)) or None
    title : str
    max_depth : float or None, m

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..io.figures import finish, new_figure

    n_full = res.speed_rpm
    n, p_map, block = display_map(n_full, res.p_stable)
    a_mm = res.depth_m * 1e3
    curve = {k: _reduce(np.where(np.isfinite(v), v * 1e3, np.nan), block, "min") for k, v in res.quantiles.items()}
    deterministic = res.depth_limit_m.shape[0] == 1
    fig = new_figure(9, 6.5)
    ax = fig.add_subplot(1, 1, 1)
    step = np.diff(n)
    if n.size > 1 and np.allclose(step, step[0], rtol=1e-6) and np.allclose(np.diff(a_mm), a_mm[1] - a_mm[0], rtol=1e-6):
        dn, da = step[0] / 2, (a_mm[1] - a_mm[0]) / 2 if a_mm.size > 1 else a_mm[0] / 2
        mesh = ax.imshow(p_map.T, origin="lower", aspect="auto", interpolation="nearest", cmap="RdYlGn", vmin=0,
                         vmax=1, alpha=0.75, extent=(n[0] - dn, n[-1] + dn, a_mm[0] - da, a_mm[-1] + da))
    else:
        mesh = ax.pcolormesh(n, a_mm, p_map.T, shading="nearest", cmap="RdYlGn", vmin=0, vmax=1, alpha=0.75,
                             rasterized=True)
    fig.colorbar(mesh, ax=ax, label="P(stable)")
    top = a_mm[-1]
    levels = [v for v in (0.05, 0.5, 0.95) if p_map.min() < v < p_map.max()]
    if not deterministic and levels:
        # one line style per level, named in the key: labels written on the contours sat on top of each other and
        # of the lobes where the levels run close together (a narrow posterior)
        styles = {0.05: ":", 0.5: "-", 0.95: "-."}
        ax.contour(n, a_mm, p_map.T, levels=levels, colors="k", linewidths=0.8, linestyles=[styles[v] for v in levels])
        for v in levels:
            ax.plot([], [], styles[v], color="k", lw=0.8, label=f"P(stable) = {v:g}")
    ax.plot(n, np.minimum(curve[0.5], top * 1.05), "-", color="navy", lw=1.4,
            label="lobe" if deterministic else "median boundary (q50)")
    if not deterministic:
        ax.fill_between(n, np.minimum(curve[0.05], top), np.minimum(curve[0.95], top), color="navy", alpha=0.15,
                        label="5-95 % band")
        if res.envelope is not None:
            env = _reduce(np.where(np.isfinite(res.envelope), res.envelope * 1e3, np.nan), block, "min")
            ax.plot(n, np.minimum(env, top * 1.05), "--", color="crimson", lw=1.3,
                    label=f"robust envelope, P(stable) >= {res.level:g}")
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
    ax.set_xlim(n_full[0], n_full[-1])
    ax.set_ylim(0, top)
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth of cut (mm)")
    ax.set_title(title)
    # the key under the chart: inside, it hid the tests and pockets in the deep part of the map
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, frameon=False)
    finish(fig)
    return fig
