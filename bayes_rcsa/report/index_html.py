"""The demo's HTML landing page, linking the identify, predict and lobes outputs.

Kept deliberately simple (string formatting, no template engine); the page
only reads the JSON files the sub-commands write, so it can be rebuilt from
any output directory with :func:`write_demo_index`.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from ..io.atomic import atomic_write_text

__all__ = ["demo_index_html", "write_demo_index"]


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
        pred = "&mdash;" if lo is None or hi is None else f"{lo:.1f} &ndash; {hi:.1f}"
        rows.append(
            f"<tr><td>{p['clamping_length'] * 1e3:.1f}</td><td>{html.escape(p['direction'])}</td>"
            f"<td>{p['q05_hz']:.1f} &ndash; {p['q95_hz']:.1f}</td><td>{p['q50_hz']:.1f}</td><td>{pred}</td>"
            f"<td>{'' if measured is None else f'{measured:.1f}'}</td><td>{err}</td></tr>"
        )
    stiff = []
    for s in summary.get("stiffness", []):
        stiff.append(
            f"<tr><td>{s['clamping_length'] * 1e3:.1f}</td>"
            f"<td>{s['k_xf']['q05']:.4g} &ndash; {s['k_xf']['q95']:.4g}</td>"
            f"<td>{s['k_thetaM']['q05']:.4g} &ndash; {s['k_thetaM']['q95']:.4g}</td></tr>"
        )
    rec = lobes.get("recommended")
    rec_text = (
        "no speed reaches the required P(stable)"
        if not rec
        else f"{rec['spindle_speed_rpm']:.0f} rpm, a<sub>p</sub> = {rec['depth_m'] * 1e3:.3f} mm "
        f"(P(stable) = {rec['p_stable']:.2f})"
    )
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in summary.get("warnings", [])) or "<li>none</li>"
    disc = ""
    if discrepancy is not None:
        named = discrepancy.get("named_effect")
        verdict = (f"the model misses <b>{html.escape(named)}</b>; the amended setup is "
                   f"<a href=\"discrepancy/setup.amended.toml\">discrepancy/setup.amended.toml</a>" if named else
                   "no known effect is missing" if discrepancy.get("adequate") else
                   "the model disagrees with the measurements but no known effect explains it; the intervals were "
                   "widened by a statistical discrepancy term")
        disc = (f"<h2>Model check (discrepancy workflow)</h2><p>Adequate: <b>{_yes_no(discrepancy.get('adequate'))}</b>; "
                f"{verdict}. Gap ({html.escape(str(discrepancy.get('gap_metric', '')).split(':')[0])}): "
                f"{discrepancy.get('gap_before', float('nan')):.3g} before, {discrepancy.get('gap_after', float('nan')):.3g} "
                f"after. <a href=\"discrepancy/summary.md\">discrepancy/summary.md</a> &middot; "
                f"<a href=\"discrepancy/discrepancy.json\">discrepancy/discrepancy.json</a></p>")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bayes_rcsa demo</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #999;padding:3px 8px;text-align:right}}img{{max-width:100%}}</style></head><body>
<h1>bayes_rcsa demo: ER32 collet + 7.94 mm end mill</h1>
<p>Contact identified from the 25 mm and 40 mm hammer tests (x and y); 30 mm and 35 mm are held out.
Sampler converged: <b>{_yes_no(summary.get('converged'))}</b>. Warnings: <ul>{warnings}</ul></p>
<h2>Contact stiffness, 90 % credible intervals</h2>
<table><tr><th>clamping (mm)</th><th>k<sub>xf</sub> (N/m)</th><th>k<sub>&theta;M</sub> (N m/rad)</th></tr>
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
<h2>Stability lobes at 30 mm, case b (95 % immersion, feed y)</h2>
<p>Recommended operating point: {rec_text}</p>
<img src="lobes/lobes.png" alt="stability lobes">
{disc}
<h2>Sampler</h2><img src="identify/trace.png" alt="trace"><img src="identify/corner.png" alt="corner">
</body></html>
"""


def _yes_no(b) -> str:
    return "unknown" if b is None else ("yes" if b else "NO")


def write_demo_index(out) -> Path:
    """Write ``out/index.html`` from ``out/identify``, ``out/predict``, ``out/lobes`` (and ``out/discrepancy``); returns its path."""
    out = Path(out)
    summary = json.loads((out / "identify" / "summary.json").read_text())
    freqs = json.loads((out / "predict" / "frequencies.json").read_text())
    lobes = json.loads((out / "lobes" / "lobes.json").read_text())
    disc_path = out / "discrepancy" / "discrepancy.json"
    disc = json.loads(disc_path.read_text()) if disc_path.is_file() else None
    index = out / "index.html"
    atomic_write_text(index, demo_index_html(summary, freqs, lobes, disc))
    return index
