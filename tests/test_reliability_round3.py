"""Issue #21, the rest of families 3, 7 and 8 and a false rejection: through the real command line where it is cheap.

- Family 3: an amplitude off by a near-constant factor (sensor sensitivity) is named after the fit; a spindle
  block whose h/l/n/p columns are permuted but still reciprocal is refused by its physics, naming the permutation.
- False rejection: a flange p whose largest value sits on a weak resonance above a large real background (rotor
  bench, stiffer and softer bearings; a two-mode model) is accepted, while real swaps of it are still refused.
- Family 7: predict's frequencies.json and the spindle command's summary carry the printed warnings; batch has a
  warnings column in its table and HTML (tests/test_reliability_batch.py).

Refusals assert exit status 2, ONE stderr line naming the cause, no traceback and the directory listing before
and after; warnings assert exit status 0, the warning on stderr, in --json and in the written document.
"""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir
from bayes_rcsa.errors import DataError
from bayes_rcsa.io import checks
from bayes_rcsa.io.receptance_csv import read_spindle_csv, write_spindle_csv
from bayes_rcsa.model.receptance import PointReceptance

SIMULATE = ["simulate", "{data}/setup.toml", "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
            "--freq", "600,800,50", "--out", "{run}/h.csv"]
DETERMINISTIC = ["identify", "{data}/setup.toml", "--out", "{run}/out", "--lengths", "0.03", "--method",
                 "deterministic", "--quiet", "--no-plots", "--json"]


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _scale_tip(name: str, factor: float):
    def edit(d: Path) -> None:
        p = d / name
        lines = p.read_text(encoding="latin-1").splitlines()
        head = [ln for ln in lines if ln.startswith("#")]
        rows = [ln for ln in lines if not ln.startswith("#")]
        cols = rows[0].split(",")
        out = []
        for r in rows[1:]:
            v = [float(x) for x in r.split(",")]
            for c in ("real", "imag"):
                v[cols.index(c)] *= factor
            out.append(",".join(repr(x) for x in v))
        p.write_text("\n".join(head + [rows[0]] + out) + "\n")

    return edit


_INDEX = {"h": (0, 0), "l": (0, 1), "n": (1, 0), "p": (1, 1)}


def _permute_spindle(mapping: dict[str, str]):
    """The file's column ``k`` holds the true entry ``mapping[k]`` (the others stay)."""

    def edit(d: Path) -> None:
        rec = read_spindle_csv(d / "spindle_x.csv")
        b = rec.block.copy()
        for column, true in mapping.items():
            b[(slice(None), *_INDEX[column])] = rec.block[(slice(None), *_INDEX[true])]
        write_spindle_csv(d / "spindle_x.csv", PointReceptance(rec.frequency_hz, b))

    return edit


def _scale_cross(factor: float):
    def edit(d: Path) -> None:
        rec = read_spindle_csv(d / "spindle_x.csv")
        b = rec.block.copy()
        b[:, 0, 1] *= factor
        b[:, 1, 0] *= factor
        write_spindle_csv(d / "spindle_x.csv", PointReceptance(rec.frequency_hz, b))

    return edit


@dataclasses.dataclass
class Case:
    id: str
    argv: list[str]
    fragments: list[str]
    status: int = 2
    edit: object = None
    absent: list[str] = dataclasses.field(default_factory=list)


