"""The command line answers at once (issue #44): ``--help`` of every command and the one-line errors for a
missing or malformed input file import none of the heavy libraries (numba, scipy, matplotlib, arviz, h5py).

Asserted as the set of imported modules in a fresh interpreter, not as a time (times depend on the machine's
load; the import set is what makes them).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bayes_rcsa.cli.main import COMMANDS

ROOT = Path(__file__).resolve().parent.parent
HEAVY = ("numba", "scipy", "matplotlib", "arviz", "h5py")

_PROBE = """
import contextlib, io, json, sys
from bayes_rcsa.cli.main import main
err = io.StringIO()
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
    try:
        status = main(json.loads(sys.argv[1]))
    except SystemExit as exc:
        status = exc.code
heavy = set(json.loads(sys.argv[2]))
print(json.dumps({"status": status, "heavy": sorted({m.split('.')[0] for m in sys.modules} & heavy),
                  "stderr": err.getvalue()}))
"""

# The same probe for many argument lists: one fresh interpreter imports the command line's entry module (what
# every probe's interpreter does first) and forks a child per argument list, so each probe still starts from
# a fresh interpreter's module set without paying interpreter and numpy start-up again (~0.3 s each, 23 probes).
# The server refuses to start if its own module set already holds a heavy library, so a fork cannot hide one.
_FORK_SERVER = """
import contextlib, io, json, os, sys
from bayes_rcsa.cli.main import main
heavy = set(json.loads(sys.argv[1]))
loaded = sorted({m.split('.')[0] for m in sys.modules} & heavy)
print(json.dumps({"ready": True, "heavy": loaded}), flush=True)
for line in sys.stdin:
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read_end)
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            try:
                status = main(json.loads(line))
            except SystemExit as exc:
                status = exc.code
        result = {"status": status, "heavy": sorted({m.split('.')[0] for m in sys.modules} & heavy),
                  "stderr": err.getvalue()}
        with os.fdopen(write_end, "w") as fh:
            fh.write(json.dumps(result))
        os._exit(0)
    os.close(write_end)
    with os.fdopen(read_end) as fh:
        reply = fh.read()
    os.waitpid(pid, 0)
    print(reply, flush=True)
"""


@pytest.fixture(scope="module")
def probe():
    """``probe(argv) -> {"status", "heavy", "stderr"}`` for ``bayes-rcsa argv`` in a fresh interpreter's state."""
    server = subprocess.Popen([sys.executable, "-c", _FORK_SERVER, json.dumps(HEAVY)], cwd=ROOT, text=True,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    ready = json.loads(server.stdout.readline() or "{}")
    if not ready.get("ready"):
        server.kill()
        pytest.fail(f"probe server did not start: {server.stderr.read()}")
    assert ready["heavy"] == [], ready

    def run(argv: list[str]) -> dict:
        server.stdin.write(json.dumps(argv) + "\n")
        server.stdin.flush()
        line = server.stdout.readline()
        assert line, server.stderr.read()
        return json.loads(line)

    yield run
    server.stdin.close()
    server.wait(timeout=60)


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_help_imports_no_heavy_library(command, probe):
    out = probe(["--help"] if command is None else [command, "--help"])
    assert out["status"] == 0
    assert out["heavy"] == []


def _bad_inputs(tmp: Path) -> list[tuple[list[str], str]]:
    bad_toml = tmp / "bad.toml"
    bad_toml.write_text("[tool\nname = 'x'\n")
    bad_csv = tmp / "bad.csv"
    bad_csv.write_text("frequency_hz,real,imag\n100,1e-7\n")
    missing = str(tmp / "missing.toml")
    cut = ["--kt", "790e6", "--kr", "230e6", "--flutes", "4", "--immersion", "0.5", "--speeds", "5000:20000:50"]
    out = str(tmp / "out")
    return [
        (["identify", missing, "--out", out], "setup file not found"),
        (["identify", str(bad_toml), "--out", out], "malformed TOML"),
        (["predict", missing, "--posterior", str(tmp / "posterior.nc"), "--out", out], "no such file"),
        (["lobes", missing, "--posterior", str(tmp / "posterior.nc"), "--clamping-length", "0.03", *cut,
          "--out", out], "no such file"),
        (["lobes", "--measured-x", str(tmp / "missing.csv"), "--measured-y", str(tmp / "missing.csv"), *cut,
          "--out", out], "FRF file not found"),
        (["lobes", "--measured-x", str(bad_csv), "--measured-y", str(bad_csv), *cut, "--out", out], "bad.csv"),
    ]


@pytest.mark.parametrize("case", range(6))
def test_bad_input_errors_import_no_heavy_library(case, tmp_path, probe):
    argv, needle = _bad_inputs(tmp_path)[case]
    out = probe(argv)
    lines = out["stderr"].strip().splitlines()
    assert out["status"] == 2 and len(lines) == 1 and "error:" in lines[0] and needle in lines[0], out["stderr"]
    assert out["heavy"] == []


def test_an_importance_sampled_identify_imports_neither_arviz_nor_scipy_stats_nor_matplotlib(tmp_path):
    # issue #42's cold-process target (the bundled example's two-length identification in <= 5 s): ArviZ,
    # scipy.stats, matplotlib, xarray, pandas and dask.array are ~4 s of imports together, more than the
    # identification itself.  An accepted importance-sampled run without plots needs none of them (PSIS is the
    # package's own; posterior.nc is written with h5netcdf).  The written file is still ArviZ's InferenceData.
    from bayes_rcsa.data import example_dir

    argv = ["identify", str(example_dir() / "setup.toml"), "--lengths", "0.025,0.040", "--no-plots",
            "--out", str(tmp_path / "out")]
    proc = subprocess.run([sys.executable, "-c", _PROBE.replace("m.split('.')[0] for m", "m for m"), json.dumps(argv),
                           json.dumps(["arviz", "scipy.stats", "matplotlib", "matplotlib.pyplot", "xarray", "pandas",
                                       "dask.array"])],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["status"] == 0 and out["heavy"] == [], out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["sampler"]["mode"] == "importance"
    import arviz

    idata = arviz.from_netcdf(str(tmp_path / "out" / "posterior.nc"))
    assert {"posterior", "log_likelihood", "sample_stats", "observed_data", "constant_data"} <= set(idata.groups())


_THREADS_PROBE = """
import json, os, sys
import bayes_rcsa.cli.main
import numpy
from bayes_rcsa.threads import THREAD_VARIABLES
print(json.dumps({k: os.environ.get(k) for k in THREAD_VARIABLES}))
"""


def test_the_command_line_runs_one_blas_thread_unless_the_user_sets_another_number():
    """The command line caps numpy's BLAS at one thread before numpy loads (bayes_rcsa.threads: small batched
    problems, where a second thread cost the discrepancy fit's SVD 150x on a busy machine); a user's own setting
    is kept."""
    from bayes_rcsa.threads import THREAD_VARIABLES

    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    proc = subprocess.run([sys.executable, "-c", _THREADS_PROBE], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == {k: "1" for k in THREAD_VARIABLES}
    env["OPENBLAS_NUM_THREADS"] = "2"
    proc = subprocess.run([sys.executable, "-c", _THREADS_PROBE], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=120)
    assert json.loads(proc.stdout)["OPENBLAS_NUM_THREADS"] == "2"
