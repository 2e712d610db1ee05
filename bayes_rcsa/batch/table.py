"""The library summary: one row per setup, as CSV, HTML and JSON."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Sequence

from ..io.atomic import atomic_write_text

__all__ = ["summary_columns", "write_summary"]

#: Columns shown first, in this order; the rest (parameter and frequency quantiles) follow sorted.
LEAD_COLUMNS = ("name", "status", "reused", "method", "seed", "converged", "n_warnings", "rhat_max", "ess_bulk_min",
                "n_steps", "lobes_speed_rpm", "lobes_depth_m", "lobes_p_stable", "lobes_limit", "seconds", "failed_step",
                "error", "setup")
#: Columns of lists (joined with "; "), shown last: ``warnings`` holds every step's warnings ("STEP: text").
_LIST_COLUMNS = ("warnings", "identify_warnings")

_HTML = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bayes-rcsa batch: {{ title }}</title>
<style>
body { font-family: sans-serif; margin: 1.5em; }
table { border-collapse: collapse; font-size: 0.85em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.4em; text-align: right; white-space: nowrap; }
th { background: #eee; position: sticky; top: 0; }
td.text { text-align: left; }
tr.failed td, tr.lost td { background: #fdd; }
td.bad { background: #fdb; font-weight: bold; }
td.list { white-space: normal; min-width: 30em; }
</style></head><body>
<h1>Tool library: {{ title }}</h1>
<p>{{ counts }}. Stiffness in N/m and N m/rad, natural frequencies in Hz (dominant mode; q05..q95 is the 90 %
credible interval of the model's natural frequency), depth in m, speed in rpm. A setup that did not converge is
marked; its numbers are not reliable. Per-setup outputs: setups/NAME/.</p>
{% if warnings %}<ul class="warnings">{% for w in warnings %}<li>warning: {{ w }}</li>{% endfor %}</ul>{% endif %}
<table>
<thead><tr>{% for c in columns %}<th>{{ c }}</th>{% endfor %}</tr></thead>
<tbody>
{% for r in rows %}<tr class="{{ r.status }}">{% for c in columns %}{% set v = r.cells[c] %}<td class="{{ v.cls }}">{{ v.text }}</td>{% endfor %}</tr>
{% endfor %}</tbody></table>
</body></html>
"""


def summary_columns(rows: Sequence[dict]) -> list[str]:
    """Every column any row has: :data:`LEAD_COLUMNS` first, then the others sorted."""
    keys = {k for r in rows for k in r}
    return [c for c in LEAD_COLUMNS if c in keys] + sorted(keys - set(LEAD_COLUMNS) - set(_LIST_COLUMNS)) \
        + [c for c in _LIST_COLUMNS if c in keys]


def _text(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "nan" if not math.isfinite(v) else f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return "; ".join(str(x) for x in v)
    return str(v)


def write_summary(rows: Sequence[dict], out_dir, title: str, warnings: Sequence[str] = ()) -> dict[str, Path]:
    """Write ``summary.csv`` (full precision), ``summary.html`` and ``summary.json`` into ``out_dir``.

    ``warnings`` (the batch command's own, printed on stderr) go into summary.json as ``"warnings"`` and
    above the HTML table; each setup's step warnings are its row's ``warnings`` column.

    Returns
    -------
    dict ``{"csv", "html", "json"}`` -> path
    """
    import jinja2

    out_dir = Path(out_dir)
    cols = summary_columns(rows)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        # repr keeps every digit of a float; lists (warnings) are joined
        w.writerow(["" if r.get(c) is None else repr(r[c]) if isinstance(r.get(c), float) else _text(r.get(c))
                    for c in cols])
    paths = {"csv": out_dir / "summary.csv", "html": out_dir / "summary.html", "json": out_dir / "summary.json"}
    atomic_write_text(paths["csv"], buf.getvalue())
    atomic_write_text(paths["json"], json.dumps({"columns": cols, "rows": list(rows), "warnings": list(warnings)}, indent=1,
                                                  default=str))

    def cell(r, c):
        v = r.get(c)
        bad = (c == "converged" and v is False) or (c == "status" and v != "done") or (c == "n_warnings" and bool(v))
        kind = "text list" if isinstance(v, (list, tuple)) else "" if isinstance(v, (int, float)) else "text"
        return {"text": _text(v), "cls": ("bad " if bad else "") + kind}

    counts = ", ".join(f"{sum(1 for r in rows if r['status'] == s)} {s}" for s in ("done", "failed", "lost")
                       if any(r["status"] == s for r in rows))
    not_conv = sum(1 for r in rows if r.get("converged") is False)
    if not_conv:
        counts += f"; {not_conv} NOT converged"
    warned = sum(1 for r in rows if r.get("n_warnings"))
    if warned:
        counts += f"; {warned} with warnings (column warnings)"
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
    html = env.from_string(_HTML).render(
        title=title, counts=counts, columns=cols, warnings=list(warnings),
        rows=[{"status": r["status"], "cells": {c: cell(r, c) for c in cols}} for r in rows])
    atomic_write_text(paths["html"], html)
    return paths
