"""Universal file (dataset 58) reading and lossless writing of tool-point FRFs."""

from __future__ import annotations

import numpy as np
import pytest

pyuff = pytest.importorskip("pyuff")

from bayes_rcsa.errors import DataError  # noqa: E402
from bayes_rcsa.io import read_frf, read_frf_uff, write_frf_uff  # noqa: E402
from bayes_rcsa.model.receptance import FRF  # noqa: E402


def _frf(rng, n=300, coherence=True, even=False) -> FRF:
    f = np.linspace(100.0, 4000.0, n) if even else 100.0 + np.cumsum(rng.uniform(0.1, 20.0, n)) / 3.0
    v = (rng.normal(size=n) + 1j * rng.normal(size=n)) * 10.0 ** rng.uniform(-10, -5, n)
    return FRF(f, v, rng.uniform(0, 1, n) if coherence else None, source="test")


def _foreign(path, dsets):
    """Write datasets with pyuff directly, as another program would."""
    path.write_bytes(b"")
    uff = pyuff.UFF(str(path))
    for d in dsets:
        uff.write_sets([d], mode="add")
    return path


def _dset(f, v, binary=0, spacing=0, **kw):
    d = dict(type=58, binary=binary, func_type=4, rsp_node=1, rsp_dir=1, ref_node=1, ref_dir=1, data=v, x=f,
             abscissa_spacing=spacing, abscissa_spec_data_type=18, ordinate_spec_data_type=8, orddenom_spec_data_type=13)
    d.update(kw)
    return d


@pytest.mark.parametrize("even, coherence", [(False, True), (True, False)])
def test_round_trip_is_bit_exact(tmp_path, even, coherence):
    frf = _frf(np.random.default_rng(4), coherence=coherence, even=even)
    path = tmp_path / "tip.uff"
    write_frf_uff(path, frf, direction="y", description="tip FRF, 25 mm")
    back = read_frf_uff(path)
    # Acceptance asks 1e-12 relative; binary doubles give exact equality.
    np.testing.assert_array_equal(back.frequency_hz, frf.frequency_hz)
    np.testing.assert_array_equal(back.values, frf.values)
    if coherence:
        np.testing.assert_array_equal(back.coherence, frf.coherence)
    else:
        assert back.coherence is None
    assert list(tmp_path.iterdir()) == [path]
    # The file is standard: pyuff sees units (164) then the FRF, with our metadata.
    uff = pyuff.UFF(str(path))
    assert list(uff.get_set_types()) == [164, 58] + ([58] if coherence else [])
    d = uff.read_sets(1)
    assert (d["func_type"], d["rsp_dir"], d["ref_dir"], d["abscissa_spacing"], d["ord_data_type"]) == (4, 2, 2, 0, 6)
    assert d["id1"].strip() == "tip FRF, 25 mm"


def test_binary_header_counts_all_data_bytes(tmp_path):
    frf = _frf(np.random.default_rng(5), n=17)
    path = tmp_path / "tip.uff"
    write_frf_uff(path, frf)
    headers = [line for line in path.read_bytes().split(b"\n") if line.startswith(b"    58b")]
    # complex uneven: 3 doubles per point; coherence (real uneven): 2 doubles per point
    assert [int(h[31:43]) for h in headers] == [17 * 3 * 8, 17 * 2 * 8]


def test_reads_foreign_ascii_even_file_with_positive_imaginary_lines(tmp_path):
    f = np.arange(1, 201) * 2.5
    rng = np.random.default_rng(6)
    v = (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)) * 1e-7
    v[3] = 2e-7 + 3e-9j  # Im > 0: measurement noise is data
    path = _foreign(tmp_path / "tip.unv", [_dset(f, v, binary=0, spacing=1)])
    frf = read_frf(path)
    # ASCII 58 stores the ordinate with 12 significant digits (E20.12 format)
    # and the abscissa start/step with 6: compare at those precisions.
    np.testing.assert_allclose(frf.frequency_hz, f, rtol=1e-6)
    np.testing.assert_allclose(frf.values, v, rtol=1e-10, atol=0)
    assert frf.values[3].imag > 0


def test_several_frfs_need_an_index(tmp_path):
    rng = np.random.default_rng(7)
    f = np.linspace(100, 200, 11)
    v1, v2 = (rng.normal(size=(2, 11)) + 1j) * 1e-7
    path = _foreign(tmp_path / "two.uff", [_dset(f, v1, binary=1), _dset(f, v2, binary=1, rsp_node=2)])
    with pytest.raises(DataError, match=r"two\.uff: 2 FRF datasets.*index = 0\.\.1"):
        read_frf_uff(path)
    np.testing.assert_array_equal(read_frf_uff(path, index=1).values, v2)
    np.testing.assert_array_equal(read_frf_uff(path, index=0).values, v1)
    assert read_frf_uff(path, index=1).source.endswith("two.uff[1]")
    with pytest.raises(DataError, match=r"index 2 out of range.*2 FRF"):
        read_frf_uff(path, index=2)


@pytest.mark.parametrize(
    "kw, fragments",
    [
        (dict(ordinate_spec_data_type=12), ["ordinate numerator", "12 (acceleration)", "receptance"]),
        (dict(abscissa_spec_data_type=17), ["abscissa", "17 (time)", "frequency"]),
        (dict(func_type=1), ["no FRF", "time response"]),
    ],
)
def test_refuses_non_receptance_content(tmp_path, kw, fragments):
    f = np.linspace(100, 200, 5)
    path = _foreign(tmp_path / "acc.uff", [_dset(f, f * (1 + 1j), binary=1, **kw)])
    with pytest.raises(DataError) as info:
        read_frf_uff(path)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


def test_refuses_non_si_units_and_bad_axes(tmp_path):
    f = np.linspace(100, 200, 5)
    mm = dict(type=164, units_code=5, units_description="mm", temp_mode=1, length=1e-3, force=1e-3, temp=1.0,
              temp_offset=273.15)
    with pytest.raises(DataError, match=r"non-SI units.*length factor 0\.001"):
        read_frf_uff(_foreign(tmp_path / "mm.uff", [mm, _dset(f, f * 1j, binary=1)]))
    with pytest.raises(DataError, match=r"point 0 at 0\.0 Hz.*> 0"):
        read_frf_uff(_foreign(tmp_path / "dc.uff", [_dset(np.arange(5.0), f * 1j, binary=1)]))
    with pytest.raises(DataError, match=r"point 2 .*strictly increasing"):
        read_frf_uff(_foreign(tmp_path / "dec.uff", [_dset(np.array([1.0, 3, 2, 4, 5]), f * 1j, binary=1)]))
    with pytest.raises(DataError, match=r"real-valued ordinate"):
        read_frf_uff(_foreign(tmp_path / "real.uff", [_dset(f, f, binary=1)]))


def test_missing_empty_and_garbage_files(tmp_path):
    with pytest.raises(DataError, match=r"nope\.uff.*not found"):
        read_frf_uff(tmp_path / "nope.uff")
    (tmp_path / "empty.uff").write_bytes(b"")
    with pytest.raises(DataError, match=r"empty\.uff.*no universal-file datasets"):
        read_frf(tmp_path / "empty.uff")
    (tmp_path / "text.UF").write_text("frequency_hz,real,imag\n1,2,3\n")
    with pytest.raises(DataError, match=r"text\.UF.*no universal-file datasets"):
        read_frf(tmp_path / "text.UF")
