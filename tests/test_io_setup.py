"""Setup files (TOML): parsing, validation messages, and the TOML writer."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.errors import DataError, SetupError
from bayes_rcsa.io import dump_toml, load_setup, write_frf_csv, write_frf_uff, write_spindle_csv
from bayes_rcsa.io._setup_parser import parse_setup
from bayes_rcsa.model.assembly import Configuration, ToolPointModel
from bayes_rcsa.model.receptance import FRF, PointReceptance

# The contract's example (docs/setup.example.toml), reproduced here so that the
# test never reads outside the repository's tests, plus one table the core
# parser does not interpret.
EXAMPLE = """\
name = "ER32 + 7.94 mm carbide end mill"

[materials.steel]
youngs_modulus = 200e9
density = 7850.0
poisson_ratio = 0.29
loss_factor = 0.002          # structural damping, E -> E(1 + i*eta)

[materials.carbide]
youngs_modulus = 580e9
density = 14500.0
poisson_ratio = 0.22
loss_factor = 0.001

[spindle]
x = "spindle_x.csv"
y = "spindle_y.csv"          # optional

[holder]
material = "steel"
segments = [
  { length = 0.020, outer_diameter = 0.063, inner_diameter = 0.0 },
  { length = 0.0595, outer_diameter = 0.050, inner_diameter = 0.00794 },
]

[tool]
material = "carbide"
total_length = 0.1016
segments = [
  { length = 0.030, diameter = 0.00794, diameter_ratio = 0.80 },
  { length = 0.0716, diameter = 0.00794 },
]

[contact]
translational_stiffness = [1e5, 1e9]
rotational_stiffness = [1e3, 1e8]
growth_bound = 0.5
clamping_range = [0.020, 0.045]
translational_damping = 10.0
rotational_damping = 5e-4

[sampler]
walkers = 32

[[measurement]]
file = "tip_25mm.csv"
clamping_length = 0.025
direction = "x"

