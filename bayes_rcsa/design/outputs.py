"""design.json and the expected-width plot, written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_text
from ..io.figures import finish, new_figure, save_png
from ..io.jsonable import dumps_strict

__all__ = ["write_design_outputs", "design_figure"]


def write_design_outputs(result, out_dir, plots: bool = True) -> list[Path]:
    """Write ``design.json`` (and ``design.png``) of a DesignResult or PlanningResult into ``out_dir``."""
    out = Path(out_dir)
    doc = result.as_dict()
    written = []
    if plots:
        written.append(_plot(doc, out / "design.png"))
        doc["plot"] = "design.png"
    atomic_write_text(out / "design.json", dumps_strict(doc, indent=2) + "\n")
    written.insert(0, out / "design.json")
    return written


def _plot(doc: dict, path: Path) -> Path:
    return save_png(design_figure(doc), path)


def design_figure(doc: dict):
    """The expected 90 % width of the target against the candidate tests (a matplotlib Figure) of a design.json
    document."""
    fig = new_figure(6.4, 4.2)
    ax = fig.add_subplot(111)
    unit = doc.get("unit", "")
    if doc["mode"] == "prior":
        # expected width of every pair, against the second length, one line per first length
        firsts = sorted({c["clamping_lengths"][0] for c in doc["candidates"]})
        for a in firsts:
            rows = sorted((c["clamping_lengths"][1], c["expected_width"], c["mc_error"]) for c in doc["candidates"]
                          if c["clamping_lengths"][0] == a)
            x, y, e = (np.array(v, dtype=float) for v in zip(*rows))
            ax.errorbar(1e3 * x, y, yerr=e, marker="o", capsize=2, label=f"first test at {a * 1e3:.4g} mm")
        ax.set_xlabel("second clamping length (mm)")
        ax.set_title("no data yet: expected transfer uncertainty of two tests", fontsize=9)
    else:
        groups: dict = {}
        for c in doc["candidates"]:
            groups.setdefault((c["direction"], c["tool"]), []).append(c)
        for (d, t), rows in sorted(groups.items()):
            rows = sorted(rows, key=lambda c: c["clamping_length"])
            x = 1e3 * np.array([c["clamping_length"] for c in rows])
            y = np.array([c["expected_width"] for c in rows])
            lo = np.array([c["width_range_90"][0] for c in rows])
            hi = np.array([c["width_range_90"][1] for c in rows])
            e = np.array([c["mc_error"] for c in rows])
            ax.errorbar(x, y, yerr=e, marker="o", capsize=3, label=f"direction {d}, {t} (± MC error)")
            ax.fill_between(x, lo, hi, alpha=0.15, label="5-95 % of the width after one test")
        ax.axvline(1e3 * doc["target_clamping_length"], color="0.5", ls=":", label="target length")
        ax.set_xlabel("candidate clamping length (mm)")
        ax.set_title(f"expected 90 % width of {doc['target']} after one more test", fontsize=9)
    ax.axhline(doc["current_width"], color="k", ls="--", lw=1, label="current width")
    ax.set_ylabel(f"expected 90 % width ({unit})")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    finish(fig)
    return fig
