"""Public helpers to parse TOML tables strictly, with messages naming file, table and key.

Used by the setup parser (:func:`bayes_rcsa.io.load_setup`) and by other
TOML inputs that share its tables, e.g. the spindle artifact file
(:mod:`bayes_rcsa.spindle.artifact`).  Every helper takes a
:class:`TableContext` (the file being parsed) and a ``where`` label such as
``"[holder]"`` and raises :class:`~bayes_rcsa.errors.SetupError` with a
message of the form ``file: where key = value: expected ...``.

Unknown keys and unknown tables are errors with a "did you mean"
suggestion: in a configuration file a misspelling is far more likely than a
deliberate extra entry, and silently ignoring it changes the result.
"""

from __future__ import annotations

import difflib
import math
import os
import tomllib
from pathlib import Path
from typing import Any, Callable, Iterable

from ..errors import SetupError
from ..model.geometry import Holder, HolderSegment, Tool, ToolSegment
from ..model.materials import Material

__all__ = [
    "REQUIRED",
    "TableContext",
    "load_document",
    "is_number",
    "table",
    "check_keys",
    "check_top_level",
    "number",
    "string",
    "table_list",
    "bounds",
    "wrap",
    "check_prior_spec",
    "parse_materials",
    "parse_holder",
    "parse_tool",
    "material_ref",
    "did_you_mean",
]

#: Sentinel default meaning "the key is required".
REQUIRED = object()
_POSITIVE_M = "a finite number > 0 (m)"
# Plausible physical ranges: outside them the model's linear algebra overflows
# long before a result could mean anything (e.g. youngs_modulus = 1e300).
_MAX_LENGTH_M = 10.0
_YOUNGS_RANGE = (1e6, 1e13)  # Pa: soft polymers ... beyond diamond
_DENSITY_RANGE = (10.0, 1e5)  # kg/m^3: foams ... beyond osmium


class TableContext:
    """The TOML file being parsed: its name for messages and its directory for relative file names.

    Parameters
    ----------
    path : Path
        The TOML file.
    """

    def __init__(self, path: Path):
        self.path = Path(path)
        self.file = str(path)
        self.dir = self.path.parent

    def error(self, where: str, message: str) -> SetupError:
        """``file: where: message``."""
        return SetupError(f"{self.file}: {where}: {message}")

    def bad(self, where: str, key: str, value: Any, expected: str) -> SetupError:
        """``file: where key = value: expected ...``."""
        return SetupError(f"{self.file}: {where} {key} = {value!r}: expected {expected}")

    def missing(self, where: str, key: str, expected: str) -> SetupError:
        """``file: where missing required key 'key' (expected)``."""
        return SetupError(f"{self.file}: {where} missing required key {key!r} ({expected})")

    def resolve(self, name: str) -> Path:
        """Absolute path of a file named relative to the TOML file."""
        # abspath, not resolve(): keep the user's symlinked layout in messages.
        return Path(os.path.abspath(self.dir / name))


