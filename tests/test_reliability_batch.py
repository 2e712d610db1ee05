"""Issue #21: batch paths (family 8), the batch's warnings column (family 7), full disks under batch, synthesize,
discrepancy and demo (family 1), through the real command line.

The batch runs its real code (manifest, run_batch, run_setup, write_summary) on a thread pool with the three
steps replaced by a stand-in that writes what the real ones write (summary.json, frequencies.json, lobes.json,
each with warnings), so that a case costs milliseconds; the equality with the real commands is
tests/test_batch.py's.  Full-disk cases inject an OSError at one write (tests/test_reliability_fs.py's Faults).
"""

from __future__ import annotations

import concurrent.futures as cf
import errno
import json
import os
import shutil
from pathlib import Path

import pytest

import bayes_rcsa.cli.main as cli_main
from bayes_rcsa.batch import run as batch_run
from bayes_rcsa.data import example_dir
from bayes_rcsa.io.atomic import atomic_write_text
from test_reliability_fs import Faults, _one_error_line, _tree

MAIN = cli_main.main

MANIFEST = """\
[defaults]
method = "single"
[defaults.predict]
lengths = [0.030]
[defaults.lobes]
clamping_length = 0.030
flutes = 4
kt = "790e6"
kr = "230e6"
immersion = 0.95
"""


def _fake_step(argv: list[str]) -> int:
    """identify / predict / lobes stand-in: writes the step's document (with one warning) into its --out."""
    out = Path(argv[argv.index("--out") + 1])
    setup = Path(argv[1])
    if "FAIL" in setup.read_text():
        print(f"bayes-rcsa {argv[0]}: error: {setup}: FAIL marker", file=os.sys.stderr)
        return 2
    name = {"identify": "summary.json", "predict": "frequencies.json", "lobes": "lobes.json"}[argv[0]]
    doc = {"warnings": [f"{argv[0]} data warning"], "converged": True, "parameters": {}, "predictions": []}
    atomic_write_text(out / name, json.dumps(doc))
    return 0


@pytest.fixture()
def batch_env(monkeypatch, tmp_path):
    """Steps replaced by :func:`_fake_step`, setups run on a thread pool in this process."""
    monkeypatch.setattr(cli_main, "main", _fake_step)
    monkeypatch.setattr(batch_run, "_local_pool", lambda workers: cf.ThreadPoolExecutor(1))
    lib = tmp_path / "lib"
    lib.mkdir()
    for name in ("a", "b"):
        (lib / name).mkdir()
        (lib / name / "setup.toml").write_text("# setup\n")
    return lib


def _manifest(lib: Path, files: dict[str, str]) -> Path:
    text = MANIFEST + "".join(f'\n[[setup]]\nname = "{n}"\nfile = "{f}"\n' for n, f in files.items())
    (lib / "library.toml").write_text(text)
    return lib / "library.toml"


def _batch(manifest: Path, out: Path, *extra: str) -> int:
    return MAIN(["batch", str(manifest), "--out", str(out), "--quiet", "--workers", "1", *extra])


# --------------------------------------------------------------------------- family 8: setup files outside the folder


def _outside_relative(lib: Path, tmp: Path) -> str:
    (tmp / "elsewhere").mkdir()
    (tmp / "elsewhere" / "setup.toml").write_text("# setup\n")
    return "../elsewhere/setup.toml"


def _outside_absolute(lib: Path, tmp: Path) -> str:
    (tmp / "abs").mkdir()
    (tmp / "abs" / "setup.toml").write_text("# setup\n")
    return str(tmp / "abs" / "setup.toml")


def _outside_symlink(lib: Path, tmp: Path) -> str:
    (tmp / "linked").mkdir()
    (tmp / "linked" / "setup.toml").write_text("# setup\n")
    (lib / "link").symlink_to(tmp / "linked")
    return "link/setup.toml"


@pytest.mark.parametrize("where", [_outside_relative, _outside_absolute, _outside_symlink],
                         ids=["relative-dotdot", "absolute", "symlink"])
def test_setup_outside_the_manifest_folder_runs_with_one_warning(where, batch_env, tmp_path, capsys):
    lib = batch_env
    manifest = _manifest(lib, {"a": "a/setup.toml", "far": where(lib, tmp_path)})
    out = tmp_path / "out"
    assert _batch(manifest, out, "--json") == 0
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err
    hits = [ln for ln in cap.err.splitlines() if ": warning: " in ln and "outside the manifest's folder" in ln]
    assert len(hits) == 1 and "'far'" in hits[0], cap.err
    assert any("outside the manifest's folder" in w for w in json.loads(cap.out)["warnings"])
    assert any("outside the manifest's folder" in w
               for w in json.loads((out / "summary.json").read_text())["warnings"])
    # inside the folder: no such warning
    manifest = _manifest(lib, {"a": "a/setup.toml", "b": "b/setup.toml"})
    assert _batch(manifest, tmp_path / "out2") == 0
    assert "outside the manifest" not in capsys.readouterr().err


