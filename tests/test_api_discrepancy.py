"""The public model check: ``bayes_rcsa.workflows.model_check`` and its :class:`ModelCheck`.

One computed check (a synthetic campaign with a hidden 2 g tip mass, 4 Hz lines, two candidates: the cheapest
run that names an effect) serves every test; the command line is checked against it by handing it the same
check (its computation is the same call).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.cli import main as cli_main
from bayes_rcsa.errors import SetupError
from bayes_rcsa.vocabulary import in_words
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign
from bayes_rcsa.workflows import model_check as api
from bayes_rcsa.workflows.model_check import ModelCheck, check_model

FIT = (0.025, 0.040)
CANDIDATES = ("tip_mass", "contact_damping")
PLOTS = {"frf_before_after", "residuals_before_after", "frequency_errors", "stiffness_before_after"}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    cfg = default_bench_config(hidden_effects={"tip_mass": True}, frequency_step=4.0)
    return Path(write_campaign(generate_campaign(cfg, np.random.default_rng(0)), tmp_path_factory.mktemp("tip") / "c"))


@pytest.fixture(scope="module")
def check(campaign):
    return check_model(campaign, lengths=FIT, candidates=CANDIDATES, seed=0)


def _fresh(check: ModelCheck) -> ModelCheck:
    """A copy not yet saved (``save`` records where it wrote)."""
    return dataclasses.replace(check, report=copy.deepcopy(check.report), path=None, saved_files=())


def test_the_check_names_the_tip_mass_and_its_attributes_are_the_document(check):
    r = check.report
    assert check.named_effect == "tip_mass" == r["named_effect"] and not check.adequate
    assert check.gap_after < 0.5 * check.gap_before and (check.gap_before, check.gap_after) == (r["gap_before"],
                                                                                                 r["gap_after"])
    assert check.usable_for_prediction and not check.gap_grew and check.final_terms == ("tip_mass",)
    first, second = check.candidates
    assert (first.effect, first.name, second.name) == ("tip_mass", "mass at the tool tip", "joint damping off the assumed value")
    assert first.criterion == r["candidates"][0]["criterion"] > np.log(100)
    # the fraction of the baseline's systematic gap at the fitted lines each candidate removes: the tip mass
    # all of it, the joint damping part; the same ratio the naming rule uses (select.decide)
    from bayes_rcsa.discrepancy.select import fitted_systematic_gap

    base = fitted_systematic_gap(check.computation.baseline)["gap"]
    for c, refit in zip(check.candidates, check.computation.decision["ranked"]):
        assert c.explained_gap == pytest.approx(1 - refit.systematic["gap"] / base)
    assert first.explained_gap > 0.9 and second.explained_gap < first.explained_gap
    assert check.warnings and tuple(r["warnings"]) == check.warnings


def test_the_final_model_posterior_is_inference_data(check):
    idata = check.inference_data
    tm = idata.posterior["tip_mass_kg"].values
    assert tm.shape == (1, 400)
    q = check.report["candidates"][0]["parameters"]["tip_mass_kg"]
    assert q["q05"] < float(np.median(tm)) < q["q95"] and 0.0015 < float(np.median(tm)) < 0.0025  # the true 2 g
    assert set(check.posterior_draws) >= {"tip_mass_kg", "tip_mass_offset_m"}


def test_the_command_line_saves_the_check_of_the_same_call(check, campaign, tmp_path, monkeypatch, capsys):
    calls = []

    def fake(setup, **kw):
        calls.append((setup, kw))
        return _fresh(check)

    monkeypatch.setattr(api, "check_model", fake)
    out = tmp_path / "disc"
    code = cli_main.main(["discrepancy", str(campaign), "--out", str(out), "--lengths", "0.025,0.040", "--seed", "0",
                          "--candidates", "tip_mass, contact_damping", "--no-plots", "--json"])
    captured = capsys.readouterr()
    assert code == 0
    assert calls == [(campaign, {"lengths": [0.025, 0.040], "candidates": list(CANDIDATES), "seed": 0,
                                 "n_refit": None, "progress": False})]
    assert json.loads((out / "discrepancy.json").read_text()) == check.to_dict()
    saved = dataclasses.replace(_fresh(check), path=out)
    err = captured.err.strip().splitlines()
    assert err[-1] == f"bayes-rcsa discrepancy: {saved.summary_line()}"
    assert err[-1].endswith(f"wrote {out}/discrepancy.json and setup.amended.toml")
    assert err[:-1] == [f"bayes-rcsa discrepancy: warning: {in_words(w)}" for w in check.warnings]  # printed in words
    data = json.loads(captured.out)
    assert data["files"] == [str(out.resolve() / n) for n in ("setup.amended.toml", "discrepancy.json", "summary.md")]
    assert {k: data[k] for k in check.summary_data()} == check.summary_data()


def test_save_load_round_trip_and_figures(check, campaign, tmp_path):
    first = _fresh(check)
    main = first.save(tmp_path / "a")  # figures() draws the four plots it writes
    assert main == tmp_path / "a" / "discrepancy.json"
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == sorted(ModelCheck.files)
    assert {f"{name}.png" for name in PLOTS} <= {p.name for p in first.saved_files}
    loaded = ModelCheck.load(tmp_path / "a", setup=campaign)
    assert loaded.to_dict() == check.to_dict() and loaded.warnings == check.warnings
    assert loaded.headline() == check.headline() and loaded.summary_line() == first.summary_line()
    assert loaded.candidates == check.candidates and loaded.named_effect == "tip_mass"
    assert loaded.inference_data is None  # no fit is stored
    figures = loaded.figures()  # no FRFs are stored: the plots of the document only
    assert set(figures) == {"frequency_errors", "stiffness_before_after"}
    assert all(f.axes and f.axes[0].lines for f in figures.values())
    # a loaded check saved elsewhere: the same document, text and amended setup (its files found from there)
    ModelCheck.load(tmp_path / "a").save(tmp_path / "b" / "deeper", plots=False)
    for name in ("discrepancy.json", "summary.md"):
        assert (tmp_path / "b" / "deeper" / name).read_bytes() == (tmp_path / "a" / name).read_bytes()
    amended = load_setup(tmp_path / "b" / "deeper" / "setup.amended.toml")
    assert amended.model_table["terms"] == ["tip_mass"] and all(m.frf is not None for m in amended.measurements)
    with pytest.raises(SetupError, match="use --force"):
        first.save(tmp_path / "a")


def test_notebook_view_speaks_a_machinist_s_words(check):
    text = check._repr_html_()
    rows = dict(check.headline())
    assert rows["Missing effect"] == "mass at the tool tip" and rows["Usable for prediction"] == "yes"
    assert f"{100 * check.gap_before:.2g} %" in text and "at the noise floor (below" in text
    assert "tip mass (kg)" in text  # the parameter's printed label, with its unit
    for internal in ("tip_mass", "systematic_relative_residual", "gap_before", "k_xf", "statistical_discrepancy"):
        assert internal not in "".join(k + v for k, v in check.headline()), internal


def test_warnings_issued_during_the_check_reach_the_result_and_every_file(check, campaign, tmp_path, monkeypatch,
                                                                          capsys):
    import bayes_rcsa.discrepancy.workflow as wf

    def fake(setup, options, progress=None):
        progress("screen: tip_mass 12")
        warnings.warn("spindle file: coherence below 0.8 at 3 lines")
        res = copy.copy(check.computation)
        res.report = copy.deepcopy(check.computation.report)
        return res

    monkeypatch.setattr(wf, "run_discrepancy", fake)
    with pytest.warns(UserWarning, match="coherence below"):  # a script sees it at once, and keeps it
        result = check_model(campaign, lengths=FIT, candidates=CANDIDATES, progress=True)
    assert capsys.readouterr().err.startswith("bayes-rcsa discrepancy: screen: tip_mass 12\n")
    assert result.warnings[0] == "spindle file: coherence below 0.8 at 3 lines"
    assert result.warnings[1:] == check.warnings
    result.save(tmp_path / "w", plots=False)
    doc = json.loads((tmp_path / "w" / "discrepancy.json").read_text())
    assert doc["warnings"] == list(result.warnings)


def test_bad_candidates_are_refused_before_any_fit(campaign):
    with pytest.raises(SetupError, match="flying_saucer.*tip_mass|tip_mass.*flying_saucer"):
        check_model(campaign, lengths=FIT, candidates=("tip_mass", "flying_saucer"))
    with pytest.raises(SetupError, match="at least one effect"):
        check_model(campaign, lengths=FIT, candidates=())
