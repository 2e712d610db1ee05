"""Bad input through the real command line: exit 2, one stderr line naming the culprit, nothing left behind.

One row per kind of bad input (issue "Reliability": items 1-3, 5-7, 10-13 plus the
cases that were already handled).  Most rows run ``bayes_rcsa.cli.main.main`` in
process (start-up of a fresh interpreter would dominate the run time); the rows
marked ``subprocess`` go through ``python3 -m bayes_rcsa`` to prove the
promise holds for the real executable, with its real stderr.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from bayes_rcsa.cli.main import main

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "bayes_rcsa" / "data" / "example"
LOBES_CASE = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95", "--speeds", "5000:30000:20"]


# --------------------------------------------------------------------------- file mutations


def _edit_setup(old: str, new: str) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        p = d / "setup.toml"
        text = p.read_text()
        assert old in text, old
        p.write_text(text.replace(old, new, 1))

    return edit


def _append_setup(extra: str) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        with open(d / "setup.toml", "a", encoding="utf-8") as fh:
            fh.write("\n" + extra + "\n")

    return edit


def _prepend_setup(extra: str) -> Callable[[Path], None]:
    """Top-level keys must come before the first table."""

    def edit(d: Path) -> None:
        p = d / "setup.toml"
        p.write_text(extra + "\n" + p.read_text())

    return edit


def _rewrite_frf(name: str, fn: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]):
    """Rewrite columns real/imag of an example FRF CSV with ``fn(real, imag) -> (real, imag)``."""

    def edit(d: Path) -> None:
        p = d / name
        lines = p.read_text().splitlines()
        head = [ln for ln in lines if ln.startswith("#")]
        rows = [ln for ln in lines if not ln.startswith("#")]
        header = rows[0].split(",")
        data = np.array([[float(v) for v in r.split(",")] for r in rows[1:]])
        i_re, i_im = header.index("real"), header.index("imag")
        data[:, i_re], data[:, i_im] = fn(data[:, i_re].copy(), data[:, i_im].copy())
        body = [",".join(repr(float(v)) for v in row) for row in data]
        p.write_text("\n".join(head + [rows[0]] + body) + "\n")

    return edit


def _set_cell(name: str, row: int, column: str, value: str) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        p = d / name
        lines = p.read_text().splitlines()
        data_idx = [i for i, ln in enumerate(lines) if not ln.startswith("#")]
        header = lines[data_idx[0]].split(",")
        i = data_idx[1 + row]
        cells = lines[i].split(",")
        cells[header.index(column)] = value
        lines[i] = ",".join(cells)
        p.write_text("\n".join(lines) + "\n")

    return edit


def _negate_spindle_n(d: Path) -> None:
    _flip_spindle(d, ("n_real", "n_imag"))


def _make_file(name: str) -> Callable[[Path, Path], None]:
    def make(d: Path, run: Path) -> None:
        (run / name).write_text("not a directory\n")

    return make


# --------------------------------------------------------------------------- the table


@dataclass
class Case:
    id: str
    argv: list[str]  # "{setup}", "{data}", "{run}" are substituted
    fragments: list[str]  # each must appear in the one stderr line
    edit: Callable[[Path], None] | None = None  # mutates the copied example data directory
    before: Callable[[Path, Path], None] | None = None  # creates things in the run directory
    subprocess: bool = False
    absent: list[str] = field(default_factory=list)  # must NOT appear in the message


S = "{setup}"
OUT = "{run}/out"

CASES = [
    # item 11: --seed -1
    Case("identify-seed-negative", ["identify", S, "--out", OUT, "--seed", "-1"], ["--seed", "-1"], subprocess=True),
    Case("predict-seed-negative", ["predict", S, "--posterior", "{run}/p.nc", "--out", OUT, "--seed", "-1"], ["--seed"]),
    Case("lobes-seed-negative", ["lobes", S, "--posterior", "{run}/p.nc", "--clamping-length", "0.03", *LOBES_CASE,
                                 "--out", OUT, "--seed", "-1"], ["--seed", "-1"]),
    # item 11: --out is an existing file
    Case("identify-out-file", ["identify", S, "--out", "{run}/f"], ["--out", "exists and is not a directory"],
         before=_make_file("f")),
    Case("predict-out-file", ["predict", S, "--posterior", "{run}/p.nc", "--out", "{run}/f"], ["--out", "not a directory"],
         before=_make_file("f")),
    Case("lobes-out-file", ["lobes", "--measured-x", "{data}/tip_x_30mm.csv", "--measured-y", "{data}/tip_y_30mm.csv",
                            *LOBES_CASE, "--out", "{run}/f"], ["--out", "not a directory"], before=_make_file("f")),
    Case("demo-out-file", ["demo", "--out", "{run}/f"], ["--out", "not a directory"], before=_make_file("f")),
    Case("simulate-out-under-file", ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                                     "--out", "{run}/f/x.csv"], ["--out", "is a file, not a directory"],
         before=_make_file("f")),
    # item 12: simulate --out DIR must not name an internal temp file
    Case("simulate-out-dir", ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                              "--out", "{run}"], ["--out", "is a directory"], absent=[".tmp"]),
    Case("simulate-out-unknown-type", ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                                       "--out", "{run}/x.txt"], ["--out", "unsupported FRF output type '.txt'"]),
    # item 11: absurd numbers
    Case("youngs-modulus-1e300", ["identify", S, "--out", OUT], ["[materials.steel] youngs_modulus = 1e+300"],
         edit=_edit_setup("youngs_modulus = 200000000000.0", "youngs_modulus = 1e300"), subprocess=True),
    Case("csv-cell-1e300", ["identify", S, "--out", OUT], ["tip_x_30mm.csv", "implausible"],
         edit=_set_cell("tip_x_30mm.csv", 10, "imag", "1e300"), subprocess=True),
    Case("simulate-freq-too-many-lines", ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                                          "--freq", "500,3500,1e-9", "--out", "{run}/x.csv"],
         ["--freq", "at most 1000000"], subprocess=True),
    # item 11: top-level keys of the wrong type, non-numeric prior bounds
    Case("likelihood-is-number", ["identify", S, "--out", OUT], ["[likelihood]", "expected a table"],
         edit=_prepend_setup("likelihood = 5")),
    Case("sampler-is-string", ["identify", S, "--out", OUT], ["[sampler]", "expected a table", "'fast'"],
         edit=_prepend_setup('sampler = "fast"')),
    Case("priors-non-numeric", ["identify", S, "--out", OUT], ["[priors] k_xf", "'a'"],
         edit=_append_setup('[priors]\nk_xf = ["a", 1e9]')),
    # item 12: the right key for a bad log-normal sigma
    Case("prior-lognormal-sigma", ["identify", S, "--out", OUT], ["[priors] k_xf.sigma = -1"],
         edit=_append_setup('[priors]\nk_xf = { distribution = "log-normal", median = 1e7, sigma = -1 }')),
    # item 3: misspelled top-level tables
    Case("table-prior-typo", ["identify", S, "--out", OUT], ["unknown table [prior]", "did you mean 'priors'"],
         edit=_append_setup("[prior]\nk_xf = [1e6, 1e8]")),
    Case("table-likelihod-typo", ["identify", S, "--out", OUT], ["[likelihod]", "did you mean 'likelihood'"],
         edit=_append_setup("[likelihod]\nnoise_floor = 0.0")),
    Case("model-terms-not-list", ["identify", S, "--out", OUT], ["[model] terms = 'tip_mass'", "list of term names"],
         edit=_append_setup('[model]\nterms = "tip_mass"')),
    Case("model-override-bad", ["identify", S, "--out", OUT], ["[model] tip_mass_kg", "fixed value"],
         edit=_append_setup('[model]\nterms = ["tip_mass"]\ntip_mass_kg = "heavy"')),
    # item 7: non-finite numeric options
    Case("ess-min-nan", ["identify", S, "--out", OUT, "--ess-min", "nan"], ["--ess-min", "finite"]),
    Case("checkpoint-interval-nan", ["identify", S, "--out", OUT, "--checkpoint-interval", "nan"],
         ["--checkpoint-interval", "finite"]),
    Case("checkpoint-interval-inf", ["identify", S, "--out", OUT, "--checkpoint-interval", "inf"],
         ["--checkpoint-interval", "finite"]),
    Case("band-nan", ["identify", S, "--out", OUT, "--band", "1000,nan"], ["--band", "1000,nan"]),
    Case("simulate-kx-nan", ["simulate", S, "--clamping-length", "0.03", "--kx", "nan", "--ktheta", "1e5",
                             "--out", "{run}/x.csv"], ["--kx", "finite"]),
    # item 12: negative numbers in scientific notation reach the option's own check (not "expected one argument")
    Case("lobes-kt-negative", ["lobes", "--measured-x", "{data}/tip_x_30mm.csv", "--measured-y", "{data}/tip_y_30mm.csv",
                               "--flutes", "4", "--kt", "-790e6", "--kr", "230e6", "--immersion", "0.95",
                               "--speeds", "5000:30000:20", "--out", OUT], ["--kt -790e6", "> 0"],
         absent=["expected one argument"]),
    Case("simulate-kx-negative", ["simulate", S, "--clamping-length", "0.03", "--kx", "-1e7", "--ktheta", "1e5",
                                  "--out", "{run}/x.csv"], ["--kx '-1e7'", "> 0"]),
    # item 13: early identify failures leave no --out
    Case("walkers-odd", ["identify", S, "--out", OUT, "--walkers", "5"], ["n_walkers = 5"]),
    Case("resume-without-checkpoint", ["identify", S, "--out", OUT, "--resume"], ["--resume", "no checkpoint"]),
    Case("spindle-uncertainty-missing", ["identify", S, "--out", OUT, "--spindle-uncertainty", "{run}/nope.npz"],
         ["nope.npz", "not found"]),
    Case("start-outside-prior", ["identify", S, "--out", OUT, "--lengths", "0.025,0.040"], ["k_xf", "outside its prior"],
         edit=_append_setup("[sampler]\nstart = { k_xf = 1e12 }")),
    # item 1: non-passive measured FRFs (tool point, lobes' measured files, spindle direct terms)
    Case("tip-imag-negated", ["identify", S, "--out", OUT], ["tip_x_30mm.csv", "wrong sign", "e^{-iωt}"],
         edit=_rewrite_frf("tip_x_30mm.csv", lambda re_, im: (re_, -im))),
    Case("tip-real-imag-swapped", ["identify", S, "--out", OUT], ["tip_x_35mm.csv", "swapped"],
         edit=_rewrite_frf("tip_x_35mm.csv", lambda re_, im: (im, re_))),
    Case("lobes-measured-sign-flipped", ["lobes", "--measured-x", "{data}/tip_x_30mm.csv", "--measured-y",
                                         "{data}/tip_y_30mm.csv", *LOBES_CASE, "--out", OUT],
         ["tip_x_30mm.csv", "wrong sign"], edit=_rewrite_frf("tip_x_30mm.csv", lambda re_, im: (re_, -im)),
         subprocess=True),
    Case("spindle-h-sign", ["simulate", S, "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
                            "--out", "{run}/x.csv"], ["spindle_x.csv", "h (h_real, h_imag)", "wrong sign"],
         edit=lambda d: _flip_spindle(d, ("h_imag",))),
    # item 2: non-reciprocal spindle block
    Case("spindle-not-reciprocal", ["identify", S, "--out", OUT], ["spindle_x.csv", "not reciprocal", "n = -l"],
         edit=_negate_spindle_n),
    # item 5: one measurement at two clamping lengths
    Case("same-file-two-lengths", ["identify", S, "--out", OUT], ["tip_x_25mm.csv", "two clamping lengths"],
         edit=_edit_setup('file = "tip_x_30mm.csv"', 'file = "tip_x_25mm.csv"')),
    # item 6: data in mm/N
    Case("tip-in-mm-per-N", ["identify", S, "--out", OUT], ["tip_x_40mm.csv", "mm/N instead of m/N"],
         edit=_rewrite_frf("tip_x_40mm.csv", lambda re_, im: (1e3 * re_, 1e3 * im))),
    # cases handled before this issue (kept so they stay handled)
    Case("setup-missing", ["identify", "{run}/missing.toml", "--out", OUT], ["missing.toml", "not found"]),
    Case("unknown-key-in-table", ["identify", S, "--out", OUT], ["[contact]", "growth_bond", "did you mean 'growth_bound'"],
         edit=_edit_setup("growth_bound = 0.5", "growth_bond = 0.5")),
    Case("malformed-toml", ["identify", S, "--out", OUT], ["malformed TOML"], edit=_append_setup("[contact")),
    Case("measurement-file-missing", ["identify", S, "--out", OUT], ["tip_x_99mm.csv", "not found"],
         edit=_edit_setup('file = "tip_x_30mm.csv"', 'file = "tip_x_99mm.csv"')),
    Case("csv-not-a-number", ["identify", S, "--out", OUT], ["tip_x_30mm.csv", "line", "'abc' is not a number"],
         edit=_set_cell("tip_x_30mm.csv", 3, "real", "abc")),
    Case("predict-posterior-missing", ["predict", S, "--posterior", "{run}/p.nc", "--out", OUT], ["p.nc", "no such file"]),
]


def _flip_spindle(d: Path, columns: tuple[str, ...]) -> None:
    p = d / "spindle_x.csv"
    lines = p.read_text().splitlines()
    data_idx = [i for i, ln in enumerate(lines) if not ln.startswith("#")]
    header = lines[data_idx[0]].split(",")
    cols = [header.index(c) for c in columns]
    for i in data_idx[1:]:
        cells = lines[i].split(",")
        for c in cols:
            cells[c] = repr(-float(cells[c]))
        lines[i] = ",".join(cells)
    p.write_text("\n".join(lines) + "\n")


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_gives_one_line_and_leaves_nothing(case: Case, tmp_path, capsys):
    data = tmp_path / "data"
    shutil.copytree(EXAMPLE, data)
    run = tmp_path / "run"
    run.mkdir()
    if case.edit is not None:
        case.edit(data)
    if case.before is not None:
        case.before(data, run)
    argv = [a.format(setup=data / "setup.toml", data=data, run=run) for a in case.argv]
    before_run, before_data = _tree(run), _tree(data)
    if case.subprocess:
        env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONWARNINGS="default")
        proc = subprocess.run([sys.executable, "-m", "bayes_rcsa", *argv], capture_output=True, text=True,
                              cwd=tmp_path, env=env, timeout=120)
        rc, err, out = proc.returncode, proc.stderr, proc.stdout
    else:
        try:
            rc = main(argv)
        except SystemExit as exc:  # argparse usage errors exit like the real executable
            rc = exc.code
        captured = capsys.readouterr()
        err, out = captured.err, captured.out
    assert rc == 2, (rc, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and "Warning:" not in err, err
    assert re.match(r"^bayes-rcsa \w+: error: ", lines[0]), lines[0]
    for fragment in case.fragments:
        assert fragment in lines[0], (fragment, lines[0])
    for fragment in case.absent:
        assert fragment not in lines[0], (fragment, lines[0])
    assert out == ""
    # Nothing new in the output's parent (run/) nor beside the data (e.g. lock or temp files).
    assert _tree(run) == before_run
    assert _tree(data) == before_data
