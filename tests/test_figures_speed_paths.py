"""The cheaper drawing paths of bayes_rcsa.io.figures give the figures of the plain matplotlib calls.

``finish`` lays a figure out with every axes' tight box and every axis' ticks measured once per pass, and
``write_png`` draws with the ticks computed once per pass; both must place and paint exactly what
``fig.tight_layout`` and ``fig.savefig`` do, and leave no memo behind on the figure.
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from bayes_rcsa.io import figures as F


def _figure(log: bool = True, title: bool = True):
    """Two panels (log and linear |H|) with titles, a legend, a suptitle and annotations; small, to stay cheap."""
    fig = F.new_figure(6.0, 3.0)
    axes = fig.subplots(1, 2)
    f = np.linspace(300.0, 3000.0, 50)
    for k, ax in enumerate(axes.ravel()):
        y = 1e-7 / np.abs(1 - (f / (900.0 + 100 * k)) ** 2 + 0.06j * f / 900.0)
        (ax.semilogy if log and k % 2 == 0 else ax.plot)(f, y, label="median")
        ax.annotate(str(k), (1000.0, 1.0), xycoords=("data", "axes fraction"), textcoords="offset points",
                    xytext=(2, -3), va="top")
        if title:
            ax.set_title(f"panel {k}: a title long enough to need room", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("|H| (m/N)")
    axes[0].legend(loc="best")
    fig.suptitle("four panels", y=0.99, va="top")
    return fig


def _pixels(fig, **kwargs) -> np.ndarray:
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", **kwargs)
    buf.seek(0)
    return np.asarray(Image.open(buf).convert("RGBA"))


@pytest.mark.parametrize("rect, log", [((0.0, 0.05, 1.0, 0.9), True), (None, False)])
def test_layout_with_boxes_measured_once_is_tight_layout(rect, log):
    ref, fast = _figure(log), _figure(log)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        ref.tight_layout(**({} if rect is None else {"rect": rect}))
    F._layout(fast, rect)
    for a, b in zip(ref.axes, fast.axes):
        assert np.array_equal(a.get_position().get_points(), b.get_position().get_points())
        assert a.title.get_position() == b.title.get_position()
    # nothing of the memo stays on the figure: the classes' own methods answer again
    for ax in fast.axes:
        assert "get_tightbbox" not in vars(ax)
        assert "_update_ticks" not in vars(ax.xaxis) and "_update_ticks" not in vars(ax.yaxis)


def test_write_png_paints_what_savefig_paints():
    """At the figure's dpi (the PNG files) and at another (the report's data URIs), with the text chunks."""
    from PIL import Image

    fig = F.finish(_figure())
    for dpi in (None, 75):
        ref = _pixels(fig, **({} if dpi is None else {"dpi": dpi}))
        buf = io.BytesIO()
        F.write_png(fig, buf, dpi=dpi, metadata={"k": "v"})
        buf.seek(0)
        with Image.open(buf) as im:
            assert im.text["k"] == "v"
            assert np.array_equal(np.asarray(im.convert("RGBA")), ref)
    assert all("_update_ticks" not in vars(ax.yaxis) for ax in fig.axes)


def test_tick_memo_follows_the_view_and_the_dpi():
    """Within one block the ticks are computed again when the limits or the pixel size change."""
    fig = _figure(log=False)
    ax = fig.axes[1]  # the linear one
    with F._ticks_once(fig):
        first = [t.get_loc() for t in ax.xaxis._update_ticks()]
        assert [t.get_loc() for t in ax.xaxis._update_ticks()] == first
        ax.set_xlim(1000.0, 1200.0)
        moved = [t.get_loc() for t in ax.xaxis._update_ticks()]
        fig.set_dpi(50)
        coarse = [t.get_loc() for t in ax.xaxis._update_ticks()]
    fig.set_dpi(100)
    assert moved != first and min(moved) >= 1000.0 and max(moved) <= 1200.0
    with F._ticks_once(fig):
        fig.set_dpi(50)
        assert [t.get_loc() for t in ax.xaxis._update_ticks()] == coarse
    fig.set_dpi(100)
    assert [t.get_loc() for t in ax.xaxis._update_ticks()] == moved
    with F._ticks_once(fig):  # nested blocks: the inner one hands the outer one's memo back
        outer = vars(ax.xaxis)["_update_ticks"]
        with F._ticks_once(fig):
            assert vars(ax.xaxis)["_update_ticks"] is not outer
        assert vars(ax.xaxis)["_update_ticks"] is outer
    assert "_update_ticks" not in vars(ax.xaxis)


def _boxes(fig, renderer) -> list:
    out = []
    for ax in fig.axes:
        out.append(tuple(ax.get_position().bounds))
        for t in (ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts):
            out.append(tuple(t.get_window_extent(renderer).bounds))
        for axis in (ax.xaxis, ax.yaxis):
            out += [tuple(tk.label1.get_window_extent(renderer).bounds) for tk in axis._update_ticks()]
    return out


def test_texts_placed_without_a_draw_are_where_a_draw_puts_them():
    """finish's annotation pass places titles, labels, ticks and aspect-bound axes as draw_without_rendering does
    (a log panel with a title, an equal-aspect panel and a colorbar, whose axes has a locator)."""
    figs = []
    for _ in range(2):
        fig = _figure()
        ax = fig.axes[1]
        ax.set_aspect("equal")
        ax.set_xlim(1000.0, 1400.0)
        ax.set_ylim(0.0, 100.0)
        fig.colorbar(ax.scatter([1100.0, 1200.0], [20.0, 40.0], c=[0.0, 1.0]), ax=ax, label="c")
        F._layout(fig, None)
        figs.append(fig)
    figs[0].draw_without_rendering()
    renderer = F._place_texts(figs[1])
    assert _boxes(figs[1], renderer) == _boxes(figs[0], figs[0].canvas.get_renderer())


@pytest.mark.parametrize("lims", [(3.6e-9, 3.6e-6), (2e-3, 7e-3), (1e-12, 1e3), (0.5, 1.0)])
def test_in_view_log_locator_keeps_every_tick_the_axis_draws(lims):
    from matplotlib.ticker import LogLocator

    from bayes_rcsa.io._log_ticks import in_view

    fig = F.new_figure(4.0, 3.0)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_yscale("log")
    ax.set_ylim(*lims)
    lo, hi = np.log10(lims)
    tol = 1e-10 * (hi - lo)
    for subs in ((1.0,), "auto"):
        plain = LogLocator(10.0, subs)
        plain.set_axis(ax.yaxis)
        trimmed = in_view(plain)
        trimmed.set_axis(ax.yaxis)
        ref = plain()
        drawn = ref[(np.log10(ref) >= lo - tol) & (np.log10(ref) <= hi + tol)]
        assert np.array_equal(trimmed(), drawn)


def test_finished_log_panels_paint_as_with_the_plain_log_locators():
    """finish swaps a log axis' LogLocator for the in-view one: same pixels."""
    from matplotlib.ticker import LogLocator

    fast = F.finish(_figure(title=False))
    ref = F.finish(_figure(title=False))
    for ax in ref.axes:
        if ax.get_yscale() == "log":
            assert type(ax.yaxis.get_minor_locator()) is not LogLocator
            ax.yaxis.set_major_locator(LogLocator(10.0))
            ax.yaxis.set_minor_locator(LogLocator(10.0, "auto"))
    assert np.array_equal(_pixels(fast), _pixels(ref))
