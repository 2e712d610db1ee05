"""Every figure the package draws is legible at the size it is saved (#45 item 5).

Each figure type is drawn from small synthetic inputs (no MCMC: the figure functions are called directly) and
the rendered figure is inspected: every text at least ``MIN_FONT_PT``, tick labels one size, no offset or
multiplier text beside an axis, no text outside the canvas, no two texts on top of each other, and no
annotation on top of the plotted data points.  ``test_every_figure_builder_is_covered`` finds every function of
the package that makes a figure (a call of ``new_figure``) and fails when one has no renderer here.
"""

from __future__ import annotations

import ast
import types
from collections import namedtuple
from pathlib import Path

import numpy as np
import pytest

import bayes_rcsa
from bayes_rcsa.io.figures import MIN_FONT_PT, TICK_FONT_PT

NS = types.SimpleNamespace
PACKAGE = Path(bayes_rcsa.__file__).parent


# -- synthetic inputs ------------------------------------------------------------------------------------------


def _sdof(f, fn, k=2e7, zeta=0.03):
    r = f / fn
    return 1.0 / (k * (1 - r ** 2 + 2j * zeta * r))


Config = namedtuple("Config", "tool direction clamping_length")


def _configs():
    return [Config("T1", "x", 0.025), Config("T1", "y", 0.040)]


def _bands_and_modes():
    from bayes_rcsa.io.frf import FRF

    f = np.linspace(300.0, 3000.0, 300)
    bands, modes = [], []
    for i, c in enumerate(_configs()):
        fns = (1020.0 + 40 * i, 1090.0 + 40 * i, 2400.0)  # two close modes: their labels would collide
        h = sum(_sdof(f, fn, k=2e7 * (1 + j)) for j, fn in enumerate(fns))
        mag = np.abs(h) * np.array([0.8, 0.9, 1.0, 1.1, 1.2])[:, None]
        bands.append(NS(configuration=c, frequency_hz=f, magnitude=mag, real=mag, imag=mag,
                        measured=FRF(f, h * (1 + 0.02 * np.sin(f)))))
        for j, fn in enumerate(fns):
            nf = {"q05": fn - 3.2, "q25": fn - 1.5, "q50": fn, "q75": fn + 1.5, "q95": fn + 3.1}
            modes.append(NS(configuration=c, mode=j + 1, dominant=j == 0, natural_frequency_hz=nf,
                            has_measurement=True, measured_hz=fn + 0.7, fitted=i == 0))
    return bands, modes


def _posterior_plots():
    from bayes_rcsa.posterior import plots as P

    bands, modes = _bands_and_modes()
    # three rows: the title and the key on top must keep their height in inches, not in figure fractions
    yield "frf_band_plot", P.frf_band_plot(bands * 3, modes, None, title="predicted tool-point FRF")["figure"]
    yield "frf_zoom_plot", P.frf_zoom_plot(bands, modes, None)["figure"]
    yield "natural_frequency_plot", P.natural_frequency_plot(modes, None)["figure"]
    rng = np.random.default_rng(0)
    groups = [{"title": f"{d} direction", "datasets": {"single": rng.normal(size=(400, 3)) * [1, 2, 0.3] + 7,
                                                      "multi": rng.normal(size=(400, 3)) * 0.5 + 7}}
              for d in ("x", "y")]
    yield "corner_overlay_figure", P.corner_overlay_figure(groups, ["k_xf", "k_thetaM", "sigma_0"],
                                                           fit_order=["single", "multi"])[0]
    q = lambda m, s: {"q05": m - 2 * s, "q25": m - s, "q50": m, "q75": m + s, "q95": m + 2 * s}  # noqa: E731
    panels = [{"title": "natural frequency error", "xlabel": "error (%)",
               "rows": [{"label": f"{cl} mm {d}", "fits": {"single": q(0.3, 0.2), "multi": q(-0.1, 0.1)},
                         "reference": 0.0} for cl in (25, 30, 35, 40) for d in "xy"]},
              {"title": "contact stiffness", "xlabel": "k (N/m)",
               "rows": [{"label": f"{cl} mm", "fits": {"single": q(2.94166e-1, 1e-5), "multi": q(2.94170e-1, 2e-5)},
                         "reference": None} for cl in (25, 30)]}]
    yield "forest_figure", P.forest_figure(panels, ["single", "multi"], title="identifiability")[0]


