"""Human outputs in a machinist's words and one unit policy (issue #45 items 2, 3, 7; docs/data-formats.md,
"Numbers and names for people").

The policy lives in bayes_rcsa/units.py and bayes_rcsa/vocabulary.py; the scanner of stderr, Markdown and HTML is
tests/human_text.py.  The demo's outputs (identify, predict, lobes, discrepancy, report, index.html, summary.md)
are scanned by tests/test_demo.py on its module fixture and the report of a named effect, a design and a
library by tests/test_report_html.py, so that no command runs twice for this; this file covers the policy
itself, the scanner (it must catch every case measured on main) and the commands no other fixture here covers
cheaply: simulate, the batch summary table and the result views of design, library and update documents.
"""

from __future__ import annotations

import re


from bayes_rcsa import units, vocabulary
from bayes_rcsa.cli.main import main
from human_text import identifiers, offences, visible_text

# -- the policy -------------------------------------------------------------------------------------------------


def test_every_registered_identifier_has_printed_words():
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.data import example_dir
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
    from bayes_rcsa.params.terms import TERMS
    from bayes_rcsa.stability.methods import STABILITY_METHODS

    assert set(TERMS.names()) <= set(vocabulary.EFFECTS), set(TERMS.names()) - set(vocabulary.EFFECTS)
    assert set(STABILITY_METHODS.names()) <= set(vocabulary.STABILITY_METHODS)
    for term in TERMS.names():
        assert "_" not in vocabulary.effect_name(term) and vocabulary.effect_sentence(term).endswith(".")
    setup = load_setup(example_dir() / "setup.toml", load_data=True)
    pm = build_problem_from_setup(setup, IdentificationOptions(lengths=(0.025, 0.040))).parameters
    measurements = ["25 mm x", "25 mm y", "40 mm x", "40 mm y"]
    printed = {n: vocabulary.parameter_name(n, pm[n].label, measurements) for n in pm.all_names}
    assert printed["k_xf"] == "contact stiffness, translational (kxf)"
    assert printed["c_thetaM"] == "contact damping, rotational (cθM)" and printed["sigma_2"] == "noise scale, 40 mm x"
    for name, words in printed.items():
        assert name not in words and "_" not in words, (name, words)
    assert vocabulary.method_name("zoa") == "zero-order approximation"
    assert vocabulary.gap_name("systematic_relative_residual: sqrt(...)").startswith("systematic mismatch")
    library = vocabulary.identification_name("multi", library=True)
    assert library == "Bayesian fit of the tap tests with the library prior"


def test_numbers_read_one_way():
    # the cases measured on main (#45): metres, lists, exponents, unequal digits
    assert units.mm(5.321e-05) == "0.053 mm" and units.mm(0.000164344) == "0.164 mm"
    assert units.mm(3.88e-7) == "0.00039 mm" and units.mm(0.0) == "0 mm"
    assert units.hz(859.893, 859.848, 859.939) == "859.89 Hz (859.85–859.94)"
    assert units.hz(1075.9, 1074.2, 1077.6) == "1075.9 Hz (1074.2–1077.6)" and units.hz(859.8) == "859.8 Hz"
    assert units.hz(962.0, 955.0, 970.0) == "962 Hz (955–970)"
    assert units.sci(2.34e6, 3, 2.34e6, 2.342e6, "N/m") == "2.340×10⁶ N/m (2.340×10⁶–2.342×10⁶)"
    assert units.sci(2.34e6, unit="N/m") == "2.34×10⁶ N/m" and units.sci(4.84e5) == "484×10³"
    assert units.rpm(13647.4) == "13647 rpm" and units.length_mm(0.025) == "25 mm"
    assert units.num(1.2e-5) == "12×10⁻⁶" and units.num(0.02213) == "0.02213" and units.percent(0.0024) == "0.24 %"
    for x in (units.parse("2.340×10⁶"), units.parse("12×10⁻⁶"), units.parse("0.164")):
        assert x in (2.34e6, 1.2e-5, 0.164)
    assert units.width(2.345, "Hz") == "2.35 Hz" and units.width(5.321e-05, "m") == "0.053 mm"


def test_warnings_are_printed_in_words_but_setup_keys_stay_as_typed():
    text = "k_xf: R-hat = 1.02; sigma_1 piles up; spindle_error fits; [priors] k_xf = 3; 'k_thetaM'; k_xf.json"
    out = vocabulary.in_words(text, ["25 mm x", "25 mm y"])
    assert out.startswith("contact stiffness, translational (kxf): R-hat = 1.02; noise scale, 25 mm y piles up; "
                          "spindle file off the real spindle fits; [priors] k_xf = 3; 'k_thetaM'; k_xf.json")


def test_the_scanner_catches_every_case_measured_on_main():
    names = identifiers(["k_xf", "sigma_0"])
    measured = {  # issue #45, "What was measured" 4, 5, 8
        "Gap (systematic_relative_residual): 0 before, 0 after": "identifier",
        "next best explanation spindle_error": "identifier", "Method zoa, 300 draws": "identifier",
        "| k_xf | 1.8e+06 |": "identifier", "sigma_0 0.022": "identifier",
        "next cut 13647 rpm, 5.321e-05 m": "exponent", "depth 0.5 m": "metres",
        "859.893 [859.848, 859.939]": "list of numbers", "1 holder type(s) ['ER32']": "list of strings",
        "x 30 mm, tool tool": "doubled", "Warnings:\n- none\n": "'none'", "value None": "placeholder",
    }
    for text, what in measured.items():
        found = offences(text, names)
        assert any(what in f for f in found), (text, found)
    clean = ("recommended 13647 rpm, 0.164 mm; 2.34×10⁶ N/m (2.30×10⁶–2.38×10⁶); 859.89 Hz (859.85–859.94); "
             "wrote /tmp/k_xf/lobes.json, p_stable.npz; none of the known effects; 12.3×10⁻⁶ m/N; N m/rad")
    assert offences(clean, names) == []


