"""Resume after SIGKILL at every stage, refusal of a changed run, and the empty checkpoint (issue #12 items 8, 9, 13)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.errors import SetupError
from bayes_rcsa.inference.checkpoint import Checkpoint
from bayes_rcsa.store import read_posterior
from bayes_rcsa.inference.identify import identify, run_fingerprint
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.model import Material, ToolPointModel
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

from test_inference_support import bench, bench_model, contact_spec, quick_settings

REPO = Path(__file__).resolve().parent.parent
# --ess-min out of reach: every run goes to --max-steps, so runs are comparable step for step
# the chain (the default importance sampling keeps no checkpoint)
COMMON = ["--seed", "5", "--sampler", "mcmc", "--max-steps", "400", "--walkers", "14", "--ess-min", "1e12",
          "--no-plots", "--quiet", "--lengths", "0.025,0.040", "--check-every", "400", "--checkpoint-interval", "1000"]


def _run(argv):
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(REPO))
    return subprocess.Popen([sys.executable, "-m", "bayes_rcsa", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)


def _posterior(out: Path) -> dict:
    post = read_posterior(out / "posterior.nc").posterior
    return {n: np.asarray(post[n].values) for n in ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "sigma_0", "sigma_1")}


@pytest.fixture(scope="module")
def setup_and_reference(tmp_path_factory):
    """A small written campaign (8 Hz lines) and the uninterrupted run's posterior."""
    cfg = default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.040), frequency_step=8.0)
    camp = generate_campaign(cfg, np.random.default_rng(33))
    setup = write_campaign(camp, tmp_path_factory.mktemp("camp") / "bench")
    ref = tmp_path_factory.mktemp("ref") / "out"
    assert main(["identify", str(setup), "--out", str(ref), *COMMON]) == 0  # in process: the same code path
    return setup, _posterior(ref)


def _stored_steps(ck) -> int:
    try:
        return ck.read().iteration
    except Exception:  # noqa: BLE001 - a file being written may not be readable yet; poll again
        return -1


def _kill_when(proc, condition, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None and not condition():
        time.sleep(0.005)
    assert proc.poll() is None, "the run ended before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)


@pytest.mark.slow  # a process killed per stage, then the resume; the mid-run kill is in test_inference_cli.py
@pytest.mark.parametrize("stage", ["zero_steps", "output_writing"])
def test_sigkill_then_resume_gives_the_uninterrupted_posterior(setup_and_reference, tmp_path, stage):
    setup, reference = setup_and_reference
    out = tmp_path / "out"
    proc = _run(["identify", str(setup), "--out", str(out), *COMMON])
    ck = Checkpoint(out / "chain.h5")
    if stage == "zero_steps":
        # nothing is flushed before step 400 (check_every = max_steps, interval 1000 s): the file holds 0 steps
        _kill_when(proc, lambda: ck.path.exists() and ck.mirror.exists())
        assert ck.read().iteration == 0
    else:
        # the mirror is dropped once sampling is complete; then summaries and posterior.nc are written.
        # (The main file also exists without a mirror for an instant at creation, before the mirror is made:
        # wait for the stored steps too, or a loaded machine kills the run in that window.)
        _kill_when(proc, lambda: ck.path.exists() and not ck.mirror.exists() and _stored_steps(ck) == 400)
        assert ck.read().iteration == 400
    assert not (out / "summary.json").exists()
    # the resume in process: only the killed run needs a process of its own (a SIGKILL); the resume reads
    # nothing but the files it left (the reference above ran in process too), and a second interpreter's
    # start-up, about 3.5 s of CPU (mostly imports) per stage, proves nothing more
    assert main(["identify", str(setup), "--out", str(out), *COMMON, "--resume"]) == 0
    got = _posterior(out)
    for name, ref in reference.items():
        np.testing.assert_array_equal(got[name], ref, err_msg=name)


# -- library level: empty checkpoint, changed inputs ------------------------------------------------


@pytest.fixture(scope="module")
def small_problem():
    cfg, camp = bench(seed=8, frequency_step=4.0)
    return cfg, camp, build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                                    IdentificationOptions(lengths=(0.025, 0.040)))


