"""Parser of the setup file (TOML) into :class:`bayes_rcsa.io.setup.Setup`.

Strict about the tables it interprets (unknown keys there are typos until
proven otherwise), lenient about the rest: unknown top-level keys and tables
are kept in ``Setup.extra`` for later stages.  Every message starts with the
setup file and names the table and key, e.g.
``setup.toml: [holder] segments[1].inner_diameter = -0.01: expected ...``.
"""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path
from typing import Any, Callable

from ..errors import DataError, SetupError
from ..model.geometry import Holder, HolderSegment, Tool, ToolSegment, check_clamping, holder_segments
from ..model.materials import Material
from .frf import FRF_SUFFIXES, read_frf
from .receptance_csv import read_spindle_csv
from .setup import ContactSpec, MeasurementSpec, Setup

__all__ = ["parse_setup"]

_KNOWN = ("name", "materials", "spindle", "holder", "tool", "tools", "contact", "measurement")
_DIRECTIONS = ("x", "y")
_REQUIRED = object()
_POSITIVE_M = "a finite number > 0 (m)"


class _Ctx:
    """The setup file being parsed: its name for messages and its directory."""

    def __init__(self, path: Path):
        self.file = str(path)
        self.dir = path.parent

    def error(self, where: str, message: str) -> SetupError:
        return SetupError(f"{self.file}: {where}: {message}")

    def bad(self, where: str, key: str, value: Any, expected: str) -> SetupError:
        return SetupError(f"{self.file}: {where} {key} = {value!r}: expected {expected}")

    def missing(self, where: str, key: str, expected: str) -> SetupError:
        return SetupError(f"{self.file}: {where} missing required key {key!r} ({expected})")

    def resolve(self, name: str) -> Path:
        # abspath, not resolve(): keep the user's symlinked layout in messages.
        return Path(os.path.abspath(self.dir / name))


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _table(ctx: _Ctx, parent: dict, key: str, where: str, required: bool = True) -> dict | None:
    v = parent.get(key)
    if v is None:
        if required:
            raise ctx.error(where, "missing required table (see docs/setup.example.toml)")
        return None
    if not isinstance(v, dict):
        raise ctx.error(where, f"expected a table, found {type(v).__name__} {v!r}")
    return v


def _check_keys(ctx: _Ctx, tbl: dict, where: str, allowed: tuple[str, ...]) -> None:
    unknown = [k for k in tbl if k not in allowed]
    if unknown:
        raise ctx.error(where, f"unknown key(s) {', '.join(repr(k) for k in unknown)}; allowed: {', '.join(allowed)}")


def _num(
    ctx: _Ctx, tbl: dict, where: str, key: str, ok: Callable[[float], bool], expected: str,
    default=_REQUIRED, label: str | None = None,
) -> float:
    """A finite number ``tbl[key]`` satisfying ``ok``; ``label`` names it in messages."""
    label = label or key
    if key not in tbl:
        if default is _REQUIRED:
            raise ctx.missing(where, label, expected)
        return default
    v = tbl[key]
    if not (_is_number(v) and ok(float(v))):
        raise ctx.bad(where, label, v, expected)
    return float(v)


def _str(ctx: _Ctx, tbl: dict, where: str, key: str, expected: str, default=_REQUIRED) -> str:
    if key not in tbl:
        if default is _REQUIRED:
            raise ctx.missing(where, key, expected)
        return default
    v = tbl[key]
    if not isinstance(v, str) or not v.strip():
        raise ctx.bad(where, key, v, expected)
    return v


def _positive(x: float) -> bool:
    return x > 0


def _table_list(ctx: _Ctx, tbl: dict, where: str, key: str, expected: str) -> list[dict]:
    if key not in tbl:
        raise ctx.missing(where, key, expected)
    v = tbl[key]
    if not isinstance(v, list) or not v or not all(isinstance(e, dict) for e in v):
        raise ctx.bad(where, key, v, expected)
    return v


def _wrap(ctx: _Ctx, where: str, build: Callable[[], Any]):
    """Run a model constructor, prefixing its SetupError with file and table."""
    try:
        return build()
    except SetupError as exc:
        raise ctx.error(where, str(exc)) from exc


def _bounds(ctx: _Ctx, tbl: dict, where: str, key: str, unit: str, default=_REQUIRED) -> tuple[float, float] | None:
    expected = f"[lo, hi] with 0 < lo < hi ({unit})"
    if key not in tbl:
        if default is _REQUIRED:
            raise ctx.missing(where, key, expected)
        return default
    v = tbl[key]
    if not (isinstance(v, list) and len(v) == 2 and all(_is_number(e) for e in v) and 0 < v[0] < v[1]):
        raise ctx.bad(where, key, v, expected)
    return (float(v[0]), float(v[1]))


