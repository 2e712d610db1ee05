"""Issue #21, families 2-8 through the real command line: limits, measurements that identify nothing, products that
do not belong together, one-line messages, Latin-1 exports, warnings that travel with the results.

Every row runs ``bayes_rcsa.cli.main.main`` in process on a copy of the bundled example.  A refusal asserts exit
status 2, ONE stderr line naming the cause (and not naming what it must not), no traceback and the directory
listing before and after; a warning asserts exit status 0, the warning on stderr AND in the ``--json`` object AND
in the written document (lobes.json, summary.json).  None of them runs a sampler.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir
from bayes_rcsa.io.receptance_csv import read_spindle_csv, write_spindle_csv
from bayes_rcsa.model.receptance import PointReceptance

CUT = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95"]
SMALL = [*CUT, "--speeds", "5000:30000:8", "--depth-points", "8", "--quiet"]
# measured mode on the bundled files ('# averages = 5': probabilistic): 20 FRF realisations cost what one does,
# the default 500 about 3 s of CPU per run
DRAWS = ["--draws", "20"]
S = "{data}/setup.toml"
OUT = "{run}/out"


def _lobes(fx: str = "tip_x_30mm.csv", fy: str = "tip_y_30mm.csv", *extra: str) -> list[str]:
    return ["lobes", "--measured-x", f"{{data}}/{fx}", "--measured-y", f"{{data}}/{fy}", *SMALL, *DRAWS, *extra,
            "--no-plots", "--out", OUT]


# --------------------------------------------------------------------------- file edits


def _lines(p: Path) -> list[str]:
    return p.read_text(encoding="latin-1").splitlines()


def _data_rows(name: str, fn: Callable[[list[list[float]], list[str]], list[list[float]]]):
    """Rewrite the numeric rows of an example CSV with ``fn(rows, header) -> rows``."""

    def edit(d: Path) -> None:
        p = d / name
        lines = _lines(p)
        head = [ln for ln in lines if ln.startswith("#")]
        rows = [ln for ln in lines if not ln.startswith("#")]
        header = rows[0].split(",")
        data = fn([[float(v) for v in r.split(",")] for r in rows[1:]], header)
        p.write_text("\n".join(head + [rows[0]] + [",".join(repr(v) for v in r) for r in data]) + "\n")

    return edit


def _scale_column(name: str, column: str, factor: float):
    def fn(rows, header):
        i = header.index(column)
        for r in rows:
            r[i] *= factor
        return rows

    return _data_rows(name, fn)


def _keep_rows(name: str, n: int):
    return _data_rows(name, lambda rows, header: rows[:n])


def _write_bytes(name: str, data: bytes):
    def edit(d: Path) -> None:
        (d / name).write_bytes(data)

    return edit


def _prefix_bytes(name: str, data: bytes):
    def edit(d: Path) -> None:
        p = d / name
        p.write_bytes(data + p.read_bytes())

    return edit


def _replace_bytes(name: str, old: bytes, new: bytes):
    def edit(d: Path) -> None:
        p = d / name
        raw = p.read_bytes()
        assert old in raw
        p.write_bytes(raw.replace(old, new, 1))

    return edit


def _append_setup(extra: str):
    def edit(d: Path) -> None:
        with open(d / "setup.toml", "a", encoding="utf-8") as fh:
            fh.write("\n" + extra + "\n")

    return edit


def _symlink(name: str, target: str):
    def edit(d: Path) -> None:
        (d / name).unlink()
        (d / name).symlink_to(target)

    return edit


def _spindle_cross_scaled(factor: float):
    def edit(d: Path) -> None:
        rec = read_spindle_csv(d / "spindle_x.csv")
        b = rec.block.copy()
        b[:, 1, 0] *= factor
        write_spindle_csv(d / "spindle_x.csv", PointReceptance(rec.frequency_hz, b))

    return edit


def _lobes_run(d: Path, run: Path) -> None:
    """A lobes run directory made by the real command (for report rows)."""
    assert main(["lobes", "--measured-x", str(d / "tip_x_30mm.csv"), "--measured-y", str(d / "tip_y_30mm.csv"),
                 *SMALL, *DRAWS, "--out", str(run / "lob")]) == 0


def _edit_lobes_json(fn: Callable[[dict], None]):
    def before(d: Path, run: Path) -> None:
        _lobes_run(d, run)
        p = run / "lob" / "lobes.json"
        doc = json.loads(p.read_text())
        fn(doc)
        p.write_text(json.dumps(doc))

    return before


def _set(path: list, value) -> Callable[[dict], None]:
    def fn(doc):
        node = doc
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value

    return fn


def _delete(key: str) -> Callable[[dict], None]:
    return lambda doc: doc.pop(key)


# --------------------------------------------------------------------------- the table


@dataclass
class Case:
    id: str
    family: int
    argv: list[str]
    fragments: list[str]  # in the one error line, or (status 0) in a warning
    status: int = 2
    edit: Callable[[Path], None] | None = None
    before: Callable[[Path, Path], None] | None = None
    absent: list[str] = field(default_factory=list)
    env: dict = field(default_factory=dict)
    document: str | None = None  # status 0: the file under OUT whose "warnings" must hold the warning


CASES = [
    # 2: limits, refused before any allocation, naming the limit and the way past it
    Case("seed-2**70", 2, ["identify", S, "--out", OUT, "--seed", str(2**70)], ["--seed", "2**63 - 1"]),
    Case("lobes-seed-2**64", 2, ["lobes", S, "--posterior", "{run}/p.nc", "--clamping-length", "0.03", *SMALL,
                                 "--seed", str(2**64), "--out", OUT], ["--seed", "at most"]),
    Case("speed-count-1e11", 2, ["lobes", "--measured-x", "{data}/tip_x_30mm.csv", "--measured-y",
                                 "{data}/tip_y_30mm.csv", *CUT, "--speeds", "5000:30000:100000000000", "--out", OUT],
         ["--speeds", "at most 100 000", "split the speed range"]),
    Case("walkers-1e6", 2, ["identify", S, "--out", OUT, "--walkers", "1000000"], ["--walkers 1000000", "at most"]),
    Case("draws-1e7", 2, ["lobes", S, "--posterior", "{run}/p.nc", "--clamping-length", "0.03", *SMALL, "--draws",
                          "10000000", "--out", OUT], ["--draws 10000000", "at most 100 000", "--seed"]),
    Case("sampler-max-steps-1e12", 2, ["identify", S, "--out", OUT], ["[sampler] max_steps", "at most"],
         edit=_append_setup("[sampler]\nmax_steps = 1000000000000")),
    Case("memory-speeds-x-depths", 2, ["lobes", "--measured-x", "{data}/tip_x_30mm.csv", "--measured-y",
                                       "{data}/tip_y_30mm.csv", *CUT, "--speeds", "5000:30000:100000",
                                       "--depth-points", "100000", "--out", OUT], ["of memory", "fewer"]),
    Case("input-file-size", 2, _lobes(), ["tip_x_30mm.csv", "above the limit", "BAYES_RCSA_MAX_INPUT_MB"],
         env={"BAYES_RCSA_MAX_INPUT_MB": "0.01"}),
    # 3: measurements that cannot identify anything
    Case("tip-cut-below-mode", 3, ["identify", S, "--out", OUT, "--lengths", "0.03"],
         ["tip_x_30mm.csv", "no resonance", "--allow-no-resonance"], edit=_keep_rows("tip_x_30mm.csv", 12)),
    Case("tip-four-lines", 3, ["identify", S, "--out", OUT, "--lengths", "0.03"],
         ["tip_x_30mm.csv", "only 4 frequency line(s)"], edit=_keep_rows("tip_x_30mm.csv", 4)),
    Case("tip-band-below-mode", 3, ["identify", S, "--out", OUT, "--lengths", "0.025", "--max-steps", "20"],
         ["tip_y_25mm.csv", "no resonance", "last line"],
         edit=_data_rows("tip_y_25mm.csv", lambda rows, h: [r for r in rows if r[0] < 700])),
    # 4: products that do not belong together
    Case("lobes-x-equals-y", 4, _lobes("tip_x_30mm.csv", "tip_x_30mm.csv", "--json"), ["hold the same data"],
         status=0, document="lobes.json"),
    Case("lobes-x-y-other-lengths", 4, _lobes("tip_x_30mm.csv", "tip_y_40mm.csv", "--json"),
         ["tip_x_30mm.csv", "tip_y_40mm.csv", "different clamping lengths"], status=0, document="lobes.json"),
    Case("lobes-x-y-25-30", 4, _lobes("tip_x_25mm.csv", "tip_y_30mm.csv", "--json"), ["differ by 12 %"], status=0,
         document="lobes.json"),
    Case("report-nan", 4, ["report", "{run}/lob", "--out", "{run}/r.html"], ["lobes.json", "'level'", "NaN"],
         before=_edit_lobes_json(_set(["level"], math.nan))),
    Case("report-nested-inf", 4, ["report", "{run}/lob", "--out", "{run}/r.html"],
         ["lobes.json", "'cutting.kt'", "NaN or infinite"], before=_edit_lobes_json(_set(["cutting", "kt"], math.inf))),
    Case("report-missing-key", 4, ["report", "{run}/lob", "--out", "{run}/r.html"],
         ["lobes.json", "missing key(s) 'recommended'"], before=_edit_lobes_json(_delete("recommended"))),
    # 5: one line, the real cause, no echo of a file that is not a measurement
    Case("rad-per-s", 5, ["identify", S, "--out", OUT], ["tip_x_35mm.csv", "rad/s", "2π"],
         edit=_scale_column("tip_x_35mm.csv", "frequency_hz", 2 * math.pi), absent=["swapped", "falls"]),
    Case("rad-per-s-predict", 5, ["predict", S, "--posterior", "{run}/p.nc", "--out", OUT], ["tip_y_25mm.csv", "rad/s"],
         edit=_scale_column("tip_y_25mm.csv", "frequency_hz", 2 * math.pi), absent=["swapped"]),
    Case("symlink-passwd", 5, _lobes("tip_x_30mm.csv", "tip_y_30mm.csv"), ["tip_x_30mm.csv", "no header"],
         edit=_symlink("tip_x_30mm.csv", "/etc/passwd"), absent=["root:", ":0:0:", "/bin/"]),
    Case("binary-as-csv", 5, _lobes(), ["tip_y_30mm.csv", "binary"],
         edit=_write_bytes("tip_y_30mm.csv", bytes(range(256)) * 4)),
    Case("text-not-csv", 5, _lobes(), ["tip_x_30mm.csv", "no header"],
         edit=_write_bytes("tip_x_30mm.csv", b"secret: line one\nsecret: line two\n"), absent=["secret"]),
    Case("shell-script-as-csv", 5, _lobes(), ["tip_y_30mm.csv", "no header"],
         edit=_write_bytes("tip_y_30mm.csv", b"#!/bin/sh\nexport TOKEN=abc123, echo done\n"), absent=["TOKEN", "abc"]),
    # 6: Latin-1 / Windows-1252 in comments and headers are accepted; numbers must still parse
    Case("cp1252-comment", 6, _lobes("tip_x_30mm.csv", "tip_y_30mm.csv", "--json"), [], status=0,
         edit=_prefix_bytes("tip_x_30mm.csv", "# Beschleunigungsaufnehmer – Empfindlichkeit 10 mV/(m/s²) „ü“\n"
                            .encode("cp1252"))),
    Case("latin1-extra-header-column", 6, _lobes("tip_x_30mm.csv", "tip_y_30mm.csv", "--json"), [], status=0,
         edit=_replace_bytes("tip_y_30mm.csv", b"coherence", "Kohärenz (°)".encode("latin-1"))),
    Case("latin1-spindle-comment", 6, ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                                       "--freq", "600,800,50", "--out", "{run}/h.csv", "--json"], [], status=0,
         edit=_prefix_bytes("spindle_x.csv", "# Spindel Nr. 3, gemessen bei 20 °C\n".encode("latin-1"))),
    Case("latin1-in-number", 6, _lobes(), ["tip_x_30mm.csv", "is not a number"],
         edit=_replace_bytes("tip_x_30mm.csv", b"\n5", "\n5°".encode("latin-1"))),
    # 7: data warnings travel with the results
    Case("spindle-warning-in-json", 7, ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                                        "--freq", "600,800,50", "--out", "{run}/h.csv", "--json"],
         ["spindle_x.csv", "cross terms differ"], status=0, edit=_spindle_cross_scaled(1.25)),
    Case("lobes-unusual-kt-in-lobes.json", 7, ["lobes", "--measured-x", "{data}/tip_x_30mm.csv", "--measured-y",
                                              "{data}/tip_y_30mm.csv", "--flutes", "4", "--kt", "20e6", "--kr",
                                              "10e6", "--immersion", "0.95", "--speeds", "5000:30000:8",
                                              "--depth-points", "8", "--quiet", "--allow-unusual", *DRAWS, "--json",
                                              "--out", OUT], ["--kt 20e6", "range for metals"], status=0,
         document="lobes.json"),
    Case("lobes-xy-warning-in-lobes.json", 7, _lobes("tip_y_30mm.csv", "tip_y_30mm.csv", "--json"),
         ["tip_y_30mm.csv", "same data"], status=0, document="lobes.json"),
    Case("lobes-spindle-free-data-warning", 7, _lobes("tip_x_40mm.csv", "tip_y_25mm.csv", "--json"),
         ["differ by 40 %"], status=0, document="lobes.json"),
]


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """A tiny identify run of the bundled example (its posterior.nc and summary.json with setup_geometry)."""
    root = tmp_path_factory.mktemp("ident")
    assert main(["identify", str(example_dir() / "setup.toml"), "--out", str(root / "ident"), "--lengths", "0.03",
                 "--max-steps", "20", "--walkers", "10", "--check-every", "10", "--quiet", "--no-plots"]) == 0
    return root / "ident"


def _edit_text(name: str, old: str, new: str):
    def edit(d: Path) -> None:
        p = d / name
        text = p.read_text()
        assert old in text, old
        p.write_text(text.replace(old, new, 1))

    return edit


GEOMETRY = [
    ("tool-modulus", "predict", _edit_text("setup.toml", "youngs_modulus = 580000000000.0",
                                           "youngs_modulus = 600000000000.0"), "tools.tool.material.youngs_modulus"),
    ("tool-length", "lobes", lambda d: [_edit_text("setup.toml", "total_length = 0.1016", "total_length = 0.1116")(d),
                                        _edit_text("setup.toml", "length = 0.0716", "length = 0.0816")(d)],
     "tools.tool.total_length"),
    ("tool-diameter", "predict", _edit_text("setup.toml", "{ length = 0.0716, diameter = 0.00794 }",
                                            "{ length = 0.0716, diameter = 0.0078 }"), "tools.tool.segments[1].diameter"),
]


@pytest.mark.parametrize("name,command,edit,key", GEOMETRY, ids=[g[0] for g in GEOMETRY])
def test_posterior_of_another_geometry_is_named(name, command, edit, key, identified, tmp_path, capsys):
    """Family 4: a setup whose tool differs from the identification's gives one warning line naming the key."""
    data = tmp_path / "data"
    shutil.copytree(example_dir(), data)
    edit(data)
    out = tmp_path / "out"
    post = str(identified / "posterior.nc")
    if command == "predict":
        argv = ["predict", str(data / "setup.toml"), "--posterior", post, "--out", str(out), "--lengths", "0.03",
                "--directions", "x", "--max-draws", "10", "--quiet", "--no-plots", "--json"]
    else:
        argv = ["lobes", str(data / "setup.toml"), "--posterior", post, "--clamping-length", "0.03", "--draws", "5",
                *SMALL, "--no-plots", "--out", str(out), "--json"]
    assert main(argv) == 0
    cap = capsys.readouterr()
    hits = [ln for ln in cap.err.splitlines() if ": warning: " in ln and key + " = " in ln]
    assert len(hits) == 1, cap.err
    assert any(key in w for w in json.loads(cap.out)["warnings"])
    # family 7: the printed warnings travel with the results (frequencies.json, lobes.json)
    document = out / ("frequencies.json" if command == "predict" else "lobes.json")
    written = json.loads(document.read_text())["warnings"]
    for line in cap.err.splitlines():
        if ": warning: " in line:
            assert line.split(": warning: ", 1)[1] in written, (line, written)
    # the same setup as the identification: no such warning
    argv[1] = str(example_dir() / "setup.toml")
    shutil.rmtree(out)
    assert main(argv) == 0
    assert "differs from" not in capsys.readouterr().err


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def test_every_family_has_three_variants():
    for family in (2, 3, 4, 5, 6, 7):
        assert sum(c.family == family for c in CASES) >= 3, family