CASES = [
    # 3a: sensor sensitivity (a near-constant factor between the fitted and the measured amplitudes)
    Case("sensitivity-x3", DETERMINISTIC, ["tip_x_30mm.csv", "sensor sensitivity / calibration factor ≈ 2.9"],
         status=0, edit=_scale_tip("tip_x_30mm.csv", 3.0)),
    Case("sensitivity-x10", DETERMINISTIC, ["tip_y_30mm.csv", "calibration factor ≈ 9.9"], status=0,
         edit=_scale_tip("tip_y_30mm.csv", 10.0)),
    Case("sensitivity-x25", DETERMINISTIC, ["tip_x_30mm.csv", "calibration factor ≈ 2"], status=0,
         edit=_scale_tip("tip_x_30mm.csv", 25.0)),
    Case("sensitivity-clean", DETERMINISTIC, [], status=0, absent=["calibration"]),
    # 3b: permuted but reciprocal spindle columns, named by their physics
    Case("spindle-h-p-swapped", SIMULATE, ["spindle_x.csv", "look permuted", "median |p|", "h = p_real/p_imag",
                                           "p = h_real/h_imag"], edit=_permute_spindle({"h": "p", "p": "h"})),
    Case("spindle-h-p-and-l-n-swapped", SIMULATE, ["spindle_x.csv", "look permuted", "h = p_real/p_imag"],
         edit=_permute_spindle({"h": "p", "p": "h", "l": "n", "n": "l"})),
    Case("spindle-diagonal-in-cross", SIMULATE, ["spindle_x.csv", "look permuted", "l and n differ",
                                                 "h = l_real/l_imag"],
         edit=_permute_spindle({"h": "l", "l": "h", "n": "p", "p": "n"}), absent=["Im h > 0"]),
    Case("spindle-cross-in-other-units", SIMULATE, ["spindle_x.csv", "negative semi-definite", "|Im l| > 2"],
         edit=_scale_cross(5.0)),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_case(case: Case, tmp_path, capsys):
    data = tmp_path / "data"
    shutil.copytree(example_dir(), data)
    run = tmp_path / "run"
    run.mkdir()
    if case.edit is not None:
        case.edit(data)
    before = _tree(tmp_path)
    rc = main([a.format(data=data, run=run) for a in case.argv])
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err, cap.err
    assert rc == case.status, cap.err
    lines = cap.err.strip().splitlines()
    if case.status == 2:
        assert len(lines) == 1 and re.match(r"^bayes-rcsa \w+: error: ", lines[0]), cap.err
        for f in case.fragments:
            assert f in lines[0], (f, lines[0])
        for f in case.absent:
            assert f not in lines[0], (f, lines[0])
        assert _tree(tmp_path) == before
        return
    warns = [ln.split(": warning: ", 1)[1] for ln in lines if ": warning: " in ln]
    doc = json.loads(cap.out)
    written = json.loads((run / "out" / "summary.json").read_text())["warnings"]
    for f in case.fragments:
        assert any(f in w for w in warns), (f, cap.err)
    for w in warns:  # every warning printed travels with the results
        assert w in doc["warnings"] and w in written, (w, written)
    for f in case.absent:
        assert f not in cap.err


# --------------------------------------------------------------------------- the false rejection of a valid flange


def _rotor_blocks():
    from bayes_rcsa.synthetic.rotor.campaign import exported_spindle_receptance
    from bayes_rcsa.synthetic.rotor.config import rotor_bench_config

    base = rotor_bench_config()
    for scale in (0.1, 1.0, 3.0):  # softer, default and stiffer bearings
        bearings = tuple(dataclasses.replace(b, stiffness=b.stiffness * scale,
                                             rotational_stiffness=b.rotational_stiffness * scale)
                         for b in base.bearings)
        f = np.arange(50.0, 2000.0, 8.0)
        yield f"bearings-x{scale:g}", f, exported_spindle_receptance(rotor_bench_config(bearings=bearings), "x", f).block


def _two_mode_block():
    """A passive reciprocal two-mode flange block whose p has a large real background and a weak resonance."""
    f = np.arange(100.0, 3000.0, 5.0)
    w = 2 * np.pi * f
    block = np.zeros((f.size, 2, 2), complex)
    # modes: (natural frequency Hz, damping ratio, modal stiffness, shape (u, theta) at the flange)
    for fn, zeta, k, shape in ((900.0, 0.03, 2e8, (1.0, 8.0)), (6000.0, 0.05, 1e7, (0.2, 40.0))):
        wn = 2 * np.pi * fn
        g = 1 / (k * (1 - (w / wn) ** 2 + 2j * zeta * w / wn))
        block += g[:, None, None] * np.outer(shape, shape)[None]
    return f, block


def test_flange_blocks_with_a_large_real_background_are_accepted_and_real_swaps_refused(tmp_path):
    cases = list(_rotor_blocks()) + [("two-mode", *_two_mode_block())]
    for name, f, block in cases:
        p = block[:, 1, 1]
        assert p.real.min() > 0 and p.imag.max() <= 0  # the shape of the reported file: background + weak peak
        path = tmp_path / f"{name}.csv"
        write_spindle_csv(path, PointReceptance(f, block))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            read_spindle_csv(path)  # was: "real and imag columns look swapped" for p
        # a real swap of p (and of h) is still refused
        for i, label in ((1, "p (p_real"), (0, "h (h_real")):
            bad = block.copy()
            v = bad[:, i, i]
            bad[:, i, i] = v.imag + 1j * v.real
            write_spindle_csv(path, PointReceptance(f, bad))
            with pytest.raises(DataError, match="not a passive point receptance") as exc:
                read_spindle_csv(path)
            assert label in str(exc.value), (name, str(exc.value))


def test_sensitivity_factor_is_named_only_for_a_near_constant_ratio():
    f = np.linspace(500, 1500, 301)
    w, wn = 2 * np.pi * f, 2 * np.pi * 1000.0
    model = 1 / (1e7 * (1 - (w / wn) ** 2 + 0.06j * w / wn))
    assert checks.sensitivity_factor(model, model) is None
    assert checks.sensitivity_factor(4.0 * model, model) == pytest.approx(4.0)
    assert checks.sensitivity_factor(model / 8.0, model) == pytest.approx(1 / 8.0)
    assert "1/8" in checks.likely_cause(model / 8.0, model)
    shifted = 1 / (1e7 * (1 - (w / (1.05 * wn)) ** 2 + 0.06j * w / wn))  # a wrong contact: the peak moves
    assert checks.sensitivity_factor(3.0 * shifted, model) is None
    # several model sets (the load-time check over the prior's corners) never name it
    assert checks.likely_cause(3.0 * model, np.stack([model, 2 * model])) is None


def test_spindle_summary_carries_the_printed_warnings(tmp_path, monkeypatch, capsys):
    """Family 7, spindle command: the warnings printed go to spindle_summary.json (identification stubbed)."""
    import bayes_rcsa.spindle.identification as ident
    import bayes_rcsa.spindle.outputs as outputs
    from bayes_rcsa.errors import DataWarning

    assert main(["synthesize", "--artifact", str(Path(__file__).parent.parent / "bayes_rcsa" / "synthetic"
                                                  / "example_bench.toml"), "--out", str(tmp_path / "art")]) == 0
    capsys.readouterr()

    def identify_directions(setup, directions, **kw):
        warnings.warn("h11_x.csv: a data warning of the artifact tests", DataWarning)
        return {}

    written = {}
    real_summary = outputs.summary_document

    def summary_document(*a, **kw):  # what the workflow puts into spindle_summary.json
        doc = real_summary(*a, **kw)
        written["warnings"] = list(doc.get("warnings", []))
        return doc

    monkeypatch.setattr(ident, "identify_directions", identify_directions)
    monkeypatch.setattr(outputs, "summary_document", summary_document)
    assert main(["spindle", str(tmp_path / "art" / "artifact.toml"), "--out", str(tmp_path / "out"), "--quiet",
                 "--samples", "0", "--json"]) == 0, capsys.readouterr().err
    cap = capsys.readouterr()
    printed = [ln.split(": warning: ", 1)[1] for ln in cap.err.splitlines() if ": warning: " in ln]
    assert printed == ["h11_x.csv: a data warning of the artifact tests"], cap.err
    assert written["warnings"] == printed and json.loads(cap.out)["warnings"] == printed
    on_disk = json.loads((tmp_path / "out" / "spindle_summary.json").read_text())
    assert on_disk["warnings"] == printed
