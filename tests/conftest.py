"""Fixtures shared by several test files."""

from __future__ import annotations

import shutil

import pytest

from bayes_rcsa.data import example_dir


@pytest.fixture()
def example(tmp_path):
    """A writable copy of the bundled example campaign; returns its setup.toml path."""
    dst = tmp_path / "example"
    shutil.copytree(example_dir(), dst)
    return dst / "setup.toml"
