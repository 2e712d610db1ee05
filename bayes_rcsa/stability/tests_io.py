"""Cutting-test files for lobe validation (``bayes-rcsa lobes --tests``).

CSV with a header naming the columns ``spindle_speed_rpm,depth_m,outcome``
(any order, case-insensitive, ``#`` comments allowed); ``outcome`` is
``stable`` or ``chatter``.  Depths in metres.
"""

from __future__ import annotations

import csv
import io as _io
import math
from pathlib import Path

import numpy as np

from ..errors import DataError

__all__ = ["read_cutting_tests"]


def read_cutting_tests(path):
    """Read a cutting-test CSV.

    Returns
    -------
    speed_rpm (n,), depth_m (n,), stable (n,) bool
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
    need = ("spindle_speed_rpm", "depth_m", "outcome")
    missing = [c for c in need if c not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {','.join(header)})")
    col = {c: header.index(c) for c in need}
    speed, depth, stable = [], [], []
    for lineno, line in rows[1:]:
        cells = next(csv.reader(_io.StringIO(line)))
        if len(cells) != len(header):
            raise DataError(f"{path}:{lineno}: {len(cells)} fields, expected {len(header)}")
        try:
            s = float(cells[col["spindle_speed_rpm"]])
            d = float(cells[col["depth_m"]])
        except ValueError:
            raise DataError(f"{path}:{lineno}: spindle_speed_rpm and depth_m must be numbers") from None
        if not (math.isfinite(s) and s > 0 and math.isfinite(d) and d > 0):
            raise DataError(f"{path}:{lineno}: expected speed > 0 rpm and depth > 0 m, got {s!r}, {d!r}")
        o = cells[col["outcome"]].strip().lower()
        if o not in ("stable", "chatter"):
            raise DataError(f"{path}:{lineno}: outcome {cells[col['outcome']]!r}, expected 'stable' or 'chatter'")
        speed.append(s)
        depth.append(d)
        stable.append(o == "stable")
    if not speed:
        raise DataError(f"{path}: no cutting tests after the header")
    return np.array(speed), np.array(depth), np.array(stable, dtype=bool)
