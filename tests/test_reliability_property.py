"""Issue #21, the property test: every command, for any subset of corrupted inputs, either succeeds with finite
outputs or refuses with one line.

For each command listed by ``bayes-rcsa --help`` a Hypothesis strategy draws a subset of corruptions relevant to
that command (CSV / UFF / TOML / JSON / netCDF bytes, NaN and infinite numbers, swapped columns, truncated and
missing files, wrong units, bad option values, an --out that is taken) and runs ``bayes_rcsa.cli.main.main`` in
process on a fresh copy of the inputs.  The invariant:

- exit status 0: no traceback, ONE JSON object on stdout (``--json``) whose numbers are finite, every promised
  output file present and every JSON file written under --out finite;
- exit status 2: exactly one stderr line ``bayes-rcsa <command>: error: ...``, no traceback, the --json error
  object on stdout and nothing new left anywhere in the trial's folder (--out included);
- ``batch`` only: exit status 1 is its documented "a setup failed" (the failure is in summary.json, finite).

Budget (issue: the whole property test under 30 s on the 2-core machine, measured serially): the inputs are the
bundled example, one tiny posterior (the smallest sampler settings of the other tests: 10 walkers, 20 steps) and a
tenfold-thinned standard-artifact campaign, made once per module.  The slow commands draw only corruptions that
are refused at input validation (``FAST``), plus their clean run where it is affordable; ``demo`` (35 s even with
``--max-steps 20``) always draws at least one such corruption.  Examples per command: ``Spec.examples`` drawn
(12-16, 8 for demo and identifiability) plus the ``Spec.explicit`` valid-but-odd cases; about 165 runs in 20 s
(``pytest -n0``, serially, on the busy 2-core machine; the module fixture is 5 s of it).  ``batch`` runs its setups
on a thread of this process (a worker process costs 4 s of imports); its steps are the real commands.
Set ``BAYES_RCSA_PROPERTY_LOG=FILE`` to get one line per example (what was drawn, how it ended).

Supersedes the three-command property test formerly in tests/test_reliability_families.py (its corruptions are
among ``CSV_EDITS``).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import io
import json
import math
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from bayes_rcsa.batch import run as batch_run
from bayes_rcsa.cli.main import COMMANDS, main
from bayes_rcsa.data import example_dir
from bayes_rcsa.io.frf import read_frf
from bayes_rcsa.io.uff58 import write_frf_uff

CUT = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95", "--speeds", "5000:30000:8",
       "--depth-points", "8", "--quiet"]
BENCH = '[campaign]\nclamping_lengths = [0.03]\ndirections = ["x"]\n[frequency]\nstep = 40.0\n'
MANIFEST = """\
[defaults]
method = "deterministic"
lengths = [0.030]
plots = false
predict = false
lobes = false

