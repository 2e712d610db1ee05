"""Tool-point FRF files in CSV form (``frequency_hz, real, imag[, coherence]``).

The format is the project's data contract (docs/data-formats.md): a header
row is required, columns may come in any order, names are case-insensitive,
extra columns are ignored and lines starting with ``#`` are comments.

:func:`read_csv_columns` is the strict table reader shared with the spindle
receptance files (:mod:`bayes_rcsa.io.receptance_csv`); every problem it
finds is reported with the file name, the physical line number and the
column.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from ..errors import DataError
from ..model.receptance import FRF
from .atomic import atomic_path
from .checks import check_magnitude
from .limits import check_input_size

__all__ = [
    "read_frf_csv", "write_frf_csv", "read_csv_columns", "format_float", "check_finite_columns",
    "check_frequency_column", "comment_lines",
]


def format_float(value: float) -> str:
    """Shortest decimal text that reads back to exactly the same double."""
    return repr(float(value))


def _read_text(path: Path, what: str) -> str:
    if not path.exists():
        raise DataError(f"{path}: {what} not found (no such file)")
    if not path.is_file():
        raise DataError(f"{path}: {what} is not a regular file")
    check_input_size(path, what)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataError(f"{path}: cannot read {what}: {exc.strerror or exc}") from exc
    if b"\0" in raw:
        raise DataError(f"{path}: {what} is not a text file (it holds binary data)")
    try:
        # utf-8-sig: spreadsheet programs often prepend a byte-order mark.
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        pass
    # DAQ software on Windows writes comments and headers in Windows-1252 or Latin-1 ("Beschleunigung in m/s²",
    # "°C"); numbers are ASCII in every one of them and are still parsed strictly.  Windows-1252 leaves five bytes
    # undefined, which Latin-1 maps to control characters.
    try:
        return raw.decode("cp1252")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


_HEADER_FIELD = re.compile(r"^[^\W\d][\w ()\[\]/.°%-]{0,40}$")


def _looks_like_header(fields: Sequence[str]) -> bool:
    """Whether a line is a CSV header (two or more short names), so that it may be quoted in a message.

    Anything else (a line of a file that is not a measurement, e.g. a symbolic link to a system file) is
    never echoed.
    """
    return len(fields) >= 2 and all(_HEADER_FIELD.match(f.strip()) for f in fields)


def _parse_number(text: str, path: Path, line: int, column: str) -> float:
    s = text.strip()
    try:
        if "_" in s:  # float() accepts "1_000", which is not a number in a data file
            raise ValueError
        return float(s)
    except ValueError:
        raise DataError(f"{path}: line {line}, column {column!r}: {text!r} is not a number") from None


def _fast_columns(body: list[list[str]], n_fields: int, index: dict[str, int], numbered) -> dict | None:
    """The columns of a well-formed table in one pass per column, or None for the row-by-row pass.

    Accepts exactly what :func:`_parse_number` accepts (``float`` of the field, no ``_``): a repeated header
    or any bad field fails ``float`` here, and the row-by-row pass then raises the message naming it.
    """
    if any(len(fields) != n_fields for fields in body) or any("_" in raw for _, raw in numbered[1:]):
        return None
    try:
        return {name: np.array([float(fields[k]) for fields in body]) for name, k in index.items()}
    except ValueError:
        return None


def read_csv_columns(
    path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    what: str = "CSV file",
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Read the named numeric columns of a commented CSV table.

    Parameters
    ----------
    path : path-like
    required : sequence of str
        Lower-case column names that must be present.
    optional : sequence of str
        Lower-case column names read when present.
    what : str
        Description of the file used in messages (e.g. ``"FRF file"``).

    Returns
    -------
    columns : dict of str to (n_rows,) float
        Every required column and the optional columns found.
    lines : (n_rows,) int
        Physical 1-based line number of each data row, for messages.

    Raises
    ------
    DataError
        Missing or unreadable file, no header, no data rows, a missing or
        duplicated column, the header row again in mid-file, a row with the wrong number of fields, or a field
        that is not a number.  NaN and inf parse here; range checks belong to
        the caller.
    """
    path = Path(path)
    text = _read_text(path, what)
    # Keep physical line numbers: comments and blank lines are skipped, not removed.
    numbered = [
        (i + 1, raw)
        for i, raw in enumerate(text.splitlines())
        if raw.strip() and not raw.lstrip().startswith("#")
    ]
    if not numbered:
        raise DataError(f"{path}: {what} is empty (no header row and no data)")
    rows = list(csv.reader([raw for _, raw in numbered]))
    header_line = numbered[0][0]
    header = [name.strip().lower() for name in rows[0]]
    wanted = list(required) + list(optional)
    index: dict[str, int] = {}
    for k, name in enumerate(header):
        if name in wanted:
            if name in index:
                raise DataError(f"{path}: line {header_line}: column {name!r} appears twice in the header")
            index[name] = k
    missing = [name for name in required if name not in index]
    if missing and not index and not _looks_like_header(rows[0]):
        # not a header of this format at all: say so without echoing the line (the file may be anything,
        # e.g. a symlink to a system file)
        raise DataError(
            f"{path}: line {header_line}: no header with the columns {', '.join(required)}; the first line that is "
            f"not a '#' comment must name them (is it really a {what}?)"
        )
    if missing:
        raise DataError(
            f"{path}: line {header_line}: missing column(s) {', '.join(repr(m) for m in missing)}; "
            f"header has {', '.join(repr(h) for h in header)}; expected columns "
            f"{', '.join(required)}" + (f" (optional: {', '.join(optional)})" if optional else "")
        )
    body = rows[1:]
    if not body:
        raise DataError(f"{path}: {what} has a header but no data rows")
    lines = np.array([ln for ln, _ in numbered[1:]], dtype=int)
    fast = _fast_columns(body, len(header), index, numbered)
    if fast is not None:
        return fast, lines
    # the row-by-row pass finds and names the first bad field
    columns = {name: np.empty(len(body)) for name in index}
    for r, (fields, line) in enumerate(zip(body, lines)):
        if [f.strip().lower() for f in fields] == header:
            raise DataError(f"{path}: line {line}: the header row repeats in mid-file (two tables joined into one "
                            f"{what}?); keep one header at the top and one table")
        if len(fields) != len(header):
            raise DataError(f"{path}: line {line}: {len(fields)} fields, but the header has {len(header)} columns")
        for name, k in index.items():
            columns[name][r] = _parse_number(fields[k], path, int(line), name)
    return columns, lines


