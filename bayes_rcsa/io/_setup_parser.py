"""Parser of the setup file (TOML) into :class:`bayes_rcsa.io.setup.Setup`.

Strict everywhere: unknown keys and unknown top-level tables are typos until
proven otherwise (with a "did you mean" suggestion).  The tables later
stages interpret (``[likelihood]``, ``[priors]``, ``[sampler]``,
``[model]``) are checked for shape and types here and kept in
``Setup.extra``; ``[model]`` is also returned as ``Setup.model_table``.  Every message starts with the
setup file and names the table and key, e.g.
``setup.toml: [holder] segments[1].inner_diameter = -0.01: expected ...``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError, SetupError
from ..model.geometry import Holder, Tool, check_clamping, holder_segments
from ..model.materials import Material
from . import checks
from .frf import FRF_SUFFIXES, read_frf
from .receptance_csv import read_spindle_csv
from .setup import ContactSpec, MeasurementSpec, Setup
from .tables import TableContext as _Ctx
from .tables import bounds as _bounds
from .tables import check_keys as _check_keys
from .tables import check_prior_spec, check_top_level
from .tables import is_number as _is_number
from .tables import load_document
from .tables import number as _num
from .tables import parse_holder, parse_materials, parse_tool
from .tables import string as _str
from .tables import table as _table

__all__ = ["parse_setup"]

# Tables the core parser builds the model from ...
_CORE = ("name", "materials", "spindle", "holder", "tool", "tools", "contact", "measurement")
# ... and tables later stages interpret (kept in Setup.extra; their shape is checked here).
_STAGES = ("likelihood", "priors", "sampler", "model")
_KNOWN = _CORE + _STAGES
_DIRECTIONS = ("x", "y")
_POSITIVE_M = "a finite number > 0 (m)"
_SAMPLER_INTS = ("walkers", "max_steps", "check_every")


def _positive(x: float) -> bool:
    return x > 0


def _damping(ctx: _Ctx, tbl: dict, where: str, key: str, unit: str) -> float | tuple[float, float]:
    v = tbl.get(key, 0.0)
    if _is_number(v) and v >= 0:
        return float(v)
    if isinstance(v, list):
        return _bounds(ctx, tbl, where, key, unit)
    raise ctx.bad(where, key, v, f"a number >= 0 (fixed) or [lo, hi] with 0 < lo < hi (sampled), {unit}")


def _stage_tables(ctx: _Ctx, doc: dict) -> dict:
    """Shape/type checks of ``[likelihood]``, ``[priors]``, ``[sampler]`` and ``[model]``.

    Parameter names, term names and the likelihood's keys are checked by
    the stages that know them (:mod:`bayes_rcsa.inference`,
    :mod:`bayes_rcsa.params`); here every entry must at least have the right
    form, so that no later stage meets e.g. ``likelihood = 5``.
    """
    out = {}
    for key in _STAGES:
        tbl = _table(ctx, doc, key, f"[{key}]", required=False)
        if tbl is not None:
            out[key] = tbl
    for name, spec in out.get("priors", {}).items():
        check_prior_spec(ctx, "[priors]", name, spec)
    sampler = out.get("sampler", {})
    _check_keys(ctx, sampler, "[sampler]", ("start",) + _SAMPLER_INTS)
    for key in _SAMPLER_INTS:
        v = sampler.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
            raise ctx.bad("[sampler]", key, v, "a positive integer")
    if "start" in sampler:
        start = sampler["start"]
        if not isinstance(start, dict):
            raise ctx.bad("[sampler]", "start", start, "a table of parameter = value")
        for k, v in start.items():
            if not _is_number(v):
                raise ctx.bad("[sampler]", f"start.{k}", v, "a finite number")
    model = out.get("model")
    if model is not None:
        terms = model.get("terms", [])
        if not isinstance(terms, list) or not all(isinstance(t, str) and t for t in terms):
            raise ctx.bad("[model]", "terms", terms, 'a list of term names, e.g. ["tip_mass"]')
        if len(set(terms)) != len(terms):
            raise ctx.bad("[model]", "terms", terms, "each term at most once")
        for name, spec in model.items():
            if name != "terms":
                check_prior_spec(ctx, "[model]", name, spec, allow_fixed=True)
    return out


def _check_campaign(setup: Setup) -> None:
    """Campaign-level plausibility of the loaded measurements (see :mod:`bayes_rcsa.io.checks`).

    Raises on identical data at two clamping lengths or on a gross scale or
    sign mismatch against the model over the whole contact prior; warns when
    natural frequencies fall with clamping length.
    """
    entries = [(m.file.name, m.clamping_length, m.direction, m.tool, m.frf.frequency_hz, m.frf.values)
               for m in setup.measurements if m.frf is not None]
    # rad/s first: a file in rad/s also trips every later check, which would name a wrong cause
    for m in setup.measurements:
        if m.frf is None:
            continue
        refs = [(Path(s.source).name, s.frequency_hz, None) for s in setup.spindle.values()]
        refs += [(o.file.name, o.frf.frequency_hz, o.frf.values) for o in setup.measurements
                 if o.frf is not None and o is not m]
        problem = checks.radians_problem(m.file.name, m.frf.frequency_hz, m.frf.values, refs)
        if problem is not None:
            raise DataError(f"{setup.path}: [[measurement]] file = {problem}")
    checks.warn_all(checks.check_campaign(entries))
    if not setup.spindle:
        return
    model = setup.model()
    c = setup.contact
    kx = np.array([c.translational_stiffness[i] for i in (0, 0, 1, 1)])
    kt = np.array([c.rotational_stiffness[i] for i in (0, 1, 0, 1)])
    damping = [d if isinstance(d, float) else d[0] for d in (c.translational_damping, c.rotational_damping)]
    for m in setup.measurements:
        if m.frf is None or m.direction not in setup.spindle:
            continue
        sp = setup.spindle[m.direction].frequency_hz
        f = m.frf.frequency_hz
        inside = np.flatnonzero((f >= sp[0]) & (f <= sp[-1]))
        if inside.size < 3:
            continue  # nothing to compare on; the identification reports the missing overlap
        # The median scale needs no fine grid: <= 64 evenly spread lines keep load_setup fast.
        lines = inside[np.unique(np.linspace(0, inside.size - 1, min(64, inside.size)).round().astype(int))]
        h = model.frf(m.configuration, f[lines], kx, kt, *damping)
        cause = checks.likely_cause(m.frf.values[lines], h)
        if cause is not None:
            raise DataError(f"{setup.path}: [[measurement]] file = {m.file.name!r} ({m.file}): {cause}")


def _holder_type(ctx: _Ctx, doc: dict) -> str | None:
    """The optional ``[holder] type`` (a free string naming the holder type, e.g. ``"ER32"``); ``None`` if absent.

    Any non-blank string is accepted (a shop names its own holder types); an
    empty string or a non-string is refused, naming the key.
    """
    tbl = doc.get("holder")
    if not isinstance(tbl, dict) or "type" not in tbl:
        return None  # a missing or malformed [holder] is reported by parse_holder
    return _str(ctx, tbl, "[holder]", "type", 'a non-empty string naming the holder type, e.g. "ER32"')


def _without_holder_type(doc: dict) -> dict:
    """``doc`` with ``[holder] type`` removed: the shared holder parser knows geometry keys only."""
    tbl = doc.get("holder")
    if not isinstance(tbl, dict) or "type" not in tbl:
        return doc
    return {**doc, "holder": {k: v for k, v in tbl.items() if k != "type"}}


def _tools(ctx: _Ctx, doc: dict, materials: dict[str, Material]) -> dict[str, Tool]:
    tools: dict[str, Tool] = {}
    single = _table(ctx, doc, "tool", "[tool]", required=False)
    if single is not None:
        name = _str(ctx, single, "[tool]", "name", "a non-empty string", default="tool")
        tools[name] = parse_tool(ctx, single, "[tool]", name, materials, allow_name=True)
    several = _table(ctx, doc, "tools", "[tools]", required=False)
    for name, tbl in (several or {}).items():
        where = f"[tools.{name}]"
        if not isinstance(tbl, dict):
            raise ctx.error(where, f"expected a table, found {tbl!r}")
        if name in tools:
            raise ctx.error(where, f"tool name {name!r} is already used by [tool]")
        tools[name] = parse_tool(ctx, tbl, where, name, materials, allow_name=False)
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


#: Geometry lengths (m) at or above which a setup value is taken for millimetres: no holder, tool or clamping
#: length reaches 1 m (the same rule as the command line's length options).
_MM_SUSPECT_M = 1.0


def _geometry_lengths(doc: dict):
    """``(where, key, value)`` of every length of the holder, the tools, the clamping range and the measurements."""
    def segments(where, tbl, keys):
        listed = tbl.get("segments")
        for i, seg in enumerate(listed if isinstance(listed, list) else []):
            if isinstance(seg, dict):
                for key in keys:
                    yield where, f"segments[{i}].{key}", seg.get(key)

    holder = doc.get("holder")
    if isinstance(holder, dict):
        yield from segments("[holder]", holder, ("length", "outer_diameter", "inner_diameter"))
    tools = [("[tool]", doc.get("tool"))]
    if isinstance(doc.get("tools"), dict):
        tools += [(f"[tools.{name}]", t) for name, t in doc["tools"].items()]
    for where, tool in tools:
        if isinstance(tool, dict):
            yield where, "total_length", tool.get("total_length")
            yield from segments(where, tool, ("length", "diameter"))
    contact = doc.get("contact")
    if isinstance(contact, dict) and isinstance(contact.get("clamping_range"), list):
        for k, v in enumerate(contact["clamping_range"]):
            yield "[contact]", f"clamping_range[{k}]", v
    if isinstance(doc.get("measurement"), list):
        for i, m in enumerate(doc["measurement"]):
            if isinstance(m, dict):
                file = f" ({m['file']})" if isinstance(m.get("file"), str) else ""
                yield f"[[measurement]] {i}{file}", "clamping_length", m.get("clamping_length")


def _check_metres(ctx: _Ctx, doc: dict) -> None:
    """Refuse a geometry length that looks like millimetres, naming it and its value in metres."""
    for where, key, v in _geometry_lengths(doc):
        if _is_number(v) and v >= _MM_SUSPECT_M:
            raise SetupError(f"{ctx.file}: {where} {key} = {v!r}: lengths are in metres; did you mean {v * 1e-3:g}?")


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
    doc = load_document(path)
    check_top_level(ctx, doc, _KNOWN)
    _check_metres(ctx, doc)
    name = _str(ctx, doc, "(top level)", "name", "a non-empty string", default=path.stem)
    stage_tables = _stage_tables(ctx, doc)
    materials = parse_materials(ctx, doc)
    holder_type = _holder_type(ctx, doc)
    holder = parse_holder(ctx, _without_holder_type(doc), materials)
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
    setup = Setup(
        name=name,
        path=path,
        materials=materials,
        holder=holder,
        tools=tools,
        spindle=spindle,
        contact=contact,
        measurements=measurements,
        extra=stage_tables,
        model_table=dict(stage_tables.get("model", {})),
        spindle_files=dict(spindle_files),
        holder_type=holder_type,
    )
    if load_data:
        _check_campaign(setup)
    return setup