def _inference_plots():
    from bayes_rcsa.inference import plots as I
    from bayes_rcsa.inference.sbc_plots import sbc_figure

    rng = np.random.default_rng(1)
    chain = np.cumsum(rng.normal(size=(300, 8, 3)), axis=0) * 1e-3 + 0.294166  # values with a large offset
    yield "trace_figure", I.trace_figure(chain, ["k_xf", "k_thetaM", "sigma_0"], burn=100)
    yield "corner_figure", I.corner_figure(rng.normal(size=(500, 3)) * [1e-4, 1, 2] + [0.2941, 7, 3],
                                           ["k_xf", "k_thetaM", "sigma_0"])
    f = np.linspace(500, 2000, 300)
    h = _sdof(f, 1100.0)
    panels = [{"title": f"x {cl} mm", "frequency_hz": f, "measured": h, "q05": 0.9 * np.abs(h),
               "q50": np.abs(h), "q95": 1.1 * np.abs(h)} for cl in (25, 30, 35)]
    yield "frf_figure", I.frf_figure(panels)
    ranks = rng.integers(0, 20, size=(40, 2))
    yield "sbc_figure", sbc_figure(ranks, 19, ["k_xf", "k_thetaM"], rng, p_values=[0.5, 0.01], n_bins=10,
                                   title="simulation-based calibration")


def _evaluation():
    f = np.linspace(500, 2000, 200)
    ms, frf = [], {"frequency_hz": [], "measured": [], "predicted": []}
    for cl in (0.025, 0.030, 0.035, 0.040):
        for d in "xy"[: 1 + (cl == 0.040)]:
            fm = 1100.0 - 4000 * (cl - 0.025)
            ms.append({"direction": d, "clamping_length": cl, "fitted": cl != 0.035,
                       "modes": [{"model_interval": {"q05": fm * (1 + s - 0.004), "q95": fm * (1 + s + 0.004)},
                                  "measured_hz": fm, "error_pct": 100 * s} for s in (0.002, -0.03)]})
            frf["frequency_hz"].append(f)
            frf["measured"].append(_sdof(f, fm))
            frf["predicted"].append(_sdof(f, fm * 1.01))
    stiff = {"k_xf": {str(L): {"q05": 2.9e7, "q50": 3e7, "q95": 3.1e7} for L in (25, 30, 35, 40)},
             "k_thetaM": {str(L): {"q05": 2.9e5, "q50": 3e5, "q95": 3.1e5} for L in (25, 30, 35, 40)}}
    side = {"measurements": ms, "stiffness": stiff, "frf": frf}
    return {"before": side, "after": side}


def _discrepancy_plots():
    from bayes_rcsa.discrepancy.plots import plot_figures

    figs = plot_figures(_evaluation(), "stiffness_step")
    yield "_frf_plot", figs["frf_before_after"]
    yield "_panels", figs["frf_before_after"]
    yield "_residual_plot", figs["residuals_before_after"]
    yield "_frequency_plot", figs["frequency_errors"]
    yield "_stiffness_plot", figs["stiffness_before_after"]


def _design_plots():
    from bayes_rcsa.design.outputs import design_figure

    prior = {"mode": "prior", "unit": "Hz", "current_width": 80.0,
             "candidates": [{"clamping_lengths": [a, b], "expected_width": 40 - 100 * (b - a), "mc_error": 1.0}
                            for a in (0.025, 0.030) for b in (0.035, 0.040)]}
    yield "design_figure", design_figure(prior)
    post = {"mode": "posterior", "unit": "Hz", "current_width": 30.0, "target": "natural frequency at 32 mm",
            "target_clamping_length": 0.032,
            "candidates": [{"direction": d, "tool": "T1", "clamping_length": cl, "expected_width": 20 - 100 * cl,
                            "width_range_90": [15 - 100 * cl, 25 - 100 * cl], "mc_error": 0.5}
                           for d in "xy" for cl in (0.025, 0.030, 0.035, 0.040)]}
    yield "design_figure", design_figure(post)


