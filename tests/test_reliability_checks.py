"""The dangerous inputs: refused or flagged with their likely cause, and no false alarm on clean data.

Issue "Reliability" items 1 (non-passive FRFs), 2 (non-reciprocal spindle
blocks), 5 (one measurement at two lengths, mislabelled lengths), 6 (mm/N,
flipped sign) and 10 (two runs into one output directory).  Clean data are
the bundled example and ten seeds of the synthetic bench (readers only).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.errors import DataError, DataWarning
from bayes_rcsa.io import load_setup, read_frf, read_spindle_csv, write_frf_csv, write_spindle_csv
from bayes_rcsa.io import checks
from bayes_rcsa.io.atomic import begin_directory, clean_stale_temporaries, directory_lock
from bayes_rcsa.model import FRF, PointReceptance
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "bayes_rcsa" / "data" / "example"


@pytest.fixture(scope="module")
def example_setup():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no false alarm on the bundled example
        return load_setup(EXAMPLE / "setup.toml")


# --------------------------------------------------------------------------- no false alarms


def test_bundled_example_passes_every_check_without_warning(example_setup):
    for m in example_setup.measurements:
        assert checks.passivity_problem(m.frf.values) is None, m.file
    for d, rec in example_setup.spindle.items():
        assert checks.reciprocity_error(rec.block) < 1e-10, d
    entries = [(m.file.name, m.clamping_length, m.direction, m.tool, m.frf.frequency_hz, m.frf.values)
               for m in example_setup.measurements]
    assert checks.check_campaign(entries) == []


def test_band_without_resonance_is_not_mistaken_for_swapped_columns():
    """A mass line only (above the resonance): Re h < 0 everywhere and little damping - still passive."""
    f = np.linspace(2000, 4000, 201)
    w, wn, zeta = 2 * np.pi * f, 2 * np.pi * 800.0, 0.02
    h = 1 / (1e4 * (wn ** 2 - w ** 2 + 2j * zeta * wn * w))
    assert h.imag.max() < 0 and h.real.max() < 0
    assert checks.passivity_problem(h) is None
    g = 1 / (1e4 * (wn ** 2 - (w / 10) ** 2 + 2j * zeta * wn * w / 10))  # quasi-static: Re h > 0 everywhere
    assert checks.passivity_problem(g) is None


@pytest.mark.parametrize("seed", range(10))
def test_clean_synthetic_campaigns_load_without_warnings(seed, tmp_path):
    # A coarser grid than the default (6 Hz lines instead of 2) keeps the FE bench fast; the
    # checks see the same noise model and peaks.
    cfg = default_bench_config(frequency_step=6.0)
    campaign = generate_campaign(cfg, np.random.default_rng(seed))
    path = write_campaign(campaign, tmp_path / "c")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        setup = load_setup(path)
    assert len(setup.measurements) == len(campaign.measurements)


@pytest.mark.parametrize("effect", ["contact_damping", "tip_mass", "fluted_section", "extra_mode",
                                    "nonlinear_stiffness_law", "spindle_error", "spindle_rotation_omitted"])
def test_campaigns_with_hidden_effects_are_not_flagged(effect, tmp_path):
    """Model discrepancies are not data errors: the checks must leave them to the discrepancy workflow."""
    cfg = default_bench_config(frequency_step=8.0, hidden_effects={effect: True})
    path = write_campaign(generate_campaign(cfg, np.random.default_rng(1)), tmp_path / "c")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_setup(path)


# --------------------------------------------------------------------------- item 1: passivity


def _example_frf(name="tip_x_30mm.csv") -> FRF:
    return read_frf(EXAMPLE / name)


def test_noise_violations_far_from_resonance_are_accepted():
    frf = _example_frf()
    v = frf.values.copy()
    # Far from the peak (smallest 30 % of |H|) push Im h above zero by more than the noise already does.
    small = np.abs(v) < np.quantile(np.abs(v), 0.3)
    v[small] = v[small].real + 0.5j * np.abs(v[small])
    assert checks.passivity_problem(v) is None


@pytest.mark.parametrize("edit, cause", [
    (lambda v: v.conj(), "wrong sign"),                 # e^{-iωt} convention
    (lambda v: -v.imag + 1j * v.real, "swapped and the imaginary part has the wrong sign"),  # e^{-iωt}, then swapped
    (lambda v: v.imag + 1j * v.real, "swapped"),       # swapped columns
])
def test_clearly_non_passive_files_are_refused_with_cause(tmp_path, edit, cause):
    frf = _example_frf()
    path = tmp_path / "bad.csv"
    write_frf_csv(path, FRF(frf.frequency_hz, edit(frf.values)))
    with pytest.raises(DataError, match=cause) as exc:
        read_frf(path)
    assert str(path) in str(exc.value)
    # A transfer FRF (artifact h12/h21) may have either sign: not checked.
    read_frf(path, point=False)


def test_spindle_direct_terms_are_checked(tmp_path, example_setup):
    rec = example_setup.spindle["x"]
    for i, name in ((0, "h (h_real"), (1, "p (p_real")):
        b = rec.block.copy()
        b[:, i, i] = b[:, i, i].conj()
        path = tmp_path / f"s{i}.csv"
        write_spindle_csv(path, PointReceptance(rec.frequency_hz, b))
        with pytest.raises(DataError, match=r"not a passive point receptance") as exc:
            read_spindle_csv(path)
        assert name in str(exc.value) and str(path) in str(exc.value)


# --------------------------------------------------------------------------- item 2: reciprocity


def test_reciprocity_warns_then_refuses(tmp_path, example_setup):
    rec = example_setup.spindle["x"]
    ok = tmp_path / "ok.csv"
    write_spindle_csv(ok, rec)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_spindle_csv(ok)
    # 25 % apart: within what a noisy inverse-RCSA block could show -> a warning.
    b = rec.block.copy()
    b[:, 1, 0] *= 1.25
    write_spindle_csv(tmp_path / "warn.csv", PointReceptance(rec.frequency_hz, b))
    with pytest.warns(DataWarning, match=r"cross terms differ by 22 %"):
        read_spindle_csv(tmp_path / "warn.csv")
    # n = 2 l: no noise does that -> refused.
    b[:, 1, 0] = 2 * rec.block[:, 0, 1]
    write_spindle_csv(tmp_path / "bad.csv", PointReceptance(rec.frequency_hz, b))
    with pytest.raises(DataError, match=r"bad.csv: l and n: not reciprocal: \|\|l - n\|\| is 67 %"):
        read_spindle_csv(tmp_path / "bad.csv")


def test_reciprocity_error_reference_values():
    l = np.array([1.0 + 1j, 2.0 - 1j])
    block = np.zeros((2, 2, 2), complex)
    block[:, 0, 1] = l
    block[:, 1, 0] = l
    assert checks.reciprocity_error(block) == 0.0
    block[:, 1, 0] = 3 * l  # ||l - 3l|| / ||2l|| = 1
    assert checks.reciprocity_error(block) == pytest.approx(1.0)
    block[:, 1, 0] = -l
    assert checks.reciprocity_error(block) == np.inf


# --------------------------------------------------------------------------- item 5: campaign consistency


def _copy_example(tmp_path) -> Path:
    d = tmp_path / "ex"
    shutil.copytree(EXAMPLE, d)
    return d


def test_swapped_clamping_lengths_warn(tmp_path):
    d = _copy_example(tmp_path)
    p = d / "setup.toml"
    text = p.read_text()
    # Label the 25 mm and 40 mm x-files the wrong way round.
    text = text.replace('file = "tip_x_25mm.csv"', 'file = "@@"').replace('file = "tip_x_40mm.csv"', 'file = "tip_x_25mm.csv"')
    p.write_text(text.replace('file = "@@"', 'file = "tip_x_40mm.csv"'))
    with pytest.warns(DataWarning) as record:
        load_setup(p)
    messages = [str(w.message) for w in record]
    assert len(messages) == 1, messages  # one warning per direction and tool, naming every fall
    assert messages[0].startswith("direction x, tool tool: the dominant natural frequency falls from 1202.0 Hz "
                                  "(tip_x_40mm.csv, 25 mm) to 962.0 Hz (tip_x_30mm.csv, 30 mm); from 1076.0 Hz "
                                  "(tip_x_35mm.csv, 35 mm) to 860.0 Hz (tip_x_25mm.csv, 40 mm)"), messages
    assert "swapped or mislabelled" in messages[0]


def test_cli_prints_a_warning_as_one_line(tmp_path, capsys):
    from bayes_rcsa.cli.main import main

    d = _copy_example(tmp_path)
    rec = read_spindle_csv(d / "spindle_x.csv")
    b = rec.block.copy()
    b[:, 1, 0] *= 1.25
    write_spindle_csv(d / "spindle_x.csv", PointReceptance(rec.frequency_hz, b))
    rc = main(["simulate", str(d / "setup.toml"), "--clamping-length", "0.03", "--kx", "1e7", "--ktheta", "1e5",
               "--freq", "600,800,50", "--out", str(tmp_path / "h.csv")])
    err = capsys.readouterr().err
    assert rc == 0
    # the warning is one line, followed by the command's one closing summary line
    lines = err.splitlines()
    assert len(lines) == 2 and lines[0].startswith("bayes-rcsa simulate: warning: ") and "spindle_x.csv" in lines[0], err
    assert lines[1].startswith("bayes-rcsa simulate: wrote "), err


def test_identical_data_refused_or_flagged():
    f = np.linspace(100, 200, 11)
    v = (1 - 1j) * 1e-7 * np.ones(11)
    with pytest.raises(DataError, match="listed at two clamping lengths"):
        checks.check_campaign([("a.csv", 0.025, "x", "t", f, v), ("b.csv", 0.030, "x", "t", f, v)])
    with pytest.raises(DataError, match="listed twice"):
        checks.check_campaign([("a.csv", 0.025, "x", "t", f, v), ("a.csv", 0.025, "x", "t", f, v)])
    # The x file reused for y (a deliberate symmetry assumption?) is flagged, not refused.
    out = checks.check_campaign([("a.csv", 0.025, "x", "t", f, v), ("a.csv", 0.025, "y", "t", f, v)])
    assert len(out) == 1 and "same data" in out[0]


# --------------------------------------------------------------------------- item 6: units and sign


def test_likely_cause_names_units_and_sign(example_setup):
    m = example_setup.measurements[1]
    model = example_setup.model()
    c = example_setup.contact
    f = m.frf.frequency_hz
    h = model.frf(m.configuration, f, np.array([1e6, 1e8]), np.array([1e4, 1e6]), 10.0, 5e-4)
    assert checks.likely_cause(m.frf.values, h) is None
    assert "mm/N instead of m/N" in checks.likely_cause(1e3 * m.frf.values, h)
    assert "µm/N instead of m/N" in checks.likely_cause(1e6 * m.frf.values, h)
    assert "wrong units" in checks.likely_cause(1e-3 * m.frf.values, h)
    assert "wrong sign" in checks.likely_cause(m.frf.values.conj(), h)
    assert c.translational_stiffness[0] < 1e6  # the sets above lie inside the example's prior


def test_mm_per_newton_file_is_refused_at_load(tmp_path):
    d = _copy_example(tmp_path)
    frf = read_frf(d / "tip_y_35mm.csv")
    write_frf_csv(d / "tip_y_35mm.csv", FRF(frf.frequency_hz, 1e3 * frf.values, frf.coherence))
    with pytest.raises(DataError, match=r"tip_y_35mm.csv.*about 1\.\d+e\+03 x the largest.*mm/N instead of m/N"):
        load_setup(d / "setup.toml")
    load_setup(d / "setup.toml", load_data=False)  # the setup itself is fine


def test_absurd_magnitudes_are_refused(tmp_path):
    path = tmp_path / "big.csv"
    path.write_text("frequency_hz,real,imag\n100,1e-7,-1e-7\n200,1e300,-1e-7\n")
    with pytest.raises(DataError, match=r"big.csv: \|receptance\| = 1e\+300 at 200 Hz is implausible"):
        read_frf(path)
    path.write_text("frequency_hz,real,imag\n100,1e-7,-1e-7\n1e300,1e-7,-1e-7\n")
    with pytest.raises(DataError, match=r"frequency 1e\+300 Hz is implausible"):
        read_frf(path)


# --------------------------------------------------------------------------- item 10: lock; item 13: stale temporaries


def test_directory_lock_is_exclusive_and_released(tmp_path):
    out = tmp_path / "out"
    with directory_lock(out):
        lock = tmp_path / ".out.lock"
        assert lock.read_text().strip() == str(os.getpid())
        # A second holder (another open file description, as another process has) is refused at once.
        code = ("import sys; from bayes_rcsa.io.atomic import directory_lock\n"
                "try:\n    directory_lock(sys.argv[1]).__enter__()\nexcept Exception as e:\n    print(e)")
        msg = subprocess.run([sys.executable, "-c", code, str(out)], capture_output=True, text=True, timeout=60).stdout
        assert f"{out} is in use by PID {os.getpid()}" in msg
    assert not (tmp_path / ".out.lock").exists()
    with directory_lock(out):  # free again
        pass


def test_stale_temporary_directories_of_dead_runs_are_removed(tmp_path):
    out = tmp_path / "synK"
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = int(proc.stdout)
    stale = tmp_path / f".synK.{dead}.abc123.tmp"
    stale.mkdir()
    (stale / "half.csv").write_text("x")
    alive = tmp_path / f".synK.{os.getpid()}.def456.tmp"  # a concurrent run's work in progress
    alive.mkdir()
    other = tmp_path / f".synKK.{dead}.x.tmp"  # another output's temporary
    other.mkdir()
    _, tmp = begin_directory(out)
    assert not stale.exists() and alive.is_dir() and other.is_dir() and tmp.is_dir()
    assert clean_stale_temporaries(out) == []


def test_synthesize_after_sigkill_cleans_its_temporary(tmp_path):
    """A killed synthesize leaves .NAME.PID.*.tmp; the next run removes it and succeeds."""
    out = tmp_path / "synK"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    cfg = tmp_path / "bench.toml"
    cfg.write_text('[campaign]\nclamping_lengths = [0.025, 0.040]\ndirections = ["x"]\n'
                   "[frequency]\nstep = 16.0\n")
    proc = subprocess.Popen([sys.executable, "-m", "bayes_rcsa", "synthesize", str(cfg), "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".synK.*.tmp")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.kill()
    proc.wait()
    left = list(tmp_path.glob(".synK.*.tmp"))
    if not left:  # the run finished before it could be killed: simulate what a kill leaves behind
        shutil.rmtree(out, ignore_errors=True)
        (tmp_path / f".synK.{proc.pid}.zz.tmp").mkdir()
    # the next run in this process (the kill needs a process of its own, the clean-up does not; a fresh
    # interpreter's imports cost ~2 s)
    from bayes_rcsa.cli.main import main

    assert main(["synthesize", str(cfg), "--out", str(out)]) == 0
    assert (out / "setup.toml").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.toml", "synK"]


def test_two_identify_runs_on_one_out(tmp_path):
    """Exactly one of two concurrent runs proceeds; the other exits 2 at once; the result equals a solo run."""
    cfg = default_bench_config(directions=("x",), clamping_lengths=(0.025, 0.040), frequency_step=16.0)
    setup = write_campaign(generate_campaign(cfg, np.random.default_rng(3)), tmp_path / "bench")
    env = dict(os.environ, OMP_NUM_THREADS="1")
    # The cheapest Bayesian run (one length, two parameters, 60 steps): the lock, not the posterior, is tested.
    argv = [sys.executable, "-m", "bayes_rcsa", "identify", str(setup), "--method", "single", "--lengths", "0.025",
            "--max-steps", "60", "--check-every", "30", "--walkers", "16", "--no-plots", "--quiet", "--seed", "5",
            "--no-tail-check"]
    out = tmp_path / "out"
    # Both start together and race for the lock after the same validation: the loser meets a held lock.
    t0 = time.monotonic()
    procs = [subprocess.Popen(argv + ["--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env) for _ in range(2)]
    ended = {}
    while len(ended) < 2 and time.monotonic() - t0 < 300:
        for i, p in enumerate(procs):
            if i not in ended and p.poll() is not None:
                ended[i] = time.monotonic() - t0
        time.sleep(0.02)
    results = [(p.returncode, *p.communicate(timeout=60)) for p in procs]
    codes = sorted(r[0] for r in results)
    assert codes == [0, 2], results
    winner, loser = (0, 1) if results[0][0] == 0 else (1, 0)
    assert results[loser][2].strip() == (
        f"bayes-rcsa identify: error: --out {out} is in use by PID {procs[winner].pid} "
        "(another bayes-rcsa run writes there; wait for it or choose another directory)")
    assert results[loser][1] == ""
    # "At once": the loser does not wait for the lock; it ends well before the winner.
    assert ended[loser] < ended[winner]
    lock = tmp_path / ".out.lock"
    # the solo run in this process: the same command line and code path (the batch tests find in-process runs
    # bit-identical to worker processes'), without a third interpreter's start-up and imports
    from bayes_rcsa.cli.main import main

    solo = tmp_path / "solo"
    assert main(argv[3:] + ["--out", str(solo)]) == 0
    a = json.loads((out / "summary.json").read_text())
    b = json.loads((solo / "summary.json").read_text())
    assert a["parameters"] == b["parameters"] and a["n_steps"] == b["n_steps"]
    assert not lock.exists()
