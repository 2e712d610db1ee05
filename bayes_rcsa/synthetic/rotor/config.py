"""Configuration of the rotor bench: geometry, bearings, contact, campaign, noise and hidden effects.

All values SI.  :func:`rotor_bench_config` returns the defaults (an ER32
collet chuck with a CAT40-like taper in a three-bearing-set spindle, and a
7.94 mm 4-flute carbide end mill of 101.6 mm, after Table 1 of Zhao et al.,
Machines 12 (2024) 911) with any field replaced and hidden effects added.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import SetupError
from .sections import FluteProfile, RotorMaterial

__all__ = [
    "HolderSegment", "ShaftSegment", "BearingSet", "Housing", "HolderTaper",
    "RotorBenchConfig", "rotor_bench_config", "EffectInfo", "ROTOR_EFFECTS", "CANONICAL_EFFECTS",
    "OUT_OF_LIBRARY_EFFECTS", "front_bearing_sets", "SPINDLE_ERROR_LIMIT",
]


@dataclass(frozen=True)
class EffectInfo:
    """A hidden effect: its default magnitude (used for ``True``), unit and meaning."""

    default: float
    unit: str
    description: str
    low: float
    high: float


#: Every hidden effect of the rotor bench.  ``low``/``high``: realistic range of the magnitude.
ROTOR_EFFECTS: dict[str, EffectInfo] = {
    "contact_damping": EffectInfo(
        5.0, "factor", "true tool-holder joint damping (c_xf, c_thetaM) = magnitude x the assumed values", 2.0, 50.0),
    "tip_mass": EffectInfo(
        0.003, "kg", "a finite body (accelerometer) at the tool tip, with its own rotary inertia", 0.0005, 0.01),
    "fluted_section": EffectInfo(
        1.0, "flute depth scale", "the fluted segment's true section comes from a flute profile "
        "(A, I, shear coefficient), not from the declared circle", 0.5, 1.5),
    "extra_mode": EffectInfo(
        2400.0, "Hz", "a ring around the collet nut on a compliant fit: a holder-side resonator "
        "(magnitude = its uncoupled translational frequency)", 1500.0, 3300.0),
    "nonlinear_stiffness_law": EffectInfo(
        3.0, "saturation rate (saturating) / relative jump (step)",
        "contact stiffness saturates (or steps at a collet slot) with clamping length", 1.0, 6.0),
    "spindle_error": EffectInfo(
        0.15, "relative bearing stiffness change", "the exported spindle file comes from the rotor with "
        "changed bearing stiffness (spindle_error_kind; 'bearing_sets': the front sets' change, the rear sets' "
        "is spindle_error_rear)", -0.3, 0.3),
    "spindle_rotation_omitted": EffectInfo(
        1.0, "fraction removed", "the exported spindle file's l, n, p are scaled by (1 - magnitude)", 0.2, 1.0),
    "tool_modulus": EffectInfo(
        -0.09, "relative change of E", "the tool's true Young's and shear moduli differ from the declared", -0.15, 0.1),
    "hysteretic_joint": EffectInfo(
        0.05, "loss factor", "the tool-holder joint has a frequency-independent loss factor instead of "
        "viscous damping", 0.01, 0.2),
    "slotted_holder": EffectInfo(
        0.15, "relative EI loss (y)", "slots in the holder body: EI_y x (1 - m), EI_x x (1 - m/5), "
        "mass x (1 - m/4)", 0.05, 0.25),
}

#: How the user's setup declares the fluted tip (``fluted_declared``): a separate tip segment at the effective
#: diameter ratio, a separate tip segment declared solid (ratio 1), or not at all: the tool written as one cylinder of
#: the nominal diameter over its total length (the usual first try with a catalogue tool).
FLUTE_DECLARATIONS = ("effective", "solid", "undeclared")

#: Names shared with the model terms of the setup's ``[model] terms`` (data-formats.md).
CANONICAL_EFFECTS = ("contact_damping", "tip_mass", "fluted_section", "extra_mode",
                     "nonlinear_stiffness_law", "spindle_error", "spindle_rotation_omitted")
#: Effects that no model term represents.
OUT_OF_LIBRARY_EFFECTS = ("tool_modulus", "hysteretic_joint", "slotted_holder")


@dataclass(frozen=True)
class HolderSegment:
    """Hollow circular holder segment (flange -> tip): length, outer and inner diameter, m."""

    length: float
    outer_diameter: float
    inner_diameter: float = 0.0


@dataclass(frozen=True)
class ShaftSegment:
    """Spindle shaft segment (nose -> rear).

    Attributes
    ----------
    length, outer_diameter, inner_diameter : float, m
        The inner diameter is replaced by the holder taper's diameter where
        the taper sits.
    added_mass : float, kg/m
        Non-structural mass (drawbar, disc springs, motor rotor) per length.
    """

    length: float
    outer_diameter: float
    inner_diameter: float
    added_mass: float = 0.0


@dataclass(frozen=True)
class BearingSet:
    """A bearing set between shaft and housing.

    Attributes
    ----------
    name : str
    position : float, m
        Axial position (z < 0: behind the spindle nose).
    stiffness : float, N/m
    rotational_stiffness : float, N m/rad
    damping : float, N s/m
    rotational_damping : float, N m s/rad
    """

    name: str
    position: float
    stiffness: float
    rotational_stiffness: float
    damping: float
    rotational_damping: float


@dataclass(frozen=True)
class Housing:
    """Rigid spindle housing on mounting springs to the (rigid) head.

    Attributes
    ----------
    mass : float, kg
    rotary_inertia : float, kg m^2 (about its centre)
    position : float, m (axial position of its centre)
    stiffness, rotational_stiffness : float, N/m, N m/rad
    damping, rotational_damping : float, N s/m, N m s/rad
    """

    mass: float = 40.0
    rotary_inertia: float = 0.6
    position: float = -0.20
    stiffness: float = 2e8
    rotational_stiffness: float = 2e7
    damping: float = 3e4
    rotational_damping: float = 1500.0


@dataclass(frozen=True)
class HolderTaper:
    """The holder's steep taper inside the spindle nose and its joint.

    Attributes
    ----------
    gauge_diameter : float, m (at the spindle face, z = 0)
    length : float, m
    taper : float
        Diameter change per length (7/24 for steep tapers).
    bore : float, m (retention-knob thread)
    joint_stiffness : float, N/m per m of taper (distributed radial springs)
    joint_damping : float, N s/m per m
    joint_loss_factor : float
    """

    gauge_diameter: float = 0.04445
    length: float = 0.0684
    taper: float = 7.0 / 24.0
    bore: float = 0.016
    joint_stiffness: float = 3e11
    joint_damping: float = 3e4
    joint_loss_factor: float = 0.01

    def diameter(self, z):
        """Taper diameter (m) at z (m, ≤ 0)."""
        return self.gauge_diameter + self.taper * np.asarray(z)


def _materials() -> dict:
    return {
        "steel": RotorMaterial(200e9, 7850.0, 0.29, 0.002),
        "carbide": RotorMaterial(580e9, 14500.0, 0.22, 0.001),
        "spindle_steel": RotorMaterial(208e9, 7820.0, 0.29, 0.002),
    }


@dataclass(frozen=True)
class RotorBenchConfig:
    """Everything the rotor bench simulates (see docs/synthetic.md, "Second generator").

    Geometry, lengths in m; stiffness N/m and N m/rad; damping N s/m and
    N m s/rad; frequencies Hz.  ``hidden_effects`` maps canonical effect
    names to magnitudes (see :data:`ROTOR_EFFECTS`).

    The exported spindle file's bearings (``spindle_error``) follow
    ``spindle_error_kind``: ``"preload"`` (every set's stiffness × (1 + m)),
    ``"one_bearing"`` (front_1 only), ``"rear"`` (the rearmost set only) or
    ``"bearing_sets"``: the front sets (:func:`front_bearing_sets`) stiffer by
    (1 + m), the rear sets by (1 + ``spindle_error_rear``) (None: the same
    m), translational and rotational alike, and each set's translational and
    rotational damping × (1 + e)^``spindle_error_damping_exponent`` (default
    0.5; dimensionless) with e its own set's change; |m|, |e| ≤ 0.5.  The
    first three kinds leave the bearing damping unchanged.
    """

    name: str = "ER32 collet + 7.94 mm 4-flute carbide end mill (rotor bench)"
    materials: dict = field(default_factory=_materials)
    holder_material: str = "steel"
    tool_material: str = "carbide"
    spindle_material: str = "spindle_steel"
    taper: HolderTaper = HolderTaper()
    holder_segments: tuple = (
        HolderSegment(0.016, 0.0635, 0.014),    # V-flange
        HolderSegment(0.022, 0.044, 0.014),     # neck
        HolderSegment(0.020, 0.044, 0.00794),   # collet body
        HolderSegment(0.022, 0.050, 0.00794),   # nut region (nut + collet nose)
    )
    tool_total_length: float = 0.1016
    tool_diameter: float = 0.00794
    flute_length: float = 0.030
    diameter_ratio: float = 0.80
    flute_profile: FluteProfile = FluteProfile(4, 0.60, 0.30)
    fluted_declared: str = "effective"
    spindle_segments: tuple = (
        ShaftSegment(0.060, 0.110, 0.030),          # nose
        ShaftSegment(0.070, 0.085, 0.030, 5.0),     # front bearing seats (+ drawbar)
        ShaftSegment(0.160, 0.075, 0.030, 5.0),     # middle (+ drawbar, disc springs)
        ShaftSegment(0.050, 0.070, 0.030, 5.0),     # rear bearing seat
        ShaftSegment(0.050, 0.060, 0.030, 20.0),    # rear end (+ motor rotor / pulley)
    )
    bearings: tuple = (
        BearingSet("front_1", -0.075, 8.0e8, 4.8e6, 6.0e3, 20.0),
        BearingSet("front_2", -0.125, 7.0e8, 3.6e6, 5.0e3, 16.0),
        BearingSet("rear", -0.330, 3.0e8, 2.0e5, 3.0e3, 1.0),
    )
    housing: Housing = Housing()
    y_stiffness_factor: float = 0.96
    y_housing_factor: float = 1.05
    k_xf: float = 3.5e6
    k_thetaM: float = 5.0e5
    growth: float = 0.45
    growth_thetaM: float = 0.45
    c_xf: float = 10.0
    c_thetaM: float = 5e-4
    clamping_range: tuple = (0.025, 0.040)
    contact_model: str = "lumped"
    prior_k_xf: tuple = (1e5, 1e9)
    prior_k_thetaM: tuple = (1e3, 1e8)
    growth_bound: float = 0.5
    setup_clamping_range: tuple = (0.025, 0.040)
    clamping_lengths: tuple = (0.025, 0.030, 0.035, 0.040)
    directions: tuple = ("x", "y")
    frequency_start: float = 500.0
    frequency_stop: float = 3500.0
    frequency_step: float = 2.0
    noise_relative: float = 0.02
    noise_floor: float = 1e-8
    n_averages: int = 5
    mesh_size: float = 0.004
    spindle_mesh_size: float = 0.015
    mode_cutoff_hz: float = 40e3
    hidden_effects: dict = field(default_factory=dict)
    spindle_error_kind: str = "preload"
    spindle_error_rear: float | None = None
    spindle_error_damping_exponent: float = 0.5
    stiffness_law_kind: str = "saturating"
    step_position: float = 0.0325
    tip_body_diameter: float = 0.0065
    tip_body_height: float = 0.0055
    ring_outer_diameter: float = 0.060
    ring_inner_diameter: float = 0.050
    ring_length: float = 0.020
    ring_damping_ratio: float = 0.03
    ring_rocking_ratio: float = 1.4

    @property
    def frequency_hz(self) -> np.ndarray:
        """(n_freq,) Hz: ``start, start + step, ..., stop``."""
        n = int(round((self.frequency_stop - self.frequency_start) / self.frequency_step)) + 1
        return self.frequency_start + self.frequency_step * np.arange(n)

    @property
    def holder_length(self) -> float:
        """Holder length outside the spindle, flange -> tip, m."""
        return float(sum(s.length for s in self.holder_segments))

    def magnitude(self, name: str) -> float | None:
        """Magnitude of a hidden effect, or None when absent."""
        return self.hidden_effects.get(name)

    def with_effects(self, **effects) -> "RotorBenchConfig":
        """Copy with more hidden effects (``name=magnitude`` or ``name=True``)."""
        merged = dict(self.hidden_effects)
        merged.update(_normalise_effects(effects))
        return dataclasses.replace(self, hidden_effects=dict(sorted(merged.items())))


def _normalise_effects(effects) -> dict:
    out = {}
    for name, value in dict(effects or {}).items():
        if name not in ROTOR_EFFECTS:
            raise SetupError(f"hidden_effects: unknown effect {name!r}; expected one of {sorted(ROTOR_EFFECTS)}")
        if value is False or value is None:
            continue
        if value is True:
            value = ROTOR_EFFECTS[name].default
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SetupError(f"hidden_effects.{name} = {value!r}: expected True or a finite number")
        out[name] = float(value)
    return out


#: Largest plausible relative bearing-set stiffness change of a spindle file taken on another day
#: (kind ``"bearing_sets"``): preload and temperature move a set's stiffness by 10-30 %, never by half.
SPINDLE_ERROR_LIMIT = 0.5
#: Plausible exponents of the bearing damping law ``c' = c (1 + e)^beta`` (0: preload-independent damping,
#: 1: damping proportional to stiffness).
SPINDLE_DAMPING_EXPONENT_RANGE = (0.0, 2.0)


def front_bearing_sets(config: RotorBenchConfig) -> tuple[bool, ...]:
    """Which bearing sets are front sets (the kind ``"bearing_sets"`` of ``spindle_error``).

    A set is at the front when it sits in the front half of the shaft, nearer the spindle nose (the flange,
    z = 0) than the shaft's rear end: ``position > −L_shaft / 2`` with ``L_shaft`` the summed length of
    ``spindle_segments`` (m).  Defaults: front_1 (−75 mm) and front_2 (−125 mm) are front, rear (−330 mm)
    is rear (boundary −195 mm).

    Parameters
    ----------
    config : RotorBenchConfig

    Returns
    -------
    tuple of bool
        One per entry of ``config.bearings``, True for a front set.
    """
    half = 0.5 * sum(s.length for s in config.spindle_segments)
    return tuple(b.position > -half for b in config.bearings)


def _check_spindle_error(config: RotorBenchConfig) -> None:
    kind = config.spindle_error_kind
    if kind not in ("preload", "one_bearing", "rear", "bearing_sets"):
        raise SetupError(f"spindle_error_kind = {kind!r}: "
                         "expected 'preload', 'one_bearing', 'rear' or 'bearing_sets'")
    rear = config.spindle_error_rear
    if rear is not None:
        if kind != "bearing_sets":
            raise SetupError(f"spindle_error_rear = {rear!r}: only used with spindle_error_kind = 'bearing_sets' "
                             f"(got {kind!r}); expected None")
        if isinstance(rear, bool) or not isinstance(rear, (int, float)) or not math.isfinite(rear) \
                or abs(rear) > SPINDLE_ERROR_LIMIT:
            raise SetupError(f"spindle_error_rear = {rear!r}: expected a relative stiffness change with "
                             f"|e| <= {SPINDLE_ERROR_LIMIT} (10-30 % is typical)")
    beta = config.spindle_error_damping_exponent
    lo, hi = SPINDLE_DAMPING_EXPONENT_RANGE
    if isinstance(beta, bool) or not isinstance(beta, (int, float)) or not (lo <= beta <= hi):
        raise SetupError(f"spindle_error_damping_exponent = {beta!r}: expected a number in [{lo:g}, {hi:g}]")
    if kind != "bearing_sets":
        return
    m = config.magnitude("spindle_error")
    if m is not None and abs(m) > SPINDLE_ERROR_LIMIT:
        raise SetupError(f"hidden_effects.spindle_error = {m!r}: with spindle_error_kind = 'bearing_sets' it is the "
                         f"front sets' relative stiffness change; expected |e| <= {SPINDLE_ERROR_LIMIT}")
    front = front_bearing_sets(config)
    if all(front) or not any(front):
        raise SetupError(f"bearings: positions {[b.position for b in config.bearings]!r} m put "
                         f"{'every' if all(front) else 'no'} set in the front half of the shaft; "
                         "spindle_error_kind = 'bearing_sets' expects front and rear sets")


def _check(config: RotorBenchConfig) -> None:
    def positive(key, value):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise SetupError(f"{key} = {value!r}: expected a finite number > 0")

    for key in ("tool_total_length", "tool_diameter", "flute_length", "diameter_ratio", "k_xf", "k_thetaM",
                "frequency_start", "frequency_stop", "frequency_step", "mesh_size", "spindle_mesh_size",
                "mode_cutoff_hz", "noise_floor"):
        positive(key, getattr(config, key))
    if config.frequency_stop <= config.frequency_start:
        raise SetupError(f"frequency_stop = {config.frequency_stop!r}: expected > frequency_start")
    if not (isinstance(config.n_averages, int) and config.n_averages >= 1):
        raise SetupError(f"n_averages = {config.n_averages!r}: expected an integer >= 1")
    if not (0 <= config.noise_relative < 1):
        raise SetupError(f"noise_relative = {config.noise_relative!r}: expected a number in [0, 1)")
    if config.diameter_ratio > 1:
        raise SetupError(f"diameter_ratio = {config.diameter_ratio!r}: expected a number in (0, 1]")
    for d in config.directions:
        if d not in ("x", "y"):
            raise SetupError(f"directions: {d!r} is not a direction; expected 'x' or 'y'")
    la, lb = config.clamping_range
    if not 0 < la < lb:
        raise SetupError(f"clamping_range = {config.clamping_range!r}: expected [l_a, l_b] with 0 < l_a < l_b")
    nose = config.holder_segments[-1].length + config.holder_segments[-2].length
    shank = config.tool_total_length - config.flute_length
    for cl in config.clamping_lengths:
        if not (0 < cl <= min(nose, shank)):
            raise SetupError(f"clamping_lengths: {cl!r} m: expected 0 < l <= {min(nose, shank):.4g} m "
                             "(collet bore and shank length)")
    if config.contact_model not in ("lumped", "distributed"):
        raise SetupError(f"contact_model = {config.contact_model!r}: expected 'lumped' or 'distributed'")
    if config.fluted_declared not in FLUTE_DECLARATIONS:
        raise SetupError(f"fluted_declared = {config.fluted_declared!r}: expected one of {FLUTE_DECLARATIONS}")
    _check_spindle_error(config)
    if config.stiffness_law_kind not in ("saturating", "step"):
        raise SetupError(f"stiffness_law_kind = {config.stiffness_law_kind!r}: expected 'saturating' or 'step'")
    for name in (config.holder_material, config.tool_material, config.spindle_material):
        if name not in config.materials:
            raise SetupError(f"materials: no material {name!r}; defined: {sorted(config.materials)}")
    if len(config.bearings) < 3:
        raise SetupError(f"bearings: {len(config.bearings)} sets given; expected at least 3")


def rotor_bench_config(hidden_effects=None, **overrides) -> RotorBenchConfig:
    """Default rotor bench with fields replaced and hidden effects added.

    Parameters
    ----------
    hidden_effects : dict of str to (float or True), optional
        Canonical effect names (:data:`ROTOR_EFFECTS`); ``True`` takes the
        default magnitude.
    **overrides
        Any :class:`RotorBenchConfig` field.

    Returns
    -------
    RotorBenchConfig

    Raises
    ------
    SetupError
        An unknown field or effect, or an implausible value (the message
        names the key and what is expected).
    """
    names = {f.name for f in dataclasses.fields(RotorBenchConfig)}
    for key in overrides:
        if key not in names:
            raise SetupError(f"rotor_bench_config: unknown field {key!r}; expected one of {sorted(names)}")
    for key in ("clamping_lengths", "directions", "clamping_range", "prior_k_xf", "prior_k_thetaM",
                "setup_clamping_range", "holder_segments", "spindle_segments", "bearings"):
        if key in overrides:
            overrides[key] = tuple(overrides[key])
    if "materials" in overrides:
        merged = _materials()
        merged.update(overrides["materials"])
        overrides["materials"] = merged
    effects = dict(overrides.pop("hidden_effects", {}) or {})
    effects.update(dict(hidden_effects or {}))
    config = RotorBenchConfig(**overrides, hidden_effects=dict(sorted(_normalise_effects(effects).items())))
    _check(config)
    return config