def _library_plots():
    from bayes_rcsa.library.outputs import shrinkage_figure

    setups = [{"name": f"setup_{i}", "holder_type": t, "diameter_m": d, "outlier": i == 2,
               "k_xf_own": [7.1, 7.3, 7.5], "k_xf_pooled": [7.2, 7.3, 7.4],
               "k_thetaM_own": [5.0, 5.2, 5.4], "k_thetaM_pooled": [5.1, 5.2, 5.3]}
              for i, (t, d) in enumerate([("ER32", 0.012), ("ER32", 0.016), ("shrink-fit", 0.016),
                                          ("shrink-fit", 0.020)])]
    yield "shrinkage_figure", shrinkage_figure(["k_xf", "k_thetaM"], setups)


def _lobes():
    n = np.linspace(5000, 30000, 400)
    a = np.linspace(0.1e-3, 6e-3, 60)
    lim = 2e-3 + 1.5e-3 * np.cos(n / 900.0) ** 2
    p = 1 / (1 + np.exp((a[None, :] - lim[:, None]) / 2e-4))
    quant = {0.05: lim * 0.9, 0.5: lim, 0.95: lim * 1.1}
    rec = NS(speed_window_rpm=(17000.0, 18000.0), depth_checked_m=2.5e-3, spindle_speed_rpm=17500.0,
             depth_m=2.2e-3)
    alts = [{"spindle_speed_rpm": s, "depth_m": 3e-3} for s in (9000.0, 9100.0, 21000.0)]
    return NS(speed_rpm=n, depth_m=a, p_stable=p, quantiles=quant, depth_limit_m=np.ones((50, 400)),
              envelope=lim * 0.85, level=0.95, alternatives=alts,
              pointwise=NS(spindle_speed_rpm=20000.0, depth_m=3.1e-3), recommended=rec)


def _stability_plots():
    from bayes_rcsa.stability.plots import lobes_figure

    tests = (np.array([8000.0, 12000.0, 20000.0]), np.array([1e-3, 4e-3, 2e-3]), np.array([True, False, True]))
    yield "lobes_figure", lobes_figure(_lobes(), tests, title="probabilistic lobes, 30 mm", max_depth=5e-3)


def _next_cut_plots():
    from bayes_rcsa.cuts.next_cut import next_cut_figure

    res = _lobes()
    cands = [NS(speed_rpm=s, depth_m=d, allowed=d < 3e-3, gain=d * 100) for s in np.linspace(6000, 29000, 8)
             for d in (1e-3, 2e-3, 4e-3)]
    best = cands[4]
    r = NS(map_speed_rpm=res.speed_rpm, map_depth_m=res.depth_m, p_stable_map=res.p_stable, candidates=cands,
           risk_budget=0.1, cuts_so_far=(np.array([9000.0, 15000.0]), np.array([1e-3, 3e-3]), np.array([True, False])),
           best=NS(speed_rpm=best.speed_rpm, depth_m=best.depth_m, p_chatter=0.04),
           target=NS(text="mrr at 0.95", kind="mrr"))
    yield "next_cut_figure", next_cut_figure(r)