SETTINGS = dict(n_walkers=14, max_steps=120, check_every=120, ess_min=1e12, checkpoint_interval=1000.0)


def test_resume_from_an_empty_checkpoint_equals_a_fresh_run(small_problem, tmp_path):
    _, _, prob = small_problem
    settings = quick_settings(**SETTINGS)
    (tmp_path / "a").mkdir()
    fresh = identify(prob, sampler="mcmc", seed=3, settings=settings, checkpoint_path=tmp_path / "a" / "chain.h5")
    # a checkpoint killed right after the start-up stage: meta written, no step stored
    full = Checkpoint(tmp_path / "a" / "chain.h5").read()
    empty = Checkpoint(tmp_path / "b" / "chain.h5")
    (tmp_path / "b").mkdir()
    empty.create(full.chain.shape[1], full.chain.shape[2], full.meta)
    resumed = identify(prob, sampler="mcmc", seed=3, settings=settings, checkpoint_path=empty.path, resume=True)
    np.testing.assert_array_equal(resumed.theta, fresh.theta)
    assert resumed.summary["timing"]["new_steps"] == 120


def test_resume_after_a_change_is_refused_naming_it_without_writing(small_problem, tmp_path):
    cfg, camp, prob = small_problem
    settings = quick_settings(**SETTINGS)
    path = tmp_path / "chain.h5"
    identify(prob, sampler="mcmc", seed=3, settings=quick_settings(**{**SETTINGS, "max_steps": 1}), checkpoint_path=path)
    n_walkers = settings.walkers(prob.parameters.ndim)
    fp = run_fingerprint(prob, 3, settings, n_walkers)
    assert set(fp) >= {"geometry", "materials", "spindle", "data", "band", "likelihood", "parameter_model", "seed",
                       "n_walkers"}
    spec = contact_spec(camp)
    model = bench_model(cfg, camp)
    steel = Material(190e9, 7850.0, 0.29, 0.002, "steel")
    changes = {
        "the materials": build_problem(ToolPointModel(replace(cfg.holder, material=steel), {"tool": cfg.tool},
                                                      camp.spindle), camp.measurements, spec, prob.options),
        "the spindle data": build_problem(ToolPointModel(cfg.holder, {"tool": cfg.tool},
                                                         {"x": replace(camp.spindle["x"],
                                                                       block=camp.spindle["x"].block * 1.01)}),
                                          camp.measurements, spec, prob.options),
        "the [likelihood] options": build_problem(model, camp.measurements, spec,
                                                  replace(prob.options, noise_floor=0.02)),
        "the priors, fixed values or [model] terms": build_problem(model, camp.measurements,
                                                                   replace(spec, translational_damping=12.0), prob.options),
        "the likelihood band": build_problem(model, camp.measurements, spec, replace(prob.options, band_ratio=1.3)),
    }
    # the finished run left only chain.h5: a resume that went on would restore chain.mirror.h5 from it
    ck = Checkpoint(path)
    before = sorted(p.name for p in tmp_path.iterdir())
    for what, changed in changes.items():
        with pytest.raises(SetupError, match=r"different run: .*" + what.replace("[", r"\[").replace("]", r"\]")) as exc:
            identify(changed, sampler="mcmc", seed=3, settings=settings, checkpoint_path=path, resume=True)
        assert "\n" not in str(exc.value)
        assert sorted(p.name for p in tmp_path.iterdir()) == before  # no chain.mirror.h5 written by a refusal
    assert not ck.mirror.exists()
    with pytest.raises(SetupError, match="--seed"):
        identify(prob, sampler="mcmc", seed=4, settings=settings, checkpoint_path=path, resume=True)
