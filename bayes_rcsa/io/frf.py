"""Read a tool-point FRF from any supported file type, chosen by suffix."""

from __future__ import annotations

from pathlib import Path

from ..errors import DataError
from ..model.receptance import FRF
from .checks import check_passive

__all__ = ["read_frf", "FRF_SUFFIXES"]

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