def _spindle_plots():
    from bayes_rcsa.spindle.plots import receptance_figure, reproduction_figure

    f = np.linspace(100, 3000, 300)
    rng = np.random.default_rng(2)
    block = np.empty((f.size, 2, 2), complex)
    block[:, 0, 0] = _sdof(f, 900.0, 5e7)
    block[:, 0, 1] = block[:, 1, 0] = _sdof(f, 900.0, 5e7) * 20
    block[:, 1, 1] = _sdof(f, 900.0, 5e7) * 400
    raw = block * (1 + 0.05 * rng.normal(size=block.shape))
    samples = block[None] * (1 + 0.02 * rng.normal(size=(20,) + block.shape))
    meas = np.stack([block[:, 0, 0], block[:, 0, 1], block[:, 1, 1]], axis=1)
    res = NS(frequency_hz=f, raw=raw, smoothed=block, samples=samples, bands=[(1400.0, 1500.0)],
             fit=NS(model=NS(n_modes=3)), direction="x", threshold=0.3, measured=meas, reproduced=meas * 1.01)
    yield "receptance_figure", receptance_figure(res, truth=block)
    yield "reproduction_figure", reproduction_figure(res)


def _capture(monkeypatch, module):
    """Make ``module.figure_data_uri`` hand over the figures instead of encoding them."""
    got = []
    monkeypatch.setattr(module, "figure_data_uri", lambda fig, dpi=90: got.append(fig) or "data:")
    return got


def _report_plots(monkeypatch):
    from bayes_rcsa.data import example_dir
    from bayes_rcsa.io.frf import FRF
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.report import cuts_section, figures as F

    got = _capture(monkeypatch, F)
    setup = load_setup(example_dir() / "setup.toml", load_data=False, load_spindle=False)
    F.geometry_figure(setup.holder, next(iter(setup.tools.values())), 0.03, tuple(setup.feasible_range))
    yield "geometry_figure", got.pop()
    f = np.linspace(1000, 1200, 200)
    rng = np.random.default_rng(3)
    h = np.stack([_sdof(f, 1100.0 + rng.normal()) for _ in range(40)])
    modes = [{"mode": 1, "zoom_lo_hz": 1050.0, "zoom_hi_hz": 1150.0}, {"mode": 2, "zoom_lo_hz": 1000.0,
                                                                       "zoom_hi_hz": 1080.0}]
    F.frf_zoom_figure("30 mm, x", f, h, modes, FRF(f[::5], h[0, ::5]))
    yield "frf_zoom_figure", got.pop()
    lob = _lobes()
    F.p_stable_figure(lob.speed_rpm, lob.depth_m, lob.p_stable, 0.95,
                      {"spindle_speed_rpm": 17500.0, "depth_m": 2.2e-3})
    yield "p_stable_figure", got.pop()
    got = _capture(monkeypatch, F)
    side = lambda k: {"median_limit_m": list(lob.quantiles[0.5] * k), "q05_limit_m": list(lob.quantiles[0.05] * k),  # noqa: E731
                      "recommended": {"spindle_speed_rpm": 17500.0, "depth_m": 2.2e-3 * k}}
    cuts_section._figure({"speed_rpm": list(lob.speed_rpm), "clamping_length_m": 0.03, "hammer_only": side(1.0),
                          "with_cuts": side(1.1)},
                         [{"clamping_length_m": 0.03, "outcome": o, "spindle_speed_rpm": s, "depth_m": 2e-3}
                          for o, s in (("stable", 9000.0), ("chatter", 15000.0))])
    yield "_figure", got.pop()


def _workflow_plots():
    from bayes_rcsa.io.frf import FRF
    from bayes_rcsa.workflows.simulation import SimulatedFRF
    from bayes_rcsa.workflows.synthesis import Campaign

    f = np.linspace(300, 3000, 400)
    yield "figures", SimulatedFRF.figures(NS(frequency_hz=f, h=_sdof(f, 1100.0), direction="x",
                                             clamping_length=0.03))["frf"]
    frfs = {f"tip_{d}_{L}mm.csv": FRF(f, _sdof(f, 1100.0 - 10 * L)) for d in "xy" for L in (25, 30, 35, 40)}
    yield "figures", Campaign.figures(NS(frfs=frfs, kind="campaign", seed=7))["frfs"]


