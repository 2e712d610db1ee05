"""Property-based tests of the readers: arbitrary bytes and mutated valid files never crash.

Whatever a file holds, reading it gives a result or a
:class:`~bayes_rcsa.errors.BayesRCSAError` with a one-line message (what the
CLI prints) - never another exception, i.e. never a traceback for the user.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bayes_rcsa.errors import BayesRCSAError
from bayes_rcsa.io import load_setup, read_frf, read_spindle_csv

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "bayes_rcsa" / "data" / "example"
SETUP_TEXT = (EXAMPLE / "setup.toml").read_bytes()
# A short valid FRF file (the example's first rows) so that mutations stay fast to parse.
_FRF_LINES = (EXAMPLE / "tip_x_30mm.csv").read_bytes().splitlines(keepends=True)
FRF_TEXT = b"".join(_FRF_LINES[:40])
_SP_LINES = (EXAMPLE / "spindle_x.csv").read_bytes().splitlines(keepends=True)
SPINDLE_TEXT = b"".join(_SP_LINES[:40])

# Bounded so that the three properties together add a few seconds to the suite.
COMMON = settings(max_examples=60, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])

TOKENS = [b",", b"\n", b"#", b"nan", b"inf", b"-", b"1e300", b"0", b"\xff", b"\"", b"[", b"]", b"=", b"{", b"}",
          b"real", b"imag", b"frequency_hz", b"x", b"  ", b"\r\n", b"1_0", b"-1e-7", b"[[measurement]]"]


@st.composite
def mutated(draw, valid: bytes):
    """``valid`` with a few random edits: delete, duplicate or replace a span, insert a token."""
    data = bytearray(valid)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["delete", "insert", "replace", "duplicate", "truncate"]))
        i = draw(st.integers(0, len(data)))
        j = min(len(data), i + draw(st.integers(0, 40)))
        if kind == "delete":
            del data[i:j]
        elif kind == "insert":
            data[i:i] = draw(st.sampled_from(TOKENS) | st.binary(max_size=8))
        elif kind == "replace":
            data[i:j] = draw(st.sampled_from(TOKENS))
        elif kind == "duplicate":
            data[i:i] = data[i:j]
        else:
            del data[i:]
    return bytes(data)


def _check_one_line(call) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=UserWarning)  # DataWarning: a plausible-but-odd result is fine
        try:
            call()
        except BayesRCSAError as exc:
            message = " ".join(str(exc).split())  # what the CLI prints
            assert message, "empty error message"


def _read(data: bytes, name: str, reader) -> None:
    """Write ``data`` to a fresh temporary file ``name`` and check ``reader(path)``."""
    with tempfile.TemporaryDirectory(prefix="hyp") as d:
        path = Path(d) / name
        path.write_bytes(data)
        _check_one_line(lambda: reader(path))


@COMMON
@given(st.one_of(st.binary(max_size=300), mutated(FRF_TEXT)))
def test_frf_csv_reader_never_crashes(data):
    _read(data, "tip.csv", read_frf)


@COMMON
@given(st.one_of(st.binary(max_size=300), mutated(SPINDLE_TEXT)))
def test_spindle_csv_reader_never_crashes(data):
    _read(data, "spindle.csv", read_spindle_csv)


@COMMON
@given(st.one_of(st.binary(max_size=300), mutated(SETUP_TEXT)))
def test_setup_reader_never_crashes(data):
    # Setup-level validation only (load_data=False): the data files' readers are covered above.
    _read(data, "setup.toml", lambda p: load_setup(p, load_data=False))


@pytest.mark.parametrize("data", [b"\x00" * 10, b"name = 1\n" * 3, b"[materials]\nsteel = 5\n", b"a = [" * 2000])
def test_known_nasty_setups(data):
    _read(data, "setup.toml", lambda p: load_setup(p, load_data=False))


@pytest.fixture(scope="module")
def example_copy(tmp_path_factory):
    import shutil

    d = tmp_path_factory.mktemp("example") / "ex"
    shutil.copytree(EXAMPLE, d)
    return d


@settings(max_examples=25, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(data=mutated(SETUP_TEXT))
def test_setup_with_data_never_crashes(example_copy, data):
    # Mutated setups beside the real data files: exercises the data readers and the campaign checks.
    path = example_copy / "mutated.toml"
    path.write_bytes(data)
    _check_one_line(lambda: load_setup(path))
