"""``bayes-rcsa library`` and ``identify --library`` end to end, and their bad input (#20).

A hand-made population (no stage 1) stands in for a fitted library where the population's numbers do
not matter; stage 1 itself runs on two tiny bench combinations (single sampler chunks, coarse lines)
under the process pool and a Dask LocalCluster.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.library.outputs import read_population, write_population
from bayes_rcsa.library.population import Hyperprior
from bayes_rcsa.library.predictive import Population

NAMES = ("k_xf", "k_thetaM", "g_xf", "g_thetaM")
BOX = np.array([[5.0, 9.0], [3.0, 8.0], [0.0, 0.5], [0.0, 0.5]])


def _population(tmp_path, version=None, growth=(0.025, 0.040, 0.5)):
    """A population of holder types ER32 and HSK near the bundled example's contact (k_xf ~ 2.5e6 N/m at 25 mm)."""
    rng = np.random.default_rng(1)
    n = 400
    draws = {}
    for t, shift in (("ER32", 0.0), ("HSK", 0.3)):
        a = np.array([6.4 + shift, 5.3, 0.25, 0.25]) + 0.02 * rng.standard_normal((n, 4))
        b = np.array([1.0, 1.5, 0.0, 0.0]) + 0.05 * rng.standard_normal((n, 4))
        s = np.abs(np.array([0.05, 0.08, 0.05, 0.05]) + 0.01 * rng.standard_normal((n, 4)))
        draws[t] = np.concatenate([a, b, s], axis=1)
    pop = Population(NAMES, draws, BOX, growth, {"ER32": (0.006, 0.012), "HSK": (0.006, 0.012)})
    rows = [{"name": "c0", "holder_type": "ER32", "diameter_m": 0.008, "ess": 500.0, "p_value": 0.5, "outlier": False,
             **{f"{c}_own": [0.0, 0.1, 0.2] for c in NAMES}}]
    path = tmp_path / "population.nc"
    attrs = {} if version is None else {"model_version": version}
    write_population(path, pop, rows, Hyperprior.from_box(NAMES, BOX, 0.5).describe(), attrs)
    return path


def _typed(example, holder_type='"ER32"', extra=""):
    text = example.read_text(encoding="utf-8")
    text = text.replace("\n[holder]\n", f"\n[holder]\ntype = {holder_type}\n", 1) if holder_type else text
    example.write_text(text + extra, encoding="utf-8")
    return example


def test_population_file_round_trips_and_is_arviz_readable(tmp_path):
    import arviz as az

    path = _population(tmp_path)
    pop = read_population(path)
    assert pop.names == NAMES and pop.holder_types == ("ER32", "HSK") and pop.growth == (0.025, 0.040, 0.5)
    idata = az.from_netcdf(str(path))
    assert idata.posterior["a"].dims == ("chain", "draw", "holder_type", "coordinate")
    assert json.loads(idata.attrs["coordinate_units"])["k_xf"] == "log10(N/m)"


