"""Tool-point FRFs in universal file format, dataset 58 (via :mod:`pyuff`).

Reading accepts what measurement systems export: ASCII or binary (58b)
datasets, even or uneven abscissa, single or double precision, several
datasets per file.  The FRF must be a complex displacement/force receptance
in SI units (m/N) over frequency in Hz; files that declare something else
(mobility, accelerance, a time axis, non-SI units in dataset 164) are
refused rather than converted silently.

Writing is lossless: pyuff's ASCII layout stores the abscissa with six
significant digits and the ordinate with twelve, which cannot meet a 1e-12
round trip, so the writer always uses the binary 58b form with an uneven
(explicitly stored, double precision) abscissa.  A dataset 164 declaring SI
units precedes the FRF; a coherence, if present, follows as a second
dataset 58 of function type 6 on the same DOFs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from ..model.receptance import FRF
from .atomic import atomic_path
from .checks import check_magnitude

__all__ = ["read_frf_uff", "write_frf_uff"]

_FUNC_FRF = 4
_FUNC_COHERENCE = 6
_FUNC_NAMES = {
    0: "general", 1: "time response", 2: "auto spectrum", 3: "cross spectrum", 4: "FRF", 5: "transmissibility",
    6: "coherence", 9: "PSD",
}
# Specific data types (records 8-10) that are compatible with a receptance in
# Hz; 0 (unknown) and 1 (general) are what many exporters write.
_ABSCISSA_OK = {0, 1, 18}
_NUMERATOR_OK = {0, 1, 8}
_DENOMINATOR_OK = {0, 1, 9, 13}
_DATA_TYPE_NAMES = {
    8: "displacement", 9: "reaction force", 11: "velocity", 12: "acceleration", 13: "excitation force",
    17: "time", 18: "frequency", 19: "rpm", 20: "order",
}
_DIRECTION_CODES = {"x": 1, "y": 2, "z": 3}


def _type_name(code) -> str:
    return f"{code} ({_DATA_TYPE_NAMES[code]})" if code in _DATA_TYPE_NAMES else str(code)


def _open(path: Path):
    import pyuff  # lazy: only UFF users pay for the import

    if not path.exists():
        raise DataError(f"{path}: FRF file not found (no such file)")
    if not path.is_file():
        raise DataError(f"{path}: FRF file is not a regular file")
    from .limits import check_input_size

    check_input_size(path, "FRF file")
    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
    except Exception as exc:  # pyuff raises bare Exception for every problem
        raise DataError(f"{path}: not a readable universal file ({exc})") from exc
    if not types:
        raise DataError(f"{path}: no universal-file datasets found (empty or not a UFF file)")
    return uff, types


def _read_set(uff, path: Path, k: int, header_only: bool = False) -> dict:
    try:
        return uff.read_sets(k, header_only=header_only)
    except Exception as exc:
        raise DataError(f"{path}: dataset {k} cannot be read ({exc})") from exc


def _check_units(uff, path: Path, types: list[int]) -> None:
    for k, t in enumerate(types):
        if t == 164:
            d = _read_set(uff, path, k)
            if d.get("length") != 1.0 or d.get("force") != 1.0:
                raise DataError(
                    f"{path}: dataset 164 declares non-SI units (length factor {d.get('length')!r}, force factor "
                    f"{d.get('force')!r}); expected SI (m, N); convert the file to SI first"
                )


def _check_frf_header(d: dict, path: Path, where: str) -> None:
    checks = [
        ("abscissa", d.get("abscissa_spec_data_type", 0), _ABSCISSA_OK, "frequency"),
        ("ordinate numerator", d.get("ordinate_spec_data_type", 0), _NUMERATOR_OK, "displacement"),
        ("ordinate denominator", d.get("orddenom_spec_data_type", 0), _DENOMINATOR_OK, "force"),
    ]
    for record, code, ok, expected in checks:
        if code not in ok:
            raise DataError(
                f"{path}: {where}: {record} data type {_type_name(code)}, expected {expected}; the file must hold a "
                "displacement/force receptance (m/N) over frequency (Hz)"
            )
    if d.get("ord_data_type") not in (5, 6):
        raise DataError(f"{path}: {where}: real-valued ordinate (data type {d.get('ord_data_type')}), expected complex")


def _check_axis(x: np.ndarray, path: Path, where: str) -> None:
    if not np.all(np.isfinite(x)):
        raise DataError(f"{path}: {where}: frequency axis contains NaN or inf")
    if np.any(x <= 0):
        i = int(np.argmax(x <= 0))
        raise DataError(f"{path}: {where}: point {i} at {float(x[i])!r} Hz, expected frequencies > 0 (drop the DC line)")
    if np.any(np.diff(x) <= 0):
        i = int(np.argmax(np.diff(x) <= 0)) + 1
        raise DataError(
            f"{path}: {where}: point {i} at {float(x[i])!r} Hz after {float(x[i - 1])!r} Hz, "
            "expected strictly increasing frequencies"
        )


def read_frf_uff(path, index: int | None = None) -> FRF:
    """Read one tool-point FRF from a universal file (dataset 58).

    Parameters
    ----------
    path : path-like
    index : int, optional
        0-based position of the FRF among the file's FRF datasets (dataset 58
        with function type 4), in file order.  ``None`` requires exactly one.

    Returns
    -------
    FRF
        ``values`` (n_freq,) complex m/N.  ``coherence`` is attached when the
        file holds exactly one coherence dataset (function type 6) on the
        same response/reference DOFs.

    Raises
    ------
    DataError
        Missing or unreadable file, no (or an ambiguous) FRF, non-receptance
        or non-SI content, NaN/inf, frequencies not > 0 and increasing,
        coherence outside [0, 1] or on another frequency axis.
    """
    path = Path(path)
    uff, types = _open(path)
    _check_units(uff, path, types)
    headers = {k: _read_set(uff, path, k, header_only=True) for k, t in enumerate(types) if t == 58}
    frfs = [k for k, d in headers.items() if d.get("func_type") == _FUNC_FRF]
    if not frfs:
        def describe(k: int, t: int) -> str:
            if t != 58:
                return f"dataset {t}"
            func = headers[k].get("func_type")
            return f"dataset 58 ({_FUNC_NAMES.get(func, f'function type {func}')})"

        found = ", ".join(describe(k, t) for k, t in enumerate(types))
        raise DataError(f"{path}: no FRF (dataset 58, function type 4) in the file; found {found}")
    if index is None:
        if len(frfs) > 1:
            raise DataError(f"{path}: {len(frfs)} FRF datasets in the file; choose one with index = 0..{len(frfs) - 1}")
        index = 0
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(frfs):
        raise DataError(f"{path}: FRF index {index!r} out of range; the file holds {len(frfs)} FRF dataset(s)")
    k = frfs[int(index)]
    where = f"FRF dataset {k}"
    _check_frf_header(headers[k], path, where)
    d = _read_set(uff, path, k)
    x = np.asarray(d["x"], dtype=float)
    values = np.asarray(d["data"], dtype=complex)
    _check_axis(x, path, where)
    if values.shape != x.shape:
        raise DataError(f"{path}: {where}: {values.size} values for {x.size} frequencies")
    if not np.all(np.isfinite(values)):
        i = int(np.argmax(~np.isfinite(values)))
        raise DataError(f"{path}: {where}: value at point {i} ({float(x[i])!r} Hz) is NaN or inf")

    dof_keys = ("rsp_node", "rsp_dir", "ref_node", "ref_dir")
    dofs = tuple(headers[k].get(key) for key in dof_keys)
    coh_sets = [
        j for j, h in headers.items()
        if h.get("func_type") == _FUNC_COHERENCE and tuple(h.get(key) for key in dof_keys) == dofs
    ]
    coherence = None
    if len(coh_sets) == 1:
        c = _read_set(uff, path, coh_sets[0])
        cx = np.asarray(c["x"], dtype=float)
        coherence = np.asarray(c["data"]).real.astype(float)
        if cx.shape != x.shape or not np.allclose(cx, x, rtol=1e-12, atol=0):
            raise DataError(f"{path}: coherence dataset {coh_sets[0]} is not on the frequency axis of {where}")
        bad = ~np.isfinite(coherence) | (coherence < 0) | (coherence > 1)
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(
                f"{path}: coherence dataset {coh_sets[0]}: {float(coherence[i])!r} at {float(x[i])!r} Hz, "
                "expected a value in [0, 1]"
            )
    source = str(path) if len(frfs) == 1 else f"{path}[{index}]"
    check_magnitude(x, values, source)
    return FRF(x, values, coherence, source=source)


def _id_line(text) -> str:
    # ID records are 80 fixed columns and may not be blank.
    line = " ".join(str(text).split())[:80]
    return line or "NONE"


def _patch_byte_count(path: Path, offset: int, n_bytes: int) -> None:
    """Correct the 58b header's byte count, which pyuff writes as 8 per point.

    The field counts every binary byte after the ASCII header (3 doubles per
    point for complex uneven data, 2 for real uneven data); pyuff's reader
    ignores it but other readers rely on it.
    """
    start = offset + len("    -1\n")
    with open(path, "r+b") as fh:
        fh.seek(start)
        head = fh.read(43)
        if head[:7] != b"    58b":
            return  # layout not as expected: leave pyuff's header untouched
        fh.seek(start + 31)
        fh.write(b"%12d" % n_bytes)


def write_frf_uff(path, frf: FRF, *, direction: str = "x", node: int = 1, description: str | None = None) -> None:
    """Write ``frf`` to a universal file, losslessly and atomically.

    Parameters
    ----------
    path : path-like
    frf : FRF
        Complex receptance, m/N.
    direction : {"x", "y", "z"}
        Response and reference direction code of the point FRF.
    node : int
        Response and reference node number.
    description : str, optional
        ID line 1 (at most 80 characters are kept); defaults to ``frf.source``.

    Notes
    -----
    Binary 58b, double precision, uneven abscissa: frequencies and values
    read back bit-identical with :func:`read_frf_uff`.
    """
    import pyuff  # lazy: only UFF users pay for the import

    if direction not in _DIRECTION_CODES:
        raise DataError(f"UFF direction {direction!r}: expected one of {', '.join(_DIRECTION_CODES)}")
    code = _DIRECTION_CODES[direction]
    dof = dict(rsp_node=int(node), rsp_dir=code, ref_node=int(node), ref_dir=code)
    units = dict(type=164, units_code=1, units_description="SI", temp_mode=1, length=1.0, force=1.0, temp=1.0,
                 temp_offset=273.15)
    x = np.array(frf.frequency_hz, dtype=float)
    common = dict(
        type=58, binary=1, abscissa_spacing=0, abscissa_spec_data_type=18, z_axis_spec_data_type=0,
        id1=_id_line(description if description is not None else frf.source), **dof,
    )
    sets = [
        dict(common, func_type=_FUNC_FRF, ordinate_spec_data_type=8, orddenom_spec_data_type=13,
             data=np.array(frf.values, dtype=complex), x=x.copy()),
    ]
    if frf.coherence is not None:
        sets.append(dict(common, func_type=_FUNC_COHERENCE, id2="coherence", ordinate_spec_data_type=0,
                         orddenom_spec_data_type=0, data=np.array(frf.coherence, dtype=float), x=x.copy()))
    with atomic_path(path) as tmp:
        uff = pyuff.UFF(str(tmp))
        try:
            # Append mode only: pyuff's binary writer truncates the file
            # between header and data in its 'overwrite' mode.
            uff.write_sets([units], mode="add")
            for dset in sets:
                offset = tmp.stat().st_size
                uff.write_sets([dset], mode="add")
                per_point = 3 if np.iscomplexobj(dset["data"]) else 2
                _patch_byte_count(tmp, offset, per_point * 8 * x.size)
        except Exception as exc:
            raise DataError(f"{path}: pyuff could not write the FRF ({exc})") from exc
