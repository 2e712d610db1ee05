"""The tool-library bench (issue #20): the ``[holder] type`` setup key and the synthetic library generator.

Cheap by design: setups are parsed without data where possible, the generator runs on coarse frequency
grids, and no sampler is run here (the statistical acceptance tables come from benchmarks/library.py and
stand in docs/library.md).
"""

from __future__ import annotations


import pytest

from bayes_rcsa.errors import SetupError
from bayes_rcsa.io import load_setup


def _with_holder_line(example, line: str):
    """The example setup with ``line`` inserted at the top of its [holder] table."""
    text = example.read_text(encoding="utf-8")
    assert "\n[holder]\n" in text
    example.write_text(text.replace("\n[holder]\n", f"\n[holder]\n{line}\n", 1), encoding="utf-8")
    return example


def test_holder_type_absent_is_none(example):
    assert load_setup(example, load_data=False).holder_type is None


def test_holder_type_is_read_as_a_free_string(example):
    setup = load_setup(_with_holder_line(example, 'type = "HSK-A63 shrink fit #2"'), load_data=False)
    assert setup.holder_type == "HSK-A63 shrink fit #2"
    # the geometry is still parsed from the same table
    assert setup.holder.segments and setup.holder.material.name == "steel"


@pytest.mark.parametrize("value", ['""', '"   "', "32", "true", '["ER32"]'])
def test_holder_type_empty_or_not_a_string_is_refused(example, value):
    path = _with_holder_line(example, f"type = {value}")
    with pytest.raises(SetupError) as err:
        load_setup(path, load_data=False)
    msg = str(err.value)
    assert "\n" not in msg and "[holder] type" in msg and str(path) in msg


def test_holder_misspelled_key_is_still_refused(example):
    with pytest.raises(SetupError, match="typ"):
        load_setup(_with_holder_line(example, 'typ = "ER32"'), load_data=False)


# ---------------------------------------------------------------- the synthetic library generator --

import json
import math

import numpy as np

from bayes_rcsa.batch.manifest import load_manifest
from bayes_rcsa.cli.main import main
from bayes_rcsa.synthetic.library import LibrarySpec, Special, generate_library, library_base_config, write_library
from bayes_rcsa.synthetic.library_population import D_REF, GROWTH_CEILING, HOLDER_TYPES, draw_law, median_law

# Two combinations per holder type, two tap lengths, truth at both ends of the range, a 10 Hz grid:
# six FE campaigns of ~0.3 s each.
SPEC = LibrarySpec(per_type=2, clamping_lengths=(0.025, 0.040), truth_lengths=(0.020, 0.045),
                   specials=(Special(1, softer=3.0), Special(4, hidden_effects={"tip_mass": True})),
                   identify={"walkers": 16, "max_steps": 200})
BASE = library_base_config(frequency_step=10.0)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    library = generate_library(SPEC, BASE, seed=7)
    manifest = write_library(library, tmp_path_factory.mktemp("lib") / "library")
    return library, manifest


def test_library_layout_and_manifest_read_by_batch(written):
    library, manifest = written
    jobs = load_manifest(manifest)
    assert [j.name for j in jobs] == [c.name for c in library.combinations]
    assert len({j.seed for j in jobs}) == len(jobs)  # every setup its own identify seed
    for job, combo in zip(jobs, library.combinations):
        assert job.steps == ("identify",)  # a library needs stage 1 only
        argv = job.argv("identify", "/x")
        assert argv[argv.index("--walkers") + 1] == "16" and argv[argv.index("--max-steps") + 1] == "200"
        setup = load_setup(job.setup_file)  # with its data: the campaign checks pass
        assert setup.holder_type == combo.holder_type
        assert setup.tools["tool"].segments[-1].diameter == combo.diameter
        assert sorted(m.clamping_length for m in setup.measurements) == [0.025, 0.040]
        truth = json.loads((job.setup_file.parent / "truth.json").read_text())
        assert truth["library"]["law"] == pytest.approx(combo.law)
        assert [t["clamping_length"] for t in truth["tool_point_frequencies"]] == [0.020, 0.045]
    record = json.loads((manifest.parent / "library.json").read_text())
    assert [c["name"] for c in record["combinations"]] == [c.name for c in library.combinations]


def test_library_covers_three_holder_types_and_diameters_in_range(written):
    library, _ = written
    types = [c.holder_type for c in library.combinations]
    assert sorted(set(types)) == sorted(HOLDER_TYPES) and all(types.count(t) == 2 for t in set(types))
    for c in library.combinations:
        assert 0.006 <= c.diameter <= 0.020
        # the holder's bore is the shank and deep enough for the longest truth length
        nose = c.campaign.config.holder_segments[-1]
        assert nose.inner_diameter == c.diameter and c.campaign.config.holder.bore_depth > 0.045


