"""Cutting-test files (``bayes-rcsa lobes --tests``, ``bayes-rcsa update --cuts``).

CSV with a header naming the columns ``spindle_speed_rpm,depth_m,outcome``
(any order, case-insensitive, ``#`` comments allowed); ``outcome`` is
``stable`` or ``chatter``.  Depths in metres.

Optional columns, so that cuts of different setups combine in one file
(an empty cell means "the command's value"):

- ``clamping_length_m``: clamping length of the tool in the holder (m);
- ``radial_immersion``: radial depth of cut / tool diameter, in (0, 1];
- ``feed_direction``: ``x`` or ``y``, the machine axis the tool advances along;
- ``tool``: name of a ``[tool]`` of the setup.

Files with the three required columns only stay valid.
"""

from __future__ import annotations

import csv
import io as _io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError

__all__ = ["read_cutting_tests", "read_cut_table", "CutTable", "OPTIONAL_COLUMNS"]

REQUIRED_COLUMNS = ("spindle_speed_rpm", "depth_m", "outcome")
#: Optional columns and what an empty cell or a missing column means (the command's value).
OPTIONAL_COLUMNS = ("clamping_length_m", "radial_immersion", "feed_direction", "tool")


@dataclass(frozen=True)
class CutTable:
    """The rows of a cutting-test file.

    Attributes
    ----------
    path : Path
    line : (n,) int, line number of each row in the file (for messages)
    speed_rpm : (n,) rpm
    depth_m : (n,) m, axial depth of cut
    stable : (n,) bool, True for ``stable``, False for ``chatter``
    clamping_length_m : (n,) m, NaN where not given
    radial_immersion : (n,) in (0, 1], NaN where not given
    feed_direction : tuple of str or None per row ("x", "y")
    tool : tuple of str or None per row
    """

    path: Path
    line: np.ndarray
    speed_rpm: np.ndarray
    depth_m: np.ndarray
    stable: np.ndarray
    clamping_length_m: np.ndarray
    radial_immersion: np.ndarray
    feed_direction: tuple
    tool: tuple

    @property
    def n_cuts(self) -> int:
        return int(self.speed_rpm.size)

    def where(self, i: int) -> str:
        """``FILE:LINE`` of row ``i``."""
        return f"{self.path}:{int(self.line[i])}"


def _optional_number(cell: str, name: str, where: str, lo: float, hi: float) -> float:
    if not cell.strip():
        return math.nan
    try:
        v = float(cell)
    except ValueError:
        raise DataError(f"{where}: {name} {cell!r} must be a number") from None
    if not (math.isfinite(v) and lo < v <= hi):
        raise DataError(f"{where}: {name} {cell!r}: expected a number in ({lo:g}, {hi:g}]")
    return v


def read_cut_table(path) -> CutTable:
    """Read a cutting-test CSV with its optional columns (module docstring).

    Raises
    ------
    DataError
        Naming the file and line: missing columns, wrong field counts, non-numbers, an outcome other
        than ``stable``/``chatter``, a non-positive speed or depth, an optional value out of range.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a UTF-8 text file") from None
    rows = [(i + 1, line) for i, line in enumerate(text.splitlines()) if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        raise DataError(f"{path}: no header row (expected spindle_speed_rpm,depth_m,outcome)")
    header = [h.strip().lower() for h in next(csv.reader(_io.StringIO(rows[0][1])))]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {','.join(header)})")
    col = {c: header.index(c) for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in header}
    lines, speed, depth, stable, length, immersion, feed, tool = [], [], [], [], [], [], [], []
    for lineno, line in rows[1:]:
        where = f"{path}:{lineno}"
        cells = next(csv.reader(_io.StringIO(line)))
        if [c.strip().lower() for c in cells] == header:
            raise DataError(f"{where}: the header row repeats in mid-file (two tables joined?); keep one header "
                            "at the top")
        if len(cells) != len(header):
            raise DataError(f"{where}: {len(cells)} fields, expected {len(header)}")
        try:
            s = float(cells[col["spindle_speed_rpm"]])
            d = float(cells[col["depth_m"]])
        except ValueError:
            raise DataError(f"{where}: spindle_speed_rpm and depth_m must be numbers") from None
        if not (math.isfinite(s) and s > 0 and math.isfinite(d) and d > 0):
            raise DataError(f"{where}: expected speed > 0 rpm and depth > 0 m, got {s!r}, {d!r}")
        o = cells[col["outcome"]].strip().lower()
        if o not in ("stable", "chatter"):
            raise DataError(f"{where}: outcome {cells[col['outcome']]!r}, expected 'stable' or 'chatter'")
        get = lambda name: cells[col[name]].strip() if name in col else ""  # noqa: E731
        length.append(_optional_number(get("clamping_length_m"), "clamping_length_m", where, 0.0, math.inf))
        immersion.append(_optional_number(get("radial_immersion"), "radial_immersion", where, 0.0, 1.0))
        f = get("feed_direction").lower()
        if f not in ("", "x", "y"):
            raise DataError(f"{where}: feed_direction {get('feed_direction')!r}, expected 'x' or 'y'")
        feed.append(f or None)
        tool.append(get("tool") or None)
        lines.append(lineno)
        speed.append(s)
        depth.append(d)
        stable.append(o == "stable")
    if not speed:
        raise DataError(f"{path}: no cutting tests after the header")
    return CutTable(path, np.array(lines), np.array(speed), np.array(depth), np.array(stable, dtype=bool),
                    np.array(length), np.array(immersion), tuple(feed), tuple(tool))


def read_cutting_tests(path):
    """Read a cutting-test CSV (the three required columns; optional columns are checked and ignored).

    Returns
    -------
    speed_rpm (n,), depth_m (n,), stable (n,) bool
    """
    t = read_cut_table(path)
    return t.speed_rpm, t.depth_m, t.stable
