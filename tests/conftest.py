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


@pytest.fixture()
def example(tmp_path):
    """A writable copy of the bundled example campaign; returns its setup.toml path."""
    dst = tmp_path / "example"
    shutil.copytree(example_dir(), dst)
    return dst / "setup.toml"