def test_identify_with_the_library_one_tap_and_zero_taps_feed_predict_and_lobes(example, tmp_path, capsys):
    setup = _typed(example)
    pop = _population(tmp_path)
    one, zero = tmp_path / "one", tmp_path / "zero"
    assert main(["identify", str(setup), "--library", str(pop), "--lengths", "0.025", "--out", str(one),
                 "--max-steps", "60", "--walkers", "16", "--check-every", "30", "--no-plots", "--quiet"]) == 0
    post = json.loads((one / "summary.json").read_text())
    # the population is the prior: the growth factors are sampled from it even with a single length
    assert {"k_xf", "k_thetaM", "g_xf", "g_thetaM"} <= set(post["parameters"])
    assert post["priors"]["g_xf"]["distribution"] == "joint-normal"
    assert post["library"]["holder_type"] == "ER32" and post["library"]["population"] == str(pop)
    assert main(["identify", str(setup), "--library", str(pop), "--no-taps", "--out", str(zero)]) == 0
    zsum = json.loads((zero / "summary.json").read_text())
    assert zsum["method"] == "library-predictive" and any("zero taps" in w for w in zsum["warnings"])
    from bayes_rcsa.posterior.draws import load_posterior

    # zero taps: the population predictive at the example's 7.94 mm shank, 10^(6.4 + 1.0 ln(7.94 / 10)) N/m
    zdraws = load_posterior(zero / "posterior.nc")
    assert np.median(np.log10(zdraws.values["k_xf"])) == pytest.approx(6.4 + math.log(0.794), abs=0.03)
    # one tap: the joint prior travels in posterior.nc; the growth factors are sampled inside the library's box
    odraws = load_posterior(one / "posterior.nc")
    assert odraws.parameters["g_xf"].prior.kind == "joint-normal" and odraws.growth.l_b == 0.040
    g = odraws.values["g_xf"]
    assert np.ptp(g) > 0 and np.all((g >= 0) & (g <= 0.5))
    for name, d in (("one", one), ("zero", zero)):
        assert main(["predict", str(setup), "--posterior", str(d / "posterior.nc"), "--lengths", "0.030,0.040",
                     "--directions", "x", "--max-draws", "40", "--out", str(d / "pred"), "--no-plots", "--quiet"]) == 0
        preds = json.loads((d / "pred" / "frequencies.json").read_text())["predictions"]
        dom = [p for p in preds if p["dominant"] and p["clamping_length"] == pytest.approx(0.040)]
        assert dom and all(math.isfinite(p["q50_hz"]) for p in dom)
        assert main(["lobes", str(setup), "--posterior", str(d / "posterior.nc"), "--clamping-length", "0.030",
                     "--draws", "4", "--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95",
                     "--speeds", "5000:30000:12", "--depth-points", "12", "--out", str(d / "lobes"),
                     "--no-plots"]) == 0  # lobes.png is not read (shrinkage.png below is)
        assert json.loads((d / "lobes" / "lobes.json").read_text())["depth_limits_m"]


@pytest.mark.parametrize("case, expected", [
    ("unknown type", "holder type 'BT40' is not in the library's population (known: ['ER32', 'HSK'])"),
    ("no type", "no [holder] type; the library knows ['ER32', 'HSK']"),
    ("mixed units", "(mixed units?)"),
    # version 1 had no pooling across holder types: its file holds other hyperparameters
    ("other version", "model_version 'bayes_rcsa.library/1', expected 'bayes_rcsa.library/2'"),
    ("no library", "--no-taps needs --library"),
])
def test_identify_library_bad_input_is_one_line_and_exit_2(example, tmp_path, capsys, case, expected):
    # mixed units: a library whose lengths were given in mm (the setup parser refuses such a setup itself,
    # so the population file is made by hand)
    pop = _population(tmp_path, version="bayes_rcsa.library/1" if case == "other version" else None,
                      growth=(25.0, 40.0, 0.5) if case == "mixed units" else (0.025, 0.040, 0.5))
    if case == "unknown type":
        setup = _typed(example, '"BT40"')
    elif case == "no type":
        setup = _typed(example, None)
    else:
        setup = _typed(example)
    argv = ["identify", str(setup), "--out", str(tmp_path / "fit"), "--no-taps"]
    if case != "no library":
        argv += ["--library", str(pop)]
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and expected in err, err
    assert not (tmp_path / "fit").exists()


