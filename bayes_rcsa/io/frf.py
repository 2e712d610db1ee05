"""Read a tool-point FRF from any supported file type, chosen by suffix."""

from __future__ import annotations

from pathlib import Path

from ..errors import DataError
from ..model.receptance import FRF

__all__ = ["read_frf", "FRF_SUFFIXES"]

_CSV = (".csv",)
_UFF = (".uff", ".unv", ".uf")
FRF_SUFFIXES = _CSV + _UFF


def read_frf(path) -> FRF:
    """Read a tool-point FRF file.

    Parameters
    ----------
    path : path-like
        ``.csv`` (data contract CSV) or ``.uff``/``.unv``/``.uf`` (universal
        file, dataset 58, holding exactly one FRF); the suffix is
        case-insensitive.

    Returns
    -------
    FRF

    Raises
    ------
    DataError
        Unsupported suffix, or any problem reported by the format's reader.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in _CSV:
        from .frf_csv import read_frf_csv

        return read_frf_csv(path)
    if suffix in _UFF:
        from .uff58 import read_frf_uff

        return read_frf_uff(path)
    raise DataError(
        f"{path}: unsupported FRF file type {path.suffix or '(no suffix)'!r}; expected one of {', '.join(FRF_SUFFIXES)}"
    )