[[measurement]]
file = "tip_40mm.csv"
clamping_length = 0.040
direction = "x"
"""


def _spindle(rng, f) -> PointReceptance:
    b = (rng.normal(size=(f.size, 2, 2)) - 1j) * np.array([[1e-8, 1e-7], [1e-7, 1e-6]])
    b[:, 1, 0] = b[:, 0, 1]  # a point block is reciprocal (the reader checks it)
    return PointReceptance(f, b)


def _frf(rng, f) -> FRF:
    return FRF(f, (rng.normal(size=f.size) - 1j) * 1e-7)


@pytest.fixture
def example(tmp_path):
    """Write the example setup and its data files; return (setup path, written data)."""
    rng = np.random.default_rng(8)
    f = np.linspace(200.0, 4000.0, 40)
    data = {
        "spindle_x.csv": _spindle(rng, f),
        "spindle_y.csv": _spindle(rng, f),
        "tip_25mm.csv": _frf(rng, f[2:-2]),
        "tip_40mm.csv": _frf(rng, f[1:-1]),
    }
    for name, obj in data.items():
        (write_spindle_csv if isinstance(obj, PointReceptance) else write_frf_csv)(tmp_path / name, obj)
    path = tmp_path / "setup.toml"
    path.write_text(EXAMPLE)
    return path, data


def test_example_setup_loads_with_all_values(example):
    path, data = example
    s = load_setup(path)
    assert s.name == "ER32 + 7.94 mm carbide end mill"
    assert s.path == path
    assert set(s.materials) == {"steel", "carbide"}
    steel = s.materials["steel"]
    assert (steel.youngs_modulus, steel.density, steel.poisson_ratio, steel.loss_factor, steel.name) == (
        200e9, 7850.0, 0.29, 0.002, "steel")
    assert s.holder.material is steel
    assert [(g.length, g.outer_diameter, g.inner_diameter) for g in s.holder.segments] == [
        (0.020, 0.063, 0.0), (0.0595, 0.050, 0.00794)]
    assert s.holder.bore_depth == 0.0595
    tool = s.tools["tool"]
    assert list(s.tools) == ["tool"] and tool.name == "tool" and tool.material is s.materials["carbide"]
    assert tool.total_length == 0.1016
    assert [(g.length, g.diameter, g.diameter_ratio) for g in tool.segments] == [(0.030, 0.00794, 0.80), (0.0716, 0.00794, 1.0)]
    c = s.contact
    assert c.translational_stiffness == (1e5, 1e9) and c.rotational_stiffness == (1e3, 1e8)
    assert (c.growth_bound, c.clamping_range) == (0.5, (0.020, 0.045))
    assert (c.translational_damping, c.rotational_damping) == (10.0, 5e-4)
    assert s.feasible_range == (0.020, 0.045)
    assert s.extra == {"sampler": {"walkers": 32}}
    assert [(m.file, m.clamping_length, m.direction, m.tool) for m in s.measurements] == [
        (path.parent / "tip_25mm.csv", 0.025, "x", "tool"), (path.parent / "tip_40mm.csv", 0.040, "x", "tool")]
    assert s.measurements[1].configuration == Configuration(0.040, "x", "tool")
    for m in s.measurements:
        np.testing.assert_array_equal(m.frf.values, data[m.file.name].values)
    for d in "xy":
        np.testing.assert_array_equal(s.spindle[d].block, data[f"spindle_{d}.csv"].block)
    assert isinstance(s.model(), ToolPointModel)


def test_load_data_false_needs_no_data_files(tmp_path):
    path = tmp_path / "setup.toml"
    path.write_text(EXAMPLE)  # no CSV files exist
    s = load_setup(path, load_data=False)
    assert s.spindle == {}
    assert all(m.frf is None for m in s.measurements)
    assert s.measurements[0].file == tmp_path / "tip_25mm.csv"
    # A forward simulation needs the spindle but not the (not yet existing) measurements.
    with pytest.raises(DataError, match=r"\[spindle\] x = 'spindle_x.csv'.*not found"):
        parse_setup(path, load_data=False, load_spindle=True)
    rec = _spindle(np.random.default_rng(9), np.linspace(100.0, 200.0, 3))
    write_spindle_csv(tmp_path / "spindle_x.csv", rec)
    write_spindle_csv(tmp_path / "spindle_y.csv", rec)
    s = parse_setup(path, load_data=False, load_spindle=True)
    assert set(s.spindle) == {"x", "y"} and all(m.frf is None for m in s.measurements)
    np.testing.assert_array_equal(s.spindle["y"].block, rec.block)


def test_defaults_method_one_tools_and_uff_measurement(example):
    path, data = example
    text = EXAMPLE.replace('name = "ER32 + 7.94 mm carbide end mill"\n', "")
    text = text.replace("growth_bound = 0.5\nclamping_range = [0.020, 0.045]\n", "")
    text = text.replace("translational_damping = 10.0\n", "translational_damping = [1.0, 100.0]\n")
    text = text.replace("[tool]\n", "[tools.long]\n")
    text = text.replace("[sampler]", """[tools.short]
material = "carbide"
total_length = 0.07
segments = [{ length = 0.07, diameter = 0.006 }]