[[setup]]
name = "a"
file = "data/setup.toml"
"""


# --------------------------------------------------------------------------- the inputs, made once


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """The example, a tiny posterior, a lobes run and a thinned artifact campaign (made once, copied per trial)."""
    root = tmp_path_factory.mktemp("world")
    data = root / "data"
    shutil.copytree(example_dir(), data)
    with contextlib.redirect_stderr(io.StringIO()):
        assert main(["identify", str(data / "setup.toml"), "--out", str(root / "ident"), "--lengths", "0.03",
                     "--max-steps", "20", "--walkers", "10", "--check-every", "10", "--quiet", "--no-plots",
                     "--checkpoint-interval", "0"]) == 0
        assert main(["lobes", "--measured-x", str(data / "tip_x_30mm.csv"), "--measured-y",
                     str(data / "tip_y_30mm.csv"), *CUT, "--draws", "20", "--out", str(root / "lob")]) == 0
        (root / "bench.toml").write_text(BENCH)
        assert main(["synthesize", "--artifact", str(root / "bench.toml"), "--out", str(root / "art")]) == 0
    for f in (root / "art").glob("h*_x.csv"):  # every tenth line: the spindle fit costs ~1 s instead of ~10 s
        lines = f.read_text().splitlines()
        head = [ln for ln in lines if ln.startswith("#")]
        rows = [ln for ln in lines if not ln.startswith("#")]
        f.write_text("\n".join(head + rows[:1] + rows[1::10]) + "\n")
    for d in "xy":
        write_frf_uff(data / f"tip_{d}_30mm.uff", read_frf(data / f"tip_{d}_30mm.csv"), direction=d)
    return root


@dataclass
class Trial:
    """One run: a fresh folder with copies of the inputs, and the command line to be built."""

    root: Path
    world: Path
    pos: list[str] = field(default_factory=list)
    opts: dict = field(default_factory=dict)  # option -> value (None: a flag)

    @property
    def data(self) -> Path:
        return self.root / "data"

    @property
    def out(self) -> Path:
        return Path(self.opts["--out"])

    def argv(self, command: str) -> list[str]:
        argv = [command, *self.pos]
        for k, v in self.opts.items():
            argv += [k] if v is None else [k, v]
        return [*argv, "--json"]


# --------------------------------------------------------------------------- corruptions of a file


def _lines(p: Path) -> list[str]:
    return p.read_text(encoding="latin-1").splitlines()


def _rows(p: Path, fn) -> None:
    """Rewrite the numeric rows of a CSV with ``fn(header, rows) -> (header, rows)``."""
    lines = _lines(p)
    head = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if not ln.startswith("#")]
    header, rows = fn(body[0].split(","), [r.split(",") for r in body[1:]])
    p.write_text("\n".join(head + [",".join(header)] + [",".join(r) for r in rows]) + "\n", encoding="latin-1")


def _scale(column: int, factor: float):
    def fn(header, rows):
        for r in rows:
            r[column] = repr(float(r[column]) * factor)
        return header, rows

    return lambda p: _rows(p, fn)


def _swap_columns(i: int, j: int):
    def fn(header, rows):
        header[i], header[j] = header[j], header[i]
        return header, rows

    return lambda p: _rows(p, fn)


def _cell(value: str, row: int = 3, column: int = 1):
    def fn(header, rows):
        rows[min(row, len(rows) - 1)][column] = value
        return header, rows

    return lambda p: _rows(p, fn)


def _text_replace(old: str, new: str):
    def edit(p: Path) -> None:
        text = p.read_text(encoding="latin-1")
        if old in text:
            p.write_text(text.replace(old, new, 1), encoding="latin-1")

    return edit


FILE_EDITS: dict[str, Callable[[Path], None]] = {
    "missing": lambda p: p.unlink(),
    "empty": lambda p: p.write_bytes(b""),
    "binary": lambda p: p.write_bytes(bytes(range(256)) * 8),
    "truncated": lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "nul-bytes": lambda p: p.write_bytes(p.read_bytes()[:300] + b"\x00" * 64 + p.read_bytes()[300:]),
}
CSV_EDITS: dict[str, Callable[[Path], None]] = {
    **FILE_EDITS,
    "nan-cell": _cell("nan"),
    "inf-cell": _cell("inf", column=2),
    "text-cell": _cell("1.2e-6x"),
    "swap-real-imag": _swap_columns(1, 2),
    "swap-freq-real": _swap_columns(0, 1),
    "rad-per-s": _scale(0, 2 * math.pi),
    "mm-per-n": _scale(1, 1000.0),
    "negate-imag": _scale(2, -1.0),
    "few-lines": lambda p: _rows(p, lambda h, r: (h, r[:3])),
    "reversed": lambda p: _rows(p, lambda h, r: (h, r[::-1])),
    "semicolons": lambda p: p.write_text(p.read_text(encoding="latin-1").replace(",", ";"), encoding="latin-1"),
    # valid but odd: accepted (DAQ exports)
    "latin1-comment": lambda p: p.write_bytes("# Empfindlichkeit 10 mV/(m/s²) °C\n".encode("latin-1")
                                              + p.read_bytes()),
    "crlf": lambda p: p.write_bytes(p.read_bytes().replace(b"\n", b"\r\n")),
}
TOML_EDITS: dict[str, Callable[[Path], None]] = {
    **FILE_EDITS,
    "unclosed-table": lambda p: p.write_text(p.read_text() + "\n[[[\n"),
    "bom": lambda p: p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes()),
    "utf16": lambda p: p.write_bytes(p.read_text().encode("utf-16")),
}
SETUP_EDITS: dict[str, Callable[[Path], None]] = {
    **TOML_EDITS,
    "nan-modulus": _text_replace("youngs_modulus = 580000000000.0", "youngs_modulus = nan"),
    "inf-length": _text_replace("total_length = 0.1016", "total_length = inf"),
    "length-in-mm": _text_replace("clamping_length = 0.03\n", "clamping_length = 30.0\n"),
    "negative-density": _text_replace("density = 14500.0", "density = -14500.0"),
    "string-number": _text_replace("poisson_ratio = 0.22", 'poisson_ratio = "0.22"'),
    "missing-file-named": _text_replace('file = "tip_x_30mm.csv"', 'file = "tip_x_30mm_missing.csv"'),
    "swapped-range": _text_replace("clamping_range = [0.025, 0.04]", "clamping_range = [0.04, 0.025]"),
    "no-spindle": _text_replace('x = "spindle_x.csv"\ny = "spindle_y.csv"', ""),
    "duplicate-key": _text_replace("density = 14500.0", "density = 14500.0\ndensity = 14500.0"),
}
JSON_EDITS: dict[str, Callable[[Path], None]] = {
    **FILE_EDITS,
    "nan-value": lambda p: p.write_text(re.sub(r'("level": )[-0-9.e]+', r"\1NaN", p.read_text(), count=1)),
    "inf-value": lambda p: p.write_text(re.sub(r"(: )(\d+\.\d+)", r"\1Infinity", p.read_text(), count=1)),
    "not-an-object": lambda p: p.write_text("[1, 2, 3]"),
    "drop-key": lambda p: p.write_text(json.dumps({k: v for i, (k, v) in enumerate(json.loads(p.read_text())
                                                                                   .items()) if i != 1})),
}


def _file(edits: dict, path: Callable[[Trial], Path]) -> dict:
    """Corruptions named ``<edit>`` of the file ``path(trial)``."""
    return {name: (lambda t, e=edit: e(path(t))) for name, edit in edits.items()}


def _opt(option: str, value: str | None):
    def corrupt(t: Trial) -> None:
        t.opts[option] = value

    return corrupt


def _drop(option: str):
    return lambda t: t.opts.pop(option, None)


def _out_taken(kind: str):
    """--out already used: a file where a folder goes, a non-empty folder, a folder where a file goes."""

    def corrupt(t: Trial) -> None:
        out = t.out
        out.parent.mkdir(parents=True, exist_ok=True)
        if kind == "file":
            out.write_text("not yours\n")
        elif kind == "nonempty":
            out.mkdir(exist_ok=True)
            (out / "keep.txt").write_text("not yours\n")
        else:  # a missing folder under a file
            (t.root / "afile").write_text("x\n")
            t.opts["--out"] = str(t.root / "afile" / "sub")

    return corrupt


OUT_TAKEN = {"out-is-file": _out_taken("file"), "out-nonempty": _out_taken("nonempty"),
             "out-under-file": _out_taken("under")}


# --------------------------------------------------------------------------- per command


@dataclass
class Spec:
    base: Callable[[Trial], None]  # copies the inputs into the trial and fills pos / opts
    corruptions: dict  # name -> corrupt(trial)
    promised: list[str]  # files under --out (or --out itself: ".") on exit status 0
    examples: int
    fast: set[str] | None = None  # slow commands: only these (refused at input validation) are drawn
    min_size: int = 0
    max_size: int = 2
    explicit: tuple = ()  # corruption lists always run (the valid-but-odd cases), on top of ``examples``


def _copy_data(t: Trial) -> None:
    shutil.copytree(t.world / "data", t.data)


def _copy_posterior(t: Trial) -> None:
    shutil.copy(t.world / "ident" / "posterior.nc", t.root / "posterior.nc")


def _setup(t: Trial) -> Path:
    return t.data / "setup.toml"


def _tip(name: str):
    return lambda t: t.data / name


def _base_simulate(t):
    _copy_data(t)
    t.pos = [str(_setup(t))]
    t.opts = {"--clamping-length": "0.03", "--kx": "1e7", "--ktheta": "1e5", "--freq": "500,3500,20",
              "--out": str(t.root / "out" / "h.csv")}


def _base_identify(t):
    _copy_data(t)
    t.pos = [str(_setup(t))]
    t.opts = {"--lengths": "0.03", "--method": "deterministic", "--quiet": None, "--no-plots": None,
              "--out": str(t.root / "out")}


def _base_lobes(t):
    _copy_data(t)
    t.pos = []
    t.opts = {"--measured-x": str(t.data / "tip_x_30mm.csv"), "--measured-y": str(t.data / "tip_y_30mm.csv")}
    for i in range(0, len(CUT) - 1, 2):
        t.opts[CUT[i]] = CUT[i + 1]
    t.opts["--quiet"] = None
    t.opts["--draws"] = "20"  # the files' '# averages = 5' make it probabilistic; the default 500 cost ~3 s CPU a run
    # as the other slow commands here: lobes.png was nearly all of a clean run (0.4-1.0 s of CPU; 0.04 s without)
    t.opts["--no-plots"] = None
    t.opts["--out"] = str(t.root / "out")


def _lobes_posterior_mode(t):
    _copy_posterior(t)
    t.opts.pop("--measured-x"), t.opts.pop("--measured-y")
    t.pos = [str(_setup(t))]
    t.opts.update({"--posterior": str(t.root / "posterior.nc"), "--clamping-length": "0.03", "--draws": "5"})


def _base_predict(t):
    _copy_data(t)
    _copy_posterior(t)
    t.pos = [str(_setup(t))]
    t.opts = {"--posterior": str(t.root / "posterior.nc"), "--lengths": "0.03", "--directions": "x",
              "--max-draws": "10", "--quiet": None, "--no-plots": None, "--out": str(t.root / "out")}


CUTS = ("spindle_speed_rpm,depth_m,outcome\n8000,0.00001,stable\n12000,0.00002,stable\n9000,0.002,chatter\n"
        "15000,0.003,chatter\n")


def _base_update(t):
    _copy_data(t)
    _copy_posterior(t)
    (t.root / "cuts.csv").write_text(CUTS)
    t.pos = [str(_setup(t))]
    t.opts = {"--posterior": str(t.root / "posterior.nc"), "--cuts": str(t.root / "cuts.csv"),
              "--clamping-length": "0.03", "--flutes": "4", "--kt": "790e6±30%", "--kr": "230e6",
              "--immersion": "0.5", "--draws": "20", "--particles": "4", "--min-ess": "1",
              "--out": str(t.root / "out")}


def _cuts_edit(old: str, new: str):
    return lambda t: _text_replace(old, new)(t.root / "cuts.csv")


def _base_report(t):
    shutil.copytree(t.world / "lob", t.root / "lob")
    t.pos = [str(t.root / "lob")]
    t.opts = {"--out": str(t.root / "out" / "report.html"), "--summary": str(t.root / "out" / "summary.md")}


def _base_spindle(t):
    shutil.copytree(t.world / "art", t.root / "art")
    t.pos = [str(t.root / "art" / "artifact.toml")]
    t.opts = {"--samples": "0", "--workers": "1", "--max-modes": "2", "--no-plots": None, "--quiet": None,
              "--out": str(t.root / "out")}


def _base_synthesize(t):
    (t.root / "bench.toml").write_text(BENCH)
    t.pos = [str(t.root / "bench.toml")]
    t.opts = {"--out": str(t.root / "out")}


def _base_batch(t):
    _copy_data(t)
    (t.root / "library.toml").write_text(MANIFEST)
    t.pos = [str(t.root / "library.toml")]
    t.opts = {"--workers": "1", "--quiet": None, "--out": str(t.root / "out")}


def _base_discrepancy(t):
    _copy_data(t)
    t.pos = [str(_setup(t))]
    t.opts = {"--lengths": "0.03", "--candidates": "tip_mass", "--refit": "1", "--no-plots": None,
              "--out": str(t.root / "out")}


def _base_design(t):
    _copy_data(t)
    _copy_posterior(t)
    t.pos = [str(_setup(t))]
    t.opts = {"--posterior": str(t.root / "posterior.nc"), "--target": "frequency@0.03", "--candidates": "0.035",
              "--draws": "20", "--truths": "4", "--no-plots": None, "--out": str(t.root / "out")}


def _base_identifiability(t):
    _copy_data(t)
    t.pos = [str(_setup(t))]
    t.opts = {"--lengths": "0.03", "--max-steps": "20", "--walkers": "10", "--check-every": "10", "--quiet": None,
              "--no-plots": None, "--no-posteriors": None, "--out": str(t.root / "out")}


LIBRARY_MANIFEST = """\
[defaults]
method = "multi"
max_steps = 20
walkers = 14
check_every = 10
plots = false

