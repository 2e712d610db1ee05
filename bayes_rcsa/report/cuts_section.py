"""The report's section of a ``bayes-rcsa update`` run: hammer only against hammer + N cuts.

Reads ``update.json`` only (:mod:`bayes_rcsa.cuts.workflow` writes it): the
effective sample size, K_t/K_r before and after, a row per cut (its outcome,
P(chatter) predicted before and after, the median limit at it before and
after, how far it moved that limit and the recommendation) and, when the
update was run with ``--speeds``, the two recommendations side by side and a
figure of the median and 5 % limits before and after with the cuts.
"""

from __future__ import annotations

import numpy as np

from ..io.figures import finish, new_figure
from . import figures as F
from ..units import mm, num, rpm
from ..vocabulary import in_words

__all__ = ["cuts_section"]


def _mm(v) -> str:
    return "—" if v is None else num(1e3 * float(v), 4)


def _depth(v) -> str:
    """A depth in mm as every human output writes it (units.mm), without the unit (the column has it)."""
    return "—" if v is None else mm(v).removesuffix(" mm")


def _pct(v) -> str:
    return "—" if v is None else f"{100 * float(v):+.1f} %"


def _rec(r) -> str:
    return "no recommendation" if not r else f"{rpm(r['spindle_speed_rpm'])}, {mm(r['depth_m'])}"


def _figure(lobes: dict, cuts: list) -> str:
    n = np.asarray(lobes["speed_rpm"], dtype=float)
    fig = new_figure(7.5, 3.6)
    ax = fig.add_subplot(1, 1, 1)
    for key, colour, label in (("hammer_only", "0.55", "hammer only"), ("with_cuts", "C0", f"hammer + {len(cuts)} cuts")):
        s = lobes[key]
        med = np.array([np.nan if v is None else v for v in s["median_limit_m"]], dtype=float) * 1e3
        q05 = np.array([np.nan if v is None else v for v in s["q05_limit_m"]], dtype=float) * 1e3
        ax.plot(n, med, color=colour, lw=1.6, label=f"{label}: median limit")
        ax.plot(n, q05, color=colour, lw=1.0, ls="--", label=f"{label}: 5 % limit")
        r = s.get("recommended")
        if r:
            ax.plot(r["spindle_speed_rpm"], 1e3 * r["depth_m"], marker="*", ms=12, color=colour, ls="none")
    for c in cuts:
        if abs(c["clamping_length_m"] - lobes["clamping_length_m"]) < 1e-9:
            stable = c["outcome"] == "stable"
            ax.plot(c["spindle_speed_rpm"], 1e3 * c["depth_m"], ls="none", marker="o" if stable else "x",
                    mfc="none", color="k")
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth (mm)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("hammer only vs hammer + cuts (○ stable, × chatter, ★ recommendation)", fontsize=9)
    finish(fig)
    return F.figure_data_uri(fig)


def cuts_section(run) -> dict:
    """Template context of one update run (``run.document`` = update.json)."""
    d = run.document
    kt, kr, ess = d["kt_pa"], d["kr_pa"], d["ess"]
    q = lambda v: f"{num(v[1] / 1e6)} ({num(v[0] / 1e6)}–{num(v[2] / 1e6)})"  # noqa: E731  (MPa, as update prints)
    facts = [("cuts (chatter)", f"{d['inputs']['n_cuts']} ({d['inputs']['n_chatter']})"),
             ("effective hammer draws", f"{num(ess['draws'], 4)} of {ess['n_draws']}"),
             ("effective particles", f"{num(ess['particles'], 5)} of {ess['n_particles']}"),
             ("Kt before, median (90 %) (MPa)", q(kt["before"])), ("Kt after, median (90 %) (MPa)", q(kt["after"])),
             ("Kr before, median (90 %) (MPa)", q(kr["before"])), ("Kr after, median (90 %) (MPa)", q(kr["after"]))]
    rows = []
    for c in d["cuts"]:
        mv = c.get("recommendation_moved") or {}
        rows.append({"line": c["line"], "speed": rpm(c["spindle_speed_rpm"], unit=False), "depth": _depth(c["depth_m"]),
                     "outcome": c["outcome"], "length": _mm(c["clamping_length_m"]),
                     "p_before": num(c["p_chatter_before"], 2), "p_after": num(c["p_chatter_after"], 2),
                     "lim_before": _depth(c["median_limit_before_m"]), "lim_after": _depth(c["median_limit_after_m"]),
                     "moved": _pct(c.get("moved")),
                     "rec_speed": "—" if mv.get("speed_moved_rpm") is None else f"{mv['speed_moved_rpm']:+.0f}",
                     "rec_depth": "—" if mv.get("depth_moved_m") is None else f"{1e3 * mv['depth_moved_m']:+.4f}"})
    lobes = d.get("lobes")
    side = None
    images = []
    if lobes:
        side = {"before": _rec(lobes["hammer_only"]["recommended"]), "after": _rec(lobes["with_cuts"]["recommended"]),
                "level": num(lobes.get("level"), 3), "clamping": _mm(lobes["clamping_length_m"])}
        images.append(_figure(lobes, d["cuts"]))
    return {"path": str(run.path), "facts": facts, "rows": rows, "side": side, "images": images,
            "warnings": [in_words(str(w)) for w in d.get("warnings", [])]}