@pytest.mark.parametrize("case", CASES, ids=[f"{c.family}-{c.id}" for c in CASES])
def test_family_case(case: Case, tmp_path, capsys, monkeypatch):
    data = tmp_path / "data"
    shutil.copytree(example_dir(), data)
    run = tmp_path / "run"
    run.mkdir()
    (run / "p.nc").write_bytes(b"")  # a posterior path that exists (every row using it is refused before reading)
    for k, v in case.env.items():
        monkeypatch.setenv(k, v)
    if case.edit is not None:
        case.edit(data)
    if case.before is not None:
        case.before(data, run)
        capsys.readouterr()
    argv = [a.format(data=data, run=run) for a in case.argv]
    before_run, before_data = _tree(run), _tree(data)
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    cap = capsys.readouterr()
    err = cap.err
    assert "Traceback" not in err and "Warning:" not in err, err
    assert rc == case.status, (rc, err)
    lines = err.strip().splitlines()
    if case.status == 2:
        assert len(lines) == 1, err
        assert re.match(r"^bayes-rcsa \w+: error: ", lines[0]), lines[0]
        for f in case.fragments:
            assert f in lines[0], (f, lines[0])
        for f in case.absent:
            assert f not in lines[0], (f, lines[0])
        assert _tree(run) == before_run and _tree(data) == before_data
        return
    warns = [ln for ln in lines if ": warning: " in ln]
    for f in case.fragments:
        assert any(f in w for w in warns), (f, err)
    if not case.fragments:
        assert not warns, err  # a valid file raises no alarm
    doc = json.loads(cap.out)
    assert len(warns) == len(doc["warnings"]), (warns, doc["warnings"])  # every warning printed is in --json
    for w in warns:
        assert w.split(": warning: ", 1)[1] in doc["warnings"]
    if case.document:
        written = json.loads((run / "out" / case.document).read_text())["warnings"]
        for f in case.fragments:
            assert any(f in w for w in written), (f, written)


# The property test (every command, any subset of corrupted inputs) is tests/test_reliability_property.py.
