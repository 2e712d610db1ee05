"""CSV readers and writers: tool-point FRF and spindle 2x2 receptance files."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.errors import DataError
from bayes_rcsa.io import read_frf, read_frf_csv, read_spindle_csv, write_frf_csv, write_spindle_csv
from bayes_rcsa.model.receptance import FRF, PointReceptance


def _random_frf(rng, n=257, coherence=True) -> FRF:
    # Irregular grid and values spanning many decades: the hardest case for
    # decimal text, since every digit of every double matters.
    f = 50.0 + np.cumsum(rng.uniform(0.01, 7.0, n)) * np.pi
    v = (rng.normal(size=n) + 1j * rng.normal(size=n)) * 10.0 ** rng.uniform(-12, -3, n)
    c = rng.uniform(0, 1, n) if coherence else None
    if coherence:
        c[0], c[-1] = 0.0, 1.0
    return FRF(f, v, c, source="random")


def _write(path, text: str):
    path.write_text(text, encoding="utf-8")
    return path


def test_frf_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(1)
    frf = _random_frf(rng)
    path = tmp_path / "tip.csv"
    write_frf_csv(path, frf, comments=["made by test", "second line\nthird line"])
    back = read_frf_csv(path)
    # Acceptance criterion is 1e-12 relative; repr-exact text gives exact equality.
    np.testing.assert_array_equal(back.frequency_hz, frf.frequency_hz)
    np.testing.assert_array_equal(back.values, frf.values)
    np.testing.assert_array_equal(back.coherence, frf.coherence)
    text = path.read_text()
    assert text.splitlines()[:4] == ["# made by test", "# second line", "# third line", "frequency_hz,real,imag,coherence"]
    assert back.source == str(path)
    # dispatch by suffix gives the same result
    np.testing.assert_array_equal(read_frf(path).values, frf.values)
    assert list(tmp_path.iterdir()) == [path]  # atomic write leaves no temp file


def test_frf_without_coherence_round_trip(tmp_path):
    frf = _random_frf(np.random.default_rng(2), n=5, coherence=False)
    path = tmp_path / "tip.csv"
    write_frf_csv(path, frf)
    back = read_frf_csv(path)
    assert back.coherence is None
    assert path.read_text().splitlines()[0] == "frequency_hz,real,imag"
    np.testing.assert_array_equal(back.values, frf.values)


def test_contract_example_any_order_case_comments_extra_columns(tmp_path):
    path = _write(
        tmp_path / "tip.csv",
        "# exported by some analyser\n"
        "\n"
        "IMAG, Frequency_Hz ,Real,channel,Coherence\n"
        "-3.1e-09,200,1.234e-07,3,0.99\n"
        "  # a comment between rows\n"
        "2.5e-10,202.5,1.3e-07,3,1\n",  # Im > 0: measured noise, must be accepted
    )
    frf = read_frf_csv(path)
    np.testing.assert_array_equal(frf.frequency_hz, [200.0, 202.5])
    np.testing.assert_array_equal(frf.values, [1.234e-07 - 3.1e-09j, 1.3e-07 + 2.5e-10j])
    np.testing.assert_array_equal(frf.coherence, [0.99, 1.0])
    assert frf.values.imag[1] > 0


def test_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "tip.csv"
    path.write_bytes(b"\xef\xbb\xbffrequency_hz,real,imag\n100,1e-7,-1e-7\n")
    assert read_frf_csv(path).values[0] == 1e-7 - 1e-7j


@pytest.mark.parametrize(
    "text, fragments",
    [
        ("", ["empty"]),
        ("# only a comment\n\n", ["empty"]),
        ("frequency_hz,real,imag\n", ["no data rows"]),
        ("frequency_hz,real\n100,1\n", ["missing column", "'imag'"]),
        ("freq,re,im\n100,1,2\n", ["missing column", "'frequency_hz'", "'real'", "'imag'"]),
        ("frequency_hz,real,imag,REAL\n100,1,2,3\n", ["'real'", "twice"]),
        ("frequency_hz,real,imag\n100,1,2\n200,abc,3\n", ["line 3", "'real'", "'abc'", "not a number"]),
        ("frequency_hz,real,imag\n100,1_0,2\n", ["line 2", "not a number"]),
        ("frequency_hz,real,imag\n100,1,2\n200,3\n", ["line 3", "2 fields", "3 columns"]),
        ("frequency_hz,real,imag\n100,1,2\n200,nan,3\n", ["line 3", "'real'", "NaN or inf"]),
        ("frequency_hz,real,imag\n100,1,inf\n", ["line 2", "'imag'", "NaN or inf"]),
        ("frequency_hz,real,imag\n0,1,2\n", ["line 2", ": 0.0 Hz", "> 0"]),
        ("frequency_hz,real,imag\n-5,1,2\n", ["line 2", "> 0"]),
        ("# c\nfrequency_hz,real,imag\n100,1,2\n300,1,2\n200,1,2\n", ["line 5", "strictly increasing"]),
        ("frequency_hz,real,imag\n100,1,2\n100,1,2\n", ["line 3", "strictly increasing"]),
        ("frequency_hz,real,imag,coherence\n100,1,2,0.5\n200,1,2,1.01\n", ["line 3", "coherence", ": 1.01,", "[0, 1]"]),
        ("frequency_hz,real,imag,coherence\n100,1,2,-0.1\n", ["line 2", "coherence", "[0, 1]"]),
    ],
)
def test_bad_frf_files(tmp_path, text, fragments):
    path = _write(tmp_path / "bad.csv", text)
    with pytest.raises(DataError) as info:
        read_frf_csv(path)
    msg = str(info.value)
    assert "bad.csv" in msg
    for fragment in fragments:
        assert fragment in msg, msg


def test_missing_file_and_unknown_suffix(tmp_path):
    with pytest.raises(DataError, match=r"nope\.csv.*not found"):
        read_frf_csv(tmp_path / "nope.csv")
    with pytest.raises(DataError, match=r"nope\.csv.*not found"):
        read_frf(tmp_path / "nope.csv")
    with pytest.raises(DataError, match=r"unsupported FRF file type '\.txt'.*\.csv"):
        read_frf(_write(tmp_path / "tip.txt", "frequency_hz,real,imag\n1,2,3\n"))
    with pytest.raises(DataError, match="not a regular file"):
        read_frf_csv(tmp_path)


def _random_block(rng, n) -> PointReceptance:
    f = np.linspace(10.0, 5000.0, n) + rng.uniform(0, 1e-3, n)
    b = (rng.normal(size=(n, 2, 2)) + 1j * rng.normal(size=(n, 2, 2))) * np.array([[1e-7, 1e-6], [1e-6, 1e-5]])
    return PointReceptance(f, b, source="random")


def test_spindle_round_trip_is_bit_exact_and_entries_land_right(tmp_path):
    rng = np.random.default_rng(3)
    rec = _random_block(rng, 101)
    path = tmp_path / "spindle_x.csv"
    write_spindle_csv(path, rec, comments=["spindle flange"])
    back = read_spindle_csv(path, check=False)  # random numbers, not a passive reciprocal block
    np.testing.assert_array_equal(back.frequency_hz, rec.frequency_hz)
    np.testing.assert_array_equal(back.block, rec.block)
    # A hand-written file with shuffled columns: check each entry's position.
    _write(
        tmp_path / "s.csv",
        "P_IMAG,p_real,n_imag,n_real,l_imag,l_real,h_imag,h_real,frequency_hz,note\n"
        "-8e-7,7e-7,-6e-7,5e-7,-4e-7,3e-7,-2e-7,1e-7,100,x\n",
    )
    s = read_spindle_csv(tmp_path / "s.csv", check=False)  # l != n on purpose: every entry distinct
    np.testing.assert_array_equal(s.block[0], [[1e-7 - 2e-7j, 3e-7 - 4e-7j], [5e-7 - 6e-7j, 7e-7 - 8e-7j]])


def test_bad_spindle_files(tmp_path):
    header = "frequency_hz,h_real,h_imag,l_real,l_imag,n_real,n_imag,p_real,p_imag"
    with pytest.raises(DataError, match=r"missing column.*'p_imag'"):
        read_spindle_csv(_write(tmp_path / "a.csv", header.rsplit(",", 1)[0] + "\n1,1,1,1,1,1,1,1\n"))
    with pytest.raises(DataError, match=r"line 3.*'n_real'.*NaN or inf"):
        read_spindle_csv(_write(tmp_path / "b.csv", header + "\n1,1,1,1,1,1,1,1,1\n2,1,1,1,1,nan,1,1,1\n"))
    with pytest.raises(DataError, match=r"line 3.*strictly increasing"):
        read_spindle_csv(_write(tmp_path / "c.csv", header + "\n2,1,1,1,1,1,1,1,1\n1,1,1,1,1,1,1,1,1\n"))
    with pytest.raises(DataError, match=r"not found"):
        read_spindle_csv(tmp_path / "missing.csv")
