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
# --durations=0 on 2026-11-30, session 11: 644 s of work in 1242 tests, 346 s wall).  xdist's loadfile mode hands out
# whole files in collection order, so a slow file collected late leaves one worker running alone at the end;
# scheduling the longest first (the classic longest-processing-time rule) balances the two workers.  Files not
# listed keep their order after these.
_SLOW_FILES = {
    "test_discrepancy_workflow.py": 54, "test_library.py": 37, "test_discrepancy_stiffer_structure.py": 33,
    "test_discrepancy_generators.py": 27, "test_sampler_tail.py": 25, "test_notebook.py": 20, "test_demo.py": 18,
    "test_examples.py": 17, "test_reliability_property.py": 16, "test_reliability_fs.py": 15,
    "test_spindle_acceptance.py": 15, "test_sbc.py": 15, "test_batch.py": 14,
    "test_identifiability_acceptance.py": 14, "test_term_spindle_rotation.py": 13, "test_api_tools.py": 12,
    "test_api_identify.py": 12, "test_library_cli.py": 11, "test_library_exact.py": 11, "test_modes.py": 10,
    "test_checkpoint_resume.py": 10, "test_term_generators.py": 10, "test_reliability_families.py": 9,
    "test_importance_identify.py": 9, "test_cuts_cli.py": 9, "test_reliability_checks.py": 9,
    "test_inference_identify.py": 8, "test_discrepancy_screen_switch.py": 7, "test_stability_warmup.py": 7,
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
