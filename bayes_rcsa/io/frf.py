"""Read a tool-point FRF from any supported file type, chosen by suffix."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from ..model.receptance import FRF
from .checks import check_passive

__all__ = ["read_frf", "overlap_mask", "FRF_SUFFIXES"]

_CSV = (".csv",)
_UFF = (".uff", ".unv", ".uf")
FRF_SUFFIXES = _CSV + _UFF


def read_frf(path, point: bool = True) -> FRF:
    """Read a measured FRF file.

    Parameters
    ----------
    path : path-like
        ``.csv`` (data contract CSV) or ``.uff``/``.unv``/``.uf`` (universal
        file, dataset 58, holding exactly one FRF); the suffix is
        case-insensitive.
    point : bool
        The file holds a point receptance (response and force at the same
        point and direction, e.g. a tool-point FRF): refuse it when it is
        clearly not passive (:func:`bayes_rcsa.io.checks.check_passive`).
        ``False`` for transfer FRFs, whose imaginary part may have either sign.

    Returns
    -------
    FRF

    Raises
    ------
    DataError
        Unsupported suffix, any problem reported by the format's reader, or
        (``point``) a clearly non-passive point receptance.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    frf = None
    if suffix in _CSV:
        from .frf_csv import read_frf_csv

        frf = read_frf_csv(path)
    elif suffix in _UFF:
        from .uff58 import read_frf_uff

        frf = read_frf_uff(path)
    if frf is not None:
        if point:
            check_passive(frf.values, frf.source)
        return frf
    raise DataError(
        f"{path}: unsupported FRF file type {path.suffix or '(no suffix)'!r}; expected one of {', '.join(FRF_SUFFIXES)}"
    )


def overlap_mask(frequency_x_hz, frequency_y_hz) -> np.ndarray:
    """X's lines inside the band both grids cover (X and Y measured or exported on different grids).

    Parameters
    ----------
    frequency_x_hz : (n_x,) Hz, increasing
    frequency_y_hz : (n_y,) Hz, increasing

    Returns
    -------
    (n_x,) bool: ``max(fx[0], fy[0]) <= fx <= min(fx[-1], fy[-1])``; ``frequency_x_hz[mask]`` is the common grid
    (Y is interpolated onto it where the grids differ)
    """
    fx = np.asarray(frequency_x_hz, dtype=float)
    fy = np.asarray(frequency_y_hz, dtype=float)
    lo, hi = max(fx[0], fy[0]), min(fx[-1], fy[-1])
    return (fx >= lo) & (fx <= hi)
