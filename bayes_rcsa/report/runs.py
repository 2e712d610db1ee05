"""Output directories of the sub-commands: which kind each one is, and its documents.

A run directory is recognised by the files the sub-command writes (never by
its name):

=================  ===========================================
kind               files
=================  ===========================================
identify           ``summary.json`` + ``posterior.nc``
predict            ``frequencies.json``
lobes              ``lobes.json`` (+ ``p_stable.npz``, ``lobes.png``)
identifiability    ``identifiability.json``
discrepancy        ``discrepancy.json``
design             ``design.json``
update             ``update.json`` (+ ``posterior.nc``; ``bayes-rcsa update``)
library            ``library.json`` (+ ``population.nc``; ``bayes-rcsa library``)
=================  ===========================================

A directory holding none of them but sub-directories that do (the output of
``bayes-rcsa demo``) stands for those sub-directories.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..errors import DataError

__all__ = ["RunDir", "KINDS", "REQUIRED_KEYS", "detect_kind", "collect_runs"]

# kind -> the file that identifies it (and is loaded as its document)
KINDS = {
    "identify": "summary.json",
    "predict": "frequencies.json",
    "lobes": "lobes.json",
    "identifiability": "identifiability.json",
    "discrepancy": "discrepancy.json",
    "design": "design.json",
    "update": "update.json",
    "library": "library.json",
}


@dataclass(frozen=True)
class RunDir:
    """One output directory of a sub-command.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    path : Path
    document : dict
        The parsed main JSON file (:data:`KINDS` ``[kind]``).
    """

    kind: str
    path: Path
    document: dict

    def file(self, name: str) -> Path | None:
        """``path / name`` if it exists, else ``None``."""
        p = self.path / name
        return p if p.is_file() else None


def detect_kind(path) -> str | None:
    """Kind of the run directory ``path`` (``None`` if it is none of :data:`KINDS`)."""
    path = Path(path)
    if (path / "summary.json").is_file() and (path / "posterior.nc").is_file():
        return "identify"
    for kind, name in KINDS.items():
        if kind != "identify" and (path / name).is_file():
            return kind
    return None


#: kind -> top-level keys its document always has (the writers put them there) and the report relies on.
REQUIRED_KEYS = {
    "identify": ("method", "converged", "parameters", "warnings"),
    "predict": ("predictions", "posterior", "setup"),
    "lobes": ("method", "recommended", "warnings"),
    "update": ("inputs", "ess", "kt_pa", "kr_pa", "cuts", "warnings"),
    "library": ("laws", "setups", "stage2", "outliers", "warnings"),
}


def _first_nan(value, where: str = "") -> str | None:
    """The key path of the first NaN or infinity in ``value`` (None if there is none)."""
    if isinstance(value, float) and not math.isfinite(value):
        return where or "(top level)"
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = ((f"[{i}]", v) for i, v in enumerate(value))
    else:
        return None
    for k, v in items:
        found = _first_nan(v, f"{where}{'' if str(k).startswith('[') or not where else '.'}{k}")
        if found:
            return found
    return None


def _load(kind: str, path: Path) -> RunDir:
    f = path / KINDS[kind]
    try:
        text = f.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{f}: cannot read it ({exc.strerror if isinstance(exc, OSError) else 'not UTF-8'})") from None
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise DataError(f"{f}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise DataError(f"{f}: expected a JSON object, got {type(doc).__name__}")
    missing = [k for k in REQUIRED_KEYS.get(kind, ()) if k not in doc]
    if missing:
        raise DataError(f"{f}: missing key(s) {', '.join(repr(k) for k in missing)} that every {kind} run writes "
                        "(an incomplete or edited file; rerun the command)")
    bad = _first_nan(doc)
    if bad:
        # the writers never write NaN (strict JSON): the file was edited or damaged, and a report would show it
        raise DataError(f"{f}: key {bad!r} is NaN or infinite (the commands write null for a missing value; "
                        "rerun the command)")
    return RunDir(kind, path, doc)


def collect_runs(paths: Sequence) -> list[RunDir]:
    """The run directories named by ``paths`` (a demo directory expands to its sub-directories).

    Raises
    ------
    DataError
        A path that is not a directory, holds no output of a sub-command, or
        a malformed JSON file.
    """
    runs: list[RunDir] = []
    for p in paths:
        p = Path(p)
        if not p.is_dir():
            raise DataError(f"{p}: not a directory (expected the output directory of a bayes-rcsa command)")
        kind = detect_kind(p)
        if kind is not None:
            runs.append(_load(kind, p))
            continue
        found = [(detect_kind(c), c) for c in sorted(p.iterdir()) if c.is_dir()]
        found = [(k, c) for k, c in found if k is not None]
        if not found:
            raise DataError(f"{p}: no output of a bayes-rcsa command found (expected one of "
                            f"{', '.join(sorted(set(KINDS.values()) | {'posterior.nc'}))} here or in a sub-directory)")
        runs += [_load(k, c) for k, c in found]
    return runs
