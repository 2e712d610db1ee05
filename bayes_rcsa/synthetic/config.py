"""Configuration of a synthetic impact-hammer campaign (:class:`BenchConfig`).

The defaults (:func:`default_bench_config`) follow Table 1 of the reference
paper (Zhao et al. 2024, Machines 12:911): an ER32 collet chuck holding a
7.94 mm four-flute carbide end mill, 101.6 mm long, measured at clamping
lengths of 25, 30, 35 and 40 mm.  The true contact stiffness grows from the
paper's identified values at 25 mm (k_xf = 1.8e6 N/m, k_thetaM = 4.5e5
N m/rad) by g = 0.45 up to 40 mm (2.6e6 N/m, 6.5e5 N m/rad), inside the
user's growth bound Q = 0.5.  With these stiffnesses and the Table 1
geometry the dominant tool-point mode lies at 0.86-1.2 kHz (the paper
measured 1.29-1.77 kHz; no spindle closes that gap, see docs/synthetic.md).
The spindle (CAT40-like, three bearings) is tuned so that its own modes stay
clear of the tool modes.

:func:`load_bench_config` reads the same fields from a TOML file; every
table and key is optional and defaults to the values above.  The keys are
documented in docs/synthetic.md and in ``example_bench.toml`` beside this
module.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import SetupError
from ..model.geometry import Holder, HolderSegment, Tool, ToolSegment
from ..model.materials import Material
from .effects import normalise_effects
from .spindle import Bearing, ShaftSegment, SpindleModel

__all__ = ["BenchConfig", "default_bench_config", "load_bench_config", "CONTACT_MODELS", "EXTRA_MODE_LOCATIONS",
           "TOOL_DECLARATIONS"]

CONTACT_MODELS = ("lumped", "distributed")
#: Forms of the ``nonlinear_stiffness_law`` effect (BenchConfig.stiffness_law_kind).
STIFFNESS_LAW_KINDS = ("saturating", "ramp")
EXTRA_MODE_LOCATIONS = ("flange", "holder_tip")
#: How the user's setup declares the tool (BenchConfig.tool_declared): its segments as configured, or one cylinder
#: of the shank's (nominal) diameter and the total length, its flutes undeclared (the usual first try).
TOOL_DECLARATIONS = ("segments", "one_cylinder")
_DIRECTIONS = ("x", "y")


def _default_materials() -> dict[str, Material]:
    return {
        "steel": Material(200e9, 7850.0, 0.29, 0.002, name="steel"),
        "carbide": Material(580e9, 14500.0, 0.22, 0.001, name="carbide"),
    }


def _default_spindle() -> SpindleModel:
    # CAT40-like shaft, nose first.  The nose bore carries the holder taper
    # (7:24, 68 mm long, mean diameter about 35 mm).  The bearing values are
    # effective (bearing + housing) stiffnesses; they put the flange modes
    # near 0.66 and 1.9 kHz with flange peaks of 1-2e-7 m/N, so that they
    # frame the tool modes (0.86-1.2 kHz) instead of sitting on them.
    return SpindleModel(
        material="steel",
        segments=(
            ShaftSegment(0.070, 0.095, 0.035),
            ShaftSegment(0.230, 0.070, 0.030),
            ShaftSegment(0.100, 0.055, 0.030),
        ),
        bearings=(
            Bearing(0.030, 5.0e7, 800.0),
            Bearing(0.065, 5.0e7, 800.0),
            Bearing(0.330, 3.0e7, 500.0),
        ),
        taper_length=0.068,
        taper_diameter=0.035,
        y_stiffness_factor=0.92,
        mesh_size=0.01,
    )


@dataclass(frozen=True)
class BenchConfig:
    """Everything that defines a synthetic campaign (truth, user belief, test conditions).

    Geometry and materials (as in the setup file; SI units)
    -------------------------------------------------------
    name : str
    materials : dict of str to Material
    holder_material : str
    holder_segments : tuple of HolderSegment, flange -> holder tip
    tool_material : str
    tool_total_length : float, m
    tool_segments : tuple of ToolSegment, tip -> shank end
        The true tool (before the ``fluted_section`` effect).
    tool_declared : {"segments", "one_cylinder"}
        What the user's setup says about the tool: ``tool_segments`` as they are, or one cylinder of the
        shank's diameter over ``tool_total_length`` (no flute declared; the truth keeps its fluted tip).
    spindle : SpindleModel

    True contact (what the data are made of)
    ----------------------------------------
    k_xf : N/m, k_thetaM : N m/rad
        Stiffness at l_a (``clamping_range[0]``).
    growth : float
        g: k(l) = k(l_a) (1 + g (l - l_a) / (l_b - l_a)) (unless the
        ``nonlinear_stiffness_law`` effect is on), for k_xf and, unless
        ``growth_thetaM`` is given, for k_thetaM.
    growth_thetaM : float or None
        Separate growth of k_thetaM; ``None`` uses ``growth``.
    c_xf : N s/m, c_thetaM : N m s/rad
        Contact damping the user assumes (and the truth, unless the
        ``contact_damping`` effect is on).
    clamping_range : (l_a, l_b) m, feasible clamping lengths
    stiffness_law_kind : {"saturating", "ramp"}
        Form of the ``nonlinear_stiffness_law`` effect: the saturating law,
        or the linear law plus a ramp ``magnitude * clip((l - ramp_start) /
        ramp_width, 0, 1)`` (relative to k(l_a)): a further contact zone
        (past a collet slot or relief groove) comes into contact over
        ``ramp_width`` from ``ramp_start`` on.
    ramp_start, ramp_width : m
    contact_model : {"lumped", "distributed"}
        Lumped springs at the holder tip (the RCSA model's assumption) or
        springs spread over the clamping length nodes with the same sums.

    Campaign and measurement
    ------------------------
    clamping_lengths : tuple of float, m
    directions : tuple of {"x", "y"}
    frequency_start, frequency_stop, frequency_step : float, Hz
    resolution_hz : float or None
        Analyser line width: each measured line is the average of the true
        FRF over ``[f - r/2, f + r/2]``; ``None`` samples it at the line.
    noise_relative : float
        Standard deviation of the complex noise relative to |H|.
    noise_floor : float
        m/N, additive standard deviation (sensor/amplifier floor).
    n_averages : int
        Impacts averaged per measurement (sets the coherence; written to each
        tool-point file as a ``# averages = N`` header line).
    repeats : int
        Repeated hits per clamping length and direction: 1 writes
        ``tip_x_25mm.csv``; R > 1 writes ``tip_x_25mm_hit1.csv`` ...
        ``_hitR.csv``, each with its own noise (same setup, independent
        measurements), all listed in the setup.
    seed : int
        Seed the command line uses to create the random generator.

    User belief (priors written to the setup)
    -----------------------------------------
    prior_k_xf : (lo, hi) N/m, prior_k_thetaM : (lo, hi) N m/rad, growth_bound : float

    Hidden effects and numerics
    ---------------------------
    hidden_effects : dict of str to float, see :mod:`bayes_rcsa.synthetic.effects`
    extra_mode_frequency : float, Hz; extra_mode_damping_ratio : float;
    extra_mode_location : {"flange", "holder_tip"}
    tip_mass_radius_of_gyration : float, m
    mesh_size : float, m, longest holder/tool element
    """

    name: str = "synthetic ER32 collet + 7.94 mm 4-flute carbide end mill"
    materials: Mapping[str, Material] = field(default_factory=_default_materials)
    holder_material: str = "steel"
    holder_segments: tuple[HolderSegment, ...] = (
        HolderSegment(0.020, 0.063, 0.0),
        HolderSegment(0.0595, 0.050, 0.00794),
    )
    tool_material: str = "carbide"
    tool_total_length: float = 0.1016
    tool_segments: tuple[ToolSegment, ...] = (
        ToolSegment(0.030, 0.00794, 0.80),
        ToolSegment(0.0716, 0.00794, 1.0),
    )
    tool_declared: str = "segments"
    spindle: SpindleModel = field(default_factory=_default_spindle)
    k_xf: float = 1.8e6
    k_thetaM: float = 4.5e5
    growth: float = 0.45
    growth_thetaM: float | None = None
    c_xf: float = 10.0
    c_thetaM: float = 5e-4
    clamping_range: tuple[float, float] = (0.025, 0.040)
    contact_model: str = "lumped"
    stiffness_law_kind: str = "saturating"
    ramp_start: float = 0.0315
    ramp_width: float = 0.003
    clamping_lengths: tuple[float, ...] = (0.025, 0.030, 0.035, 0.040)
    directions: tuple[str, ...] = ("x", "y")
    frequency_start: float = 500.0
    frequency_stop: float = 3500.0
    frequency_step: float = 2.0
    resolution_hz: float | None = None
    noise_relative: float = 0.02
    noise_floor: float = 1e-8
    n_averages: int = 5
    repeats: int = 1
    seed: int = 0
    prior_k_xf: tuple[float, float] = (1e5, 1e9)
    prior_k_thetaM: tuple[float, float] = (1e3, 1e8)
    growth_bound: float = 0.5
    hidden_effects: Mapping[str, float] = field(default_factory=dict)
    extra_mode_frequency: float = 1000.0
    extra_mode_damping_ratio: float = 0.02
    extra_mode_location: str = "flange"
    tip_mass_radius_of_gyration: float = 0.004
    mesh_size: float = 0.004

    def __post_init__(self) -> None:
        s = object.__setattr__
        s(self, "materials", dict(self.materials))
        s(self, "holder_segments", tuple(self.holder_segments))
        s(self, "tool_segments", tuple(self.tool_segments))
        s(self, "clamping_lengths", tuple(float(v) for v in self.clamping_lengths))
        s(self, "directions", tuple(self.directions))
        s(self, "clamping_range", tuple(float(v) for v in self.clamping_range))
        s(self, "prior_k_xf", tuple(float(v) for v in self.prior_k_xf))
        s(self, "prior_k_thetaM", tuple(float(v) for v in self.prior_k_thetaM))
        s(self, "hidden_effects", normalise_effects(self.hidden_effects))
        self._validate()

    def _validate(self) -> None:
        for name in (self.holder_material, self.tool_material, self.spindle.material):
            if name not in self.materials:
                raise SetupError(f"material {name!r} is not defined; materials: {sorted(self.materials)}")
        for key in ("k_xf", "k_thetaM", "tool_total_length", "frequency_start", "frequency_stop",
                    "frequency_step", "mesh_size", "extra_mode_frequency", "growth_bound"):
            _positive(getattr(self, key), key)
        for key in ("growth", "c_xf", "c_thetaM", "noise_relative", "noise_floor",
                    "extra_mode_damping_ratio", "tip_mass_radius_of_gyration"):
            _nonnegative(getattr(self, key), key)
        if self.growth_thetaM is not None:
            _nonnegative(self.growth_thetaM, "growth_thetaM")
        if self.resolution_hz is not None:
            _positive(self.resolution_hz, "resolution_hz")
        if not (isinstance(self.n_averages, int) and not isinstance(self.n_averages, bool) and self.n_averages >= 1):
            raise SetupError(f"n_averages = {self.n_averages!r}: expected an integer >= 1")
        if not (isinstance(self.repeats, int) and not isinstance(self.repeats, bool) and self.repeats >= 1):
            raise SetupError(f"repeats = {self.repeats!r}: expected an integer >= 1 (hits per clamping length and "
                             "direction)")
        if not (isinstance(self.seed, int) and not isinstance(self.seed, bool) and self.seed >= 0):
            raise SetupError(f"seed = {self.seed!r}: expected an integer >= 0")
        if self.frequency_stop <= self.frequency_start:
            raise SetupError(
                f"frequency_stop = {self.frequency_stop!r} Hz: expected more than frequency_start "
                f"{self.frequency_start!r} Hz"
            )
        if self.stiffness_law_kind not in STIFFNESS_LAW_KINDS:
            raise SetupError(f"stiffness_law_kind = {self.stiffness_law_kind!r}: expected one of {STIFFNESS_LAW_KINDS}")
        _positive(self.ramp_width, "ramp_width")
        if not self.clamping_range[0] <= self.ramp_start <= self.clamping_range[1]:
            raise SetupError(f"ramp_start = {self.ramp_start!r} m: expected within clamping_range "
                             f"{list(self.clamping_range)!r}")
        if self.contact_model not in CONTACT_MODELS:
            raise SetupError(f"contact_model = {self.contact_model!r}: expected one of {CONTACT_MODELS}")
        if self.tool_declared not in TOOL_DECLARATIONS:
            raise SetupError(f"tool_declared = {self.tool_declared!r}: expected one of {TOOL_DECLARATIONS}")
        if self.extra_mode_location not in EXTRA_MODE_LOCATIONS:
            raise SetupError(
                f"extra_mode_location = {self.extra_mode_location!r}: expected one of {EXTRA_MODE_LOCATIONS}"
            )
        dirs = self.directions
        if not dirs or any(d not in _DIRECTIONS for d in dirs) or len(set(dirs)) != len(dirs):
            raise SetupError(f"directions = {list(self.directions)!r}: expected distinct values from {_DIRECTIONS}")
        la, lb = self.clamping_range
        _positive(la, "clamping_range[0]")
        if not (math.isfinite(lb) and lb > la):
            raise SetupError(f"clamping_range = {list(self.clamping_range)!r}: expected 0 < l_a < l_b (m)")
        for key in ("prior_k_xf", "prior_k_thetaM"):
            lo, hi = getattr(self, key)
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
                raise SetupError(f"{key} = {list(getattr(self, key))!r}: expected 0 < lo < hi")
        if not self.clamping_lengths:
            raise SetupError("clamping_lengths: expected at least one clamping length")
        if len(set(self.clamping_lengths)) != len(self.clamping_lengths):
            raise SetupError(f"clamping_lengths = {list(self.clamping_lengths)!r}: expected distinct values")
        holder, tool = self.holder, self.tool  # validates segments and lengths
        bore = holder.bore_depth
        shank = tool.segments[-1]
        for cl in self.clamping_lengths:
            _positive(cl, "clamping length")
            if cl >= bore or cl >= tool.total_length:
                raise SetupError(
                    f"clamping length {cl!r} m: expected less than the holder bore depth {bore!r} m and the tool "
                    f"length {tool.total_length!r} m"
                )
        for seg in holder.segments:
            if 0 < seg.inner_diameter < shank.diameter * (1 - 1e-9):
                raise SetupError(
                    f"tool shank diameter {shank.diameter!r} m does not fit the holder bore {seg.inner_diameter!r} m"
                )
        if "fluted_section" in self.hidden_effects and not any(t.diameter_ratio < 1 for t in self.tool_segments):
            raise SetupError("hidden effect fluted_section needs a tool segment with diameter_ratio < 1 (the flutes)")

    # ----------------------------------------------------------- derived --
    @property
    def holder(self) -> Holder:
        """The holder as the user describes it."""
        return Holder(self.materials[self.holder_material], self.holder_segments)

    @property
    def tool(self) -> Tool:
        """The configured tool, ``tool_segments`` (no hidden effect); the setup declares ``declared_tool_segments``."""
        return Tool(self.materials[self.tool_material], self.tool_total_length, self.tool_segments, name="tool")

    @property
    def declared_tool_segments(self) -> tuple[ToolSegment, ...]:
        """The tool segments the user's setup declares (``tool_declared``), tip -> shank end."""
        if self.tool_declared == "one_cylinder":
            return (ToolSegment(self.tool_total_length, self.tool_segments[-1].diameter),)
        return self.tool_segments

    @property
    def frequency_hz(self) -> np.ndarray:
        """(n_freq,) Hz, the measurement grid start, start + step, ... <= stop."""
        n = int(math.floor((self.frequency_stop - self.frequency_start) / self.frequency_step + 1e-9)) + 1
        return self.frequency_start + self.frequency_step * np.arange(n)

    def with_effects(self, **effects) -> "BenchConfig":
        """A copy with these hidden effects (``name=magnitude`` or ``name=True``) added."""
        return dataclasses.replace(self, hidden_effects={**self.hidden_effects, **effects})


def _positive(value, key: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise SetupError(f"{key} = {value!r}: expected a finite number > 0")


def _nonnegative(value, key: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise SetupError(f"{key} = {value!r}: expected a finite number >= 0")


def default_bench_config(**overrides) -> BenchConfig:
    """The default campaign (paper Table 1), with any field replaced by ``overrides``.

    Examples
    --------
    >>> cfg = default_bench_config(hidden_effects={"tip_mass": True}, directions=("x",))
    """
    names = {f.name for f in dataclasses.fields(BenchConfig)}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise SetupError(f"unknown BenchConfig field(s) {unknown}; known fields: {sorted(names)}")
    return BenchConfig(**overrides)


# ------------------------------------------------------------------ TOML --

# table -> {key: BenchConfig field}; "" is the top level.
_SCALARS = {
    "": {"name": "name", "contact_model": "contact_model", "mesh_size": "mesh_size"},
    "contact": {"k_xf": "k_xf", "k_thetaM": "k_thetaM", "growth": "growth", "growth_thetaM": "growth_thetaM", "c_xf": "c_xf",
                "c_thetaM": "c_thetaM", "clamping_range": "clamping_range", "law_kind": "stiffness_law_kind",
                "ramp_start": "ramp_start", "ramp_width": "ramp_width"},
    "prior": {"translational_stiffness": "prior_k_xf", "rotational_stiffness": "prior_k_thetaM",
              "growth_bound": "growth_bound"},
    "campaign": {"clamping_lengths": "clamping_lengths", "directions": "directions", "repeats": "repeats"},
    "frequency": {"start": "frequency_start", "stop": "frequency_stop", "step": "frequency_step",
                  "resolution": "resolution_hz"},
    "noise": {"relative": "noise_relative", "floor": "noise_floor", "averages": "n_averages", "seed": "seed"},
    "effect_options": {"extra_mode_frequency": "extra_mode_frequency",
                       "extra_mode_damping_ratio": "extra_mode_damping_ratio",
                       "extra_mode_location": "extra_mode_location",
                       "tip_mass_radius_of_gyration": "tip_mass_radius_of_gyration"},
}
_TABLES = set(_SCALARS) - {""} | {"materials", "holder", "tool", "spindle", "hidden_effects"}
_PAIRS = {"clamping_range", "prior_k_xf", "prior_k_thetaM"}
_LISTS = {"clamping_lengths", "directions"}
_STRINGS = {"name", "contact_model", "extra_mode_location", "stiffness_law_kind"}
_INTS = {"n_averages", "seed", "repeats"}


def load_bench_config(path) -> BenchConfig:
    """Read a bench configuration TOML file.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    BenchConfig
        Fields missing from the file keep the defaults of
        :func:`default_bench_config`.

    Raises
    ------
    SetupError
        Missing or unreadable file, invalid TOML, unknown tables or keys,
        values of the wrong type or out of range (the message names the file
        and the key).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SetupError(f"{path}: bench configuration file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SetupError(f"{path}: cannot read bench configuration ({exc})") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SetupError(f"{path}: invalid TOML: {exc}") from None
    try:
        return _from_dict(doc)
    except SetupError as exc:
        raise SetupError(f"{path}: {exc}") from None


def _from_dict(doc: dict[str, Any]) -> BenchConfig:
    base = default_bench_config()
    kw: dict[str, Any] = {}
    for key, value in doc.items():
        if key in _TABLES and not isinstance(value, dict):
            raise SetupError(f"{key} = {value!r}: expected a table [{key}]")
        if isinstance(value, dict):
            if key not in _TABLES:
                raise SetupError(f"unknown table [{key}]; known tables: {sorted(_TABLES)}")
        elif key not in _SCALARS[""]:
            raise SetupError(
                f"unknown top-level key {key!r}; known keys: {sorted(_SCALARS[''])} and tables {sorted(_TABLES)}"
            )
    for table, keys in _SCALARS.items():
        src = doc if table == "" else doc.get(table, {})
        if table:
            unknown = sorted(set(src) - set(keys))
            if unknown:
                raise SetupError(f"[{table}]: unknown key(s) {unknown}; known keys: {sorted(keys)}")
        for key, fname in keys.items():
            if key in src:
                where = f"{table}.{key}" if table else key
                kw[fname] = _convert(src[key], fname, where)
    if "materials" in doc:
        kw["materials"] = {**base.materials, **{n: _material(n, t) for n, t in doc["materials"].items()}}
    if "holder" in doc:
        h = doc["holder"]
        _known(h, {"material", "segments"}, "holder")
        if "material" in h:
            kw["holder_material"] = _string(h["material"], "holder.material")
        if "segments" in h:
            kw["holder_segments"] = tuple(
                _record(HolderSegment, s, {"length", "outer_diameter", "inner_diameter"}, f"holder.segments[{i}]")
                for i, s in enumerate(_list(h["segments"], "holder.segments"))
            )
    if "tool" in doc:
        t = doc["tool"]
        _known(t, {"material", "total_length", "segments", "declared"}, "tool")
        if "declared" in t:
            kw["tool_declared"] = _string(t["declared"], "tool.declared")
        if "material" in t:
            kw["tool_material"] = _string(t["material"], "tool.material")
        if "total_length" in t:
            kw["tool_total_length"] = _number(t["total_length"], "tool.total_length")
        if "segments" in t:
            kw["tool_segments"] = tuple(
                _record(ToolSegment, s, {"length", "diameter", "diameter_ratio"}, f"tool.segments[{i}]")
                for i, s in enumerate(_list(t["segments"], "tool.segments"))
            )
    if "spindle" in doc:
        kw["spindle"] = _spindle(doc["spindle"], base.spindle)
    if "hidden_effects" in doc:
        kw["hidden_effects"] = normalise_effects(doc["hidden_effects"])
    return BenchConfig(**{**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)}, **kw})


def _known(table: dict, keys: set[str], where: str) -> None:
    unknown = sorted(set(table) - keys)
    if unknown:
        raise SetupError(f"[{where}]: unknown key(s) {unknown}; known keys: {sorted(keys)}")


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SetupError(f"{where} = {value!r}: expected a number")
    return float(value)


def _string(value, where: str) -> str:
    if not isinstance(value, str):
        raise SetupError(f"{where} = {value!r}: expected a string")
    return value


def _list(value, where: str) -> list:
    if not isinstance(value, list) or not value:
        raise SetupError(f"{where}: expected a non-empty array")
    return value


def _convert(value, fname: str, where: str):
    if fname in _STRINGS:
        return _string(value, where)
    if fname in _INTS:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SetupError(f"{where} = {value!r}: expected an integer")
        return value
    if fname in _PAIRS:
        if not isinstance(value, list) or len(value) != 2:
            raise SetupError(f"{where} = {value!r}: expected a pair [lo, hi]")
        return tuple(_number(v, where) for v in value)
    if fname == "directions":
        return tuple(_string(v, where) for v in _list(value, where))
    if fname in _LISTS:
        return tuple(_number(v, where) for v in _list(value, where))
    return _number(value, where)


def _record(cls, table, keys: set[str], where: str):
    if not isinstance(table, dict):
        raise SetupError(f"{where}: expected a table like {{ {', '.join(sorted(keys))} }}")
    _known(table, keys, where)
    try:
        return cls(**{k: _number(v, f"{where}.{k}") for k, v in table.items()})
    except TypeError as exc:
        raise SetupError(f"{where}: {exc}") from None
    except SetupError as exc:
        raise SetupError(f"{where}: {exc}") from None


def _material(name: str, table) -> Material:
    keys = {"youngs_modulus", "density", "poisson_ratio", "loss_factor"}
    if not isinstance(table, dict):
        raise SetupError(f"materials.{name}: expected a table")
    _known(table, keys, f"materials.{name}")
    missing = sorted({"youngs_modulus", "density"} - set(table))
    if missing:
        raise SetupError(f"materials.{name}: missing key(s) {missing}")
    return Material(**{k: _number(v, f"materials.{name}.{k}") for k, v in table.items()}, name=name)


def _spindle(table, base: SpindleModel) -> SpindleModel:
    keys = {"material", "segments", "bearings", "taper_length", "taper_diameter", "y_stiffness_factor", "mesh_size"}
    if not isinstance(table, dict):
        raise SetupError("spindle: expected a table")
    _known(table, keys, "spindle")
    kw = {}
    if "material" in table:
        kw["material"] = _string(table["material"], "spindle.material")
    if "segments" in table:
        kw["segments"] = tuple(
            _record(ShaftSegment, s, {"length", "outer_diameter", "inner_diameter"}, f"spindle.segments[{i}]")
            for i, s in enumerate(_list(table["segments"], "spindle.segments"))
        )
    if "bearings" in table:
        kw["bearings"] = tuple(
            _record(Bearing, b, {"position", "stiffness", "damping", "rotational_stiffness", "rotational_damping"},
                    f"spindle.bearings[{i}]")
            for i, b in enumerate(_list(table["bearings"], "spindle.bearings"))
        )
    for key in ("taper_length", "taper_diameter", "y_stiffness_factor", "mesh_size"):
        if key in table:
            kw[key] = _number(table[key], f"spindle.{key}")
    return dataclasses.replace(base, **kw)