def _damping(ctx: _Ctx, tbl: dict, where: str, key: str, unit: str) -> float | tuple[float, float]:
    v = tbl.get(key, 0.0)
    if _is_number(v) and v >= 0:
        return float(v)
    if isinstance(v, list):
        return _bounds(ctx, tbl, where, key, unit)
    raise ctx.bad(where, key, v, f"a number >= 0 (fixed) or [lo, hi] with 0 < lo < hi (sampled), {unit}")


# --------------------------------------------------------------------------- tables


def _materials(ctx: _Ctx, doc: dict) -> dict[str, Material]:
    tbl = _table(ctx, doc, "materials", "[materials]")
    if not tbl:
        raise ctx.error("[materials]", "no material defined; expected [materials.NAME] tables")
    out = {}
    for name, m in tbl.items():
        where = f"[materials.{name}]"
        if not isinstance(m, dict):
            raise ctx.error(where, f"expected a table, found {m!r}")
        _check_keys(ctx, m, where, ("youngs_modulus", "density", "poisson_ratio", "loss_factor"))
        e = _num(ctx, m, where, "youngs_modulus", _positive, "a finite number > 0 (Pa)")
        rho = _num(ctx, m, where, "density", _positive, "a finite number > 0 (kg/m^3)")
        nu = _num(ctx, m, where, "poisson_ratio", lambda x: -1 < x < 0.5, "a number in (-1, 0.5)")
        eta = _num(ctx, m, where, "loss_factor", lambda x: x >= 0, "a finite number >= 0", default=0.0)
        out[name] = _wrap(ctx, where, lambda: Material(e, rho, nu, eta, name=name))
    return out


def _material_ref(ctx: _Ctx, tbl: dict, where: str, materials: dict[str, Material]) -> Material:
    name = _str(ctx, tbl, where, "material", "the name of a [materials.NAME] table")
    if name not in materials:
        defined = ", ".join(sorted(materials))
        raise ctx.bad(where, "material", name, f"a defined material (unknown material; defined: {defined})")
    return materials[name]


def _holder(ctx: _Ctx, doc: dict, materials: dict[str, Material]) -> Holder:
    where = "[holder]"
    tbl = _table(ctx, doc, "holder", where)
    _check_keys(ctx, tbl, where, ("material", "segments"))
    material = _material_ref(ctx, tbl, where, materials)
    segs = []
    keys = ("length", "outer_diameter", "inner_diameter")
    listed = _table_list(ctx, tbl, where, "segments", "a non-empty array of {length, outer_diameter, inner_diameter} tables")
    for i, seg in enumerate(listed):
        _check_keys(ctx, seg, f"{where} segments[{i}]", keys)
        label = {k: f"segments[{i}].{k}" for k in keys}
        length = _num(ctx, seg, where, "length", _positive, _POSITIVE_M, label=label["length"])
        outer = _num(ctx, seg, where, "outer_diameter", _positive, _POSITIVE_M, label=label["outer_diameter"])
        inner = _num(ctx, seg, where, "inner_diameter", lambda x: 0 <= x < outer,
                     f"0 <= inner_diameter < outer_diameter ({outer!r} m)", default=0.0, label=label["inner_diameter"])
        segs.append(_wrap(ctx, f"{where} segments[{i}]", lambda: HolderSegment(length, outer, inner)))
    return _wrap(ctx, where, lambda: Holder(material, tuple(segs)))


def _tool(ctx: _Ctx, tbl: dict, where: str, name: str, materials: dict[str, Material], allow_name: bool) -> Tool:
    _check_keys(ctx, tbl, where, ("material", "total_length", "segments") + (("name",) if allow_name else ()))
    material = _material_ref(ctx, tbl, where, materials)
    total = _num(ctx, tbl, where, "total_length", _positive, _POSITIVE_M)
    segs = []
    keys = ("length", "diameter", "diameter_ratio")
    listed = _table_list(ctx, tbl, where, "segments", "a non-empty array of {length, diameter, diameter_ratio} tables")
    for i, seg in enumerate(listed):
        _check_keys(ctx, seg, f"{where} segments[{i}]", keys)
        label = {k: f"segments[{i}].{k}" for k in keys}
        length = _num(ctx, seg, where, "length", _positive, _POSITIVE_M, label=label["length"])
        diameter = _num(ctx, seg, where, "diameter", _positive, _POSITIVE_M, label=label["diameter"])
        ratio = _num(ctx, seg, where, "diameter_ratio", lambda x: 0 < x <= 1, "0 < diameter_ratio <= 1", default=1.0,
                     label=label["diameter_ratio"])
        segs.append(_wrap(ctx, f"{where} segments[{i}]", lambda: ToolSegment(length, diameter, ratio)))
    return _wrap(ctx, where, lambda: Tool(material, total, tuple(segs), name=name))


