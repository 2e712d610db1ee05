"""The library summary: one row per setup, as CSV, HTML and JSON."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Sequence

from ..io.atomic import atomic_write_text
from ..units import hz, mm, num, rpm, sci
from ..vocabulary import depth_limit_name, identification_name, parameter_name

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
td.lines { text-align: left; white-space: normal; }
table.core td { white-space: normal; }
</style></head><body>
<h1>Tool library: {{ title }}</h1>
<p>{{ counts }}. Medians with their 90 % credible interval in brackets; natural frequencies of the dominant mode at
each predicted clamping length and direction. A setup that did not converge is marked; its numbers are not
reliable. Per-setup outputs: setups/NAME/.</p>
{% if warnings %}<ul class="warnings">{% for w in warnings %}<li>warning: {{ w }}</li>{% endfor %}</ul>{% endif %}
<table class="core">
<thead><tr>{% for c in core_columns %}<th>{{ c }}</th>{% endfor %}</tr></thead>
<tbody>
{% for r in core_rows %}<tr class="{{ r.status }}">{% for v in r.cells %}<td class="{{ v.cls }}">{% for line in v.lines %}{{ line }}{% if not loop.last %}<br>{% endif %}{% endfor %}</td>{% endfor %}</tr>
{% endfor %}</tbody></table>
<details><summary>Every column of summary.csv (SI units: stiffness N/m and N m/rad, depth m, frequencies Hz; q05..q95
is the 90 % credible interval)</summary>
<table class="all">
<thead><tr>{% for c in columns %}<th>{{ c }}</th>{% endfor %}</tr></thead>
<tbody>
{% for r in rows %}<tr class="{{ r.status }} all">{% for c in columns %}{% set v = r.cells[c] %}<td class="{{ v.cls }}">{{ v.text }}</td>{% endfor %}</tr>
{% endfor %}</tbody></table>
</details>
</body></html>
"""

#: The contact parameters of the readable table (its other columns are fixed: see ``_core``).
_CORE_PARAMETERS = (("k_xf", "N/m"), ("k_thetaM", "N m/rad"))


def summary_columns(rows: Sequence[dict]) -> list[str]:
    """Every column any row has: :data:`LEAD_COLUMNS` first, then the others sorted."""
    keys = {k for r in rows for k in r}
    return [c for c in LEAD_COLUMNS if c in keys] + sorted(keys - set(LEAD_COLUMNS) - set(_LIST_COLUMNS)) \
        + [c for c in _LIST_COLUMNS if c in keys]


def _core(rows: Sequence[dict]) -> tuple[list[str], list[dict]]:
    """The readable table: printed headers with units, numbers in the unit policy's form (docs/data-formats.md)."""
    params = [(n, u) for n, u in _CORE_PARAMETERS if any(r.get(f"{n}_q50") is not None for r in rows)]
    freqs = sorted({k[:-len("_q50_hz")] for r in rows for k in r if k.startswith("fn_") and k.endswith("_q50_hz")},
                   key=lambda k: (float(k[3:].split("mm")[0]), k))
    lobes = any(r.get("lobes_speed_rpm") is not None for r in rows)
    head = ["setup", "status", "converged", "warnings"] + [f"{parameter_name(n)} ({u})" for n, u in params]
    if freqs:
        head.append("dominant natural frequency (Hz)")
    if lobes:
        head += ["recommended speed (rpm)", "recommended depth (mm)", "P(stable)"]
    out = []
    for r in rows:
        bad_conv = r.get("converged") is False
        cells = [{"lines": [str(r.get("name", ""))], "cls": "text"},
                 {"lines": [str(r["status"]) + (f" ({r['failed_step']}: {r.get('error', '')})"
                                                if r.get("failed_step") else "")],
                  "cls": "text" + (" bad" if r["status"] != "done" else "")},
                 {"lines": ["—" if r.get("converged") is None else ("yes" if r["converged"] else "NOT converged")]
                  + ([identification_name(str(r["method"]))] if r.get("method") else []),
                  "cls": "text" + (" bad" if bad_conv else "")},
                 {"lines": [num(r.get("n_warnings") or 0)], "cls": "bad" if r.get("n_warnings") else ""}]
        for n, _ in params:
            cells.append({"lines": [sci(r.get(f"{n}_q50"), 3, r.get(f"{n}_q05"), r.get(f"{n}_q95"))], "cls": ""})
        if freqs:
            cells.append({"lines": [f"{k[3:].replace('mm_', ' mm ')}: "
                                    f"{hz(r[k + '_q50_hz'], r.get(k + '_q05_hz'), r.get(k + '_q95_hz'), unit=False)}"
                                    for k in freqs if r.get(k + "_q50_hz") is not None] or ["—"], "cls": "lines"})
        if lobes:
            limit = r.get("lobes_limit")
            depth = mm(r.get("lobes_depth_m")).removesuffix(" mm") if r.get("lobes_depth_m") is not None else "—"
            cells += [{"lines": [rpm(r.get("lobes_speed_rpm"), unit=False)], "cls": ""},
                      {"lines": [depth] + ([f"set by {depth_limit_name(limit)}"] if limit and limit != "stability"
                                           else []), "cls": ""},
                      {"lines": [num(r.get("lobes_p_stable"), 3)], "cls": ""}]
        out.append({"status": r["status"], "cells": cells})
    return head, out


def _text(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "nan" if not math.isfinite(v) else num(v, 6)
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
    core_columns, core_rows = _core(rows)
    html = env.from_string(_HTML).render(
        title=title, counts=counts, columns=cols, warnings=list(warnings), core_columns=core_columns,
        core_rows=core_rows,
        rows=[{"status": r["status"], "cells": {c: cell(r, c) for c in cols}} for r in rows])
    atomic_write_text(paths["html"], html)
    return paths
