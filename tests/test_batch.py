"""``bayes-rcsa batch``: a tool library on local processes and on a Dask cluster, resumable per setup.

Four tiny setups (two synthetic-bench campaigns, single-length fits of 40 steps, 20-draw predictions,
4-draw ZOA lobes on 16 speeds): the numbers are not the point, the equality with separate runs is.  Four
setups on two workers span both campaigns and both fitted lengths and keep both workers busy twice over (the
Dask run takes two of them that still span both).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.batch import load_manifest
from bayes_rcsa.batch.run import KILL_HOOK_ENV
from bayes_rcsa.cli.main import main
from bayes_rcsa.errors import SetupError
from bayes_rcsa.store import read_posterior
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

N_SETUPS = 4
MANIFEST = """\
[defaults]
method = "single"
sampler = "mcmc"
max_steps = 40
check_every = 20
walkers = 10
plots = false
[defaults.predict]
lengths = [0.030]
max_draws = 20
plots = false
[defaults.lobes]
clamping_length = 0.030
draws = 4
flutes = 4
kt = "790e6"
kr = "230e6"
immersion = 0.95
speeds = "5000:30000:16"
depth_points = 16
plots = false
"""


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """Two written campaigns and a manifest of N_SETUPS setups over them (lengths and seeds differ)."""
    root = tmp_path_factory.mktemp("library")
    setups = []
    for i in range(2):
        cfg = default_bench_config(directions=("x", "y"), clamping_lengths=(0.025, 0.040), frequency_step=16.0)
        setups.append(write_campaign(generate_campaign(cfg, np.random.default_rng(40 + i)), root / f"camp{i}"))
    text = MANIFEST
    for k in range(N_SETUPS):
        text += (f'\n[[setup]]\nname = "tool{k}"\nfile = "camp{k % 2}/setup.toml"\nseed = {k}\n'
                 f"lengths = [{0.025 if k % 4 < 2 else 0.040}]\n")
    manifest = root / "library.toml"
    manifest.write_text(text)
    return manifest


def _results(setup_dir: Path) -> dict:
    """What a setup produced: posterior draws, predicted frequencies, recommended operating point."""
    post = read_posterior(setup_dir / "identify" / "posterior.nc").posterior
    freq = json.loads((setup_dir / "predict" / "frequencies.json").read_text())
    lobes = json.loads((setup_dir / "lobes" / "lobes.json").read_text())
    return {"k_xf": post["k_xf"].values, "k_thetaM": post["k_thetaM"].values,
            "fn": [(p["clamping_length"], p["direction"], p["mode"], p["q05_hz"], p["q50_hz"], p["q95_hz"])
                   for p in freq["predictions"]],
            "lobes": (lobes["recommended"], lobes["depth_limits_m"])}


def _assert_same(a: dict, b: dict, name: str) -> None:
    # The same code path, seed and single-threaded numbers: bit-identical, not merely close.
    np.testing.assert_array_equal(a["k_xf"], b["k_xf"], err_msg=name)
    np.testing.assert_array_equal(a["k_thetaM"], b["k_thetaM"], err_msg=name)
    assert a["fn"] == b["fn"], name
    assert a["lobes"] == b["lobes"], name


@pytest.fixture(scope="module")
def separate(library, tmp_path_factory):
    """The reference: every setup's three commands typed one by one (in this process)."""
    out = tmp_path_factory.mktemp("separate")
    results = {}
    for job in load_manifest(library):
        d = out / job.name
        for step in job.steps:
            assert main(job.argv(step, d)) == 0, (job.name, step)
        assert "--no-plots" in job.argv("lobes", d) and not (d / "lobes" / "lobes.png").exists()  # plots = false
        results[job.name] = _results(d)
    return results


@pytest.fixture(scope="module")
def pool_run(library, tmp_path_factory):
    out = tmp_path_factory.mktemp("pool") / "batch"
    assert main(["batch", str(library), "--out", str(out), "--workers", "2", "--quiet"]) == 0
    return out