#: module (relative to the package) -> the renderer of its figure builders (yielding (function name, Figure)).
RENDERERS = {
    "posterior/plots.py": _posterior_plots, "inference/plots.py": _inference_plots,
    "inference/sbc_plots.py": _inference_plots, "discrepancy/plots.py": _discrepancy_plots,
    "design/outputs.py": _design_plots, "library/outputs.py": _library_plots, "stability/plots.py": _stability_plots,
    "cuts/next_cut.py": _next_cut_plots, "spindle/plots.py": _spindle_plots, "report/figures.py": _report_plots,
    "report/cuts_section.py": _report_plots, "workflows/simulation.py": _workflow_plots,
    "workflows/synthesis.py": _workflow_plots,
}


def _builders() -> set[tuple[str, str]]:
    """(module, function) of every function of the package that calls ``new_figure`` (under any alias)."""
    out = set()
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE).as_posix()
        text = path.read_text()
        if rel == "io/figures.py" or "new_figure" not in text:
            continue
        tree = ast.parse(text)
        aliases = {"new_figure"} | {a.asname for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                                     for a in n.names if a.name == "new_figure" and a.asname}
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                calls = {c.func.id if isinstance(c.func, ast.Name) else getattr(c.func, "attr", "")
                         for c in ast.walk(fn) if isinstance(c, ast.Call)}
                if calls & aliases:
                    out.add((rel, fn.name))
    return out


def _all_figures(monkeypatch):
    done = set()
    for module, render in RENDERERS.items():
        if render in done:
            continue
        done.add(render)
        args = (monkeypatch,) if render is _report_plots else ()
        for name, fig in render(*args):
            yield render, name, fig


# -- the rules -------------------------------------------------------------------------------------------------


def _shown(t) -> bool:
    return t.get_visible() and bool(t.get_text().strip())


def _inspect(fig) -> list[str]:
    """The rule violations of a finished figure (empty when it is legible)."""
    fig.draw_without_rendering()
    r = fig.canvas.get_renderer()
    canvas = fig.bbox
    problems = []
    texts = []  # (description, Text, kind)
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for t in (ax.title, ax._left_title, ax._right_title):
            texts.append(("title", t, "free"))
        for axis in (ax.xaxis, ax.yaxis):
            texts.append(("axis label", axis.label, "free"))
            off = axis.get_offset_text()
            if off.get_visible() and off.get_text().strip():
                problems.append(f"offset text {off.get_text()!r} beside an axis")
            for tick in axis._update_ticks():
                for lab in (tick.label1, tick.label2):
                    texts.append(("tick label", lab, "tick"))
        for t in ax.texts:
            texts.append(("annotation", t, "annotation"))
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            texts += [("legend text", t, "inner") for t in leg.get_texts()]
            texts.append(("legend title", leg.get_title(), "inner"))
    for container in [fig] + list(fig.subfigs):
        for t in container.texts:
            texts.append(("figure text", t, "free"))
        if getattr(container, "_suptitle", None) is not None:
            texts.append(("suptitle", container._suptitle, "free"))
        for leg in container.legends:
            texts += [("legend text", t, "inner") for t in leg.get_texts()]
            texts.append(("legend title", leg.get_title(), "inner"))
    seen = set()  # a suptitle is also one of the figure's texts
    texts = [(d, t, k) for d, t, k in texts if _shown(t) and not (id(t) in seen or seen.add(id(t)))]
    for d, t, k in texts:
        if t.get_fontsize() < MIN_FONT_PT - 1e-9:
            problems.append(f"{d} {t.get_text()!r} at {t.get_fontsize():g} pt < {MIN_FONT_PT:g} pt")
    sizes = {t.get_fontsize() for d, t, k in texts if k == "tick"}
    if sizes and sizes != {TICK_FONT_PT}:
        problems.append(f"tick labels in sizes {sorted(sizes)} (expected all {TICK_FONT_PT:g} pt)")
    boxes = []
    for d, t, k in texts:
        b = t.get_window_extent(r)
        if b.x0 < canvas.x0 - 1 or b.y0 < canvas.y0 - 1 or b.x1 > canvas.x1 + 1 or b.y1 > canvas.y1 + 1:
            problems.append(f"{d} {t.get_text()!r} extends beyond the canvas")
        if k != "inner":
            boxes.append((d, t, b))
    legends = [leg for ax in fig.axes if ax.get_visible() and ax.get_legend() is not None
               for leg in [ax.get_legend()]] + [leg for c in [fig] + list(fig.subfigs) for leg in c.legends]
    for leg in legends:
        boxes.append(("legend", leg, leg.get_window_extent(r)))
    for i, (d1, t1, b1) in enumerate(boxes):
        for d2, t2, b2 in boxes[:i]:
            w = min(b1.x1, b2.x1) - max(b1.x0, b2.x0)
            h = min(b1.y1, b2.y1) - max(b1.y0, b2.y0)
            if w > 1 and h > 1:
                problems.append(f"{d1} {_label(t1)!r} overlaps {d2} {_label(t2)!r}")
    covers = [(f"annotation {t.get_text()!r}", t.axes, t.get_window_extent(r), np.inf) for d, t, k in texts
              if k == "annotation"]
    # a legend inside the axes may lie over a dense cloud of measured points, never over a single marked point
    # (a cutting test, the recommendation, a pocket's best point)
    covers += [("legend", ax, ax.get_legend().get_window_extent(r), 50) for ax in fig.axes
               if ax.get_visible() and ax.get_legend() is not None]
    for what, ax, b, most in covers:
        for line in ax.get_lines():
            if not line.get_visible() or line.get_marker() in (None, "None", "", " ") or len(line.get_xydata()) > most:
                continue
            xy = line.get_transform().transform(line.get_xydata())
            inside = (xy[:, 0] > b.x0) & (xy[:, 0] < b.x1) & (xy[:, 1] > b.y0) & (xy[:, 1] < b.y1)
            if inside.any():
                problems.append(f"{what} covers {int(inside.sum())} plotted points")
    return problems