def _tools(ctx: _Ctx, doc: dict, materials: dict[str, Material]) -> dict[str, Tool]:
    tools: dict[str, Tool] = {}
    single = _table(ctx, doc, "tool", "[tool]", required=False)
    if single is not None:
        name = _str(ctx, single, "[tool]", "name", "a non-empty string", default="tool")
        tools[name] = _tool(ctx, single, "[tool]", name, materials, allow_name=True)
    several = _table(ctx, doc, "tools", "[tools]", required=False)
    for name, tbl in (several or {}).items():
        where = f"[tools.{name}]"
        if not isinstance(tbl, dict):
            raise ctx.error(where, f"expected a table, found {tbl!r}")
        if name in tools:
            raise ctx.error(where, f"tool name {name!r} is already used by [tool]")
        tools[name] = _tool(ctx, tbl, where, name, materials, allow_name=False)
    if not tools:
        raise ctx.error("[tool]", "missing required table (or [tools.NAME] tables for several tools)")
    return tools


def _spindle_files(ctx: _Ctx, doc: dict) -> dict[str, Path]:
    where = "[spindle]"
    tbl = _table(ctx, doc, "spindle", where)
    _check_keys(ctx, tbl, where, _DIRECTIONS)
    if not tbl:
        raise ctx.error(where, "expected at least one receptance file: x = \"spindle_x.csv\" and/or y = ...")
    expected = "a CSV file name relative to the setup file"
    return {d: ctx.resolve(_str(ctx, tbl, where, d, expected)) for d in _DIRECTIONS if d in tbl}


def _contact(ctx: _Ctx, doc: dict, holder: Holder, tools: dict[str, Tool]) -> ContactSpec:
    where = "[contact]"
    tbl = _table(ctx, doc, "contact", where)
    _check_keys(ctx, tbl, where, (
        "translational_stiffness", "rotational_stiffness", "growth_bound", "clamping_range",
        "translational_damping", "rotational_damping",
    ))
    spec = ContactSpec(
        translational_stiffness=_bounds(ctx, tbl, where, "translational_stiffness", "N/m"),
        rotational_stiffness=_bounds(ctx, tbl, where, "rotational_stiffness", "N m/rad"),
        growth_bound=_num(ctx, tbl, where, "growth_bound", lambda x: x >= 0, "a finite number >= 0",
                          default=ContactSpec.__dataclass_fields__["growth_bound"].default),
        clamping_range=_bounds(ctx, tbl, where, "clamping_range", "m", default=None),
        translational_damping=_damping(ctx, tbl, where, "translational_damping", "N s/m"),
        rotational_damping=_damping(ctx, tbl, where, "rotational_damping", "N m s/rad"),
    )
    if spec.clamping_range is not None:
        for tool in tools.values():
            for cl in spec.clamping_range:
                try:
                    check_clamping(holder, tool, cl)
                except SetupError as exc:
                    raise ctx.error(f"{where} clamping_range = {list(spec.clamping_range)!r}", str(exc)) from exc
    return spec