def test_process_pool_equals_separate_runs(library, pool_run, separate, capsys):
    for name, ref in separate.items():
        _assert_same(_results(pool_run / "setups" / name), ref, name)
    # one table across the library, the numbers of the per-setup files
    import csv

    rows = list(csv.DictReader((pool_run / "summary.csv").open()))
    assert [r["name"] for r in rows] == [f"tool{k}" for k in range(N_SETUPS)]
    assert all(r["status"] == "done" for r in rows)
    r0 = rows[0]
    s0 = json.loads((pool_run / "setups" / "tool0" / "identify" / "summary.json").read_text())
    assert float(r0["k_xf_q50"]) == s0["parameters"]["k_xf"]["q50"]
    assert r0["converged"] == "no"  # a chain of 40 steps (sampler = "mcmc" in the manifest): reported, not hidden
    preds = json.loads((pool_run / "setups" / "tool0" / "predict" / "frequencies.json").read_text())["predictions"]
    assert float(r0["fn_30mm_x_q50_hz"]) == next(p["q50_hz"] for p in preds if p["dominant"] and p["direction"] == "x")
    html = (pool_run / "summary.html").read_text()
    assert html.count("<tr class=\"done\">") == N_SETUPS and "NOT converged" in html
    # a second run finds everything finished: nothing recomputed
    stamp = {n: (pool_run / "setups" / n / "result.json").stat().st_mtime_ns for n in separate}
    capsys.readouterr()
    assert main(["batch", str(library), "--out", str(pool_run), "--workers", "2", "--json", "--quiet"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ran"] == [] and len(doc["reused"]) == N_SETUPS and doc["done"] == N_SETUPS
    assert stamp == {n: (pool_run / "setups" / n / "result.json").stat().st_mtime_ns for n in separate}


@pytest.mark.slow
def test_dask_local_cluster_equals_separate_runs(library, separate, tmp_path):
    distributed = pytest.importorskip("distributed")
    # tool0 (camp0, 25 mm) and tool3 (camp1, 40 mm) span both campaigns and both fitted lengths: the same numbers
    # through dask's workers.  Two setups, not four: a dask worker is a freshly spawned process whose first setup
    # took 16-18 s here (cold imports of scipy.stats and emcee, numba's cached code) and a second one 5-6 s more,
    # which adds nothing dask-specific; one process running setups one after another is the pool test's case (two
    # per worker) and the in-process reference's (all four)
    text = library.read_text()
    head, entries = text.split("[[setup]]", 1)[0], text.split("[[setup]]")[1:]
    two = library.parent / "two.toml"
    two.write_text(head + "".join("[[setup]]" + entries[k] for k in (0, 3)))
    out = tmp_path / "dask"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster:
        assert main(["batch", str(two), "--out", str(out), "--scheduler", cluster.scheduler_address,
                     "--quiet"]) == 0
    ran = sorted(p.name for p in (out / "setups").iterdir())
    assert ran == ["tool0", "tool3"]
    for name in ran:
        _assert_same(_results(out / "setups" / name), separate[name], name)


@pytest.mark.slow
def test_killed_worker_loses_only_its_setup_and_the_next_run_resumes_it(library, pool_run, tmp_path, monkeypatch,
                                                                          capsys):
    # Three setups of the library; tool1's worker is SIGKILLed as it starts (while tool0 runs beside it).
    text = library.read_text()
    head, entries = text.split("[[setup]]", 1)[0], text.split("[[setup]]")[1:4]
    small = library.parent / "small.toml"
    small.write_text(head + "".join("[[setup]]" + e for e in entries))
    out = tmp_path / "killed"
    monkeypatch.setenv(KILL_HOOK_ENV, "tool1:identify")
    assert main(["batch", str(small), "--out", str(out), "--workers", "2", "--json"]) == 1
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert doc["lost"] == 1 and doc["done"] == 2 and doc["failed"] == 0
    assert "tool1: lost" in cap.err
    rows = {r["name"]: r for r in json.loads((out / "summary.json").read_text())["rows"]}
    assert rows["tool1"]["status"] == "lost" and rows["tool0"]["status"] == rows["tool2"]["status"] == "done"
    stamp = {n: (out / "setups" / n / "result.json").stat().st_mtime_ns for n in ("tool0", "tool2")}
    monkeypatch.delenv(KILL_HOOK_ENV)
    assert main(["batch", str(small), "--out", str(out), "--workers", "2", "--json", "--quiet"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ran"] == ["tool1"] and sorted(doc["reused"]) == ["tool0", "tool2"]
    assert stamp == {n: (out / "setups" / n / "result.json").stat().st_mtime_ns for n in ("tool0", "tool2")}
    # the resumed setup equals the uninterrupted library run's
    _assert_same(_results(out / "setups" / "tool1"), _results(pool_run / "setups" / "tool1"), "tool1")


def test_manifest_errors_are_one_line_before_anything_runs(library, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    cases = [
        ('[[setup]]\nname = "a"\nfile = "nope.toml"\n', "nope.toml"),
        ('[[setup]]\nname = "a"\nfile = "x"\nlenghts = [0.03]\n', "did you mean 'lengths'"),
        ('[defaults.lobes]\nflute = 4\n[[setup]]\nname = "a"\nfile = "x"\n', "did you mean 'flutes'"),
        ('[[setup]]\nname = "a/b"\nfile = "x"\n', "name = 'a/b'"),
        ('[[setup]]\nname = "a"\nfile = "x"\n[[setup]]\nname = "a"\nfile = "x"\n', "duplicate name"),
        ('[setups]\n', "did you mean 'setup'"),
        # a misspelt word of identify's is refused before any setup runs, not when that setup's identify does
        ('[defaults]\nsampler = "importance-sampling"\n[[setup]]\nname = "a"\nfile = "x"\n',
         "sampler = 'importance-sampling': expected 'mcmc' or 'importance' or 'auto'"),
        ('[[setup]]\nname = "a"\nfile = "x"\nmethod = "mult"\n', "method = 'mult': expected 'multi'"),
    ]
    shutil.copy(library.parent / "camp0" / "setup.toml", tmp_path / "x")
    for text, needle in cases:
        bad.write_text(text)
        with pytest.raises(SetupError) as exc:
            load_manifest(bad)
        assert needle in str(exc.value), (needle, str(exc.value))
        assert main(["batch", str(bad), "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and needle in err
        assert not (tmp_path / "o").exists()
    # an unrelated non-empty directory is not written into
    other = tmp_path / "other"
    other.mkdir()
    (other / "mine.txt").write_text("x")
    assert main(["batch", str(library), "--out", str(other)]) == 2
    assert "holds no earlier batch run" in capsys.readouterr().err
    assert os.listdir(other) == ["mine.txt"]
