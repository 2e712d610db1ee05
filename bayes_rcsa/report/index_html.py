"""The demo's HTML landing page and ``summary.md``, linking the identify, predict and lobes outputs.

The page opens with the summary block of ``report.html`` (:mod:`.answer`:
the recommended operating point, the tool-point frequencies with their
90 % intervals, the model check, convergence and the warnings that change
the decision), its links pointing into ``report.html``; the rest is kept
deliberately simple (string formatting).  The page only reads the JSON
files the sub-commands write, so it can be rebuilt from any output
directory with :func:`write_demo_index`, which also writes ``summary.md``
(the same block in Markdown).
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from ..errors import DataError
from ..io.atomic import atomic_write_text
from ..units import hz, hz_range, length_mm, mm, num, percent, rpm, sci
from ..vocabulary import effect_name, gap_name, in_words
from .answer import answer_css, answer_html, answer_markdown, build_answer

__all__ = ["demo_index_html", "demo_answer", "write_demo_index"]

#: sub-directory and file of each kind the demo writes, in the order of ``bayes-rcsa demo``
DEMO_FILES = (("identify", "identify/summary.json"), ("predict", "predict/frequencies.json"),
              ("lobes", "lobes/lobes.json"), ("discrepancy", "discrepancy/discrepancy.json"))


def demo_answer(summary: dict, freqs: dict, lobes: dict, discrepancy: dict | None = None):
    """The summary block (:class:`~bayes_rcsa.report.answer.Answer`) of the demo's four documents."""
    docs = (summary, freqs, lobes, discrepancy)
    return build_answer((kind, label, doc) for (kind, label), doc in zip(DEMO_FILES, docs) if doc is not None)


def demo_index_html(summary: dict, freqs: dict, lobes: dict, discrepancy: dict | None = None) -> str:
    """The demo's ``index.html``: contact intervals, predicted vs measured frequencies, lobes, links.

    Parameters
    ----------
    summary : dict
        ``identify/summary.json``.
    freqs : dict
        ``predict/frequencies.json``.
    lobes : dict
        ``lobes/lobes.json``.
    discrepancy : dict, optional
        ``discrepancy/discrepancy.json``.

    Returns
    -------
    str
        A self-contained HTML page linking the sub-reports by relative path.
    """
    rows = []
    for p in freqs["predictions"]:
        if p.get("mode") != 1:
            continue
        measured = p.get("measured_hz")
        err = "" if measured is None else f"{100 * (p['q50_hz'] - measured) / measured:+.2f} %"
        lo, hi = p.get("predictive_peak_q05_hz"), p.get("predictive_peak_q95_hz")
        median = hz(p["q50_hz"], p["q05_hz"], p["q95_hz"], unit=False).split(" ")[0]
        pred = "&mdash;" if lo is None or hi is None else hz_range(lo, hi)
        rows.append(
            f"<tr><td>{num(1e3 * p['clamping_length'])}</td><td>{html.escape(p['direction'])}</td>"
            f"<td>{hz_range(p['q05_hz'], p['q95_hz'])}</td><td>{median}</td><td>{pred}</td>"
            f"<td>{'' if measured is None else hz(measured, unit=False)}</td><td>{err}</td></tr>"
        )
    stiff = []
    for s in summary.get("stiffness", []):
        stiff.append(
            f"<tr><td>{num(1e3 * s['clamping_length'])}</td>"
            f"<td>{html.escape(sci(s['k_xf']['q50'], 3, s['k_xf']['q05'], s['k_xf']['q95']))}</td>"
            f"<td>{html.escape(sci(s['k_thetaM']['q50'], 3, s['k_thetaM']['q05'], s['k_thetaM']['q95']))}</td></tr>"
        )
    rec = lobes.get("recommended")
    rec_text = (
        "no speed reaches the required P(stable)"
        if not rec
        else f"{rpm(rec['spindle_speed_rpm'])}, a<sub>p</sub> = {mm(rec['depth_m'])} "
        f"(P(stable) = {rec['p_stable']:.2f})"
    )
    warned = "".join(f"<li>{html.escape(in_words(w))}</li>" for w in summary.get("warnings", []))
    warnings = f"Warnings: <ul>{warned}</ul>" if warned else "No warnings."
    disc = ""
    if discrepancy is not None:
        named = discrepancy.get("named_effect")
        verdict = (f"the model misses <b>{html.escape(effect_name(named))}</b>; the amended setup is "
                   f"<a href=\"discrepancy/setup.amended.toml\">discrepancy/setup.amended.toml</a>" if named else
                   "no known effect is missing" if discrepancy.get("adequate") else
                   "the model disagrees with the measurements but no known effect explains it; the intervals were "
                   "widened by a statistical discrepancy term")
        disc = (f"<h2>Model check (discrepancy workflow)</h2><p>Adequate: <b>{_yes_no(discrepancy.get('adequate'))}</b>; "
                f"{verdict}. {html.escape(gap_name(discrepancy.get('gap_metric', '')).capitalize())}: "
                f"{_gap(discrepancy, 'before')} before, {_gap(discrepancy, 'after')} after. <a href=\"discrepancy/summary.md\">discrepancy/summary.md</a> &middot; "
                f"<a href=\"discrepancy/discrepancy.json\">discrepancy/discrepancy.json</a></p>")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bayes_rcsa demo</title>