def test_library_with_one_combination_is_refused(example, tmp_path, capsys):
    setup = _typed(example)
    manifest = tmp_path / "lib.toml"
    manifest.write_text(f'[[setup]]\nname = "only"\nfile = "{setup}"\n', encoding="utf-8")
    capsys.readouterr()
    assert main(["library", str(manifest), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "at least two combinations" in err
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def tiny_library(tmp_path_factory):
    """Two ER32 combinations of the synthetic library bench, each with short (unconverged) stage-1 chains."""
    from bayes_rcsa.synthetic.library import LibrarySpec, generate_library, library_base_config, write_library

    spec = LibrarySpec(holder_types=("ER32",), per_type=2, clamping_lengths=(0.025, 0.045),
                       identify={"max_steps": 30, "walkers": 14, "check_every": 15, "plots": False})
    lib = generate_library(spec, library_base_config(frequency_step=32.0, directions=("x",)), seed=3)
    return write_library(lib, tmp_path_factory.mktemp("lib") / "library")


@pytest.mark.slow
def test_stage1_on_the_process_pool_and_the_library_reuses_it(tiny_library, tmp_path, capsys, monkeypatch):
    # stage 1 is run_batch of identify-only jobs (bayes_rcsa.library.stage1.run_stage1): that the same run_batch on
    # a Dask cluster gives the process pool's numbers bit for bit is tests/test_batch.py's dask test; a second
    # cluster here (two more identify runs and a cluster start-up, ~15 s) would test the same code
    import functools

    from bayes_rcsa.batch import load_manifest
    from bayes_rcsa.library import workflow
    from bayes_rcsa.library.stage1 import collect
    from bayes_rcsa.library.stage2 import Stage2Settings

    # This test is about stage 1 (the process pool, reuse), not stage 2's convergence: with its default rule
    # stage 2 and its two leave-one-out refits take ~60 s per library run here (tau ~140 steps in 8 dimensions, 7,500-
    # 8,250 steps each), so the leave-one-out refits get a 100-step cap after 50 of burn-in, and stage 2 too (the first
    # run through the command's --max-steps, which overrides this default).  Nothing asserted here depends on those
    # chains' length: the setups' ESS is an importance ESS (at least 1 for finite weights), the weak-fit warning counts
    # combinations.  (300-step caps after 100 of burn-in made these chains about a third of the test.)
    short = Stage2Settings(n_burn=50, ess_target=150, chunk=100, max_steps=100)
    monkeypatch.setattr(workflow, "fit_library", functools.partial(workflow.fit_library, settings=short))
    monkeypatch.setattr(workflow, "loo_p_values", functools.partial(workflow.loo_p_values, settings=short))
    jobs = load_manifest(tiny_library)
    pool_dir = tmp_path / "pool"
    capsys.readouterr()
    assert main(["library", str(tiny_library), "--out", str(pool_dir), "--workers", "2", "--quiet", "--json",
                 "--no-plots", "--max-steps", "250"]) == 0
    first = json.loads(capsys.readouterr().out)
    first_lib = json.loads((pool_dir / "library.json").read_text())
    assert any("stage 2 stopped at max_steps = 250 unconverged" in w and "--max-steps" in w
               for w in first_lib["warnings"])
    assert sorted(first["ran"]) == sorted(j.name for j in jobs) and first["holder_types"] == ["ER32"]
    a = collect(jobs, pool_dir)
    assert a.names == ("k_xf", "k_thetaM", "g_xf", "g_thetaM") and len(a.setups) == 2
    # a second library run reuses both setups (cached per setup) and writes its outputs again
    assert main(["library", str(tiny_library), "--out", str(pool_dir), "--workers", "2", "--quiet", "--json",
                 "--no-plots"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ran"] == [] and len(doc["reused"]) == 2
    lib = json.loads((pool_dir / "library.json").read_text())
    assert [s["name"] for s in lib["setups"]] == [j.name for j in jobs] and all(s["ess"] > 0 for s in lib["setups"])
    assert any("a weak fit" in w for w in lib["warnings"])  # two combinations of one type
    assert read_population(pool_dir / "population.nc").holder_types == ("ER32",)


def test_library_outputs_and_the_report_section(tmp_path):
    """write_library's files from a small stand-in fit, and the HTML report's library section built from them."""
    from bayes_rcsa.library.stage1 import Stage1
    from bayes_rcsa.library.stage2 import SetupDraws, Stage2Settings
    from bayes_rcsa.library.workflow import fit_library, write_library
    from bayes_rcsa.report import write_report_html
    from bayes_rcsa.report.answer import num

    rng = np.random.default_rng(4)
    names, box = ("k_xf", "g_xf"), np.array([[4.0, 10.0], [0.0, 0.5]])
    setups = []
    for i, dia in enumerate((0.006, 0.008, 0.010, 0.012, 0.016, 0.020)):
        z = np.array([7.0 + 1.5 * math.log(dia / 0.01), 0.25]) + 0.05 * rng.standard_normal(2)
        setups.append(SetupDraws(f"c{i}", ("ER32", "HSK")[i % 2], dia, z + 0.01 * rng.standard_normal((300, 2)),
                                 np.zeros(2), np.zeros((2, 2)), box))
    # a step cap (the outputs are under test, not stage 2's convergence; the default rule takes ~8,000 steps here):
    # 150 steps after 100 of burn-in (was 300 after 150; the fit's CPU 3.2 -> 2.4 s).  On the test's generator and seeds
    # 50-52 the ER32 law's 90 % interval at 10 mm runs from 0.066-0.077 decade below 10^7 to 0.084-0.094 above with
    # either cap, the spreads' level from 0.027-0.030 to 0.16-0.19 decade around the 0.05 asked below
    steps = 150
    fit = fit_library(Stage1(names, setups, (0.025, 0.040, 0.5), box, []), rng,
                      Stage2Settings(n_burn=100, ess_target=150, chunk=150, max_steps=steps), outliers=False)
    paths = write_library(tmp_path / "lib", fit)
    assert {p.name for p in paths.values()} == {"population.nc", "laws.json", "laws.csv", "library.json",
                                               "shrinkage.png"}
    laws = json.loads((tmp_path / "lib" / "laws.json").read_text())["laws"]
    er32 = next(r for r in laws if r["holder_type"] == "ER32" and r["parameter"] == "k_xf")
    # the population median at 10 mm is 10^7 N/m (the stand-in's law), its interval around it
    assert er32["median_at_10mm_q05"] < 1e7 < er32["median_at_10mm_q95"] and er32["unit"] == "N/m"
    # what the two types share (model version 2): the spreads' level, here the stand-in's 0.05 decade for both
    pool = json.loads((tmp_path / "lib" / "library.json").read_text())["pooling"]["coordinates"]["k_xf"]
    assert pool["sigma_geometric_mean"][0] < 0.05 < pool["sigma_geometric_mean"][2], pool
    assert 0 <= pool["tau_b"][0] <= pool["tau_b"][1] <= pool["tau_b"][2] and pool["sigma_max_over_min"][0] >= 1
    # stage 2's convergence next to its ESS, per type and with the pooling (also population.nc's "pooling")
    doc = json.loads((tmp_path / "lib" / "library.json").read_text())
    q = fit.stage2.fit.quality
    for row in doc["stage2"].values():
        assert row["rhat_max"] == pytest.approx(np.max(q.rhat)) and row["ess_bulk_min"] == pytest.approx(np.min(q.ess_bulk))
        # 150 steps cannot measure tau (50 tau): the ESS is unknown, not the bulk ESS of so short a chain
        assert not q.tau_measured and row["ess"] is None and row["converged"] is False and row["tau_measured"] is False
        assert row["steps"] == steps and row["ess_tail_min"] > 0 and row["autocorrelation_steps"] > 0
    assert doc["pooling"]["stage2_rhat_max"] == pytest.approx(np.max(q.rhat))
    assert doc["pooling"]["stage2_ess"] is None and doc["pooling"]["stage2_steps"] == steps
    assert any(f"stage 2 stopped at max_steps = {steps} unconverged" in w for w in doc["warnings"])
    html = write_report_html([tmp_path / "lib"], tmp_path / "report.html").read_text()
    assert "Tool library: the contact population" in html and html.count("<td>ER32</td><td>contact stiffness, translational (kxf)</td>") == 1
    assert "shrinkage: own vs pooled estimates" in html
    assert "<th>R-hat (max)</th>" in html and f'<td class="num">{num(np.max(q.rhat), 4)}</td>' in html
