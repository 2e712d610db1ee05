"""Does a posterior belong to the setup it is used with?  Geometry and materials, key by key.

``identify`` records the geometry and materials of its setup (holder, tools,
their materials) in summary.json as ``setup_geometry``.  ``predict`` and
``lobes`` compare the setup they are given with that record: a changed tool
modulus, length or diameter would push the contact identified for one tool
through the model of another, silently.  Each differing key is one warning
line naming the key and both values.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

__all__ = ["setup_geometry", "geometry_differences", "posterior_setup_warnings", "GEOMETRY_KEY", "GEOMETRY_RTOL"]

#: Key of the record in summary.json.
GEOMETRY_KEY = "setup_geometry"
#: Relative tolerance of the comparison (a TOML round trip is exact; this only absorbs printing).
GEOMETRY_RTOL = 1e-9


def _flatten(value, prefix: str, out: dict) -> None:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(v, f"{prefix}.{k}" if prefix else str(k), out)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _flatten(v, f"{prefix}[{i}]", out)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        out[prefix] = float(value)
    elif isinstance(value, str):
        out[prefix] = value


def setup_geometry(setup) -> dict:
    """``{"holder.segments[0].length": 0.02, "tools.tool.material.youngs_modulus": 5.8e11, ...}`` of ``setup``."""
    out: dict = {}
    _flatten({"holder": setup.holder, "tools": dict(setup.tools)}, "", out)
    return out


def geometry_differences(recorded: dict, current: dict) -> list[tuple[str, object, object]]:
    """(key, recorded, current) for every key whose value differs or that only one side has."""
    diffs = []
    for key in sorted(set(recorded) | set(current)):
        a, b = recorded.get(key), current.get(key)
        if isinstance(a, float) and isinstance(b, float):
            if math.isclose(a, b, rel_tol=GEOMETRY_RTOL, abs_tol=0.0):
                continue
        elif a == b:
            continue
        diffs.append((key, a, b))
    return diffs


def posterior_setup_warnings(posterior_path, setup, summary_document=None) -> list[str]:
    """Warnings for each geometry or material key of ``setup`` that differs from the one identified.

    The record is read from summary.json beside ``posterior_path`` (or from
    ``summary_document``, that file's content when already loaded); without
    it (a posterior moved on its own, or written before the record existed)
    nothing can be compared and the list is empty.
    """
    summary = Path(posterior_path).with_name("summary.json") if posterior_path is not None else "summary.json"
    try:
        document = (json.loads(summary.read_text(encoding="utf-8")) if summary_document is None
                    else summary_document)
        recorded = document.get(GEOMETRY_KEY)
    except (OSError, ValueError, AttributeError):
        return []
    if not isinstance(recorded, dict):
        return []
    diffs = geometry_differences(recorded, setup_geometry(setup))
    out = []
    for key, a, b in diffs[:5]:
        out.append(f"{setup.path}: {key} = {'(absent)' if b is None else b!r} differs from {'(absent)' if a is None else a!r} "
                   f"in the setup {posterior_path} was identified with; the contact identified for one geometry is "
                   "used with another (identify again with this setup, or use the setup of the identification)")
    if len(diffs) > 5:
        out.append(f"{setup.path}: {len(diffs) - 5} more geometry or material key(s) differ from the identification's "
                   f"(see {summary} setup_geometry)")
    return out
