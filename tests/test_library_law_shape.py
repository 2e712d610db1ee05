"""A tool library's population as the prior of the unexplained remainder's law shape (issue #43 item 6).

Pooling ``law_shape_bend`` (stage-1 stand-ins: Gaussian draws, as in tests/test_library.py), the contact-only
prior of a new setup, the remainder's refit with the library's prior and its report, and the command line's
refusal.  The validation on the rotor bench is benchmarks/library_law_shape.py (docs/discrepancy.md).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.discrepancy import DiscrepancyOptions, run_discrepancy
from bayes_rcsa.discrepancy.law_shape import ENVELOPE_TEXT, LawShapePrior, law_shape_report
from bayes_rcsa.discrepancy.render import summary_markdown
from bayes_rcsa.errors import SetupError
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.library.newsetup import library_options
from bayes_rcsa.library.population import Hyperprior
from bayes_rcsa.library.predictive import Population, law_shape_prior, predictive_prior
from bayes_rcsa.library.stage1 import pooled_shape_coordinates, shank_diameter
from bayes_rcsa.library.stage2 import SetupDraws, Stage2Settings, fit_population
from bayes_rcsa.params.priors import Normal
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

NAMES = ("k_xf", "law_shape_bend")
BOX = np.array([[4.0, 10.0], [0.0, 1.0]])
#: sd of a uniform on [0, 1]: what the envelope carries
UNIFORM_SD = 1.0 / np.sqrt(12.0)


def _setups(rng, u_mean, n=6, n_draws=800):
    """Stage-1 stand-ins of one holder type: each combination's bend scattered by 0.03 about ``u_mean`` and
    measured at three or more lengths to sd 0.04 (its draws), the stiffness as in tests/test_library.py."""
    out = []
    for i, dia in enumerate(np.linspace(0.006, 0.016, n)):
        z = np.array([7.0 + 1.5 * np.log(dia / 0.01), u_mean]) + np.array([0.06, 0.03]) * rng.standard_normal(2)
        sd = np.array([0.01, 0.04])
        draws = z + sd * rng.standard_normal((n_draws, 2))
        out.append(SetupDraws(f"s{i}", "ER32", float(dia), draws, np.zeros(2), np.zeros((2, 2)), BOX))
    return out


def _pooled(u_mean, seed):
    rng = np.random.default_rng(seed)
    setups = _setups(rng, u_mean)
    hyper = Hyperprior.from_box(NAMES, BOX, 0.5)
    res = fit_population(setups, hyper, rng, Stage2Settings(n_burn=100, ess_target=200, max_steps=200))
    return Population(NAMES, {"ER32": res.types["ER32"].flat}, BOX, (0.025, 0.040, 0.5), {"ER32": (0.006, 0.016)},
                      counts={"ER32": len(setups)})


@pytest.fixture(scope="module")
def pop_quarter():
    return _pooled(0.25, 58001)


def test_the_bend_gets_its_own_hyperprior_scale_and_the_others_keep_theirs():
    h = Hyperprior.from_box(("k_xf", "g_xf", "law_shape_bend"), np.array([[4.0, 10.0], [0.0, 0.5], [0.0, 1.0]]), 0.5)
    # the growth formula with Q = 1 (the bend's box width): slope sd 1 per e-fold, spread scale 0.5 (median 0.1)
    assert np.allclose(h.b_sd, [2.0, 0.5, 1.0]) and np.allclose(h.tb_scale, [0.25, 0.0625, 0.125])
    assert np.allclose(np.exp(h.ls_mean), [0.1, 0.05, 0.1])
    # a library without the bend: exactly the former defaults
    h2 = Hyperprior.from_box(("k_xf", "g_xf"), np.array([[4.0, 10.0], [0.0, 0.5]]), 0.5)
    assert np.allclose(h2.b_sd, [2.0, 0.5]) and np.allclose(np.exp(h2.ls_mean), [0.1, 0.05])


def _fit(names, n_lengths):
    return SimpleNamespace(parameters=SimpleNamespace(names=names), fit_lengths=tuple(0.02 + 0.005 * np.arange(n_lengths)))


def test_the_bend_is_pooled_only_when_every_setup_samples_it_at_three_or_more_lengths():
    contact = ("k_xf", "k_thetaM", "g_xf", "g_thetaM")
    with_bend = contact + ("law_shape_bend",)
    assert pooled_shape_coordinates([("a", _fit(contact, 3)), ("b", _fit(contact, 3))]) == ((), [])
    assert pooled_shape_coordinates([("a", _fit(with_bend, 3)), ("b", _fit(with_bend, 4))]) == (("law_shape_bend",), [])
    names, warns = pooled_shape_coordinates([("a", _fit(with_bend, 3)), ("b", _fit(contact, 3))])
    assert names == () and len(warns) == 1 and "sampled by 1 of 2 setups" in warns[0]
    names, warns = pooled_shape_coordinates([("a", _fit(with_bend, 2)), ("b", _fit(with_bend, 3))])
    assert names == () and "fewer than 3 fitted clamping lengths" in warns[0] and "a (2)" in warns[0]


def test_a_pooled_bend_gives_a_narrow_truncated_normal_prior(pop_quarter):
    prior, info, warns = law_shape_prior(pop_quarter, "ER32", 0.010, np.random.default_rng(3))
    # six combinations scattered by 0.03 about 0.25, each measured to 0.04: the predictive is centred on 0.25
    # within a few hundredths (the hyperparameters' uncertainty with six setups, 0.03 / sqrt(6) plus the stage-1
    # sd 0.04 / sqrt(6) ~ 0.02 each) and far narrower than the envelope's 0.29
    assert abs(info["mean"] - 0.25) < 0.06, info
    assert info["sd"] < 0.5 * UNIFORM_SD, info
    assert info["q05"] < 0.25 < info["q95"] and info["n_combinations"] == 6 and info["holder_type"] == "ER32"
    assert prior == Normal(info["mean"], info["sd"], 0.0, 1.0)
    assert not warns
    with pytest.raises(SetupError, match="'HSK' is not in the library"):
        law_shape_prior(pop_quarter, "HSK", 0.010, np.random.default_rng(3))
    # a population without the bend: no prior, and why
    contact_only = Population(("k_xf",), {"ER32": pop_quarter.draws["ER32"][:, [0, 2, 4]]}, BOX[:1],
                              pop_quarter.growth, pop_quarter.diameters)
    prior, info, _ = law_shape_prior(contact_only, "ER32", 0.010, np.random.default_rng(3))
    assert prior is None and info["source"] == "envelope" and "does not pool law_shape_bend" in info["reason"]


def test_a_new_setup_gets_a_contact_prior_without_the_bend(example, pop_quarter):
    text = example.read_text(encoding="utf-8").replace("\n[holder]\n", '\n[holder]\ntype = "ER32"\n', 1)
    example.write_text(text, encoding="utf-8")
    setup = load_setup(example, load_data=False)
    kw, _ = library_options(pop_quarter, setup, np.random.default_rng(4))
    assert kw["contact_prior"].names == ("k_xf",)
    # the marginal of the moment-matched joint over both (the same draws): its stiffness row and column
    joint, _ = predictive_prior(pop_quarter, "ER32", shank_diameter(setup), np.random.default_rng(4))
    assert joint.names == NAMES and kw["contact_prior"].mean[0] == joint.mean[0]
    assert kw["contact_prior"].cov[0][0] == pytest.approx(joint.cov[0][0], rel=1e-12) and kw["contact_prior"].hi == (10.0,)


@pytest.fixture(scope="module")
def remainder(tmp_path_factory):
    """tests/test_discrepancy_workflow.py's cheapest remainder: a flange resonance with tip_mass the only candidate,
    refitted with a library's bend prior concentrated near 0.1 (close to the parallel law)."""
    cfg = default_bench_config(hidden_effects={"extra_mode": True})
    camp = generate_campaign(cfg, np.random.default_rng(3))
    path = Path(write_campaign(camp, tmp_path_factory.mktemp("flange3") / "c"))
    pop = _pooled(0.1, 58002)
    prior, info, _ = law_shape_prior(pop, "ER32", 0.010, np.random.default_rng(5))
    law = LawShapePrior.from_library(prior, info)
    res = run_discrepancy(load_setup(path), DiscrepancyOptions(lengths=(0.025, 0.040), candidates=("tip_mass",),
                                                               n_refit=1, leave_one_out=False, law_shape=law))
    return res, law