[sampler]""")
    text = text.replace('direction = "x"\n', 'direction = "x"\ntool = "long"\n')
    text += '\n[[measurement]]\nfile = "short.uff"\nclamping_length = 0.030\ndirection = "y"\ntool = "short"\n'
    short = FRF(data["tip_25mm.csv"].frequency_hz, 1.01 * data["tip_25mm.csv"].values)  # not a copy (refused)
    write_frf_uff(path.parent / "short.uff", short)
    path.write_text(text)
    s = load_setup(path)
    assert s.name == "setup"  # file stem
    assert s.contact.growth_bound == 0.5 and s.contact.clamping_range is None
    assert s.contact.translational_damping == (1.0, 100.0)
    assert set(s.tools) == {"long", "short"} and s.tools["short"].segments[0].diameter_ratio == 1.0
    assert [(m.tool, m.direction) for m in s.measurements] == [("long", "x"), ("long", "x"), ("short", "y")]
    np.testing.assert_array_equal(s.measurements[2].frf.values, short.values)
    assert s.feasible_range == (0.025, 0.040)  # no clamping_range: the measured range


def _edit(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


BAD = [
    # (old text, new text, error type, message fragments); old may be a list of (old, new) edits
    ("[holder]\n", "[holder\n", SetupError, ["setup.toml", "malformed TOML", "line 19, column 8"]),
    ("total_length = 0.1016\n", "", SetupError, ["setup.toml", "[tool] missing required key 'total_length'"]),
    ("inner_diameter = 0.00794", "inner_diameter = -0.01", SetupError,
     ["setup.toml: [holder] segments[1].inner_diameter = -0.01: expected 0 <= inner_diameter < outer_diameter"]),
    ("{ length = 0.020, outer", "{ length = 0.0, outer", SetupError,
     ["setup.toml: [holder] segments[0].length = 0.0: expected a finite number > 0"]),
    ("{ length = 0.0716, diameter", "{ length = -0.0716, diameter", SetupError,
     ["[tool] segments[1].length = -0.0716", "> 0"]),
    ("{ length = 0.0716, diameter", "{ length = 0.07, diameter", SetupError, ["[tool]", "add up to", "total_length"]),
    ("density = 7850.0", 'density = "7850"', SetupError, ["[materials.steel] density = '7850': expected a finite number > 0"]),
    ('material = "steel"', 'material = "stel"', SetupError,
     ["[holder] material = 'stel'", "unknown material", "carbide, steel"]),
    ("diameter_ratio = 0.80", "diameter_ratoi = 0.80", SetupError, ["[tool] segments[0]", "unknown key", "'diameter_ratoi'"]),
    ("clamping_length = 0.040", "clamping_length = 0.2", SetupError,
     ["[[measurement]] 1 (tip_40mm.csv)", "clamping_length = 0.2", "tool 'tool' total_length 0.1016"]),
    ("clamping_length = 0.040", "clamping_length = 0.06", SetupError,
     ["[[measurement]] 1 (tip_40mm.csv)", "clamping_length = 0.06", "holder bore depth 0.0595"]),
    ("clamping_length = 0.040", "clamping_length = 0.05", SetupError,
     ["[[measurement]] 1 (tip_40mm.csv) clamping_length = 0.05", "clamping_range [0.02, 0.045]"]),
    ("clamping_length = 0.040", "clamping_length = 0", SetupError, ["clamping_length = 0: expected a finite number > 0"]),
    ("clamping_range = [0.020, 0.045]", "clamping_range = [0.020, 0.065]", SetupError,
     ["[contact] clamping_range = [0.02, 0.065]", "holder bore depth"]),
    ("translational_stiffness = [1e5, 1e9]", "translational_stiffness = [1e9, 1e5]", SetupError,
     ["[contact] translational_stiffness = [1000000000.0, 100000.0]: expected [lo, hi] with 0 < lo < hi (N/m)"]),
    ("rotational_stiffness = [1e3, 1e8]\n", "", SetupError, ["[contact] missing required key 'rotational_stiffness'"]),
    ("growth_bound = 0.5", "growth_bound = -0.5", SetupError, ["[contact] growth_bound = -0.5: expected a finite number >= 0"]),
    ("rotational_damping = 5e-4", 'rotational_damping = "low"', SetupError, ["[contact] rotational_damping = 'low'"]),
    ([('y = "spindle_y.csv"', ""), ('direction = "x"', 'direction = "y"')], None, SetupError,
     ["[[measurement]] 0 (tip_25mm.csv) direction = 'y'", "[spindle] has no 'y' file"]),
    ('file = "tip_40mm.csv"', 'file = "tip_40mm.txt"', SetupError, ["file = 'tip_40mm.txt'", ".csv, .uff"]),
    ('file = "tip_40mm.csv"', 'file = "missing.csv"', DataError,
     ["setup.toml: [[measurement]] 1 (missing.csv) file = 'missing.csv'", "missing.csv: FRF file not found"]),
    ('x = "spindle_x.csv"', 'x = "nothere.csv"', DataError, ["setup.toml: [spindle] x = 'nothere.csv'", "not found"]),
    ("[holder]\n", "[holdr]\n", SetupError, ["setup.toml: (top level): unknown table [holdr]", "did you mean 'holder'"]),
]


@pytest.mark.parametrize("case", range(len(BAD)))
def test_bad_setups_name_file_key_and_expectation(example, case):
    path, _ = example
    old, new, error, fragments = BAD[case]
    text = EXAMPLE
    for o, n in old if isinstance(old, list) else [(old, new)]:
        text = _edit(text, o, n)
    path.write_text(text)
    with pytest.raises(error) as info:
        load_setup(path)
    msg = str(info.value)
    for fragment in fragments:
        assert fragment in msg, msg


def test_bad_measurement_data_and_tool_choice(example):
    path, _ = example
    (path.parent / "tip_40mm.csv").write_text("frequency_hz,real,imag\n100,1,nan\n")
    with pytest.raises(DataError, match=r"\[\[measurement\]\] 1 .*line 2, column 'imag'.*NaN or inf"):
        load_setup(path)
    two_tools = EXAMPLE.replace("[sampler]", '[tools.other]\nmaterial = "carbide"\ntotal_length = 0.08\n'
                                             'segments = [{ length = 0.08, diameter = 0.006 }]\n\n[sampler]')
    path.write_text(two_tools)
    with pytest.raises(SetupError, match=r"\[\[measurement\]\] 0 .*missing required key 'tool'.*other, tool"):
        load_setup(path, load_data=False)
    path.write_text(two_tools.replace('direction = "x"\n', 'direction = "x"\ntool = "nope"\n', 1))
    with pytest.raises(SetupError, match=r"tool = 'nope': expected a defined tool"):
        load_setup(path, load_data=False)
    with pytest.raises(SetupError, match=r"absent\.toml: setup file not found"):
        load_setup(path.parent / "absent.toml")


def test_dump_toml_round_trips_a_setup_exactly(example):
    path, data = example
    doc = tomllib.loads(EXAMPLE)
    doc["contact"]["translational_damping"] = [0.1 + 0.2, 1 / 3]  # floats with long reprs
    doc["note"] = 'quote " backslash \\ tab \t newline \n bell \x07 unicode é'
    doc["weird key.with dot"] = {"x": [[1, 2], [3.5e-300, -0.0]], "flag": True, "empty": []}
    text = dump_toml(doc)
    assert tomllib.loads(text) == doc
    assert "[[measurement]]" in text and "segments = [\n  { length = 0.02, outer_diameter = 0.063" in text
    # The emitted file is a valid setup in its own right.
    out = path.parent / "generated.toml"
    out.write_text(dump_toml(tomllib.loads(EXAMPLE)))
    a, b = load_setup(path), load_setup(out)
    assert (a.materials, a.holder, a.tools, a.contact) == (b.materials, b.holder, b.tools, b.contact)
    assert [m.file for m in a.measurements] == [m.file for m in b.measurements]


def test_dump_toml_rejects_what_toml_cannot_hold():
    with pytest.raises(TypeError, match="None"):
        dump_toml({"a": [1, None]})
    with pytest.raises(TypeError, match="cannot write"):
        dump_toml({"a": object()})
    assert tomllib.loads(dump_toml({"a": None, "b": np.float64(0.1), "c": np.arange(3)})) == {"b": 0.1, "c": [0, 1, 2]}


def test_model_table_is_parsed_and_survives_a_round_trip(tmp_path):
    import shutil

    from bayes_rcsa.io import dump_toml, setup_document

    d = tmp_path / "ex"
    shutil.copytree(Path(__file__).resolve().parent.parent / "bayes_rcsa" / "data" / "example", d)
    p = d / "setup.toml"
    p.write_text(p.read_text() + '\n[model]\nterms = ["tip_mass"]\ntip_mass_kg = { distribution = "uniform", '
                 'lo = 0.0, hi = 0.01 }\nk_xf = 2e7\n\n[priors]\ng_xf = [0.0, 0.3]\n')
    s = load_setup(p)
    assert s.model_table == {"terms": ["tip_mass"], "tip_mass_kg": {"distribution": "uniform", "lo": 0.0, "hi": 0.01},
                             "k_xf": 2e7}
    (d / "sub").mkdir()
    q = d / "sub" / "again.toml"  # another directory: data file names are rewritten relative to it
    q.write_text(dump_toml(setup_document(s, relative_to=q.parent)))
    s2 = load_setup(q)
    for name in ("materials", "holder", "tools", "contact", "extra", "model_table", "spindle_files"):
        assert getattr(s2, name) == getattr(s, name), name
    assert [(m.file, m.clamping_length, m.direction, m.tool) for m in s2.measurements] == \
           [(m.file, m.clamping_length, m.direction, m.tool) for m in s.measurements]
    # Without [model] the table is empty and the writer adds none.
    plain = load_setup(Path(__file__).resolve().parent.parent / "bayes_rcsa" / "data" / "example" / "setup.toml",
                       load_data=False)
    assert plain.model_table == {} and "model" not in setup_document(plain)


@pytest.mark.parametrize("text, fragments", [
    ('[model]\nterms = "tip_mass"\n', ["[model] terms = 'tip_mass'", "list of term names"]),
    ('[model]\nterms = ["tip_mass", "tip_mass"]\n', ["each term at most once"]),
    ('[model]\nterms = [1]\n', ["[model] terms = [1]"]),
    ('[model]\ntip_mass_kg = "heavy"\n', ["[model] tip_mass_kg = 'heavy'", "a number (fixed value)"]),
    ('[model]\ntip_mass_kg = { distribution = "normal", mu = 0.0, sigma = 0 }\n', ["[model] tip_mass_kg.sigma = 0"]),
    ('[priors]\nk_xf = { distribution = "log-normal", median = 1e7, sigma = -1 }\n', ["[priors] k_xf.sigma = -1"]),
    ('[priors]\nk_xf = ["a", 1e9]\n', ["[priors] k_xf = ['a', 1000000000.0]"]),
    ('[priors]\nk_xf = { distribution = "lognormla", median = 1e7, sigma = 1 }\n', ["did you mean 'lognormal'"]),
    ('[priors]\nk_xf = 5\n', ["[priors] k_xf = 5", "a [lo, hi] pair"]),
    ('[prior]\nk_xf = [1e6, 1e8]\n', ["unknown table [prior]", "did you mean 'priors'"]),
    ('[sampler]\nwalkers = 0\n', ["[sampler] walkers = 0", "a positive integer"]),
    ('[sampler]\nwalker = 32\n', ["[sampler]", "'walker'", "did you mean 'walkers'"]),
    ('[sampler]\nstart = { k_xf = "x" }\n', ["[sampler] start.k_xf = 'x'"]),
])
def test_stage_tables_are_checked_for_shape(example, text, fragments):
    path, _ = example
    base = EXAMPLE.replace("[sampler]\nwalkers = 32\n", "")
    path.write_text(base + "\n" + text)
    with pytest.raises(SetupError) as exc:
        load_setup(path, load_data=False)
    for fragment in fragments:
        assert fragment in str(exc.value), (fragment, str(exc.value))


@pytest.mark.parametrize("prefix, fragment", [("likelihood = 5\n", "[likelihood]: expected a table"),
                                              ('sampler = "fast"\n', "[sampler]: expected a table"),
                                              ("colour = 1\n", "unknown key 'colour'")])
def test_top_level_values_of_the_wrong_kind(example, prefix, fragment):
    path, _ = example
    path.write_text(prefix + EXAMPLE.replace("[sampler]\nwalkers = 32\n", ""))
    with pytest.raises(SetupError, match=re.escape(fragment)):
        load_setup(path, load_data=False)
