"""The tool-library bench (issue #20): the ``[holder] type`` setup key and the synthetic library generator.

Cheap by design: setups are parsed without data where possible, the generator runs on coarse frequency
grids, and no sampler is run here (the statistical acceptance tables come from benchmarks/library.py and
stand in docs/library.md).
"""

from __future__ import annotations


import pytest

from bayes_rcsa.errors import SetupError
from bayes_rcsa.io import load_setup


def _with_holder_line(example, line: str):
    """The example setup with ``line`` inserted at the top of its [holder] table."""
    text = example.read_text(encoding="utf-8")
    assert "\n[holder]\n" in text
    example.write_text(text.replace("\n[holder]\n", f"\n[holder]\n{line}\n", 1), encoding="utf-8")
    return example


def test_holder_type_absent_is_none(example):
    assert load_setup(example, load_data=False).holder_type is None


def test_holder_type_is_read_as_a_free_string(example):
    setup = load_setup(_with_holder_line(example, 'type = "HSK-A63 shrink fit #2"'), load_data=False)
    assert setup.holder_type == "HSK-A63 shrink fit #2"
    # the geometry is still parsed from the same table
    assert setup.holder.segments and setup.holder.material.name == "steel"


@pytest.mark.parametrize("value", ['""', '"   "', "32", "true", '["ER32"]'])
def test_holder_type_empty_or_not_a_string_is_refused(example, value):
    path = _with_holder_line(example, f"type = {value}")
    with pytest.raises(SetupError) as err:
        load_setup(path, load_data=False)
    msg = str(err.value)
    assert "\n" not in msg and "[holder] type" in msg and str(path) in msg


def test_holder_misspelled_key_is_still_refused(example):
    with pytest.raises(SetupError, match="typ"):
        load_setup(_with_holder_line(example, 'typ = "ER32"'), load_data=False)
