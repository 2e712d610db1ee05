"""Fixtures shared by several test files."""

from __future__ import annotations

import os
import shutil

# The suite runs in two xdist worker processes on a two-core machine; a multi-threaded BLAS in each would
# oversubscribe the cores (measured: 6 min 02 s against 5 min 36 s with one thread per worker).  This module is
# an initial conftest (testpaths = tests), loaded before the workers start, so they inherit the limit; an
# explicit setting by the user wins.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest

from bayes_rcsa.data import example_dir


# The slowest test files (seconds of work each on the two-core development machine, measured with
# --durations=0 on 2026-11-27: 823 s of work in 922 tests, 460 s wall with the previous, stale table).  xdist's
# loadfile mode hands out whole files in collection order, so a slow file collected late leaves one worker
# running alone at the end; scheduling the longest first (the classic longest-processing-time rule) balances
# the two workers.  Files not listed keep their order after these.
_SLOW_FILES = {
    "test_discrepancy_workflow.py": 104, "test_inference_calibration.py": 74, "test_batch.py": 53, "test_demo.py": 44,
    "test_discrepancy_generators.py": 39, "test_library.py": 36, "test_discrepancy_stiffer_structure.py": 35,
    "test_library_cli.py": 27, "test_reliability_property.py": 26, "test_reliability_fs.py": 25,
    "test_inference_cli.py": 24, "test_reliability_checks.py": 22, "test_term_spindle_rotation.py": 21,
    "test_identifiability_acceptance.py": 21, "test_checkpoint_resume.py": 20, "test_examples.py": 17,
    "test_reliability_families.py": 13, "test_modes.py": 13, "test_cuts_cli.py": 12, "test_library_exact.py": 12,
    "test_spindle_acceptance.py": 11, "test_design_growth_prior.py": 11, "test_discrepancy_terms.py": 10,
    "test_lobes_measured.py": 10, "test_term_generators.py": 10, "test_identify_spindle_uncertainty.py": 10,
    "test_reliability_cli.py": 10, "test_inference_identify.py": 9, "test_synthetic_bench.py": 9,
}


def pytest_collection_modifyitems(session, config, items):
    """Run the slowest files first (see ``_SLOW_FILES``); the order inside a file is unchanged."""
    items.sort(key=lambda item: -_SLOW_FILES.get(item.path.name, 0))


@pytest.fixture()
def example(tmp_path):
    """A writable copy of the bundled example campaign; returns its setup.toml path."""
    dst = tmp_path / "example"
    shutil.copytree(example_dir(), dst)
    return dst / "setup.toml"