# -- commands no other fixture covers here ---------------------------------------------------------------------


def test_simulate_prints_in_words(example, capsys):
    assert main(["simulate", str(example), "--clamping-length", "0.03", "--kx", "2.07e6", "--ktheta", "5.175e5",
                 "--out", str(example.parent / "sim.csv")]) == 0
    err = capsys.readouterr().err
    assert offences(err, identifiers()) == []
    assert re.search(r"largest \|h\| [\d.]+×10⁻[⁰-⁹¹²³]+ m/N at [\d.]+ Hz", err)


def test_the_batch_summary_shows_a_readable_core_table(tmp_path):
    from bayes_rcsa.batch.table import write_summary

    row = {"name": "tool0", "status": "done", "method": "multi", "converged": False, "n_warnings": 1,
           "warnings": ["identify: a warning"], "k_xf_q05": 1.79e6, "k_xf_q50": 1.80e6, "k_xf_q95": 1.81e6,
           "k_thetaM_q05": 4.2e5, "k_thetaM_q50": 5.0e5, "k_thetaM_q95": 5.6e5, "fn_30mm_x_q05_hz": 962.72,
           "fn_30mm_x_q50_hz": 962.76, "fn_30mm_x_q95_hz": 962.81, "lobes_speed_rpm": 13647.2,
           "lobes_depth_m": 0.000164344, "lobes_p_stable": 0.97, "lobes_limit": "stability"}
    failed = {"name": "tool1", "status": "failed", "failed_step": "identify", "error": "setup file not found"}
    page = write_summary([row, failed], tmp_path, "t")["html"].read_text()
    core, _, rest = page.partition("<details>")
    assert "</details>" in rest and "<th>lobes_depth_m</th>" in rest  # every CSV column behind the toggle
    text = visible_text(core)
    assert offences(text, identifiers(["k_xf", "k_thetaM"])) == [] and "_q50" not in text
    assert len(re.findall(r"<th>", core)) <= 12  # fits a screen: not the ~60 CSV columns
    for cell in ("1.80×10⁶ (1.79×10⁶–1.81×10⁶)", "30 mm x: 962.76 (962.72–962.81)", "<td class=\"\">13647</td>",
                 "<td class=\"\">0.164</td>", "NOT converged", "failed (identify: setup file not found)"):
        assert cell in core, cell


def _lines(result) -> str:
    return result.summary_line() + "\n" + "\n".join(f"{k}: {v}" for k, v in result.headline()) + \
        "\n" + visible_text(result._repr_html_())


def test_design_library_and_update_views_use_the_policy():
    from types import SimpleNamespace

    from bayes_rcsa.workflows.cut_update import CutUpdate
    from bayes_rcsa.workflows.experiment_design import Design
    from bayes_rcsa.workflows.library import Population

    names = identifiers(["k_xf", "k_thetaM"])
    cut = Design(document={"mode": "next_cut", "best": {"speed_rpm": 9000.4, "depth_m": 5.321e-05, "p_chatter": 0.5,
                                                        "gain": 0.0123}, "current": 0.456}, folder="out")
    assert "next cut 9000 rpm, 0.053 mm" in cut.summary_line() and offences(_lines(cut), names) == []
    worth = Design(document={"mode": "posterior", "target": "lobes@0.03:5000:30000", "unit": "m",
                             "current_width": 8.2e-5, "worth_it": True, "verdict": "kept for JSON",
                             "best": {"test": "x 40 mm, tool tool", "clamping_length": 0.04, "direction": "x",
                                      "tool": "tool", "expected_width": 4.1e-5}}, folder="out")
    assert worth.summary_line().startswith("measure x at 40 mm: expected to shrink the 90 % width of "
                                           "lobes@0.03:5000:30000 from 0.082 mm to 0.041 mm")
    assert worth.summary_data()["verdict"] == "kept for JSON" and offences(_lines(worth), names) == []
    law = {"holder_type": "ER32", "parameter": "k_xf", "unit": "N/m", "median_at_10mm": 2.34e6,
           "median_at_10mm_q05": 2.1e6, "median_at_10mm_q95": 2.6e6}
    lib = Population(population=SimpleNamespace(holder_types=["ER32"]), setups=[{"name": "a"}, {"name": "b"}],
                     document={"laws": [law]}, folder="lib")
    assert "2 combination(s) in 1 holder type(s) (ER32); outliers: no outlier" in lib.summary_line()
    assert ("ER32: contact stiffness, translational (kxf) at 10 mm shank, 90 % interval",
            "2.34×10⁶ N/m (2.10×10⁶–2.60×10⁶)") in lib.headline()
    assert offences(_lines(lib), names) == []
    rec = {"spindle_speed_rpm": 9100.2, "depth_m": 6.2e-4}
    upd = CutUpdate(document={"inputs": {"n_cuts": 6}, "sampler": "importance",
                              "ess": {"draws": 480.0, "n_draws": 500}, "kt_pa": {"after": [7.8e8, 7.9e8, 8.0e8]},
                              "kr_pa": {"after": [2.2e8, 2.3e8, 2.4e8]},
                              "lobes": {"hammer_only": {"recommended": None}, "with_cuts": {"recommended": rec}}},
                    folder="upd")
    assert "tangential cutting coefficient Kt 790 MPa (780–800)" in upd.summary_line()
    assert "recommendation hammer only no recommendation -> with cuts 9100 rpm, 0.620 mm" in upd.summary_line()
    assert offences(_lines(upd), names) == []
