"""Markdown and HTML reports from one list of blocks, written atomically.

A report is a list of blocks (headings, paragraphs, bullet lists, tables,
images) rendered twice, to Markdown and to a self-contained HTML page, so
that both always show the same numbers.

Blocks
------
``("h", level, text)``, ``("p", text)``, ``("ul", [text, ...])``,
``("table", [header, ...], [[cell, ...], ...])``, ``("img", src, alt)``.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import Sequence

from ..io.atomic import atomic_write_text

from ..units import hz, num, sci_parts

__all__ = ["render_markdown", "render_html", "write_report", "fmt", "fmt_interval"]


def fmt(x, digits: int = 4, unit: str = "") -> str:
    """A number for a table cell in the unit policy's form (:func:`bayes_rcsa.units.num`; ``—`` for missing)."""
    return f"{num(x, digits)} {unit}".rstrip()


def fmt_interval(q: dict, lo: str = "q05", hi: str = "q95", digits: int = 3, unit: str = "") -> str:
    """``median (lo–hi)`` from a quantile dict: frequencies (``unit="Hz"``) in the digits their interval justifies,
    others in engineering form (:mod:`bayes_rcsa.units`); no unit is written (the column names it)."""
    if q.get("q50") is None:
        return "—"
    if unit == "Hz":
        return hz(q["q50"], q.get(lo), q.get(hi), unit=False)
    mid, a, b = sci_parts(q["q50"], q.get(lo), q.get(hi), digits)
    return f"{mid} ({a}–{b})"


def _md_cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def render_markdown(blocks: Sequence[tuple]) -> str:
    """Markdown text of the blocks."""
    out = []
    for b in blocks:
        kind = b[0]
        if kind == "h":
            out.append("#" * int(b[1]) + " " + b[2])
        elif kind == "p":
            out.append(b[1])
        elif kind == "ul":
            out.append("\n".join(f"- {item}" for item in b[1]))
        elif kind == "table":
            head, rows = b[1], b[2]
            lines = ["| " + " | ".join(_md_cell(h) for h in head) + " |", "|" + "---|" * len(head)]
            lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in rows]
            out.append("\n".join(lines))
        elif kind == "img":
            out.append(f"![{b[2]}]({b[1]})")
        else:
            raise ValueError(f"unknown report block {kind!r}")
    return "\n\n".join(out) + "\n"


_CSS = (
    "body{font-family:sans-serif;max-width:70em;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0;font-size:0.9em}"
    "th,td{border:1px solid #bbb;padding:0.25em 0.6em;text-align:right}"
    "th{background:#eee}td:first-child,th:first-child{text-align:left}img{max-width:100%}"
)


def render_html(blocks: Sequence[tuple], title: str) -> str:
    """A self-contained HTML page of the blocks."""
    e = html.escape
    body = []
    for b in blocks:
        kind = b[0]
        if kind == "h":
            level = min(max(int(b[1]), 1), 6)
            body.append(f"<h{level}>{e(b[2])}</h{level}>")
        elif kind == "p":
            body.append(f"<p>{e(b[1])}</p>")
        elif kind == "ul":
            body.append("<ul>" + "".join(f"<li>{e(str(i))}</li>" for i in b[1]) + "</ul>")
        elif kind == "table":
            head = "".join(f"<th>{e(str(h))}</th>" for h in b[1])
            rows = "".join("<tr>" + "".join(f"<td>{e(str(c))}</td>" for c in row) + "</tr>" for row in b[2])
            body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
        elif kind == "img":
            body.append(f'<p><img src="{e(b[1])}" alt="{e(b[2])}"></p>')
        else:
            raise ValueError(f"unknown report block {kind!r}")
    return (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{e(title)}</title>"
            f"<style>{_CSS}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def write_report(out_dir, stem: str, blocks: Sequence[tuple], title: str) -> list[Path]:
    """Write ``stem.md`` and ``stem.html`` to ``out_dir`` atomically; returns both paths."""
    out = Path(out_dir)
    md, page = out / f"{stem}.md", out / f"{stem}.html"
    atomic_write_text(md, render_markdown(blocks))
    atomic_write_text(page, render_html(blocks, title))
    return [md, page]