def test_the_remainder_refits_the_bend_with_the_library_prior_and_says_so(remainder):
    res, law = remainder
    r = res.report
    assert r["final_model"] == "statistical_discrepancy" and "law_shape_uncertainty" in r["final_terms"]
    got = res.final.problem.parameters["law_shape_bend"].prior
    assert isinstance(got, Normal) and got == law.prior and (got.lo, got.hi) == (0.0, 1.0)
    assert got.mu < 0.2 and got.sigma < 0.5 * UNIFORM_SD  # concentrated near the parallel law, not the envelope
    entry = r["law_shape_prior"]
    assert entry["source"] == "library" and entry["holder_type"] == "ER32" and entry["n_combinations"] == 6
    assert entry["mean"] == pytest.approx(law.mean) and entry["sd"] == pytest.approx(law.sd)
    assert entry["text"].startswith("library population of holder type ER32 (6 combinations): mean ")
    md = summary_markdown(r)
    assert "holder type ER32 in the tool library" in md and "law_shape" not in md
    # without a library the remainder's problem has the envelope, and the report and summary say so
    from bayes_rcsa.discrepancy.workflow import _problem, remainder_terms
    from bayes_rcsa.inference.problem import IdentificationOptions

    setup = res.setup
    p = _problem(setup, IdentificationOptions.from_setup(setup.extra, lengths=(0.025, 0.040)),
                 remainder_terms(setup, res.baseline.problem))
    assert p.parameters["law_shape_bend"].prior.describe() == {"distribution": "uniform", "lo": 0.0, "hi": 1.0}
    entry = law_shape_report(SimpleNamespace(problem=p), None)
    assert entry["source"] == "envelope" and entry["text"] == ENVELOPE_TEXT
    assert "allow the whole range between the two" in summary_markdown(dict(r, law_shape_prior=entry))
    # a named model or an adequate baseline samples no bend: no entry, no sentence
    assert law_shape_report(res.baseline, law) is None


