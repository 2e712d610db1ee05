"""Spindle-holder interface receptance files: the 2x2 flange block in CSV form.

Columns (data contract, docs/data-formats.md)::

    frequency_hz,h_real,h_imag,l_real,l_imag,n_real,n_imag,p_real,p_imag

with h in m/N, l in 1/N, n in rad/N and p in rad/(N m).  The same reading
rules as the FRF files apply (header required, any column order,
case-insensitive names, ``#`` comments, extra columns ignored).
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

from ..model.receptance import PointReceptance
from .atomic import atomic_path
from .checks import check_magnitude, check_spindle_block
from .frf_csv import check_finite_columns, check_frequency_column, comment_lines, format_float, read_csv_columns

__all__ = ["read_spindle_csv", "write_spindle_csv", "SPINDLE_COLUMNS"]

# Block entries in row-major order of [[h, l], [n, p]].
_ENTRIES = (("h", 0, 0), ("l", 0, 1), ("n", 1, 0), ("p", 1, 1))
SPINDLE_COLUMNS = ("frequency_hz",) + tuple(f"{e}_{part}" for e, _, _ in _ENTRIES for part in ("real", "imag"))


def read_spindle_csv(path, check: bool = True) -> PointReceptance:
    """Read a 2x2 flange receptance file.

    Parameters
    ----------
    path : path-like
    check : bool
        Check the block as a measured point block (default): the direct
        terms h and p passive, the cross terms reciprocal, |p| > |h| and the
        imaginary block negative semi-definite, with a permutation of the
        h/l/n/p columns named when one explains a failure
        (:func:`bayes_rcsa.io.checks.check_spindle_block`).  ``False`` only for files that are not
        point blocks.

    Returns
    -------
    PointReceptance
        ``block`` (n_freq, 2, 2) complex ``[[h, l], [n, p]]``.  Measured
        blocks are kept as they are (reciprocity l = n is checked, not
        enforced).

    Raises
    ------
    DataError
        Missing file or column, malformed numbers, NaN/inf, frequencies not
        > 0 and strictly increasing (messages name file, line and column);
        absurd magnitudes; with ``check``, direct terms that are clearly not
        passive and cross terms that differ by more than
        :data:`~bayes_rcsa.io.checks.RECIPROCITY_REFUSE`.

    Warns
    -----
    DataWarning
        Cross terms that differ by more than
        :data:`~bayes_rcsa.io.checks.RECIPROCITY_WARN`.
    """
    path = Path(path)
    columns, lines = read_csv_columns(path, SPINDLE_COLUMNS, what="spindle receptance file")
    check_finite_columns(columns, lines, path)
    f = columns["frequency_hz"]
    check_frequency_column(f, lines, path)
    block = np.empty((f.size, 2, 2), dtype=complex)
    for name, i, j in _ENTRIES:
        block[:, i, j] = columns[f"{name}_real"] + 1j * columns[f"{name}_imag"]
    check_magnitude(f, block.reshape(f.size, 4), str(path))
    if check:
        check_spindle_block(block, str(path))
    return PointReceptance(f, block, source=str(path))


def write_spindle_csv(path, receptance: PointReceptance, comments: Iterable[str] = ()) -> None:
    """Write a 2x2 flange receptance file atomically with repr-exact numbers.

    Parameters
    ----------
    path : path-like
    receptance : PointReceptance
    comments : iterable of str
        Written first as ``#`` comment lines.
    """
    b = receptance.block
    cols = [receptance.frequency_hz]
    for _, i, j in _ENTRIES:
        cols += [b[:, i, j].real, b[:, i, j].imag]
    out = comment_lines(comments) + [",".join(SPINDLE_COLUMNS)]
    out += [",".join(map(format_float, row)) for row in zip(*(c.tolist() for c in cols))]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
