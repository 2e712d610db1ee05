"""Matplotlib figures without pyplot state, one legible style, saved atomically as PNG.

Every figure of the package is made by :func:`new_figure` and finished by :func:`finish` (which replaces
``fig.tight_layout()``), so that all of them follow the same rules at the size they are saved and shown:

* no text smaller than :data:`MIN_FONT_PT` points (8 pt at the saved size: the PNGs are written at 100 dpi and
  shown at or near their natural size in the HTML reports, where 8 pt is about 11 px, the smallest size that
  stays legible on a laptop screen);
* tick labels all :data:`TICK_FONT_PT` points, on every axis of the figure;
* plain tick labels on linear axes: no offset or multiplier text beside an axis (``2.94166×10⁻¹`` and
  ``+2.9e-1``), every tick label reads as the number it marks;
* no text outside the canvas and no two texts on top of each other: the layout is recomputed after the sizes are
  raised, then annotations that collide with an earlier text are moved down (and kept inside their axes).
"""

from __future__ import annotations

import math
import warnings
from contextlib import contextmanager
from pathlib import Path

from .atomic import atomic_path

__all__ = ["new_figure", "finish", "save_png", "write_png", "plain_formatter", "lower_triangle", "MIN_FONT_PT",
           "TICK_FONT_PT", "PNG_COMPRESS_LEVEL"]

#: Smallest font size (points at the saved size) of any text in a figure.
MIN_FONT_PT = 8.0
#: The one size of every tick label.
TICK_FONT_PT = 8.0
#: zlib level of the PNG files: the package's figures (flat colours, text) pack ~5 % larger at 3 than at the
#: default 6, in two thirds of the time.
PNG_COMPRESS_LEVEL = 3