def check_finite_columns(columns: dict[str, np.ndarray], lines: np.ndarray, path: Path) -> None:
    """Reject NaN and inf in any column; name the first offending line."""
    for name, col in columns.items():
        bad = ~np.isfinite(col)
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(f"{path}: line {lines[i]}, column {name!r}: {float(col[i])!r} (NaN or inf) is not allowed")


def check_frequency_column(f: np.ndarray, lines: np.ndarray, path: Path) -> None:
    """Require ``f`` > 0 and strictly increasing; name the offending line."""
    bad = f <= 0
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(f"{path}: line {lines[i]}, column 'frequency_hz': {float(f[i])!r} Hz, expected frequencies > 0")
    step = np.diff(f) <= 0
    if step.any():
        i = int(np.argmax(step)) + 1
        raise DataError(
            f"{path}: line {lines[i]}, column 'frequency_hz': {float(f[i])!r} Hz after {float(f[i - 1])!r} Hz, "
            "expected strictly increasing frequencies"
        )


def read_frf_csv(path) -> FRF:
    """Read a tool-point FRF CSV file.

    Parameters
    ----------
    path : path-like
        CSV with columns ``frequency_hz`` (Hz), ``real`` and ``imag`` (m/N)
        and optionally ``coherence`` (in [0, 1]).

    Returns
    -------
    FRF
        ``values`` (n_freq,) complex m/N; ``source`` is the path as text.
        Positive imaginary parts (noise far from resonance) are data and are
        kept.

    Raises
    ------
    DataError
        See :func:`read_csv_columns`; also NaN/inf values, frequencies that
        are not > 0 and strictly increasing, coherence outside [0, 1] and
        absurd magnitudes (:func:`bayes_rcsa.io.checks.check_magnitude`).
    """
    path = Path(path)
    columns, lines = read_csv_columns(path, ("frequency_hz", "real", "imag"), ("coherence",), what="FRF file")
    check_finite_columns(columns, lines, path)
    f = columns["frequency_hz"]
    check_frequency_column(f, lines, path)
    coherence = columns.get("coherence")
    if coherence is not None:
        bad = (coherence < 0) | (coherence > 1)
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(
                f"{path}: line {lines[i]}, column 'coherence': {float(coherence[i])!r}, expected a value in [0, 1]"
            )
    values = columns["real"] + 1j * columns["imag"]
    check_magnitude(f, values, str(path))
    return FRF(f, values, coherence, source=str(path))


def comment_lines(comments: Iterable[str]) -> list[str]:
    """``# ``-prefixed lines for free text that may itself contain newlines."""
    if isinstance(comments, str):
        comments = [comments]
    return [f"# {part}".rstrip() for c in comments for part in str(c).splitlines() or [""]]


def write_frf_csv(path, frf: FRF, comments: Iterable[str] = ()) -> None:
    """Write ``frf`` as a tool-point FRF CSV file, atomically and losslessly.

    Every number is written as the shortest text that reads back to the same
    double, so :func:`read_frf_csv` returns bit-identical arrays.

    Parameters
    ----------
    path : path-like
    frf : FRF
    comments : iterable of str
        Written first as ``#`` comment lines (provenance, units, ...).
    """
    names = ["frequency_hz", "real", "imag"]
    cols = [frf.frequency_hz, frf.values.real, frf.values.imag]
    if frf.coherence is not None:
        names.append("coherence")
        cols.append(frf.coherence)
    out = comment_lines(comments) + [",".join(names)]
    out += [",".join(map(format_float, row)) for row in zip(*(c.tolist() for c in cols))]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")

