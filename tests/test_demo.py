"""End-to-end: ``bayes-rcsa demo`` on the bundled example campaign.

The example was made by the independent FE bench (bayes_rcsa.synthetic);
truth.json beside it holds the noise-free natural frequencies and the true
contact, so the demo's numbers can be scored, not just produced.
"""

from __future__ import annotations

import contextlib
import io
import json
import re

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    """The demo's folder and everything it printed on stderr (for tests/test_human_outputs.py's scan)."""
    out = tmp_path_factory.mktemp("demo")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["demo", "--out", str(out)]) == 0
    return out, err.getvalue()


@pytest.fixture(scope="module")
def demo_out(demo_run):
    return demo_run[0]


def test_demo_writes_every_report(demo_out):
    for rel in ("index.html", "report.html", "identify/summary.json", "identify/posterior.nc", "identify/corner.png",
                "predict/frequencies.json", "predict/report.html", "predict/frf_bands.png",
                "lobes/lobes.json", "lobes/lobes.png", "lobes/p_stable.npz", "discrepancy/discrepancy.json"):
        assert (demo_out / rel).stat().st_size > 0, rel
    html = (demo_out / "index.html").read_text()
    assert "First tool-point natural frequency" in html and "lobes/lobes.png" in html
    assert 'href="report.html"' in html and "True" not in html and "False" not in html
    report = (demo_out / "report.html").read_text()
    # self-contained: every figure embedded, nothing fetched from next to the page
    srcs = re.findall(r'<img[^>]* src="([^"]*)"', report)
    assert len(srcs) >= 6 and all(s.startswith("data:image/png;base64,") for s in srcs)
    # the demo's posterior is importance-sampled (the default): the report says so, not a chain's R-hat verdict
    assert "importance-sampled exactly and accepted" in report and "R-hat &lt; 1.01" not in report
    assert "importance sampling of the exact posterior (accepted)" in report  # the run facts' sampler row
    for section in ("Sampler convergence", "Identified parameters", "Corner plot", "FRF bands around each mode",
                    "predictive 90 % interval of a new measured peak", "Stability lobes", "recommended operating point"):
        assert section in report, section


def test_demo_predictions_are_scored_against_the_bench_truth(demo_out):
    truth = json.loads((example_dir() / "truth.json").read_text())
    true_f = {(m["clamping_length"], m["direction"]): m["dominant_frequency_hz"] for m in truth["measurements"]}
    summary = json.loads((demo_out / "identify" / "summary.json").read_text())
    assert summary["converged"] is True
    # the default sampler: importance sampling of the exact posterior, accepted by its own diagnostics
    how = summary["sampler"]
    assert how["mode"] == "importance" and how["pareto_k"] <= 0.7 and how["ess"] >= 1000
    for p in summary["parameters"].values():
        assert p["rhat"] is None and p["ess_bulk"] >= 1000
    preds = [p for p in json.loads((demo_out / "predict" / "frequencies.json").read_text())["predictions"]
             if p["mode"] == 1]
    assert {round(p["clamping_length"], 3) for p in preds} == {0.025, 0.03, 0.035, 0.04}
    for p in preds:
        f_true = true_f[(round(p["clamping_length"], 3), p["direction"])]
        # The RCSA model reproduces the lumped FE bench to ~1e-6 (test_synthetic), so the only error is
        # the measurement noise: held-out 30/35 mm included, the median lands within 0.2 % of the truth.
        assert abs(p["q50_hz"] - f_true) / f_true < 2e-3, p
        assert p["q05_hz"] <= p["q50_hz"] <= p["q95_hz"]


def test_demo_lobes_are_a_probability_map(demo_out):
    lobes = json.loads((demo_out / "lobes" / "lobes.json").read_text())
    q = {k: np.array([np.nan if v is None else v for v in lobes["depth_limit_m"][k]]) for k in ("q05", "q50", "q95")}
    ok = np.isfinite(q["q05"]) & np.isfinite(q["q95"])
    assert ok.sum() > 100
    assert np.all(q["q05"][ok] <= q["q50"][ok] + 1e-15) and np.all(q["q50"][ok] <= q["q95"][ok] + 1e-15)
    p = np.load(demo_out / "lobes" / "p_stable.npz")
    ps = p["p_stable"]  # (n_speeds, n_depths)
    assert ps.shape == (p["spindle_speed_rpm"].size, p["depth_m"].size)
    assert np.all(np.diff(ps, axis=-1) <= 1e-12)  # P(stable) never grows with depth
    rec = lobes["recommended"]
    assert rec is not None and rec["p_stable"] >= 0.95


def test_demo_checks_the_model_and_links_the_finding(demo_out):
    # the bundled campaign was made without hidden effects: the model check must not invent physics
    disc = json.loads((demo_out / "discrepancy" / "discrepancy.json").read_text())
    assert disc["named_effect"] is None and disc["gap_metric"]
    html = (demo_out / "index.html").read_text()
    assert 'href="discrepancy/summary.md"' in html and "Model check" in html
    assert (demo_out / "discrepancy" / "summary.md").stat().st_size > 0
    assert "discrepancy" in (demo_out / "report.html").read_text().lower()


def test_demo_speaks_a_machinist_s_words_in_every_human_output(demo_run):
    """No internal identifier, metre, exponent, Python list or placeholder in what the demo prints and writes
    for people, and the same number reads the same on stderr, in summary.md and in the HTML (docs/data-formats.md,
    "Numbers and names for people"; the scanner: tests/human_text.py)."""
    from human_text import identifiers, markdown_text, offences, visible_text

    from bayes_rcsa.units import mm, percent, rpm

    out, err = demo_run
    summary = json.loads((out / "identify" / "summary.json").read_text())
    names = identifiers(summary["parameter_names"])
    # the echoed command lines are what the user typed (option values such as --method zoa), not output
    printed = "\n".join(line for line in err.splitlines() if not line.startswith("$ "))
    assert "bayes-rcsa lobes: wrote" in printed and "bayes-rcsa identify: " in printed
    pages = {"stderr": printed}
    pages.update({str(p.relative_to(out)): markdown_text(p.read_text()) for p in out.rglob("*.md")})
    pages.update({str(p.relative_to(out)): visible_text(p.read_text()) for p in out.rglob("*.html")})
    assert {"summary.md", "discrepancy/summary.md", "predict/report.md", "index.html", "report.html",
            "predict/report.html"} <= set(pages)
    found = {name: offences(text, names) for name, text in pages.items()}
    assert not any(found.values()), {k: v[:5] for k, v in found.items() if v}
    # one number, one reading: the recommended point and the cost of the confidence everywhere they appear
    lobes = json.loads((out / "lobes" / "lobes.json").read_text())
    rec, cost = lobes["recommended"], lobes["confidence_cost"]
    for where in ("stderr", "summary.md", "index.html", "report.html"):
        assert rpm(rec["spindle_speed_rpm"], unit=False) in pages[where] and mm(rec["depth_m"])[:-3] in pages[where]
    for where in ("stderr", "summary.md", "report.html"):
        assert mm(cost["depth_m"]) in pages[where] and percent(cost["relative"]) in pages[where], where
