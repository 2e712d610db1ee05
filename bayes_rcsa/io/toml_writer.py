"""A small TOML emitter for setup-like documents (the standard library only reads TOML).

Layout rules, chosen so that generated setup files look like the example in
docs/setup.example.toml:

- a dict value becomes a ``[table]`` (nested: ``[a.b]``);
- a list of dicts at the top level becomes an array of tables
  (``[[measurement]]``); deeper down (e.g. ``segments``) it becomes an array
  of inline tables, one per line;
- floats are written with ``repr`` (shortest exact form), so
  ``tomllib.loads(dump_toml(d)) == d`` holds bit for bit;
- keys whose value is ``None`` are omitted (TOML has no null).
"""

from __future__ import annotations

import math
import numbers
import re
from pathlib import PurePath
from typing import Any

__all__ = ["dump_toml", "setup_document"]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def _key(k) -> str:
    if not isinstance(k, str):
        raise TypeError(f"TOML keys must be strings, got {k!r}")
    return k if _BARE_KEY.match(k) else _string(k)


def _string(s: str) -> str:
    out = []
    for ch in s:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _float(x: float) -> str:
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    text = repr(float(x))
    # repr writes "1e-05" / "1e+16" (valid TOML); only a bare integer form would not be.
    return text if any(c in text for c in ".eE") else text + ".0"


def _is_table(v) -> bool:
    return isinstance(v, dict)


def _is_table_array(v) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(e, dict) for e in v)


def _value(v, indent: str = "") -> str:
    """Inline representation of a value (scalars, arrays, inline tables)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        return _float(float(v))
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, PurePath):
        return _string(v.as_posix())
    if isinstance(v, dict):
        items = [f"{_key(k)} = {_value(x)}" for k, x in v.items() if x is not None]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    if hasattr(v, "tolist") and not isinstance(v, (list, tuple)):  # numpy arrays
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        if any(e is None for e in v):
            raise TypeError("TOML arrays cannot hold None")
        if _is_table_array(v):
            inner = indent + "  "
            return "[\n" + "".join(f"{inner}{_value(e, inner)},\n" for e in v) + indent + "]"
        return "[" + ", ".join(_value(e, indent) for e in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} value {v!r} as TOML")


def _emit_table(lines: list[str], table: dict, path: list[str], root: bool) -> None:
    scalars, tables, arrays = [], [], []
    for k, v in table.items():
        if v is None:
            continue
        if _is_table(v):
            tables.append((k, v))
        elif root and _is_table_array(v):
            arrays.append((k, v))
        else:
            scalars.append((k, v))
    for k, v in scalars:
        lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in tables:
        sub = path + [_key(k)]
        # A table holding only sub-tables needs no header of its own.
        if not all(_is_table(x) for x in v.values() if x is not None) or not v:
            lines.extend(["", f"[{'.'.join(sub)}]"])
        _emit_table(lines, v, sub, root=False)
    for k, v in arrays:
        for entry in v:
            lines.extend(["", f"[[{'.'.join(path + [_key(k)])}]]"])
            for ek, ev in entry.items():
                if ev is not None:
                    lines.append(f"{_key(ek)} = {_value(ev)}")


def dump_toml(data: dict[str, Any]) -> str:
    """Serialise a dict to TOML text.

    Parameters
    ----------
    data : dict
        Values may be str, bool, int, float (numpy scalars and arrays too),
        pathlib paths (written as POSIX strings), lists, and nested dicts.

    Returns
    -------
    str
        TOML that :func:`tomllib.loads` parses back to ``data`` (with tuples
        and arrays as lists, paths as strings and ``None`` entries dropped).

    Raises
    ------
    TypeError
        For values TOML cannot represent (e.g. ``None`` inside an array).
    """
    if not isinstance(data, dict):
        raise TypeError("dump_toml expects a dict at the top level")
    lines: list[str] = []
    _emit_table(lines, data, [], root=True)
    return "\n".join(lines).lstrip("\n") + "\n"


def setup_document(setup, relative_to=None) -> dict[str, Any]:
    """The TOML document of a parsed :class:`~bayes_rcsa.io.setup.Setup`.

    ``load_setup`` of ``dump_toml(setup_document(s, d))`` written into
    directory ``d`` gives back the same setup: geometry, materials, contact
    priors, measurements, the spindle files, the later stages' tables
    (``[likelihood]``, ``[priors]``, ``[sampler]``) and the ``[model]`` table.

    Parameters
    ----------
    setup : Setup
    relative_to : path-like, optional
        Directory the data file names are written relative to (default: the
        setup file's directory).  Files outside it keep absolute paths.

    Returns
    -------
    dict
        For :func:`dump_toml`.
    """
    import os
    from pathlib import Path

    base = Path(relative_to if relative_to is not None else setup.path.parent).absolute()

    def rel(path) -> str:
        p = Path(path).absolute()
        try:
            return p.relative_to(base).as_posix()
        except ValueError:
            return Path(os.path.relpath(p, base)).as_posix() if p.anchor == base.anchor else p.as_posix()

    def material(m) -> dict:
        return {"youngs_modulus": m.youngs_modulus, "density": m.density, "poisson_ratio": m.poisson_ratio,
                "loss_factor": m.loss_factor}

    materials = {name: material(m) for name, m in setup.materials.items()}

    def material_name(m) -> str:
        for name, known in setup.materials.items():
            if known == m:
                return name
        raise ValueError(f"material {m!r} is not among the setup's materials")

    def tool(t) -> dict:
        return {"material": material_name(t.material), "total_length": t.total_length,
                "segments": [{"length": s.length, "diameter": s.diameter, "diameter_ratio": s.diameter_ratio}
                             for s in t.segments]}

    c = setup.contact

    def pair(v):
        return list(v) if isinstance(v, tuple) else v

    doc: dict[str, Any] = {
        "name": setup.name,
        "materials": materials,
        "spindle": {d: rel(path) for d, path in setup.spindle_files.items()},
        "holder": {"material": material_name(setup.holder.material),
                   "segments": [{"length": s.length, "outer_diameter": s.outer_diameter,
                                 "inner_diameter": s.inner_diameter} for s in setup.holder.segments]},
        "tools": {name: tool(t) for name, t in setup.tools.items()},
        "contact": {
            "translational_stiffness": list(c.translational_stiffness),
            "rotational_stiffness": list(c.rotational_stiffness),
            "growth_bound": c.growth_bound,
            "clamping_range": None if c.clamping_range is None else list(c.clamping_range),
            "translational_damping": pair(c.translational_damping),
            "rotational_damping": pair(c.rotational_damping),
        },
    }
    for key in ("likelihood", "priors", "sampler"):
        if key in setup.extra:
            doc[key] = setup.extra[key]
    if setup.model_table:
        doc["model"] = setup.model_table
    doc["measurement"] = [{"file": rel(m.file), "clamping_length": m.clamping_length, "direction": m.direction,
                           "tool": m.tool} for m in setup.measurements]
    return doc