def new_figure(width: float, height: float):
    """A Figure on its own Agg canvas (no global pyplot state), size in inches at 100 dpi."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def lower_triangle(axes):
    """``(i, j, ax)`` of the panels on and below the diagonal of a square grid of axes (a corner plot); the
    panels above it are hidden."""
    p = len(axes)
    for i in range(p):
        for j in range(p):
            if j > i:
                axes[i][j].set_visible(False)
            else:
                yield i, j, axes[i][j]


def plain_formatter():
    """A tick formatter for linear axes that writes each tick as its own number (no offset, no multiplier).

    Ticks between 1e-3 and 1e6 in magnitude get the fewest decimals that tell the ticks apart (``0.2942``,
    ``0.2944``); smaller or larger magnitudes get the fewest significant digits in ``1.5e-06`` form.
    """
    return _plain_formatter_class()()


def _plain_formatter_class():
    """The formatter's class, built on first use (matplotlib is imported only by the figures that need it) and
    kept as the module attribute ``PlainFormatter``, so that a finished figure pickles and unpickles (the module's
    ``__getattr__`` builds it in a fresh process)."""
    cls = globals().get("PlainFormatter")
    if cls is not None:
        return cls
    from matplotlib.ticker import Formatter

    class PlainFormatter(Formatter):
        plain = True  # marks the formatters :func:`finish` may thin out

        def __init__(self):
            self.fmt = "{:g}"
            self._ticks = []

        def set_locs(self, locs):
            self._ticks = [float(v) for v in locs if math.isfinite(v)]
            self.fmt = _choose_format(self._ticks)

        def __call__(self, x, pos=None):
            if x == 0 or abs(x) < 1e-12 * max((abs(v) for v in self._ticks), default=1.0):
                return "0"
            return self.fmt.format(x).replace("-", "\u2212")

    PlainFormatter.__qualname__ = "PlainFormatter"
    PlainFormatter.__module__ = __name__
    globals()["PlainFormatter"] = PlainFormatter
    return PlainFormatter


def __getattr__(name: str):
    if name == "PlainFormatter":
        return _plain_formatter_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _choose_format(locs) -> str:
    """The shortest format that writes every tick in ``locs`` distinctly and within 1 % of a tick step."""
    if not locs:
        return "{:g}"
    big = max(abs(v) for v in locs)
    steps = [abs(b - a) for a, b in zip(locs, locs[1:]) if b != a]
    step = min(steps) if steps else (big or 1.0)
    if big == 0 or 1e-3 <= big < 1e6:
        for d in range(0, 10):
            if all(abs(round(v, d) - v) <= 0.01 * step for v in locs):
                return "{:." + str(d) + "f}"
        return "{:.10f}"
    for s in range(1, 10):
        texts = ["{:.{}e}".format(v, s - 1) for v in locs]
        if all(abs(float(t) - v) <= 0.01 * step for t, v in zip(texts, locs)):
            return "{:." + str(s - 1) + "e}"
    return "{:.9e}"


def _texts(fig):
    """Every text of the figure but the tick labels (titles, axis labels, annotations, legends, colorbar labels).

    Listed directly: ``fig.findobj(Text)`` walks every tick's lines too and took most of the time of a corner plot.
    """
    out = []
    for ax in fig.axes:
        out += [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label, *ax.texts]
        leg = ax.get_legend()
        if leg is not None:
            out += [*leg.get_texts(), leg.get_title()]
    containers = [fig]
    while containers:
        c = containers.pop()
        containers += list(getattr(c, "subfigs", []))
        out += list(c.texts)
        out += [t for t in (getattr(c, "_suptitle", None), getattr(c, "_supxlabel", None),
                            getattr(c, "_supylabel", None)) if t is not None]
        for leg in c.legends:
            out += [*leg.get_texts(), leg.get_title()]
    return out


def _plain_axes(ax) -> None:
    from matplotlib.ticker import ScalarFormatter

    for axis in (ax.xaxis, ax.yaxis):
        scale = axis.get_scale()
        # symlog axes (errors around zero) get plain numbers too: '-0.1', not '-10⁻¹'; log axes keep 10⁻⁶
        if (scale == "linear" and isinstance(axis.get_major_formatter(), ScalarFormatter)) or scale == "symlog":
            axis.set_major_formatter(plain_formatter())


@contextmanager
def _tightbbox_once(fig):
    """Within the block, each axes' ``get_tightbbox`` computes its box once and returns it again when asked again.

    ``tight_layout(rect=...)`` measures every axes twice with nothing moved in between (its second pass only
    fits the margins into ``rect``), and one measurement is most of a figure's layout time (every tick label
    of every axis laid out, several times over).  The memo lives on the axes only for the block (one layout
    of one figure, one renderer), so it cannot outlive the state it measured.
    """
    with _patched(fig.axes, "get_tightbbox", _memo_tightbbox), _ticks_once(fig):
        yield


@contextmanager
def _ticks_once(fig):
    """Within the block, each axis places and labels its ticks once per view interval, axes box and dpi.

    One draw or layout pass of matplotlib asks an axis for its ticks four or five times (its own box, its label's
    place, the title's place, the spines), each time running the locator and the formatter over every tick and
    moving every tick again, with nothing changed in between.  The memo is keyed by what the ticks depend on
    within a pass (view limits, the axes' place in pixels, the dpi) and lives on the axis only for the block.
    """
    axes = [axis for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)]
    with _patched(axes, "_update_ticks", _memo_ticks):
        yield


@contextmanager
def _patched(objects, name: str, memo):
    """Within the block, ``obj.name`` of every object is ``memo(obj, obj.name)`` (an instance attribute); after
    it, whatever was there before (the class' method, or an enclosing block's memo)."""
    before = []
    try:
        for obj in objects:
            before.append((obj, vars(obj).get(name)))
            setattr(obj, name, memo(obj, getattr(obj, name)))
        yield
    finally:
        for obj, old in before:
            if old is None:
                vars(obj).pop(name, None)
            else:
                setattr(obj, name, old)


def _memo_ticks(axis, update):
    last = {}

    def _update_ticks():
        key = (tuple(axis.get_view_interval()), axis.axes.bbox.bounds, axis.axes.figure.dpi)
        if last.get("key") != key:
            last["ticks"] = update()
            last["key"] = key
        return list(last["ticks"])

    return _update_ticks


def _memo_tightbbox(ax, measure):
    boxes = {}

    def get_tightbbox(renderer=None, *args, **kwargs):
        key = (id(renderer), args, tuple(sorted(kwargs.items())))
        try:
            hash(key)
        except TypeError:  # a list of extra artists: not what tight_layout asks, measured every time
            return measure(renderer, *args, **kwargs)
        if key not in boxes:
            boxes[key] = (renderer, measure(renderer, *args, **kwargs))  # the renderer kept: its id stays unique
        return boxes[key][1]

    return get_tightbbox


def _trim_log_ticks(ax) -> None:
    """Log axes make only the ticks inside the view (:class:`~bayes_rcsa.io._log_ticks.InViewLogLocator`)."""
    from matplotlib.ticker import LogLocator

    from ._log_ticks import in_view

    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() != "log":
            continue
        defaults = (axis.isDefault_majloc, axis.isDefault_minloc)
        if type(axis.get_major_locator()) is LogLocator:
            axis.set_major_locator(in_view(axis.get_major_locator()))
        if type(axis.get_minor_locator()) is LogLocator:
            axis.set_minor_locator(in_view(axis.get_minor_locator()))
        axis.isDefault_majloc, axis.isDefault_minloc = defaults  # still the scale's own (a new scale replaces them)


def _layout(fig, rect) -> None:
    with warnings.catch_warnings(), _tightbbox_once(fig):
        # "not compatible with tight_layout" for colorbars/subfigures: the layout is still the best available
        warnings.simplefilter("ignore", UserWarning)
        if rect is None:
            fig.tight_layout()
        else:
            fig.tight_layout(rect=rect)


def _overlaps(a, b, tol: float = 0.5) -> bool:
    return (min(a.x1, b.x1) - max(a.x0, b.x0) > tol) and (min(a.y1, b.y1) - max(a.y0, b.y0) > tol)


def _fixed_boxes(fig, renderer, moving) -> list:
    """Bounding boxes (display pixels) of the texts that stay where they are: all but ``moving``."""
    ids = {id(t) for t in moving}
    boxes = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for t in (ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label):
            if t.get_visible() and t.get_text().strip():
                boxes.append(t.get_window_extent(renderer))
        for axis in (ax.xaxis, ax.yaxis):
            for tick in axis._update_ticks():
                for lab in (tick.label1, tick.label2):
                    if lab.get_visible() and lab.get_text().strip():
                        boxes.append(lab.get_window_extent(renderer))
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            boxes.append(leg.get_window_extent(renderer))
        for t in ax.texts:
            if id(t) not in ids and t.get_visible() and t.get_text().strip():
                boxes.append(t.get_window_extent(renderer))
    return boxes


def _shift(text, dx: float, dy: float) -> None:
    """Move ``text`` by (dx, dy) display pixels, whatever coordinates it was placed in."""
    from matplotlib.text import Annotation

    if isinstance(text, Annotation) and text.anncoords in ("offset points", "offset pixels"):
        k = 72.0 / text.figure.dpi if text.anncoords == "offset points" else 1.0
        x, y = text.xyann
        text.xyann = (x + dx * k, y + dy * k)
        return
    tr = text.get_transform()
    x, y = tr.transform(text.get_position())
    text.set_position(tr.inverted().transform((x + dx, y + dy)))


def _thin_ticks(fig) -> bool:
    """Halve the ticks of plain linear axes whose labels touch (long plain numbers); True if any changed."""
    from matplotlib.ticker import MaxNLocator

    renderer = fig.canvas.get_renderer()
    changed = False
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() != "linear" or not getattr(axis.get_major_formatter(), "plain", False):
                continue
            labels = [t.label1 for t in axis._update_ticks() if t.label1.get_visible() and t.label1.get_text()]
            boxes = [lab.get_window_extent(renderer) for lab in labels]
            if any(_overlaps(a, b, tol=-3.0) for a, b in zip(boxes, boxes[1:])):
                axis.set_major_locator(MaxNLocator(nbins=max(1, len(labels) // 2), steps=[1, 2, 2.5, 5, 10]))
                changed = True
    return changed


def _place_texts(fig):
    """Put the axes, their titles, axis labels and tick labels where a draw puts them; returns the renderer.

    What ``fig.draw_without_rendering()`` does to those texts (the same calls, axes by axes in drawing order)
    without walking every line, patch and collection of the figure.  Figures whose axes depend on each other
    at drawing time (subfigures, twinned or child axes) get the whole draw.
    """
    axes = [ax for ax in fig.axes if ax.get_visible()]
    if fig.subfigs or any(ax.child_axes or len(ax._twinned_axes.get_siblings(ax)) > 1 for ax in axes):
        fig.draw_without_rendering()
        return fig.canvas.get_renderer()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:  # the figure applies every aspect before it draws the first axes
        locator = ax.get_axes_locator()
        ax.apply_aspect(locator(ax, renderer) if locator else None)
    for ax in sorted(axes, key=lambda a: a.get_zorder()):
        ax.viewLim  # noqa: B018 -- the property applies pending autoscaling, as the draw does first
        locator = ax.get_axes_locator()
        ax.apply_aspect(locator(ax, renderer) if locator else None)
        ax._update_title_position(renderer)
        if ax.axison:
            for axis in (ax.xaxis, ax.yaxis):
                if axis.get_visible():
                    axis._update_ticks()
                    axis._update_label_position(renderer)
    return renderer


def _separate(fig) -> None:
    """Move the axes' annotations off every earlier text, and back inside their axes (display pixels)."""
    moving = [t for ax in fig.axes if ax.get_visible() for t in ax.texts if t.get_visible() and t.get_text().strip()]
    if not moving:
        return
    with _ticks_once(fig):  # moving annotations changes no tick
        renderer = _place_texts(fig)
        placed = _fixed_boxes(fig, renderer, moving)
    for t in moving:
        inside = t.axes.get_window_extent(renderer)
        for _ in range(40):
            box = t.get_window_extent(renderer)
            dx = dy = 0.0
            if box.x1 > inside.x1:
                dx = inside.x1 - box.x1 - 1
            elif box.x0 < inside.x0:
                dx = inside.x0 - box.x0 + 1
            if box.y1 > inside.y1:
                dy = inside.y1 - box.y1 - 1
            elif box.y0 < inside.y0:
                dy = inside.y0 - box.y0 + 1
            hit = next((b for b in placed if _overlaps(box, b)), None)
            if hit is not None and not dy:
                dy = hit.y0 - box.y1 - 1  # below what it collides with
                if box.y0 + dy < inside.y0:  # no room below: beside it instead
                    dy, dx = 0.0, hit.x1 - box.x0 + 1
            if not dx and not dy:
                break
            _shift(t, dx, dy)
        placed.append(t.get_window_extent(renderer))


def finish(fig, rect=None, layout: bool = True):
    """Apply the package's figure rules to ``fig`` (in place) and lay it out; returns ``fig``.

    Raises every text to :data:`MIN_FONT_PT`, sets every tick label to :data:`TICK_FONT_PT`, writes linear
    axes' ticks plainly (:func:`plain_formatter`), lays the figure out (``tight_layout`` within ``rect``, figure
    fractions ``(left, bottom, right, top)``) and moves colliding annotations apart.  Call it where a figure
    function used to call ``fig.tight_layout()``, after everything is drawn.  ``layout=False`` keeps a layout the
    caller made itself (subfigures, the ``corner`` package's grid).
    """
    for ax in fig.axes:
        _plain_axes(ax)
        _trim_log_ticks(ax)
        ax.tick_params(axis="both", which="both", labelsize=TICK_FONT_PT)
    for t in _texts(fig):
        if t.get_fontsize() < MIN_FONT_PT:
            t.set_fontsize(MIN_FONT_PT)
    if layout:
        _layout(fig, rect)
    for _ in range(3):
        if not _thin_ticks(fig):
            break
        if layout:
            _layout(fig, rect)
    _separate(fig)
    return fig


def save_png(fig, path) -> Path:
    """Write ``fig`` to ``path`` as PNG atomically; returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        write_png(fig, tmp)
    return path


def write_png(fig, target, dpi: float | None = None, metadata: dict | None = None) -> None:
    """Render ``fig`` as PNG into ``target`` (a path or a binary file object), as ``fig.savefig`` would.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    target : str, Path or binary file object
    dpi : float, optional
        Pixels per inch of the image; the figure's own (100) by default.
    metadata : dict of str, optional
        PNG text chunks (``fig.savefig``'s ``metadata``).

    Notes
    -----
    The pixels are those of ``fig.savefig``; the draw computes each axis' ticks once (not four or five times)
    and zlib packs the image at level :data:`PNG_COMPRESS_LEVEL`, not 6.
    """
    kwargs = {} if dpi is None else {"dpi": dpi}
    with _ticks_once(fig):
        fig.savefig(target, format="png", metadata=metadata, pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL},
                    **kwargs)
