"""Several directions in worker processes: the samples do not depend on the number of workers.

The CLI identifies the directions side by side in worker processes.  Each
direction's generator is the seed's generator advanced past the bootstrap
draws of the directions before it, i.e. exactly the stream the sequential
run (one generator used direction after direction, the behaviour before the
workers) gives it.
"""

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.spindle import load_artifact, load_spindle_samples
from bayes_rcsa.spindle.identification import _direction_rng, identify_direction, identify_directions
from bayes_rcsa.synthetic import default_bench_config
from bayes_rcsa.synthetic.artifact import default_bench_artifact, generate_artifact_tests, write_artifact_tests

SEED = 4
N_SAMPLES = 2
MAX_MODES = 3  # a cheap mode-count search: these tests are about random streams, not about the fit


@pytest.fixture(scope="module")
def two_directions(tmp_path_factory):
    """A coarse campaign (400-2600 Hz, 8 Hz: 276 lines) in x and y, with artifact-model uncertainty."""
    cfg = default_bench_config()
    art = default_bench_artifact(frequency_start=400.0, frequency_stop=2600.0, frequency_step=8.0)
    tests = generate_artifact_tests(cfg, art, np.random.default_rng(8), directions=("x", "y"))
    path = write_artifact_tests(tests, tmp_path_factory.mktemp("two") / "tests")
    text = path.read_text()
    assert "[uncertainty]" not in text
    path.write_text(text + "\n[uncertainty]\nyoungs_modulus = 0.01\ndensity = 0.005\n")
    setup = load_artifact(path)
    assert setup.youngs_modulus_rsd == 0.01  # the material draws are part of the stream being skipped
    return setup


def test_direction_generator_is_the_sequential_stream(two_directions):
    """Skipping x's draws leaves the generator exactly where x's bootstrap leaves it (no fit needed)."""
    setup = two_directions
    sequential = np.random.default_rng(SEED)
    identify_direction(setup, "x", n_samples=N_SAMPLES, rng=sequential, max_modes=MAX_MODES)
    skipped = _direction_rng(SEED, setup, ("x", "y"), 1, N_SAMPLES)
    assert skipped.bit_generator.state == sequential.bit_generator.state
    # the first direction starts from the seed itself
    assert _direction_rng(SEED, setup, ("x", "y"), 0, N_SAMPLES).bit_generator.state == \
        np.random.default_rng(SEED).bit_generator.state


@pytest.fixture(scope="module")
def parallel(two_directions):
    """Both directions in two worker processes, and the progress fractions reported."""
    fractions = []
    result = identify_directions(two_directions, ("x", "y"), n_samples=N_SAMPLES, seed=SEED, max_modes=MAX_MODES,
                                 workers=2, progress=fractions.append)
    return result, fractions


def test_two_workers_give_the_samples_of_one_generator_used_in_turn(two_directions, parallel):
    setup = two_directions
    sequential = np.random.default_rng(SEED)
    reference = {d: identify_direction(setup, d, n_samples=N_SAMPLES, rng=sequential, max_modes=MAX_MODES)
                 for d in ("x", "y")}
    parallel, fractions = parallel
    assert list(parallel) == ["x", "y"]
    for d in ("x", "y"):
        ref, got = reference[d].samples, parallel[d].samples
        assert got.shape == ref.shape == (N_SAMPLES, setup.measurements[d].frequency_hz.size, 2, 2)
        # Same random draws and the same code: equal up to the rounding of the BLAS (the workers run one
        # BLAS thread, this process may run several, and the Levenberg-Marquardt path amplifies round-off
        # to about 1e-8 relative).  Different draws would differ by the bootstrap spread, about 1e-2.
        scale = np.max(np.abs(ref))
        assert np.max(np.abs(got - ref)) < 1e-6 * scale
        assert np.max(np.abs(parallel[d].smoothed - reference[d].smoothed)) < 1e-6 * np.max(np.abs(ref))
    # and the two directions' samples are not the same draws
    assert not np.allclose(parallel["x"].samples - parallel["x"].smoothed,
                           parallel["y"].samples - parallel["y"].smoothed, rtol=1e-3)
    assert fractions and fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)


def test_cli_two_directions_in_two_workers(two_directions, parallel, tmp_path, capsys):
    """The command runs both directions in workers and writes both; its samples are the library's."""
    out = tmp_path / "out"
    code = main(["spindle", str(two_directions.path), "--out", str(out), "--samples", str(N_SAMPLES),
                 "--seed", str(SEED), "--max-modes", str(MAX_MODES), "--no-plots", "--json"])
    assert code == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["spindle_files"] == {"x": "spindle_x.csv", "y": "spindle_y.csv"}
    assert "2 worker processes" in captured.err
    samples = load_spindle_samples(out / "spindle_samples.npz")
    for d in ("x", "y"):  # both from single-threaded workers: bit-identical
        assert np.array_equal(samples.samples[d], parallel[0][d].samples)


def test_cli_refuses_zero_workers(two_directions, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["spindle", str(two_directions.path), "--out", str(out), "--workers", "0", "--quiet"]) == 2
    assert "--workers 0" in capsys.readouterr().err
    assert not out.exists()