def _label(artist) -> str:
    return artist.get_text() if hasattr(artist, "get_text") else type(artist).__name__


@pytest.fixture(scope="module")
def figures():
    mp = pytest.MonkeyPatch()
    try:
        yield [(render.__name__, name, fig) for render, name, fig in _all_figures(mp)]
    finally:
        mp.undo()


def test_every_figure_builder_is_covered(figures):
    """A new figure function without a renderer here (or one that no longer draws) fails."""
    drawn = {name for _, name, _ in figures}
    missing = sorted(f"{m}:{fn}" for m, fn in _builders() if m not in RENDERERS or fn not in drawn)
    assert not missing, f"figure builders not covered by tests/test_figures_legible.py: {missing}"
    assert {m for m, _ in _builders()} == set(RENDERERS), "RENDERERS lists a module that draws no figure"


def test_every_figure_is_legible(figures):
    problems = [f"{render}:{name}: {p}" for render, name, fig in figures for p in _inspect(fig)]
    assert not problems, "\n".join(problems)


def test_the_rules_catch_an_illegible_figure():
    """The inspection itself: a tiny label, an offset axis and two colliding annotations are all reported."""
    from bayes_rcsa.io.figures import new_figure

    fig = new_figure(4, 3)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot([0, 1], [0.294166, 0.294167], "o")
    ax.set_ylabel("y", fontsize=5)
    ax.annotate("first", (0.5, 0.2941665))
    ax.annotate("second", (0.5, 0.2941665))
    fig.tight_layout()
    problems = "\n".join(_inspect(fig))
    assert "< 8 pt" in problems and "offset text" in problems and "overlaps" in problems


def test_plain_ticks_write_each_tick_as_its_number():
    from bayes_rcsa.io.figures import _choose_format

    assert _choose_format([0.29416, 0.29418, 0.29420]).format(0.29418) == "0.29418"
    assert _choose_format([0.0, 2500.0, 5000.0]).format(2500.0) == "2500"
    assert _choose_format([1e-7, 2e-7, 3e-7]).format(2e-7) == "2e-07"