def test_truth_laws_are_the_population_draws(written):
    library, _ = written
    for c in library.combinations:
        pop = HOLDER_TYPES[c.holder_type]
        soft = 1.0 if c.special is None else c.special.softer
        x = math.log(c.diameter / D_REF)
        for name in ("k_xf", "k_thetaM", "c_xf", "c_thetaM"):
            law = pop.laws[name]
            expected = law.ref * math.exp(law.slope * x + law.spread * c.z[name])
            expected /= soft if name.startswith("k") else 1.0
            assert c.law[name] == pytest.approx(expected, rel=1e-12)
        for name in ("g_xf", "g_thetaM"):
            assert 0 < c.law[name] < GROWTH_CEILING
        # the campaign's FE truth uses exactly this law at every tap length
        la, lb = SPEC.clamping_range
        for rec in c.campaign.truth["contact"]:
            grow = 1 + c.law["g_xf"] * (rec["clamping_length"] - la) / (lb - la)
            assert rec["k_xf"] == pytest.approx(c.law["k_xf"] * grow, rel=1e-12)


def test_population_draws_have_the_documented_median_and_spread():
    # 4000 draws per diameter: the sample median of ln k is within 4 standard errors (1.25 s / sqrt(4000)
    # = 0.02 s each) of the stated median, the sample sd within 5 % (4.5 standard errors) of the spread
    rng = np.random.default_rng(11)
    pop = HOLDER_TYPES["ER32"]
    for d in (0.006, 0.020):
        draws = [draw_law(pop, d, rng)[0] for _ in range(4000)]
        med = median_law(pop, d)
        for name in ("k_xf", "k_thetaM", "c_xf"):
            v = np.log([dr[name] for dr in draws])
            s = pop.laws[name].spread
            assert np.median(v) == pytest.approx(math.log(med[name]), abs=0.08 * s)
            assert np.std(v) == pytest.approx(s, rel=0.05)
        # stiffness grows with the shank diameter as documented (exponent = slope)
        assert med["k_xf"] / median_law(pop, D_REF)["k_xf"] == pytest.approx((d / D_REF) ** pop.laws["k_xf"].slope)
        g = np.array([dr["g_xf"] for dr in draws])
        assert 0 < g.min() and g.max() < GROWTH_CEILING
        assert np.median(g) == pytest.approx(pop.laws["g_xf"].ref, abs=0.01)


def test_outlier_is_three_times_softer_and_resonates_lower(written):
    library, _ = written
    out = library.combinations[1]
    assert out.special.softer == 3.0
    pop = HOLDER_TYPES[out.holder_type]
    x = math.log(out.diameter / D_REF)
    drawn = pop.laws["k_xf"].ref * math.exp(pop.laws["k_xf"].slope * x + pop.laws["k_xf"].spread * out.z["k_xf"])
    assert out.law["k_xf"] == pytest.approx(drawn / 3.0, rel=1e-12)
    assert out.campaign.config.k_thetaM == pytest.approx(out.law["k_thetaM"], rel=1e-12)
    # its data say so: a softer contact lowers the dominant frequency below that of the same tool and
    # holder at the population median (same-diameter partner regenerated here without the special)
    plain = generate_library(LibrarySpec(**{**SPEC.__dict__, "specials": ()}), BASE, seed=7).combinations
    clean = plain[1]
    assert clean.law["k_xf"] == pytest.approx(3.0 * out.law["k_xf"], rel=1e-12)
    f_out = [t["dominant_frequency_hz"] for t in out.campaign.truth["tool_point_frequencies"]]
    f_clean = [t["dominant_frequency_hz"] for t in clean.campaign.truth["tool_point_frequencies"]]
    assert all(a < 0.9 * b for a, b in zip(f_out, f_clean))
    # the other combinations' data do not change when one is made special (own noise streams)
    for a, b in zip(library.combinations[2:4], plain[2:4]):
        assert np.array_equal(a.campaign.measurements[0][1].values, b.campaign.measurements[0][1].values)


def test_hidden_effect_combination_keeps_it_hidden(written):
    library, manifest = written
    c = library.combinations[4]
    assert c.campaign.truth["hidden_effects"] == {"tip_mass": 0.002}
    text = (manifest.parent / c.name / "setup.toml").read_text()
    assert "tip_mass" not in text and "[model]" not in text
    assert all(o.campaign.truth["hidden_effects"] == {} for i, o in enumerate(library.combinations) if i != 4)


def test_synthesize_library_command_and_one_line_errors(tmp_path, capsys):
    cfg = tmp_path / "lib.toml"
    cfg.write_text("[frequency]\nstep = 20.0\n[library]\nholder_types = [\"ER32\", \"hydraulic\"]\nper_type = 1\n"
                   "clamping_lengths = [0.03]\ntruth_lengths = [0.03]\n"
                   "[[library.special]]\ncombination = 0\nsofter = 3.0\n")
    out = tmp_path / "lib"
    assert main(["synthesize", str(cfg), "--out", str(out), "--seed", "5"]) == 0
    assert "2 holder-tool combinations" in capsys.readouterr().err
    assert len(load_manifest(out / "manifest.toml")) == 2
    for text, needle in (("[library]\nper_type = 0\n", "per_type"),
                         ("[library]\ndiameters = [0.004]\n", "diameters"),
                         ("[library]\nholder_types = [\"BT40\"]\n", "BT40"),
                         ("[library]\n[[library.special]]\ncombination = 99\nsofter = 3.0\n", "combination"),
                         ("[library]\n[tool]\nmaterial = \"steel\"\n", "[tool]")):
        cfg.write_text(text)
        assert main(["synthesize", str(cfg), "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and needle in err
        assert not (tmp_path / "bad").exists()
