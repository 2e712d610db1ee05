"""The lobes warm-up thread leaves the process's warnings state alone.

``warnings.catch_warnings`` saves and restores process-global state (before Python 3.14); entered on the
warm-up thread while the job's own thread enters and leaves its blocks, it restored stale filters and a stale
``showwarning`` and a later run in the same process lost its warnings (a CI run missed the one warning line of
a setup of another geometry).  The guard: in a fresh interpreter, as a user's ``bayes-rcsa lobes`` runs with
the warm-up of both the kernels and the figure, no ``catch_warnings`` block is entered on the warm-up thread,
both with the kernels' machine code in numba's cache and without it (a fresh checkout: compiling enters such
blocks hundreds of times, and a CI run on a clean checkout lost a warning line and an error line that way).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parent.parent / "bayes_rcsa" / "data" / "example"

_PROBE = textwrap.dedent("""
    import json, sys, threading, warnings
    entered = []
    _enter = warnings.catch_warnings.__enter__

    def enter(self):
        entered.append(threading.current_thread().name)
        return _enter(self)

    warnings.catch_warnings.__enter__ = enter
    from bayes_rcsa.stability import warmup
    started = []
    _start = warmup.start

    def start(**kw):
        started.append(dict(kw, loaded_before=sorted(m for m in ("matplotlib", "numba") if m in sys.modules)))
        return _start(**kw)

    warmup.start = start
    from bayes_rcsa.cli.main import main
    rc = main(sys.argv[1:])
    for t in threading.enumerate():
        if t.name == "bayes_rcsa-warmup":
            t.join(120)
    print(json.dumps({"rc": rc, "entered": entered, "started": started}))
""")


@pytest.mark.parametrize("cache", ["compiled", "empty"])
def test_the_warm_up_thread_enters_no_catch_warnings_block(cache, tmp_path):
    env = dict(os.environ)
    if cache == "empty":
        # numba looks here first: nothing compiled yet, as on a fresh installation
        (tmp_path / "numba-cache").mkdir()
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba-cache")
    argv = ["lobes", "--measured-x", str(EXAMPLE / "tip_x_30mm.csv"), "--measured-y", str(EXAMPLE / "tip_y_30mm.csv"),
            "--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95", "--milling", "down",
            "--feed", "y", "--speeds", "5000:30000:2001", "--out", str(tmp_path / "out"), "--quiet"]
    proc = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["rc"] == 0
    # the probe must have watched a warm-up of both parts in a process that had loaded neither matplotlib nor
    # numba yet (the files carry coherence: 500 realisations, so the compiled kernels are warmed too)
    assert out["started"] == [{"kernels": True, "figure": True, "loaded_before": []}], out["started"]
    # the job's own thread does enter such blocks (matplotlib, netCDF reading, the warning log): the probe works
    assert "MainThread" in out["entered"]
    assert "bayes_rcsa-warmup" not in out["entered"], out["entered"]
    if cache == "empty":
        # the job compiled the kernels itself (on its own thread) and numba stored them where it was told
        assert any(p.suffix == ".nbi" for p in (tmp_path / "numba-cache").rglob("*")), "nothing was compiled"
