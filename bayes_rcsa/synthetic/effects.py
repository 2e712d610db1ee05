"""Hidden effects of the synthetic bench and the true contact stiffness law.

A hidden effect is present in the *true* structure that generates the data
but absent from what the user believes (the exported setup file and spindle
receptance).  Each has a canonical name (the discrepancy workflow uses the
same names) and a scalar magnitude with a documented meaning:

=========================  ==========  =====================================================
name                       unit        magnitude
=========================  ==========  =====================================================
contact_damping            factor      true contact damping = magnitude x assumed damping
joint_loss_factor          1           the joint also dissipates rate-independently: k (1 + i magnitude)
tip_mass                   kg          point mass at the tool tip (rotary inertia m r_g^2)
fluted_section             1           relative reduction of the fluted effective diameter
extra_mode                 kg          mass of a resonator hung on the spindle/holder side
nonlinear_stiffness_law    1           saturation rate s of the stiffness law (0: linear)
spindle_error              1           relative bearing-stiffness error of the exported spindle
spindle_rotation_omitted   1           fraction of rotational flange receptances dropped
=========================  ==========  =====================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import SetupError

__all__ = [
    "EffectInfo",
    "HIDDEN_EFFECTS",
    "CANONICAL_EFFECTS",
    "DEFAULT_MAGNITUDES",
    "normalise_effects",
    "stiffness_factor",
]


@dataclass(frozen=True)
class EffectInfo:
    """Description of one hidden effect (name, default magnitude, unit, meaning)."""

    name: str
    default: float
    unit: str
    description: str
    max_magnitude: float = math.inf
    #: Magnitudes below 0 down to (not including) this are allowed too (-inf: none; an effect with a direction)
    min_magnitude: float = 0.0


HIDDEN_EFFECTS: dict[str, EffectInfo] = {
    e.name: e
    for e in (
        EffectInfo(
            "contact_damping", 5.0, "factor",
            "tool-holder joint damping (c_xf, c_thetaM) is `magnitude` times the value the user assumes",
        ),
        EffectInfo(
            "joint_loss_factor", 0.05, "1",
            "the tool-holder joint also dissipates independently of frequency (micro-slip): its stiffness is "
            "k (1 + i magnitude) besides the assumed viscous damping",
            max_magnitude=1.0,
        ),
        EffectInfo(
            "tip_mass", 0.002, "kg",
            "a point mass (e.g. an accelerometer) with rotary inertia m r_g^2 sits at the tool tip",
        ),
        EffectInfo(
            "fluted_section", 0.10, "1",
            "the fluted length's effective diameter is (1 - magnitude) times the value in the user's setup",
            max_magnitude=0.9,
        ),
        EffectInfo(
            "extra_mode", 0.2, "kg",
            "a resonator of this mass, tuned near the tool mode, hangs on the spindle/holder side and is "
            "missing from the exported spindle receptance",
        ),
        EffectInfo(
            "nonlinear_stiffness_law", 4.0, "1",
            "contact stiffness saturates with clamping length, k = k_a (1 + g (1 - exp(-s x)) / (1 - exp(-s))), "
            "x = (l - l_a) / (l_b - l_a), s = magnitude (or, with stiffness_law_kind = 'ramp', a further contact "
            "zone adds magnitude x k_a over ramp_width from ramp_start on); the user assumes the linear law",
        ),
        EffectInfo(
            "spindle_error", 0.15, "1",
            "the exported spindle receptance comes from a spindle whose bearings are (1 + magnitude) times stiffer "
            "(an identification error, another day's preload or temperature; negative: softer, down to half)",
            min_magnitude=-0.5,
        ),
        EffectInfo(
            "spindle_rotation_omitted", 1.0, "1",
            "the exported spindle file keeps only (1 - magnitude) of the rotational terms l, n, p "
            "(1: translational receptance only)",
            max_magnitude=1.0,
        ),
    )
}

#: The five effects every discrepancy workflow knows by name.
CANONICAL_EFFECTS = ("contact_damping", "tip_mass", "fluted_section", "extra_mode", "nonlinear_stiffness_law")

DEFAULT_MAGNITUDES = {name: info.default for name, info in HIDDEN_EFFECTS.items()}


def normalise_effects(effects: Mapping | None, where: str = "hidden_effects") -> dict[str, float]:
    """Validate a ``{name: magnitude}`` mapping.

    ``True`` stands for the default magnitude and ``False`` drops the
    effect; any other value must be a finite number > 0 (and within the
    effect's range; an effect with a direction, ``min_magnitude < 0``, also
    takes a negative magnitude above ``min_magnitude``).  Unknown names are
    rejected with the list of known ones.

    Returns
    -------
    dict of str to float, sorted by name.
    """
    out: dict[str, float] = {}
    for name, value in dict(effects or {}).items():
        if name not in HIDDEN_EFFECTS:
            raise SetupError(f"{where}: unknown hidden effect {name!r}; known effects: {sorted(HIDDEN_EFFECTS)}")
        info = HIDDEN_EFFECTS[name]
        if value is True:
            value = info.default
        elif value is False:
            continue
        signed = info.min_magnitude < 0
        if (isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value == 0
                or value <= (info.min_magnitude if signed else 0.0)):
            wanted = (f"a finite magnitude > {info.min_magnitude!r} other than 0" if signed
                      else "a finite magnitude > 0")
            raise SetupError(f"{where}.{name} = {value!r}: expected {wanted} ({info.unit}) or true")
        if value > info.max_magnitude:
            raise SetupError(f"{where}.{name} = {value!r}: expected at most {info.max_magnitude!r} ({info.unit})")
        out[name] = float(value)
    return dict(sorted(out.items()))


def stiffness_factor(clamping_length, clamping_range: tuple[float, float], growth: float, saturation: float = 0.0,
                     kind: str = "saturating", ramp: tuple[float, float] | None = None):
    """k(l) / k(l_a) of the true contact law.

    Parameters
    ----------
    clamping_length : float or array, m
    clamping_range : (l_a, l_b) m
    growth : float
        g: the relative stiffness increase from l_a to l_b of the linear law.
    saturation : float
        The ``nonlinear_stiffness_law`` magnitude, >= 0; 0 gives the linear
        law ``1 + g x`` assumed by the user.  ``kind="saturating"``: the rate
        s of ``1 + g (1 - exp(-s x)) / (1 - exp(-s))`` (same end values at l_a
        and l_b).  ``kind="ramp"``: the relative stiffness a further contact
        zone adds, ``1 + g x + saturation clip((l - start) / width, 0, 1)``.
    kind : {"saturating", "ramp"}
    ramp : (start, width) m, for ``kind="ramp"``

    Returns
    -------
    float or array, dimensionless
    """
    la, lb = clamping_range
    l = np.asarray(clamping_length, dtype=float)
    x = (l - la) / (lb - la)
    if saturation == 0:
        return 1.0 + growth * x
    if kind == "ramp":
        start, width = ramp
        return 1.0 + growth * x + saturation * np.clip((l - start) / width, 0.0, 1.0)
    return 1.0 + growth * (-np.expm1(-saturation * x) / -math.expm1(-saturation))