[[setup]]
name = "a"
file = "data/setup.toml"

[[setup]]
name = "b"
file = "data/setup.toml"
seed = 1
"""


def _base_library(t):
    _copy_data(t)
    _text_replace("\n[holder]\n", '\n[holder]\ntype = "ER32"\n')(_setup(t))
    (t.root / "library.toml").write_text(LIBRARY_MANIFEST)
    t.pos = [str(t.root / "library.toml")]
    t.opts = {"--workers": "1", "--quiet": None, "--no-plots": None, "--out": str(t.root / "out")}


def _base_demo(t):
    t.pos = []
    t.opts = {"--max-steps": "20", "--out": str(t.root / "out")}


def _base_example(t):
    t.pos = []
    t.opts = {"--out": str(t.root / "out")}


def _manifest_edit(old: str, new: str):
    return lambda t: _text_replace(old, new)(t.root / "library.toml")


SETUP_C = _file(SETUP_EDITS, _setup)
TIP_C = {f"tip_x:{k}": v for k, v in _file(CSV_EDITS, _tip("tip_x_30mm.csv")).items()}
SPINDLE_C = {f"spindle_x:{k}": v for k, v in _file(CSV_EDITS, _tip("spindle_x.csv")).items()}
POSTERIOR_C = {f"posterior:{k}": v for k, v in _file(FILE_EDITS, lambda t: t.root / "posterior.nc").items()}
SEED_C = {"seed-negative": _opt("--seed", "-1"), "seed-2**70": _opt("--seed", str(2**70)),
          "seed-text": _opt("--seed", "zero")}

SPECS: dict[str, Spec] = {
    "simulate": Spec(_base_simulate, {
        **SETUP_C, **SPINDLE_C, **OUT_TAKEN,
        "kx-nan": _opt("--kx", "nan"), "kx-negative": _opt("--kx", "-1e7"), "ktheta-inf": _opt("--ktheta", "inf"),
        "length-outside": _opt("--clamping-length", "3"), "length-mm": _opt("--clamping-length", "30"),
        "freq-reversed": _opt("--freq", "3500,500,20"), "freq-zero-step": _opt("--freq", "500,3500,0"),
        "freq-huge": _opt("--freq", "1,1e9,1e-3"), "tool-unknown": _opt("--tool", "nope"),
        "direction-z": _opt("--direction", "z"), "out-uff": _opt("--out", "{root}/out/h.uff"),
        "out-unknown-suffix": _opt("--out", "{root}/out/h.xyz"), "cx-negative": _opt("--cx", "-5"),
    }, ["."], examples=16),
    "identify": Spec(_base_identify, {
        **SETUP_C, **TIP_C, **SPINDLE_C, **OUT_TAKEN, **SEED_C,
        "lengths-nan": _opt("--lengths", "nan"), "lengths-unmeasured": _opt("--lengths", "0.033"),
        "lengths-mm": _opt("--lengths", "30"), "band-reversed": _opt("--band", "3000,500"),
        "band-outside": _opt("--band", "1e6,2e6"), "method-bogus": _opt("--method", "magic"),
        "spindle-uncertainty-missing": _opt("--spindle-uncertainty", "{root}/nope.npz"),
        # valid but odd: the sampler stopped long before convergence (the smallest settings of the other tests)
        "sampler-20-steps": lambda t: t.opts.update({"--method": "single", "--max-steps": "20", "--walkers": "10",
                                                     "--check-every": "10", "--checkpoint-interval": "0"}),
    }, ["summary.json"], examples=12, explicit=(["tip_x:crlf", "tip_x:latin1-comment"], ["sampler-20-steps"])),
    "lobes": Spec(_base_lobes, {
        **TIP_C, **{f"tip_y:{k}": v for k, v in _file(CSV_EDITS, _tip("tip_y_30mm.csv")).items()
                    if k in ("missing", "nan-cell", "binary", "few-lines", "mm-per-n")},
        **OUT_TAKEN, **SEED_C,
        "uff": lambda t: t.opts.update({"--measured-x": str(t.data / "tip_x_30mm.uff")}),
        "uff-truncated": lambda t: [t.opts.update({"--measured-x": str(t.data / "tip_x_30mm.uff")}),
                                    FILE_EDITS["truncated"](t.data / "tip_x_30mm.uff")],
        "uff-binary": lambda t: [t.opts.update({"--measured-y": str(t.data / "tip_y_30mm.uff")}),
                                 FILE_EDITS["binary"](t.data / "tip_y_30mm.uff")],
        "uff-as-csv": lambda t: shutil.copy(t.data / "tip_x_30mm.uff", t.data / "tip_x_30mm.csv"),
        "posterior-mode": _lobes_posterior_mode,
        "kt-nan": _opt("--kt", "nan"), "kt-in-n-per-mm2": _opt("--kt", "790"), "kr-negative": _opt("--kr", "-230e6"),
        "immersion-1.5": _opt("--immersion", "1.5"), "flutes-0": _opt("--flutes", "0"),
        "speeds-reversed": _opt("--speeds", "30000:5000:8"), "speeds-text": _opt("--speeds", "fast"),
        "depth-points-1": _opt("--depth-points", "1"), "level-2": _opt("--level", "2"),
        "averages-0": _opt("--averages", "0"), "pitch-bad": _opt("--pitch", "90,90,90"),
    }, ["lobes.json"], examples=16, explicit=(["uff"], ["posterior-mode"], ["tip_x:mm-per-n"])),
    "predict": Spec(_base_predict, {
        **{k: v for k, v in SETUP_C.items() if k != "missing-file-named"}, **POSTERIOR_C, **OUT_TAKEN, **SEED_C,
        "tip_x:rad-per-s": TIP_C["tip_x:rad-per-s"], "tip_x:nan-cell": TIP_C["tip_x:nan-cell"],
        "lengths-nan": _opt("--lengths", "nan"), "lengths-outside": _opt("--lengths", "0.5"),
        "lengths-mm": _opt("--lengths", "30"), "lengths-empty": _opt("--lengths", ","),
        "directions-z": _opt("--directions", "z"), "freq-reversed": _opt("--freq", "3500,500,10"),
        "freq-nan": _opt("--freq", "500,nan,10"), "max-draws-negative": _opt("--max-draws", "-1"),
        "tool-unknown": _opt("--tool", "nope"), "posterior-is-summary": lambda t: shutil.copy(
            t.world / "ident" / "summary.json", t.root / "posterior.nc"),
        "posterior-is-setup": lambda t: t.opts.update({"--posterior": str(_setup(t))}),
        "lengths-unmeasured": _opt("--lengths", "0.033"),  # valid: predicted on the spindle grid
    }, ["frequencies.json", "frf_bands.csv", "report.md", "report.html"], examples=16,
        explicit=(["lengths-unmeasured"],)),
    "update": Spec(_base_update, {
        **POSTERIOR_C, **OUT_TAKEN, **SEED_C,
        "cuts-depth-mm": _cuts_edit("9000,0.002", "9000,2"), "cuts-outcome-bogus": _cuts_edit("chatter", "wobbly"),
        "cuts-speed-outside": _cuts_edit("15000,", "900000,"), "cuts-missing": lambda t: (t.root / "cuts.csv").unlink(),
        "cuts-no-header": _cuts_edit("spindle_speed_rpm,depth_m,outcome\n", ""),
        "length-outside": _opt("--clamping-length", "0.5"), "kt-nan": _opt("--kt", "nan"),
        "width-negative": _opt("--boundary-width", "-0.1"), "min-ess-huge": _opt("--min-ess", "1e9"),
        "label-error-1": _opt("--label-error", "1"), "speeds": _opt("--speeds", "6000:20000:20"),
    }, ["posterior.nc", "update.json"], examples=8, explicit=([], ["speeds"])),
    "report": Spec(_base_report, {
        **{f"lobes.json:{k}": v for k, v in _file(JSON_EDITS, lambda t: t.root / "lob" / "lobes.json").items()},
        "npz-truncated": lambda t: FILE_EDITS["truncated"](t.root / "lob" / "p_stable.npz"),
        "run-missing": lambda t: t.pos.append(str(t.root / "nope")),
        "run-empty": lambda t: [(t.root / "empty").mkdir(), t.pos.append(str(t.root / "empty"))],
        "run-is-file": lambda t: t.pos.append(str(t.root / "lob" / "lobes.json")),
        "run-twice": lambda t: t.pos.append(t.pos[0]),
        "out-exists": lambda t: [t.out.parent.mkdir(exist_ok=True), t.out.write_text("old\n")],
        "out-is-dir": lambda t: t.out.mkdir(parents=True),
        "summary-is-dir": lambda t: Path(t.opts["--summary"]).mkdir(parents=True),
        "seed-negative": _opt("--seed", "-1"),
        "title-script": _opt("--title", "<script>alert(1)</script>\u2028\x00"),
    }, ["report.html", "summary.md"], examples=16),
    "spindle": Spec(_base_spindle, {
        **{f"artifact.toml:{k}": v for k, v in _file(TOML_EDITS, lambda t: t.root / "art" / "artifact.toml").items()},
        **{f"h11:{k}": v for k, v in _file(CSV_EDITS, lambda t: t.root / "art" / "h11_x.csv").items()},
        **{f"h12:{k}": v for k, v in _file(CSV_EDITS, lambda t: t.root / "art" / "h12_x.csv").items()},
        "artifact-nan-length": lambda t: _text_replace("total_length = 0.125", "total_length = nan")(
            t.root / "art" / "artifact.toml"),
        "artifact-points-swapped": lambda t: _text_replace("point2 = 0.1716", "point2 = -0.1716")(
            t.root / "art" / "artifact.toml"),
        "artifact-file-missing": lambda t: _text_replace('h22 = "h22_x.csv"', 'h22 = "h22_x_gone.csv"')(
            t.root / "art" / "artifact.toml"),
        **OUT_TAKEN, **SEED_C,
        "max-modes-0": _opt("--max-modes", "0"), "max-modes-99": _opt("--max-modes", "99"),
        "samples-negative": _opt("--samples", "-1"), "samples-huge": _opt("--samples", "10000000000"),
        "workers-0": _opt("--workers", "0"), "directions-y": _opt("--directions", "y"),
        "directions-z": _opt("--directions", "z"),
    }, ["spindle_summary.json", "spindle_x.csv", "spindle_x_raw.csv", "spindle_x_reliability.csv"], examples=10,
        explicit=(["h11:latin1-comment"],),
        # the identification costs ~1 s on the thinned campaign; corruptions that pass input validation would
        # run it on odd data (the clean run, which Hypothesis draws first, is the one valid case)
        fast={"artifact.toml:missing", "artifact.toml:empty", "artifact.toml:binary", "artifact.toml:truncated",
              "artifact.toml:unclosed-table", "artifact.toml:utf16", "artifact.toml:nul-bytes",
              "h11:missing", "h11:empty", "h11:binary", "h11:nan-cell", "h11:inf-cell", "h11:text-cell",
              "h11:semicolons", "h12:missing", "h12:truncated", "h12:swap-freq-real", "h12:few-lines",
              "h12:reversed", "artifact-nan-length", "artifact-points-swapped", "artifact-file-missing",
              "out-is-file", "out-nonempty", "out-under-file", "seed-negative", "seed-2**70", "seed-text",
              "max-modes-0", "max-modes-99", "samples-negative", "samples-huge", "workers-0", "directions-y",
              "directions-z"}),
    "synthesize": Spec(_base_synthesize, {
        **{f"bench:{k}": v for k, v in _file(TOML_EDITS, lambda t: t.root / "bench.toml").items()},
        "bench-nan-step": lambda t: _text_replace("step = 40.0", "step = nan")(t.root / "bench.toml"),
        "bench-negative-step": lambda t: _text_replace("step = 40.0", "step = -40.0")(t.root / "bench.toml"),
        "bench-tiny-step": lambda t: _text_replace("step = 40.0", "step = 1e-9")(t.root / "bench.toml"),
        "bench-lengths-mm": lambda t: _text_replace("[0.03]", "[30.0]")(t.root / "bench.toml"),
        "bench-lengths-empty": lambda t: _text_replace("[0.03]", "[]")(t.root / "bench.toml"),
        "bench-direction-z": lambda t: _text_replace('["x"]', '["z"]')(t.root / "bench.toml"),
        "bench-unknown-key": lambda t: (t.root / "bench.toml").write_text(BENCH + "stepp = 2\n"),
        "bench-unknown-effect": lambda t: (t.root / "bench.toml").write_text(
            BENCH + '[hidden.warp_drive]\nstrength = 1\n'),
        **OUT_TAKEN, **SEED_C,
        "artifact": _opt("--artifact", None),
    }, ["."], examples=16),
    "batch": Spec(_base_batch, {
        **{f"manifest:{k}": v for k, v in _file(TOML_EDITS, lambda t: t.root / "library.toml").items()},
        "manifest-setup-missing": _manifest_edit('file = "data/setup.toml"', 'file = "data/nope.toml"'),
        "manifest-bad-name": _manifest_edit('name = "a"', 'name = "../a"'),
        "manifest-duplicate": lambda t: (t.root / "library.toml").write_text(
            MANIFEST + '\n[[setup]]\nname = "a"\nfile = "data/setup.toml"\n'),
        "manifest-unknown-key": _manifest_edit("plots = false", "plotz = false"),
        "manifest-lengths-nan": _manifest_edit("lengths = [0.030]", "lengths = [nan]"),
        "manifest-method-bogus": _manifest_edit('method = "deterministic"', 'method = "magic"'),
        "manifest-no-setups": lambda t: (t.root / "library.toml").write_text("[defaults]\n"),
        "setup:unclosed-table": lambda t: SETUP_EDITS["unclosed-table"](_setup(t)),  # the setup fails: status 1
        "setup:nan-modulus": lambda t: SETUP_EDITS["nan-modulus"](_setup(t)),
        "tip_x:nan-cell": TIP_C["tip_x:nan-cell"],
        "out-is-file": OUT_TAKEN["out-is-file"], "out-under-file": OUT_TAKEN["out-under-file"],
        "workers-0": _opt("--workers", "0"), "workers-text": _opt("--workers", "two"),
    }, ["summary.json", "summary.csv", "summary.html"], examples=12,
        explicit=(["setup:nan-modulus"], ["tip_x:nan-cell"])),
    "discrepancy": Spec(_base_discrepancy, {
        **SETUP_C, **TIP_C, **OUT_TAKEN, **SEED_C,
        "candidates-unknown": _opt("--candidates", "warp_drive"), "candidates-empty": _opt("--candidates", ","),
        "lengths-nan": _opt("--lengths", "nan"), "lengths-unmeasured": _opt("--lengths", "0.033"),
        "refit-0": _opt("--refit", "0"), "refit-text": _opt("--refit", "all"),
    }, ["discrepancy.json", "summary.md"], examples=10, fast={
        "missing", "empty", "binary", "truncated", "unclosed-table", "utf16", "nan-modulus", "inf-length",
        "length-in-mm", "negative-density", "string-number", "missing-file-named", "duplicate-key",
        "tip_x:missing", "tip_x:empty", "tip_x:binary", "tip_x:nan-cell", "tip_x:inf-cell", "tip_x:text-cell",
        "tip_x:few-lines", "tip_x:semicolons", "tip_x:rad-per-s", "out-is-file", "out-nonempty", "out-under-file",
        "seed-negative", "seed-2**70", "seed-text", "candidates-unknown", "candidates-empty", "lengths-nan",
        "lengths-unmeasured", "refit-0", "refit-text"}),
    "design": Spec(_base_design, {
        **{k: v for k, v in SETUP_C.items() if k != "missing-file-named"}, **POSTERIOR_C, **OUT_TAKEN, **SEED_C,
        "target-bogus": _opt("--target", "happiness@0.03"), "target-outside": _opt("--target", "frequency@0.5"),
        "target-nan": _opt("--target", "frequency@nan"), "target-missing": _drop("--target"),
        "target-lobes-no-cutting": _opt("--target", "lobes@0.03:5000:30000"),
        "candidates-text": _opt("--candidates", "tomorrow"), "candidates-outside": _opt("--candidates", "0.5"),
        "candidates-tool-unknown": _opt("--candidates", "tool:nope@0.03"),
        "candidates-dir-z": _opt("--candidates", "dir:z@0.03"), "draws-0": _opt("--draws", "0"),
        "truths-text": _opt("--truths", "many"), "noise-scale-with-posterior": _opt("--noise-scale", "0.02"),
        "method-bogus": _opt("--method", "magic"), "method-laplace": _opt("--method", "laplace"),
        "kt-nan": lambda t: t.opts.update({"--target": "lobes@0.03:5000:30000:8", "--kt": "nan", "--kr": "230e6",
                                           "--flutes": "4", "--radial-immersion": "0.5"}),
    }, ["design.json"], examples=14, explicit=(["method-laplace"],)),
    "identifiability": Spec(_base_identifiability, {
        **SETUP_C, **TIP_C, **OUT_TAKEN, **SEED_C,
        "lengths-nan": _opt("--lengths", "nan"), "lengths-unmeasured": _opt("--lengths", "0.033"),
        "walkers-odd": _opt("--walkers", "11"), "walkers-1": _opt("--walkers", "1"),
        "check-every-0": _opt("--check-every", "0"), "max-steps-text": _opt("--max-steps", "many"),
    }, ["identifiability.json", "identifiability.md", "identifiability.html"], examples=8, fast={
        "missing", "empty", "binary", "truncated", "unclosed-table", "utf16", "nan-modulus", "inf-length",
        "length-in-mm", "negative-density", "string-number", "missing-file-named", "duplicate-key",
        "tip_x:missing", "tip_x:empty", "tip_x:binary", "tip_x:nan-cell", "tip_x:inf-cell", "tip_x:text-cell",
        "tip_x:few-lines", "out-is-file", "out-nonempty", "out-under-file", "seed-negative", "seed-2**70",
        "seed-text", "lengths-nan", "lengths-unmeasured", "walkers-odd", "walkers-1", "check-every-0",
        "max-steps-text"}),
    "library": Spec(_base_library, {
        **{f"manifest:{k}": v for k, v in _file(TOML_EDITS, lambda t: t.root / "library.toml").items()},
        "manifest-one-setup": lambda t: (t.root / "library.toml").write_text(LIBRARY_MANIFEST.split("\n\n[[setup]]\nname = \"b\"")[0]),
        "manifest-deterministic": lambda t: _text_replace('method = "multi"', 'method = "deterministic"')(
            t.root / "library.toml"),
        "holder-type-missing": lambda t: _text_replace('type = "ER32"\n', "")(_setup(t)),
        "holder-type-number": lambda t: _text_replace('type = "ER32"', "type = 32")(_setup(t)),
        "setup:unclosed-table": lambda t: SETUP_EDITS["unclosed-table"](_setup(t)),
        "setup:nan-modulus": lambda t: SETUP_EDITS["nan-modulus"](_setup(t)),
        "out-is-file": OUT_TAKEN["out-is-file"], "out-nonempty": OUT_TAKEN["out-nonempty"],
        "out-under-file": OUT_TAKEN["out-under-file"], **SEED_C,
        "workers-0": _opt("--workers", "0"), "scheduler-nowhere": _opt("--scheduler", "tcp://127.0.0.1:1"),
    }, ["population.nc", "library.json", "laws.json", "laws.csv"], examples=10, min_size=1,
        # a valid library run is two identify runs and stage 2: every example carries one refused input
        fast=None),
    "demo": Spec(_base_demo, {
        **OUT_TAKEN, **SEED_C,
        "max-steps-0": _opt("--max-steps", "0"), "max-steps-text": _opt("--max-steps", "many"),
        "max-steps-huge": _opt("--max-steps", str(10**15)),
        "earlier-demo": lambda t: [t.out.mkdir(parents=True), (t.out / "report.html").write_text("old\n")],
    }, ["report.html", "index.html", "summary.md"], examples=8, min_size=1,
        # a valid demo costs ~35 s even with --max-steps 20: every example carries one refused input
        fast=None),
    "example": Spec(_base_example, {**OUT_TAKEN, **SEED_C},
                    ["README.txt", "setup.toml", "bench.toml", "artifact/artifact.toml", "library.toml"], examples=6,
                    # a valid run generates the synthetic artifact and library (~4 s): every example carries one
                    # refused input (the valid run is tests/test_docs_runner.py's)
                    min_size=1, fast=None),
}


def test_every_command_has_a_generator():
    assert set(SPECS) == set(COMMANDS), set(COMMANDS) ^ set(SPECS)


def test_fast_corruptions_exist():
    for name, spec in SPECS.items():
        assert not (spec.fast or set()) - set(spec.corruptions), name
        assert not {c for e in spec.explicit for c in e} - set(spec.corruptions), name


# --------------------------------------------------------------------------- the invariant


def _finite(value) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, list):
        return all(_finite(v) for v in value)
    return True


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _run(command: str, corruptions: list[str], world: Path, root: Path) -> None:
    spec = SPECS[command]
    t = Trial(root=root, world=world)
    spec.base(t)
    for name in corruptions:
        with contextlib.suppress(OSError, IndexError, ValueError):  # an earlier one left nothing to edit
            spec.corruptions[name](t)
    t.opts = {k: (v.format(root=root) if isinstance(v, str) else v) for k, v in t.opts.items()}
    argv = t.argv(command)
    before = _tree(root)
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            rc = main(argv)
        except SystemExit as exc:  # argparse's one-line usage error
            rc = exc.code
    text, stdout = err.getvalue(), out.getvalue()
    where = f"{command} {corruptions}: rc={rc}\n{text}"
    assert "Traceback" not in text, where
    lines = text.strip().splitlines()
    if os.environ.get("BAYES_RCSA_PROPERTY_LOG"):  # one line per example: what was drawn and how it ended
        with open(os.environ["BAYES_RCSA_PROPERTY_LOG"], "a", encoding="utf-8") as fh:
            fh.write(f"{command} {corruptions} rc={rc} {(lines or [''])[-1][:200]}\n")
    if rc == 2:
        assert len(lines) == 1, where
        assert lines[0].startswith(f"bayes-rcsa {command}: error: "), where
        assert _tree(root) == before, (where, _tree(root) ^ before)
        if stdout:  # argparse's refusals come before --json is known
            assert json.loads(stdout)["error"] == lines[0].split(": error: ", 1)[1], (where, stdout)
        return
    assert rc == 0 or (command == "batch" and rc == 1), where
    doc = json.loads(stdout)
    assert _finite(doc), (where, stdout)
    assert "None" not in lines[-1], where  # the closing line names what was written, not a Python None
    target = t.out
    for name in spec.promised:
        if command in ("report",):
            path = Path(t.opts["--out"]) if name == "report.html" else Path(t.opts["--summary"])
        else:
            path = target / name
        assert path.exists(), (where, name)
    if command == "synthesize":
        expected = ["artifact.toml"] if "--artifact" in t.opts else ["setup.toml", "truth.json", "tip_x_30mm.csv"]
        for name in expected:
            assert (target / name).exists(), (where, name)
    if command == "batch":
        rows = json.loads((target / "summary.json").read_text())["rows"]
        failed = [r for r in rows if r["status"] != "done"]
        assert (rc == 1) == bool(failed), (where, rows)  # exit status 1: a setup failed, and the table says which
        for r in failed:  # the failed step's own one-line refusal
            assert re.match(r"^bayes-rcsa \w+: error: [^\n]+$", r["error"]), (where, r)
        for log in target.rglob("log.txt"):
            assert "Traceback" not in log.read_text(), (where, log.read_text())
    if command == "simulate":
        if target.suffix == ".csv":
            body = [ln for ln in target.read_text().splitlines() if ln and not ln.startswith("#") and
                    not ln[0].isalpha()]
            assert np.isfinite(np.array([[float(v) for v in ln.split(",")] for ln in body])).all(), where
        return
    if command == "report":
        return
    for p in target.rglob("*.json"):
        assert _finite(json.loads(p.read_text())), (where, p)


@pytest.mark.parametrize("command", sorted(SPECS))
def test_corrupted_inputs_exit_0_with_finite_outputs_or_2_with_one_line(command, world, tmp_path_factory):
    spec = SPECS[command]
    names = sorted(spec.fast if spec.fast is not None else spec.corruptions)
    if command == "batch":
        # the setups run on a thread of this process instead of a fresh worker process (4 s of imports each);
        # the steps are the real commands
        patch = pytest.MonkeyPatch()
        patch.setattr(batch_run, "_local_pool", lambda workers: cf.ThreadPoolExecutor(1))
    else:
        patch = None

    @settings(max_examples=spec.examples, deadline=None, database=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(st.lists(st.sampled_from(names), min_size=spec.min_size, max_size=spec.max_size, unique=True))
    def check(corruptions):
        _run(command, corruptions, world, tmp_path_factory.mktemp(command))

    for corruptions in spec.explicit:
        check = example(corruptions)(check)

    try:
        check()
    finally:
        if patch is not None:
            patch.undo()


# --------------------------------------------------------------------------- regressions found by the property test


def test_spindle_without_samples_names_only_the_files_written(tmp_path):
    """``spindle --samples 0`` said "wrote spindle_x.csv and None in DIR" (the absent samples file as None).

    The command prints :meth:`SpindleInterface.summary_line` and ``summary_data`` of the workflow's result."""
    from bayes_rcsa.workflows.spindle import SpindleInterface

    result = SpindleInterface(summary={"samples_file": None, "directions": {"x": {}}}, receptances={"x": None},
                              raw={"x": None}, path=tmp_path / "out")
    assert result.summary_line() == f"wrote spindle_x.csv in {tmp_path / 'out'}"
    assert result.summary_data()["samples"] is None
    with_samples = SpindleInterface(summary={"samples_file": "spindle_samples.npz", "directions": {"x": {}}},
                                    receptances={"x": None}, raw={"x": None}, path=tmp_path / "out")
    assert with_samples.summary_line() == f"wrote spindle_x.csv, spindle_samples.npz in {tmp_path / 'out'}"