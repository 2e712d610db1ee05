"""The public API of batch (bayes_rcsa.batch -> BatchRun): the table the command writes, resuming, round trip."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.errors import SetupError
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign
from bayes_rcsa.workflows.batch_run import BatchRun, run_batch  # `bayes_rcsa.batch` is the batch machinery package
from test_batch import MANIFEST


@pytest.fixture(scope="module")
def manifest(tmp_path_factory):
    root = tmp_path_factory.mktemp("api_batch")
    cfg = default_bench_config(directions=("x", "y"), clamping_lengths=(0.025, 0.040), frequency_step=16.0)
    write_campaign(generate_campaign(cfg, np.random.default_rng(40)), root / "camp")
    text = MANIFEST + "".join(f'\n[[setup]]\nname = "tool{k}"\nfile = "camp/setup.toml"\nseed = {k}\n'
                              f"lengths = [0.025]\n" for k in range(2))
    (root / "library.toml").write_text(text)
    return root / "library.toml"


@pytest.fixture(scope="module")
def run(manifest, tmp_path_factory):
    out = tmp_path_factory.mktemp("api_batch_out") / "batch"
    return run_batch(manifest, out, workers=1)


def test_batch_returns_the_table_it_writes(run):
    assert isinstance(run, BatchRun)
    assert [r["name"] for r in run.rows] == ["tool0", "tool1"] and run.ran == ["tool0", "tool1"]
    assert run.count("done") == 2 and not run.failed
    written = json.loads((run.folder / "summary.json").read_text())
    assert json.loads(json.dumps(run.to_dict(), default=str)) == written
    assert run.summary_line() == (f"2 setup(s): 2 done (0 from an earlier run), 0 failed, 0 lost; table in "
                                  f"{run.folder / 'summary.html'}")
    assert run.summary_data() == {"done": 2, "failed": 0, "lost": 0, "ran": ["tool0", "tool1"], "reused": []}


def test_load_round_trips_and_a_second_run_resumes(run, manifest):
    back = BatchRun.load(run.folder)
    assert back.rows == json.loads(json.dumps(run.rows, default=str))
    assert back.table_title == manifest.name and back.warnings == run.warnings
    again = run_batch(manifest, run.folder, workers=1)
    assert again.reused == ["tool0", "tool1"] and again.ran == []
    assert json.loads(json.dumps([{**r, "reused": False} for r in again.rows], default=str)) == \
        json.loads(json.dumps(run.rows, default=str))


def test_notebook_view_and_refusal(run, manifest, tmp_path):
    page = run._repr_html_()
    assert "setups" in page and "2 (0 from an earlier run)" in page
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "x.txt").write_text("x")
    with pytest.raises(SetupError, match="holds no earlier batch run"):
        run_batch(manifest, tmp_path / "other")
