"""Registry of FRF output formats, chosen by file suffix.

Adding a format is one module with a ``write(path, frf, comments)``
function plus one :func:`register_frf_writer` call below::

    register_frf_writer(FRFWriter("csv", (".csv",), _write_csv))

Commands that write an FRF (``bayes-rcsa simulate --out FILE.uff``) call
:func:`write_frf`, which picks the writer from the suffix.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

from ..errors import SetupError
from ..model.receptance import FRF
from ..registry import Registry

__all__ = ["FRFWriter", "FRF_WRITERS", "register_frf_writer", "frf_writer_for", "write_frf", "frf_output_suffixes"]


@dataclass(frozen=True)
class FRFWriter:
    """One FRF output format.

    Attributes
    ----------
    name : str
        Format name (``"csv"``, ``"uff58"``).
    suffixes : tuple of str
        Lower-case file suffixes that select it (``".csv"``).
    write : callable ``(path, frf, comments) -> None``
        Writes atomically (no partial file on failure).
    """

    name: str
    suffixes: tuple[str, ...]
    write: Callable[[Path, FRF, list[str]], None]


FRF_WRITERS: Registry[FRFWriter] = Registry("FRF output format")


def register_frf_writer(writer: FRFWriter) -> FRFWriter:
    """Register ``writer`` under its name; its suffixes must not be taken already."""
    for other in FRF_WRITERS:
        taken = set(FRF_WRITERS.get(other).suffixes) & set(writer.suffixes)
        if taken and other != writer.name:
            raise SetupError(f"FRF output format {writer.name!r}: suffix(es) {sorted(taken)} belong to {other!r}")
    return FRF_WRITERS.register(writer.name, writer, replace=True)


def frf_output_suffixes() -> tuple[str, ...]:
    """Every registered suffix."""
    return tuple(s for name in FRF_WRITERS for s in FRF_WRITERS.get(name).suffixes)


def frf_writer_for(path, option: str = "--out") -> FRFWriter:
    """The writer selected by the suffix of ``path`` (case-insensitive)."""
    suffix = Path(path).suffix.lower()
    for name in FRF_WRITERS:
        writer = FRF_WRITERS.get(name)
        if suffix in writer.suffixes:
            return writer
    raise SetupError(f"{option} {path}: unsupported FRF output type {suffix or '(no suffix)'!r}; "
                     f"expected one of {', '.join(frf_output_suffixes())}")


def write_frf(path, frf: FRF, comments: Iterable[str] = ()) -> Path:
    """Write ``frf`` to ``path`` in the format its suffix selects; returns the path."""
    writer = frf_writer_for(path)
    writer.write(Path(path), frf, list(comments))
    return Path(path)


def _write_csv(path: Path, frf: FRF, comments: list[str]) -> None:
    from .frf_csv import write_frf_csv

    write_frf_csv(path, frf, comments=comments)


def _write_uff(path: Path, frf: FRF, comments: list[str]) -> None:
    from .uff58 import write_frf_uff

    # UFF58 has one free-text ID line (80 characters) for provenance.
    write_frf_uff(path, frf, description="; ".join(comments) if comments else None)


register_frf_writer(FRFWriter("csv", (".csv",), _write_csv))
register_frf_writer(FRFWriter("uff58", (".uff", ".unv", ".uf"), _write_uff))