def load_document(path, what: str = "setup file") -> dict:
    """Read and parse a UTF-8 TOML file.

    Raises
    ------
    SetupError
        Missing or unreadable file, not UTF-8, malformed TOML (with line and column).
    """
    path = Path(path)
    if not path.exists():
        raise SetupError(f"{path}: {what} not found (no such file)")
    if not path.is_file():
        raise SetupError(f"{path}: {what} is not a regular file")
    from .limits import check_input_size

    check_input_size(path, what, SetupError)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SetupError(f"{path}: {what} is not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    except OSError as exc:
        raise SetupError(f"{path}: cannot read {what}: {exc.strerror or exc}") from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        # tomllib's message ends with "(at line L, column C)".
        raise SetupError(f"{path}: malformed TOML: {exc}") from exc
    except RecursionError:
        raise SetupError(f"{path}: malformed TOML: nested too deeply") from None


def is_number(v) -> bool:
    """A finite int or float (not a bool)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def did_you_mean(name: str, allowed: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest allowed name, or ``""``."""
    close = difflib.get_close_matches(str(name), list(allowed), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def table(ctx: TableContext, parent: dict, key: str, where: str, required: bool = True) -> dict | None:
    """The sub-table ``parent[key]``; ``None`` when absent and not ``required``."""
    v = parent.get(key)
    if v is None:
        if required:
            raise ctx.error(where, "missing required table (see docs/setup.example.toml)")
        return None
    if not isinstance(v, dict):
        raise ctx.error(where, f"expected a table, found {type(v).__name__} {v!r}")
    return v


def check_keys(ctx: TableContext, tbl: dict, where: str, allowed: tuple[str, ...]) -> None:
    """Refuse keys of ``tbl`` outside ``allowed``, suggesting the closest allowed one."""
    unknown = [k for k in tbl if k not in allowed]
    if unknown:
        hint = did_you_mean(unknown[0], allowed)
        raise ctx.error(where, f"unknown key(s) {', '.join(repr(k) for k in unknown)}{hint}; "
                               f"allowed: {', '.join(allowed)}")


def check_top_level(ctx: TableContext, doc: dict, known: tuple[str, ...]) -> None:
    """Refuse unknown top-level keys and tables, suggesting the closest known one."""
    unknown = [k for k in doc if k not in known]
    if unknown:
        k = unknown[0]
        kind = "table" if isinstance(doc[k], (dict, list)) else "key"
        label = f"[{k}]" if kind == "table" else repr(k)
        raise ctx.error("(top level)", f"unknown {kind} {label}{did_you_mean(k, known)}; "
                                       f"known: {', '.join(known)}")


def number(
    ctx: TableContext, tbl: dict, where: str, key: str, ok: Callable[[float], bool], expected: str,
    default=REQUIRED, label: str | None = None,
) -> float:
    """A finite number ``tbl[key]`` satisfying ``ok``; ``label`` names it in messages."""
    label = label or key
    if key not in tbl:
        if default is REQUIRED:
            raise ctx.missing(where, label, expected)
        return default
    v = tbl[key]
    if not (is_number(v) and ok(float(v))):
        raise ctx.bad(where, label, v, expected)
    return float(v)


def string(ctx: TableContext, tbl: dict, where: str, key: str, expected: str, default=REQUIRED) -> str:
    """A non-blank string ``tbl[key]``."""
    if key not in tbl:
        if default is REQUIRED:
            raise ctx.missing(where, key, expected)
        return default
    v = tbl[key]
    if not isinstance(v, str) or not v.strip():
        raise ctx.bad(where, key, v, expected)
    return v


def table_list(ctx: TableContext, tbl: dict, where: str, key: str, expected: str) -> list[dict]:
    """A non-empty array of tables ``tbl[key]``."""
    if key not in tbl:
        raise ctx.missing(where, key, expected)
    v = tbl[key]
    if not isinstance(v, list) or not v or not all(isinstance(e, dict) for e in v):
        raise ctx.bad(where, key, v, expected)
    return v


def wrap(ctx: TableContext, where: str, build: Callable[[], Any]):
    """Run a model constructor, prefixing its SetupError with file and table."""
    try:
        return build()
    except SetupError as exc:
        raise ctx.error(where, str(exc)) from exc


def bounds(ctx: TableContext, tbl: dict, where: str, key: str, unit: str, default=REQUIRED) -> tuple[float, float] | None:
    """A ``[lo, hi]`` pair with 0 < lo < hi."""
    expected = f"[lo, hi] with 0 < lo < hi ({unit})"
    if key not in tbl:
        if default is REQUIRED:
            raise ctx.missing(where, key, expected)
        return default
    v = tbl[key]
    if not (isinstance(v, list) and len(v) == 2 and all(is_number(e) for e in v) and 0 < v[0] < v[1]):
        raise ctx.bad(where, key, v, expected)
    return (float(v[0]), float(v[1]))


_PRIOR_KEYS = ("distribution", "lo", "hi", "median", "mu", "sigma")
_DISTRIBUTIONS = ("uniform", "log-uniform", "loguniform", "log-normal", "lognormal", "normal")


def check_prior_spec(ctx: TableContext, where: str, key: str, spec, allow_fixed: bool = False) -> None:
    """Check the shape and types of one prior entry (``[priors]`` or a ``[model]`` override).

    Accepted forms (docs/identification.md): ``[lo, hi]`` (finite numbers,
    lo < hi), a table ``{ distribution = "...", lo, hi, median, mu, sigma }``
    with finite numbers (``sigma`` > 0, ``median`` > 0) and, with
    ``allow_fixed``, a single finite number that fixes the parameter.
    Whether the named parameter exists and the distribution's own rules are
    checked where the priors are built.
    """
    label = f"{key}"
    if allow_fixed and is_number(spec):
        return
    if isinstance(spec, list):
        if not (len(spec) == 2 and all(is_number(e) for e in spec) and spec[0] < spec[1]):
            raise ctx.bad(where, label, spec, "a [lo, hi] pair of finite numbers with lo < hi"
                          + (", a number (fixed value)" if allow_fixed else "") + " or a prior table")
        return
    if isinstance(spec, dict):
        check_keys(ctx, spec, f"{where} {key}", _PRIOR_KEYS)
        dist = spec.get("distribution", "log-uniform")
        if not isinstance(dist, str) or dist.lower() not in _DISTRIBUTIONS:
            raise ctx.bad(where, f"{key}.distribution", dist,
                          f"one of uniform, log-uniform, log-normal, normal{did_you_mean(dist, _DISTRIBUTIONS)}")
        for k in _PRIOR_KEYS[1:]:
            if k in spec:
                v = spec[k]
                positive = k == "sigma" or (k == "median")
                if not is_number(v) or (positive and v <= 0):
                    raise ctx.bad(where, f"{key}.{k}", v, "a finite number" + (" > 0" if positive else ""))
        if "lo" in spec and "hi" in spec and not spec["lo"] < spec["hi"]:
            raise ctx.bad(where, f"{key}.lo/hi", [spec["lo"], spec["hi"]], "lo < hi")
        return
    raise ctx.bad(where, label, spec, "a [lo, hi] pair or a prior table { distribution = ..., ... }"
                  + (" or a number (fixed value)" if allow_fixed else ""))


# --------------------------------------------------------------------------- shared domain tables


def parse_materials(ctx: TableContext, doc: dict) -> dict[str, Material]:
    """The ``[materials.NAME]`` tables: youngs_modulus (Pa), density (kg/m^3), poisson_ratio, loss_factor."""
    tbl = table(ctx, doc, "materials", "[materials]")
    if not tbl:
        raise ctx.error("[materials]", "no material defined; expected [materials.NAME] tables")
    out = {}
    for name, m in tbl.items():
        where = f"[materials.{name}]"
        if not isinstance(m, dict):
            raise ctx.error(where, f"expected a table, found {m!r}")
        check_keys(ctx, m, where, ("youngs_modulus", "density", "poisson_ratio", "loss_factor"))
        e_lo, e_hi = _YOUNGS_RANGE
        r_lo, r_hi = _DENSITY_RANGE
        e = number(ctx, m, where, "youngs_modulus", lambda x: e_lo <= x <= e_hi,
                   f"a finite number > 0 within [{e_lo:g}, {e_hi:g}] Pa (a solid's Young's modulus)")
        rho = number(ctx, m, where, "density", lambda x: r_lo <= x <= r_hi,
                     f"a finite number > 0 within [{r_lo:g}, {r_hi:g}] kg/m^3")
        nu = number(ctx, m, where, "poisson_ratio", lambda x: -1 < x < 0.5, "a number in (-1, 0.5)")
        eta = number(ctx, m, where, "loss_factor", lambda x: 0 <= x <= 1, "a number in [0, 1]", default=0.0)
        out[name] = wrap(ctx, where, lambda: Material(e, rho, nu, eta, name=name))
    return out


def _length(x: float) -> bool:
    return 0 < x <= _MAX_LENGTH_M


_LENGTH_EXPECTED = f"a finite number > 0 and <= {_MAX_LENGTH_M:g} (m)"


def material_ref(ctx: TableContext, tbl: dict, where: str, materials: dict[str, Material]) -> Material:
    """The material named by ``tbl["material"]``."""
    name = string(ctx, tbl, where, "material", "the name of a [materials.NAME] table")
    if name not in materials:
        defined = ", ".join(sorted(materials))
        raise ctx.bad(where, "material", name,
                      f"a defined material (unknown material{did_you_mean(name, materials)}; defined: {defined})")
    return materials[name]


def parse_holder(ctx: TableContext, doc: dict, materials: dict[str, Material], key: str = "holder") -> Holder:
    """The ``[holder]`` table: material and segments from the flange to the holder tip."""
    where = f"[{key}]"
    tbl = table(ctx, doc, key, where)
    check_keys(ctx, tbl, where, ("material", "segments"))
    material = material_ref(ctx, tbl, where, materials)
    segs = []
    keys = ("length", "outer_diameter", "inner_diameter")
    listed = table_list(ctx, tbl, where, "segments", "a non-empty array of {length, outer_diameter, inner_diameter} tables")
    for i, seg in enumerate(listed):
        check_keys(ctx, seg, f"{where} segments[{i}]", keys)
        label = {k: f"segments[{i}].{k}" for k in keys}
        length = number(ctx, seg, where, "length", _length, _LENGTH_EXPECTED, label=label["length"])
        outer = number(ctx, seg, where, "outer_diameter", _length, _LENGTH_EXPECTED, label=label["outer_diameter"])
        inner = number(ctx, seg, where, "inner_diameter", lambda x: 0 <= x < outer,
                       f"0 <= inner_diameter < outer_diameter ({outer!r} m)", default=0.0, label=label["inner_diameter"])
        segs.append(wrap(ctx, f"{where} segments[{i}]", lambda: HolderSegment(length, outer, inner)))
    return wrap(ctx, where, lambda: Holder(material, tuple(segs)))


def parse_tool(ctx: TableContext, tbl: dict, where: str, name: str, materials: dict[str, Material],
               allow_name: bool, extra_keys: tuple[str, ...] = ()) -> Tool:
    """One tool table: material, total_length and segments from the tip towards the shank end.

    ``extra_keys`` are tolerated (and ignored) keys the caller reads itself,
    e.g. the artifact blank's ``clamping_length``.
    """
    check_keys(ctx, tbl, where, ("material", "total_length", "segments") + (("name",) if allow_name else ()) + extra_keys)
    material = material_ref(ctx, tbl, where, materials)
    total = number(ctx, tbl, where, "total_length", _length, _LENGTH_EXPECTED)
    segs = []
    keys = ("length", "diameter", "diameter_ratio")
    listed = table_list(ctx, tbl, where, "segments", "a non-empty array of {length, diameter, diameter_ratio} tables")
    for i, seg in enumerate(listed):
        check_keys(ctx, seg, f"{where} segments[{i}]", keys)
        label = {k: f"segments[{i}].{k}" for k in keys}
        length = number(ctx, seg, where, "length", _length, _LENGTH_EXPECTED, label=label["length"])
        diameter = number(ctx, seg, where, "diameter", _length, _LENGTH_EXPECTED, label=label["diameter"])
        ratio = number(ctx, seg, where, "diameter_ratio", lambda x: 0 < x <= 1, "0 < diameter_ratio <= 1", default=1.0,
                       label=label["diameter_ratio"])
        segs.append(wrap(ctx, f"{where} segments[{i}]", lambda: ToolSegment(length, diameter, ratio)))
    return wrap(ctx, where, lambda: Tool(material, total, tuple(segs), name=name))