def _measurements(ctx, doc, holder, tools, spindle_dirs, contact, load_data) -> tuple[MeasurementSpec, ...]:
    raw = doc.get("measurement")
    expected = "one [[measurement]] table per FRF file, with file and clamping_length"
    if raw is None:
        raise ctx.error("[[measurement]]", f"missing; expected {expected}")
    if not isinstance(raw, list) or not raw or not all(isinstance(m, dict) for m in raw):
        raise ctx.error("measurement", f"found {raw!r}; expected {expected}")
    out = []
    for i, m in enumerate(raw):
        where = f"[[measurement]] {i}" + (f" ({m['file']})" if isinstance(m.get("file"), str) else "")
        _check_keys(ctx, m, where, ("file", "clamping_length", "direction", "tool"))
        file = _str(ctx, m, where, "file", "an FRF file name relative to the setup file")
        if Path(file).suffix.lower() not in FRF_SUFFIXES:
            raise ctx.bad(where, "file", file, f"a file ending in one of {', '.join(FRF_SUFFIXES)}")
        cl = _num(ctx, m, where, "clamping_length", _positive, _POSITIVE_M)
        direction = _str(ctx, m, where, "direction", "\"x\" or \"y\"", default="x")
        if direction not in _DIRECTIONS:
            raise ctx.bad(where, "direction", direction, "\"x\" or \"y\"")
        if direction not in spindle_dirs:
            raise ctx.bad(where, "direction", direction,
                          f"a direction with a spindle file; [spindle] has no {direction!r} file")
        if "tool" in m:
            tool = _str(ctx, m, where, "tool", "the name of a tool")
            if tool not in tools:
                defined = ", ".join(sorted(tools))
                raise ctx.bad(where, "tool", tool, f"a defined tool (unknown tool; defined: {defined})")
        elif len(tools) == 1:
            tool = next(iter(tools))
        else:
            raise ctx.missing(where, "tool", f"the setup defines several tools: {', '.join(sorted(tools))}")
        try:
            check_clamping(holder, tools[tool], cl)
            holder_segments(holder, tools[tool], cl)  # also checks the shank fits the bore
        except SetupError as exc:
            raise ctx.error(where, str(exc)) from exc
        if contact.clamping_range is not None:
            lo, hi = contact.clamping_range
            if not lo <= cl <= hi:
                raise ctx.bad(where, "clamping_length", cl,
                              f"a value within [contact] clamping_range [{lo!r}, {hi!r}] m")
        path = ctx.resolve(file)
        frf = None
        if load_data:
            try:
                frf = read_frf(path)
            except DataError as exc:
                raise DataError(f"{ctx.file}: {where} file = {file!r}: {exc}") from exc
        out.append(MeasurementSpec(file=path, clamping_length=cl, direction=direction, tool=tool, frf=frf))
    return tuple(out)


def _load_document(path: Path) -> dict:
    if not path.exists():
        raise SetupError(f"{path}: setup file not found (no such file)")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SetupError(f"{path}: setup file is not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    except OSError as exc:
        raise SetupError(f"{path}: cannot read setup file: {exc.strerror or exc}") from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        # tomllib's message ends with "(at line L, column C)".
        raise SetupError(f"{path}: malformed TOML: {exc}") from exc


def parse_setup(path: Path, load_data: bool, load_spindle: bool | None = None) -> Setup:
    """Parse and validate a setup file.

    Parameters
    ----------
    path : Path
        The TOML setup file; data file names in it are relative to its directory.
    load_data : bool
        Read the measurement files (and, by default, the spindle files).
        With ``False`` only the setup itself is validated; every
        ``MeasurementSpec.frf`` is ``None``.
    load_spindle : bool, optional
        Read the spindle receptance files; defaults to ``load_data``.  With
        ``False`` ``Setup.spindle`` is empty.  ``load_data=False,
        load_spindle=True`` is what a forward simulation needs: the model
        without (possibly not yet existing) measurements.

    Returns
    -------
    Setup

    Raises
    ------
    SetupError
        Missing or malformed file, missing/unknown/invalid keys, unknown
        material or tool, clamping lengths outside the holder bore, the tool
        or ``[contact] clamping_range``, a measurement direction without a
        spindle file.
    DataError
        A referenced data file is missing or invalid (message names the
        setup key and the data file).
    """
    path = Path(path)
    ctx = _Ctx(path)
    doc = _load_document(path)
    name = _str(ctx, doc, "(top level)", "name", "a non-empty string", default=path.stem)
    materials = _materials(ctx, doc)
    holder = _holder(ctx, doc, materials)
    tools = _tools(ctx, doc, materials)
    spindle_files = _spindle_files(ctx, doc)
    contact = _contact(ctx, doc, holder, tools)
    measurements = _measurements(ctx, doc, holder, tools, spindle_files, contact, load_data)
    spindle = {}
    if load_data if load_spindle is None else load_spindle:
        for direction, file in spindle_files.items():
            try:
                spindle[direction] = read_spindle_csv(file)
            except DataError as exc:
                raise DataError(f"{ctx.file}: [spindle] {direction} = {doc['spindle'][direction]!r}: {exc}") from exc
    extra = {k: v for k, v in doc.items() if k not in _KNOWN}
    return Setup(
        name=name,
        path=path,
        materials=materials,
        holder=holder,
        tools=tools,
        spindle=spindle,
        contact=contact,
        measurements=measurements,
        extra=extra,
    )