def test_failed_setup_leaves_no_half_made_folder_and_reruns(batch_env, tmp_path, capsys):
    lib = batch_env
    # TOML (the manifest refuses a file that is none); the fake step fails on the marker
    (lib / "b" / "setup.toml").write_text("# FAIL\n")
    manifest = _manifest(lib, {"a": "a/setup.toml", "b": "b/setup.toml"})
    out = tmp_path / "out"
    assert _batch(manifest, out) == 1
    capsys.readouterr()
    # the failure's record only: no step folder of the failed step, no start marker
    assert sorted(p.name for p in (out / "setups" / "b").iterdir()) == ["log.txt", "result.json"]
    (lib / "b" / "setup.toml").write_text("# fixed\n")
    assert _batch(manifest, out) == 0  # not blocked: the failed setup is cleared and run again
    assert (out / "setups" / "b" / "lobes" / "lobes.json").is_file()


# --------------------------------------------------------------------------- family 7: the warnings column


def test_batch_table_and_html_have_a_warnings_column(batch_env, tmp_path, capsys):
    manifest = _manifest(batch_env, {"a": "a/setup.toml", "b": "b/setup.toml"})
    out = tmp_path / "out"
    assert _batch(manifest, out) == 0
    err = capsys.readouterr().err
    assert "a: 3 warning(s)" in err
    import csv

    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert rows[0]["n_warnings"] == "3"
    assert rows[0]["warnings"] == "identify: identify data warning; predict: predict data warning; lobes: lobes data warning"
    html = (out / "summary.html").read_text()
    assert "<th>warnings</th>" in html and "lobes: lobes data warning" in html
    assert "with warnings" in html


# --------------------------------------------------------------------------- family 1: full disk under batch


@pytest.mark.parametrize("at,name,code", [(None, "batch.json", errno.ENOSPC), (None, "result.json", errno.ENOSPC),
                                          (None, "summary.html", errno.EROFS), (3, None, errno.ENOSPC)],
                         ids=["batch.json", "result.json", "summary.html-erofs", "third-write"])
def test_batch_full_disk_one_line_nothing_left_rerun(at, name, code, batch_env, monkeypatch, tmp_path, capsys):
    manifest = _manifest(batch_env, {"a": "a/setup.toml", "b": "b/setup.toml"})
    faults = Faults(monkeypatch)
    out = tmp_path / "new" / "out"
    before = _tree(tmp_path)
    faults.arm(at=at, name=name, code=code)
    rc = _batch(manifest, out)
    err = capsys.readouterr().err
    assert rc == 2, err
    _one_error_line(err, f"({errno.errorcode[code]})")
    assert _tree(tmp_path) == before
    faults.disarm()
    assert _batch(manifest, out) == 0, capsys.readouterr().err


# --------------------------------------------------------------------------- family 1: synthesize, discrepancy, demo


def _synthesize(tmp_path: Path, out: Path) -> list[str]:
    cfg = tmp_path / "bench.toml"
    if not cfg.exists():
        cfg.write_text("[campaign]\nclamping_lengths = [0.03]\ndirections = [\"x\"]\n[frequency]\nstep = 40.0\n")
    return ["synthesize", str(cfg), "--out", str(out)]


def _discrepancy(tmp_path: Path, out: Path) -> list[str]:
    return ["discrepancy", str(example_dir() / "setup.toml"), "--out", str(out), "--lengths", "0.03",
            "--candidates", "tip_mass", "--refit", "1", "--no-plots"]


# discrepancy commits its folder with one rename (one write site); it costs ~3 s a run, so one case
@pytest.mark.parametrize("command,at,code", [("synthesize", 1, errno.ENOSPC), ("synthesize", 3, errno.EROFS),
                                             ("synthesize", 2, errno.EACCES), ("discrepancy", 1, errno.ENOSPC)],
                         ids=["synthesize-first", "synthesize-third-erofs", "synthesize-second-eacces",
                              "discrepancy-enospc"])
def test_full_disk_synthesize_and_discrepancy(command, at, code, monkeypatch, tmp_path, capsys):
    argv = {"synthesize": _synthesize, "discrepancy": _discrepancy}[command]
    work = tmp_path / "work"
    work.mkdir()
    out = work / "new" / "out"
    args = argv(tmp_path, out)
    faults = Faults(monkeypatch)
    before = _tree(work)
    faults.arm(at=at, code=code)
    rc = MAIN(args)
    err = capsys.readouterr().err
    assert rc == 2, err
    _one_error_line(err, f"({errno.errorcode[code]})")
    assert _tree(work) == before
    faults.disarm()
    assert MAIN(args) == 0, capsys.readouterr().err


def test_demo_step_failure_is_one_line(monkeypatch, tmp_path, capsys):
    import bayes_rcsa.workflows.identification as identification
    from bayes_rcsa.errors import OutputError

    def failing_step(setup, **kw):
        print("identify: progress line", file=os.sys.stderr)
        raise OutputError(f"{tmp_path}/out/identify: cannot write summary.json: No space left on device (ENOSPC)")

    monkeypatch.setattr(identification, "identify", failing_step)  # the demo's first step, looked up when it runs
    rc = MAIN(["demo", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 2
    errors = [ln for ln in err.splitlines() if ": error: " in ln]
    assert len(errors) == 1 and errors[0].startswith("bayes-rcsa demo: error: step 'identify' failed: "), err
    assert "(ENOSPC)" in errors[0] and "Traceback" not in err
    assert "progress line" in err  # the step's other output still shows