def test_discrepancy_library_bad_input_is_one_line_and_exit_2(example, tmp_path, capsys):
    code = main(["discrepancy", str(example), "--out", str(tmp_path / "o"), "--library", str(tmp_path / "none.nc")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "none.nc" in err[0] and "not found" in err[0], err
    assert not (tmp_path / "o").exists()


def test_the_html_report_says_which_law_shape_the_remainder_used(remainder, tmp_path):
    import json

    from bayes_rcsa.report import write_report_html

    res, _ = remainder
    folder = tmp_path / "discrepancy"
    folder.mkdir()
    (folder / "discrepancy.json").write_text(json.dumps(res.report, default=float), encoding="utf-8")
    page = write_report_html([folder], tmp_path / "r.html").read_text(encoding="utf-8")
    assert 'id="discrepancy-law-shape-1"' in page and "holder type ER32 in the tool library" in page


def test_discrepancy_library_of_another_holder_type_is_refused_before_fitting(example, pop_quarter, tmp_path, capsys):
    from bayes_rcsa.library.outputs import read_population, write_population

    path = tmp_path / "population.nc"
    rows = [{"name": "c0", "holder_type": "ER32", "diameter_m": 0.008, "ess": 500.0, "p_value": 0.5,
             "outlier": False, **{f"{c}_own": [0.0, 0.1, 0.2] for c in NAMES}}]
    write_population(path, pop_quarter, rows, Hyperprior.from_box(NAMES, BOX, 0.5).describe())
    back = read_population(path)
    assert back.names == NAMES and back.counts == {"ER32": 1}  # the combinations of each type, from the file
    for holder, expected in (("", "no [holder] type"), ('type = "BT40"\n', "'BT40' is not in the library")):
        example.write_text(example.read_text(encoding="utf-8").replace("\n[holder]\n", f"\n[holder]\n{holder}", 1),
                           encoding="utf-8")
        out = tmp_path / f"o{len(holder)}"
        code = main(["discrepancy", str(example), "--out", str(out), "--library", str(path)])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and expected in err[0], err
        assert not out.exists()


def test_a_library_without_the_bend_leaves_the_envelope_and_says_why(remainder, pop_quarter):
    from bayes_rcsa.workflows.model_check import check_model

    res, _ = remainder
    path = Path(res.setup.path)
    path.write_text(path.read_text(encoding="utf-8").replace("\n[holder]\n", '\n[holder]\ntype = "ER32"\n', 1),
                    encoding="utf-8")
    contact_only = Population(("k_xf",), {"ER32": pop_quarter.draws["ER32"][:, [0, 2, 4]]}, BOX[:1],
                              pop_quarter.growth, {"ER32": (0.006, 0.016)})
    check = check_model(path, lengths=(0.025, 0.040), candidates=["tip_mass"], n_refit=1, leave_one_out=False,
                        library=contact_only)
    entry = check.report["law_shape_prior"]
    assert entry["source"] == "envelope" and "does not pool law_shape_bend" in entry["library_not_used"]
    assert check.computation.final.problem.parameters["law_shape_bend"].prior.describe()["distribution"] == "uniform"
    assert any(w.startswith("--library: the library does not pool law_shape_bend") for w in check.warnings)


def test_identify_of_a_new_setup_with_the_law_shape_term_takes_the_library_s_bend(example, pop_quarter):
    # a new combination fitted with law_shape_uncertainty in its model: one or two taps do not place the law between
    # the lengths, the library's combinations at three or more did; its bend prior is the population's (near 0.25)
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup

    text = example.read_text(encoding="utf-8").replace("\n[holder]\n", '\n[holder]\ntype = "ER32"\n', 1)
    example.write_text(text + '\n[model]\nterms = ["law_shape_uncertainty"]\n', encoding="utf-8")
    setup = load_setup(example)
    kw, warns = library_options(pop_quarter, setup, np.random.default_rng(4))
    assert kw["contact_prior"].names == ("k_xf",)
    entry = kw["model"]["law_shape_bend"]
    assert entry["distribution"] == "normal" and (entry["lo"], entry["hi"]) == (0.0, 1.0)
    # the pooled bend is 0.25 with a population spread of 0.03 (the stand-ins above): tolerances of 2 spreads
    assert abs(entry["mu"] - 0.25) < 0.06 and entry["sigma"] < 0.5 * UNIFORM_SD
    problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(setup.extra, **kw))
    prior = problem.parameters["law_shape_bend"].prior
    assert isinstance(prior, Normal) and prior.mu == entry["mu"] and prior.sigma == entry["sigma"]
    # the setup's own prior of the bend wins
    example.write_text(text + '\n[model]\nterms = ["law_shape_uncertainty"]\nlaw_shape_bend = {distribution = '
                       '"uniform", lo = 0.0, hi = 1.0}\n', encoding="utf-8")
    kw2, _ = library_options(pop_quarter, load_setup(example), np.random.default_rng(4))
    assert "model" not in kw2


def test_identify_with_a_library_that_does_not_pool_the_bend_keeps_the_term_s_prior_and_says_so(example, pop_quarter):
    text = example.read_text(encoding="utf-8").replace("\n[holder]\n", '\n[holder]\ntype = "ER32"\n', 1)
    example.write_text(text + '\n[model]\nterms = ["law_shape_uncertainty"]\n', encoding="utf-8")
    contact_only = Population(("k_xf",), {"ER32": pop_quarter.draws["ER32"][:, [0, 2, 4]]}, BOX[:1],
                              pop_quarter.growth, pop_quarter.diameters)
    kw, warns = library_options(contact_only, load_setup(example), np.random.default_rng(4))
    assert "model" not in kw
    assert any("does not pool law_shape_bend" in w and "keeps its prior" in w for w in warns), warns
