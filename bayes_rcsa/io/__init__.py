"""File input and output: FRF and receptance files (CSV, UFF58), setup files (TOML), atomic writes.

Submodules: :mod:`~bayes_rcsa.io.checks` (plausibility of measured data),
:mod:`~bayes_rcsa.io.tables` (strict TOML table parsing),
:mod:`~bayes_rcsa.io.writers` (FRF output formats by suffix),
:mod:`~bayes_rcsa.io.atomic` (atomic files and directories, output locks),
:mod:`~bayes_rcsa.io.jsonable` (strict JSON of result records),
:mod:`~bayes_rcsa.io.figures` (figures without pyplot state).
"""

from .atomic import atomic_path, atomic_write_bytes, atomic_write_text
from .frf import read_frf
from .frf_csv import read_frf_csv, write_frf_csv
from .receptance_csv import read_spindle_csv, write_spindle_csv
from .setup import ContactSpec, MeasurementSpec, Setup, load_setup
from .toml_writer import dump_toml, setup_document
from .uff58 import read_frf_uff, write_frf_uff
from .writers import write_frf

__all__ = [
    "read_frf", "read_frf_csv", "write_frf_csv", "read_spindle_csv", "write_spindle_csv",
    "read_frf_uff", "write_frf_uff", "dump_toml", "load_setup", "Setup", "ContactSpec", "MeasurementSpec",
    "atomic_path", "atomic_write_text", "atomic_write_bytes", "setup_document", "write_frf",
]
