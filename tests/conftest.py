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
# --durations=0 on 2026-11-30, session 10: 832 s of work in 1187 tests, 438 s wall).  xdist's loadfile mode hands out
# whole files in collection order, so a slow file collected late leaves one worker running alone at the end;
# scheduling the longest first (the classic longest-processing-time rule) balances the two workers.  Files not
# listed keep their order after these.
_SLOW_FILES = {
    "test_discrepancy_workflow.py": 65, "test_library.py": 50, "test_discrepancy_stiffer_structure.py": 42,
    "test_discrepancy_generators.py": 30, "test_demo.py": 30, "test_spindle_acceptance.py": 28, "test_batch.py": 25,
    "test_notebook.py": 20, "test_reliability_property.py": 19, "test_identifiability_acceptance.py": 19,
    "test_examples.py": 19, "test_library_cli.py": 18, "test_reliability_fs.py": 18, "test_sampler_tail.py": 17,
    "test_modes.py": 16, "test_sbc.py": 16, "test_library_exact.py": 16, "test_checkpoint_resume.py": 15,
    "test_importance_identify.py": 15, "test_api_tools.py": 15, "test_cli_startup.py": 14,
    "test_term_generators.py": 13, "test_api_identify.py": 13, "test_cuts_cli.py": 13,
    "test_term_spindle_rotation.py": 12, "test_reliability_checks.py": 12, "test_store.py": 11,
    "test_figures_legible.py": 11, "test_reliability_families.py": 10, "test_stability_warmup.py": 10,
    "test_lobes_measured.py": 9, "test_inference_calibration.py": 9, "test_inference_identify.py": 9,
    "test_api_predict.py": 9, "test_report_html.py": 8, "test_discrepancy_terms.py": 8,
    "test_discrepancy_screen_switch.py": 7,
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