<style>body{{font-family:sans-serif;max-width:1150px;margin:1.5em auto;padding:0 1em}}table{{border-collapse:collapse}}
td,th{{border:1px solid #999;padding:3px 8px;text-align:right}}img{{max-width:100%}}
{answer_css()}</style></head><body>
<h1>bayes_rcsa demo: ER32 collet + 7.94 mm end mill</h1>
{answer_html(demo_answer(summary, freqs, lobes, discrepancy), href="report.html")}
<p>Contact identified from the 25 mm and 40 mm hammer tests (x and y); 30 mm and 35 mm are held out.
Sampler converged: <b>{_yes_no(summary.get('converged'))}</b>. {warnings}</p>
<h2>Contact stiffness, median and 90 % credible interval</h2>
<table><tr><th>clamping (mm)</th><th>contact stiffness, translational k<sub>xf</sub> (N/m)</th>
<th>contact stiffness, rotational k<sub>&theta;M</sub> (N m/rad)</th></tr>
{''.join(stiff)}</table>
<h2>First tool-point natural frequency</h2>
<table><tr><th>clamping (mm)</th><th>dir</th><th>model 90 % credible interval (Hz)</th><th>model median (Hz)</th><th>new measured peak, 90 % predictive interval (Hz)</th><th>measured (Hz)</th><th>error</th></tr>
{''.join(rows)}</table>
<p>The model interval is where the noise-free natural frequency of the identified model lies; a measured peak is
noisy and is to be compared with the predictive interval of a new measurement.</p>
<p><b><a href="report.html">the full report (report.html, self-contained)</a></b> &middot;
<a href="predict/report.html">prediction report</a> &middot; <a href="identify/summary.json">identify/summary.json</a>
&middot; <a href="predict/frequencies.json">predict/frequencies.json</a> &middot; <a href="lobes/lobes.json">lobes/lobes.json</a></p>
<img src="predict/frf_bands.png" alt="FRF bands"><img src="predict/natural_frequencies.png" alt="natural frequencies">
<h2>Stability lobes at {_lobes_case(lobes)}</h2>
<p>Recommended operating point: {rec_text}</p>
<img src="lobes/lobes.png" alt="stability lobes">
{disc}
<h2>Sampler</h2><details><summary>trace and corner plots</summary><img src="identify/trace.png" alt="trace">
<img src="identify/corner.png" alt="corner"></details>
</body></html>
"""


def _gap(discrepancy: dict, when: str) -> str:
    """The model check's systematic mismatch before/after, as the model check's own summary writes it."""
    if discrepancy.get(f"gap_{when}_at_noise_floor"):
        return f"at the noise floor (below {percent(discrepancy.get('gap_resolution'))})"
    return percent(discrepancy.get(f"gap_{when}"))


def _lobes_case(lobes: dict) -> str:
    """The cutting case of a lobes run in words: ``30 mm clamping, 4 flutes, 95 % radial immersion, ...``."""
    src, cut = lobes.get("source") or {}, lobes.get("cutting") or {}
    parts = []
    if src.get("clamping_length_m"):
        parts.append(f"{length_mm(src['clamping_length_m'])} clamping")
    if cut.get("flutes"):
        parts.append(f"{cut['flutes']} flutes")
    if cut.get("radial_immersion") is not None:
        parts.append(f"{percent(cut['radial_immersion'], 3)} radial immersion")
    if cut.get("milling"):
        parts.append(f"{cut['milling']} milling")
    if cut.get("feed"):
        parts.append(f"feed in {cut['feed']}")
    return ", ".join(parts) or "the requested clamping length"


def _yes_no(b) -> str:
    return "unknown" if b is None else ("yes" if b else "NO")


def _read(path: Path) -> dict:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise DataError(f"{path}: cannot read it as JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise DataError(f"{path}: expected a JSON object, got {type(doc).__name__}")
    return doc


def write_demo_index(out) -> Path:
    """Write ``out/index.html`` and ``out/summary.md`` from ``out/identify``, ``out/predict``, ``out/lobes``
    (and ``out/discrepancy``); returns the path of ``index.html``.

    Raises
    ------
    DataError
        A document is missing or not a JSON object (its path named).
    """
    out = Path(out)
    docs = [_read(out / rel) if kind != "discrepancy" or (out / rel).is_file() else None for kind, rel in DEMO_FILES]
    index = out / "index.html"
    atomic_write_text(index, demo_index_html(*docs))
    atomic_write_text(out / "summary.md", answer_markdown(demo_answer(*docs), href="report.html"))
    return index
