"""``bayes-rcsa identify``: outputs, crash/resume, and clear errors (exit 2) for bad input."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.inference.checkpoint import Checkpoint
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    """A small written campaign: 2 lengths, x only, 8 Hz lines (cheap runs)."""
    cfg = default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.030, 0.040), frequency_step=8.0)
    camp = generate_campaign(cfg, np.random.default_rng(21))
    return write_campaign(camp, tmp_path_factory.mktemp("campaign") / "bench").parent


def _copy(campaign_dir: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "bench"
    shutil.copytree(campaign_dir, dst)
    return dst


FAST = ["--lengths", "0.025,0.040", "--quiet", "--check-every", "100"]


def test_identify_writes_outputs(campaign_dir, tmp_path):
    out = tmp_path / "out"
    rc = main(["identify", str(campaign_dir / "setup.toml"), "--out", str(out), "--seed", "4", *FAST])
    assert rc == 0
    # the default: importance sampling, accepted here, so no chain (no trace.png, no checkpoint; the chain's files
    # are checked in test_api_identify.py and test_checkpoint_resume.py)
    assert sorted(p.name for p in out.iterdir()) == ["corner.png", "frf.png", "posterior.nc", "summary.json"]
    for name in ("summary.json", "posterior.nc", "corner.png", "frf.png"):
        assert (out / name).stat().st_size > 0, name
    s = json.loads((out / "summary.json").read_text())
    assert s["method"] == "multi" and s["converged"] is True
    assert s["sampler"]["mode"] == "importance" and s["sampler"]["requested"] == "auto"
    assert s["sampler"]["pareto_k"] <= 0.7 and s["sampler"]["ess"] >= 1000
    # the chain's fields are there, null (the keys are stable whichever sampler ran)
    for key in ("tau", "n_steps", "burn_in", "thin", "acceptance_fraction"):
        assert s[key] is None, key
    assert s["warnings"] == [] and s["timing"]["importance_time_s"] > 0
    for name, p in s["parameters"].items():
        assert set(p) >= {"mean", "sd", "q05", "q50", "q95", "rhat", "ess_bulk"}, name
        assert p["rhat"] is None and p["ess_bulk"] == s["sampler"]["ess"]
        assert p["q05"] <= p["q50"] <= p["q95"]
    lengths = [e["clamping_length"] for e in s["stiffness"]]
    assert lengths == pytest.approx([0.025, 0.030, 0.040])  # every measured length, fitted or not
    nf = s["natural_frequencies"]
    assert {(e["clamping_length"], e["direction"], e["mode"]) for e in nf} == {(0.025, "x", 1), (0.03, "x", 1), (0.04, "x", 1)}
    for e in nf:
        assert e["q05_hz"] <= e["q50_hz"] <= e["q95_hz"]
        assert abs(e["q50_hz"] - e["measured_hz"]) / e["measured_hz"] < 0.01

    from bayes_rcsa.store import SCHEMA_ATTRIBUTE, SCHEMA_VERSION, posterior_attributes, read_posterior

    idata = read_posterior(out / "posterior.nc")
    for group in ("posterior", "sample_stats", "log_likelihood", "observed_data", "constant_data"):
        assert group in idata.groups(), group
    n_lines = sum(m["n_lines"] for m in s["measurements_used"])
    assert idata.log_likelihood["frf"].shape[-1] == n_lines
    assert idata.observed_data["frf_real"].shape == (n_lines,)
    assert np.allclose(idata.constant_data["fit_clamping_length"].values, [0.025, 0.040])
    assert idata.posterior["k_xf"].shape[:2] == idata.sample_stats["lp"].shape
    draws = idata.posterior["k_xf"].values.ravel()
    assert np.quantile(draws, 0.05) == pytest.approx(s["parameters"]["k_xf"]["q05"], rel=1e-9)

    # compressed (issue #14): every numeric variable zlib + shuffle; the pointwise log-likelihood in float32
    import h5py

    with h5py.File(out / "posterior.nc", "r") as f:
        for path in ("posterior/k_xf", "sample_stats/lp", "log_likelihood/frf", "observed_data/frf_real"):
            assert f[path].compression == "gzip" and f[path].shuffle, path
        assert f["log_likelihood/frf"].dtype == np.float32 and f["posterior/k_xf"].dtype == np.float64
        ll = f["log_likelihood/frf"]
        assert ll.id.get_storage_size() < 0.8 * ll.size * 4  # compressed below its float32 size
    assert idata.log_likelihood.attrs["stored_dtype"] == "float32"
    assert idata.attrs["method"] == "multi" and posterior_attributes(idata)["method"] == "multi"  # attributes kept
    assert idata.attrs[SCHEMA_ATTRIBUTE] == SCHEMA_VERSION  # written through bayes_rcsa.store.write_posterior


def test_deterministic_cli(campaign_dir, tmp_path):
    out = tmp_path / "det"
    rc = main(["identify", str(campaign_dir / "setup.toml"), "--out", str(out), "--method", "deterministic",
               "--lengths", "0.025", "--quiet", "--no-plots"])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["method"] == "deterministic"
    assert set(s["parameters"]) == {"k_xf", "k_thetaM"}
    assert not (out / "posterior.nc").exists()
    own = next(e for e in s["natural_frequencies"] if e["clamping_length"] == 0.025)
    assert abs(own["error_q50_percent"]) < 0.5


def _run(args, **kw):
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen([sys.executable, "-m", "bayes_rcsa.cli.main", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


@pytest.mark.slow
def test_sigkill_then_resume_loses_no_step(campaign_dir, tmp_path):
    setup = str(campaign_dir / "setup.toml")
    # --ess-min out of reach: the run goes to --max-steps, so the kill lands mid-run
    # (the tail check is tested elsewhere and adds nothing to resuming a chain)
    common = ["--seed", "9", "--sampler", "mcmc", "--max-steps", "800", "--walkers", "16", "--ess-min", "1e12", "--no-plots",
              "--checkpoint-interval", "0.1", "--no-tail-check", *FAST]
    out = tmp_path / "killed"
    proc = _run(["identify", setup, "--out", str(out), *common])
    ck = Checkpoint(out / "chain.h5")
    deadline = time.monotonic() + 240
    n_seen = 0
    while time.monotonic() < deadline and proc.poll() is None:
        st = Checkpoint._read(ck.path) if ck.path.exists() else None
        n_seen = st.iteration if st is not None else 0
        if n_seen >= 200:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    before = ck.open()  # the most complete readable copy
    assert 200 <= before.iteration < 800
    assert not (out / "summary.json").exists()  # no partial results

    # the resume and the reference in process: only the killed run needs a process of its own (a SIGKILL); the
    # resume reads nothing but the files it left (test_checkpoint_resume.py does the same), and each further
    # interpreter's start-up, about 3 s of CPU (mostly imports), proves nothing more
    assert main(["identify", setup, "--out", str(out), *common, "--resume"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["n_steps"] == 800 and s["converged"] is False
    after = Checkpoint._read(out / "chain.h5")
    np.testing.assert_array_equal(after.chain[: before.iteration], before.chain)
    np.testing.assert_array_equal(after.log_prob[: before.iteration], before.log_prob)

    # bit-for-bit the chain an uninterrupted run produces
    ref = tmp_path / "reference"
    assert main(["identify", setup, "--out", str(ref), *common]) == 0
    np.testing.assert_array_equal(Checkpoint._read(ref / "chain.h5").chain, after.chain)


def test_resume_without_checkpoint_is_an_error(campaign_dir, tmp_path, capsys):
    rc = main(["identify", str(campaign_dir / "setup.toml"), "--out", str(tmp_path / "none"), "--resume", *FAST])
    assert rc == 2
    assert "no checkpoint" in capsys.readouterr().err


# -- bad input: one clear line on stderr, exit status 2 ---------------------------------


def test_walker_start_outside_prior(campaign_dir, tmp_path, capsys):
    d = _copy(campaign_dir, tmp_path)
    with open(d / "setup.toml", "a", encoding="utf-8") as fh:
        fh.write("\n[sampler]\nstart = { k_xf = 1e12 }\n")
    rc = main(["identify", str(d / "setup.toml"), "--out", str(tmp_path / "o"), *FAST])
    err = capsys.readouterr().err
    assert rc == 2
    assert "walker start" in err and "k_xf = 1e+12" in err and "outside its prior" in err
    assert len(err.strip().splitlines()) == 1


def test_empty_band(campaign_dir, tmp_path, capsys):
    rc = main(["identify", str(campaign_dir / "setup.toml"), "--out", str(tmp_path / "o"), "--band", "9000,9500", *FAST])
    err = capsys.readouterr().err
    assert rc == 2
    assert "9000-9500 Hz contains no frequency line" in err


def test_all_nan_file(campaign_dir, tmp_path, capsys):
    d = _copy(campaign_dir, tmp_path)
    f = d / "tip_x_25mm.csv"
    lines = f.read_text().splitlines()
    body = [ln for ln in lines if ln and not ln.startswith("#")]
    header, rows = body[0], body[1:]
    cols = [c.strip().lower() for c in header.split(",")]
    nan_rows = []
    for row in rows:
        vals = row.split(",")
        nan_rows.append(",".join(v if cols[i] == "frequency_hz" else "nan" for i, v in enumerate(vals)))
    f.write_text("\n".join([header, *nan_rows]) + "\n")
    rc = main(["identify", str(d / "setup.toml"), "--out", str(tmp_path / "o"), *FAST])
    err = capsys.readouterr().err
    assert rc == 2
    assert "tip_x_25mm.csv" in err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_clamping_length_outside_feasible_range(campaign_dir, tmp_path, capsys):
    rc = main(["identify", str(campaign_dir / "setup.toml"), "--out", str(tmp_path / "o"), "--lengths", "0.020", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "20 mm lies outside the feasible clamping range [25, 40] mm" in err
    # a measurement outside the range written in the setup itself
    d = _copy(campaign_dir, tmp_path)
    text = (d / "setup.toml").read_text().replace("clamping_range = [0.025, 0.04]", "clamping_range = [0.028, 0.04]")
    (d / "setup.toml").write_text(text)
    rc = main(["identify", str(d / "setup.toml"), "--out", str(tmp_path / "o2"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and "clamping_range" in err
