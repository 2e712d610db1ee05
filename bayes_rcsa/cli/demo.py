"""``bayes-rcsa demo``: the main job end to end on the bundled example campaign.

The demo is a scripted sequence of the ordinary sub-commands, so everything
it writes is exactly what a user gets from running them by hand:

1. ``identify``  multi-length Bayesian identification from the 25 mm and 40 mm
   hammer tests (the paper's Method II protocol);
2. ``predict``   credible intervals of the tool-point FRF and natural
   frequencies at 25, 30, 35 and 40 mm, the 30 and 35 mm tests held out;
3. ``lobes``     probabilistic stability lobes at 30 mm clamping for the
   paper's cutting case b (4 flutes, Al 7050, Kt = 790 MPa, Kr = 230 MPa,
   95 % radial immersion, feed in y);

and finally an ``index.html`` that links the three reports.
"""

from __future__ import annotations

import argparse
import html
import json
import sys
from pathlib import Path

ORDER = 10

FIT_LENGTHS = "0.025,0.040"
PREDICT_LENGTHS = "0.025,0.030,0.035,0.040"
LOBES_CASE = ["--clamping-length", "0.030", "--flutes", "4", "--kt", "790e6", "--kr", "230e6",
              "--immersion", "0.95", "--milling", "down", "--feed", "y", "--speeds", "5000:30000:400"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo",
        help="run the main job end to end on the bundled example data",
        description="Run bayes_rcsa end to end on the bundled example campaign (synthetic hammer tests of an "
        "ER32 collet chuck with a 7.94 mm carbide end mill at 25-40 mm clamping, made by the project's "
        "independent finite-element bench): identify the tool-holder contact from the 25 and 40 mm tests, "
        "predict the tool point with credible intervals at 25-40 mm (30 and 35 mm held out), and compute "
        "probabilistic stability lobes at 30 mm.  Writes DIR/identify, DIR/predict, DIR/lobes and "
        "DIR/index.html.  Takes about a minute.",
    )
    p.add_argument("--out", default=".", metavar="DIR", help="output directory (default: current directory)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the whole run (default 0)")
    p.add_argument("--max-steps", type=int, default=20000, metavar="N", help="sampler step cap (default 20000)")
    p.set_defaults(func=run)


def _step(title: str, argv: list[str]) -> None:
    from .main import main

    print(f"\n== {title}\n$ bayes-rcsa {' '.join(argv)}", file=sys.stderr)
    status = main(argv)
    if status != 0:
        from ..errors import BayesRCSAError

        raise BayesRCSAError(f"demo step '{argv[0]}' failed with exit status {status}")


def _index_html(out: Path, summary: dict, freqs: dict, lobes: dict) -> str:
    rows = []
    for p in freqs["predictions"]:
        if p.get("mode") != 1:
            continue
        measured = p.get("measured_hz")
        err = "" if measured is None else f"{100 * (p['q50_hz'] - measured) / measured:+.2f} %"
        rows.append(
            f"<tr><td>{p['clamping_length'] * 1e3:.1f}</td><td>{html.escape(p['direction'])}</td>"
            f"<td>{p['q05_hz']:.1f} &ndash; {p['q95_hz']:.1f}</td><td>{p['q50_hz']:.1f}</td>"
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
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bayes_rcsa demo</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #999;padding:3px 8px;text-align:right}}img{{max-width:100%}}</style></head><body>
<h1>bayes_rcsa demo: ER32 collet + 7.94 mm end mill</h1>
<p>Contact identified from the 25 mm and 40 mm hammer tests (x and y); 30 mm and 35 mm are held out.
Sampler converged: <b>{summary.get('converged')}</b>. Warnings: <ul>{warnings}</ul></p>
<h2>Contact stiffness, 90 % credible intervals</h2>
<table><tr><th>clamping (mm)</th><th>k<sub>xf</sub> (N/m)</th><th>k<sub>&theta;M</sub> (N m/rad)</th></tr>
{''.join(stiff)}</table>
<h2>First tool-point natural frequency</h2>
<table><tr><th>clamping (mm)</th><th>dir</th><th>90 % interval (Hz)</th><th>median (Hz)</th><th>measured (Hz)</th><th>error</th></tr>
{''.join(rows)}</table>
<p><a href="predict/report.html">prediction report</a> &middot; <a href="identify/summary.json">identify/summary.json</a>
&middot; <a href="predict/frequencies.json">predict/frequencies.json</a> &middot; <a href="lobes/lobes.json">lobes/lobes.json</a></p>
<img src="predict/frf_bands.png" alt="FRF bands"><img src="predict/natural_frequencies.png" alt="natural frequencies">
<h2>Stability lobes at 30 mm, case b (95 % immersion, feed y)</h2>
<p>Recommended operating point: {rec_text}</p>
<img src="lobes/lobes.png" alt="stability lobes">
<h2>Sampler</h2><img src="identify/trace.png" alt="trace"><img src="identify/corner.png" alt="corner">
</body></html>
"""


def run(args: argparse.Namespace) -> int:
    from ..data import example_setup
    from ..io.atomic import atomic_write_text

    out = Path(args.out)
    setup = str(example_setup())
    seed = str(args.seed)
    _step("1/3 identify the contact from the 25 and 40 mm tests",
          ["identify", setup, "--out", str(out / "identify"), "--lengths", FIT_LENGTHS, "--seed", seed,
           "--max-steps", str(args.max_steps)])
    posterior = str(out / "identify" / "posterior.nc")
    _step("2/3 predict 25-40 mm with credible intervals",
          ["predict", setup, "--posterior", posterior, "--lengths", PREDICT_LENGTHS, "--seed", seed,
           "--out", str(out / "predict")])
    _step("3/3 probabilistic stability lobes at 30 mm",
          ["lobes", setup, "--posterior", posterior, *LOBES_CASE, "--draws", "300", "--seed", seed,
           "--out", str(out / "lobes")])
    summary = json.loads((out / "identify" / "summary.json").read_text())
    freqs = json.loads((out / "predict" / "frequencies.json").read_text())
    lobes = json.loads((out / "lobes" / "lobes.json").read_text())
    index = out / "index.html"
    atomic_write_text(index, _index_html(out, summary, freqs, lobes))
    print(f"\ndemo finished: open {index}", file=sys.stderr)
    return 0
