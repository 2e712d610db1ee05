"""Populations of tool-holder contact laws, one per holder type: the truth behind a synthetic tool library.

Every combination of a holder type and a tool draws its contact law from the
population of its holder type.  The law is the bench's linear growth law
(:mod:`bayes_rcsa.synthetic.effects`, the RCSA model's ``GrowthLaw``) over
the feasible clamping range ``[l_a, l_b]``::

    k(l) = k(l_a) (1 + g (l - l_a) / (l_b - l_a))

and its six parameters are, with ``x = ln(d / d_ref)`` the log shank
diameter relative to ``d_ref = 10 mm`` and ``z ~ N(0, 1)`` independent per
parameter and combination:

==============  ===================================================  =========
parameter       population                                           unit
==============  ===================================================  =========
k_xf (at l_a)   ln k = ln k_ref + b x + s z                          N/m
k_thetaM        ln k = ln k_ref + b x + s z                          N m/rad
g_xf, g_thetaM  g = G expit(logit(g_ref / G) + s z)                  1
c_xf            ln c = ln c_ref + b x + s z                          N s/m
c_thetaM        ln c = ln c_ref + b x + s z                          N m s/rad
==============  ===================================================  =========

``G`` (:data:`GROWTH_CEILING`) bounds every true growth factor, so the
truth always lies inside a user prior with growth bound ``Q >= G``.  The
built-in holder types (:data:`HOLDER_TYPES`) differ in their stiffness
level, diameter slope, spread, growth and damping, and in the holder body
the bench builds around the tool.  Their values are chosen (not measured)
so that the dominant tool-point mode of every carbide tool of 6-20 mm
stays between about 0.5 and 2 kHz at clamping lengths 20-45 mm on the
bench's default spindle, with the contact law's spread moving it by a few
per cent: docs/synthetic.md, "Tool libraries".
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import SetupError
from ..model.geometry import HolderSegment

__all__ = ["LawPopulation", "HolderPopulation", "HOLDER_TYPES", "GROWTH_CEILING", "D_REF", "LAW_NAMES",
           "draw_law", "median_law"]

#: m, reference shank diameter of the diameter covariate ``x = ln(d / D_REF)``.
D_REF = 0.010
#: Upper bound ``G`` of every true growth factor (the user's growth bound must be at least this).
GROWTH_CEILING = 1.0
#: The six contact-law parameters, in the names of :mod:`bayes_rcsa.params` (k at l_a, growth, damping).
LAW_NAMES = ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "c_thetaM")
_GROWTH = ("g_xf", "g_thetaM")


@dataclass(frozen=True)
class LawPopulation:
    """Population of one contact-law parameter.

    Attributes
    ----------
    ref : float
        Median at the reference diameter ``D_REF`` (unit of the parameter;
        for a growth factor its median, ``0 < ref < GROWTH_CEILING``).
    slope : float
        ``b``: d ln(median) / d ln(diameter) (0 for growth factors).
    spread : float
        ``s``: standard deviation of the log (stiffness, damping) or of the
        logit of ``g / G`` (growth), dimensionless.
    """

    ref: float
    slope: float = 0.0
    spread: float = 0.0

    def __post_init__(self) -> None:
        for key in ("ref", "slope", "spread"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SetupError(f"population {key} = {v!r}: expected a finite number")
        if self.ref <= 0 or self.spread < 0:
            raise SetupError(f"population ref = {self.ref!r}, spread = {self.spread!r}: expected ref > 0, spread >= 0")


@dataclass(frozen=True)
class HolderPopulation:
    """A holder type: its holder body and the population of its contact laws.

    Attributes
    ----------
    name : str
        The holder type, written to each setup as ``[holder] type``.
    laws : dict of str to LawPopulation
        One entry per name of :data:`LAW_NAMES`.
    flange : (length, outer_diameter) m
        Solid flange segment of the holder body.
    nose_length : float, m
        Length of the bored nose segment (its bore is the shank diameter).
    nose_outer : (a, b)
        Outer diameter of the nose, ``a + b d`` (m) for shank diameter ``d``.
    """

    name: str
    laws: Mapping[str, LawPopulation]
    flange: tuple[float, float] = (0.020, 0.063)
    nose_length: float = 0.060
    nose_outer: tuple[float, float] = (0.050, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "laws", dict(self.laws))
        missing = sorted(set(LAW_NAMES) - set(self.laws))
        if missing:
            raise SetupError(f"holder type {self.name!r}: population of {missing} missing")
        for g in _GROWTH:
            if not self.laws[g].ref < GROWTH_CEILING:
                raise SetupError(f"holder type {self.name!r}: {g} ref = {self.laws[g].ref!r}: expected < "
                                 f"{GROWTH_CEILING!r}")

    def holder_segments(self, diameter: float) -> tuple[HolderSegment, ...]:
        """The holder body for a shank of ``diameter`` (m), flange -> holder tip."""
        a, b = self.nose_outer
        return (HolderSegment(self.flange[0], self.flange[1], 0.0),
                HolderSegment(self.nose_length, a + b * diameter, diameter))

    def replace(self, **laws) -> "HolderPopulation":
        """A copy with some parameter populations replaced (``k_xf=LawPopulation(...)``)."""
        unknown = sorted(set(laws) - set(LAW_NAMES))
        if unknown:
            raise SetupError(f"holder type {self.name!r}: unknown law parameter(s) {unknown}; known: {list(LAW_NAMES)}")
        return dataclasses.replace(self, laws={**self.laws, **laws})


def _population(name, k_xf, k_thetaM, g, c_xf, c_thetaM, nose_outer):
    return HolderPopulation(
        name,
        {"k_xf": LawPopulation(*k_xf), "k_thetaM": LawPopulation(*k_thetaM), "g_xf": LawPopulation(g[0], 0.0, g[1]),
         "g_thetaM": LawPopulation(g[0], 0.0, g[1]), "c_xf": LawPopulation(*c_xf),
         "c_thetaM": LawPopulation(*c_thetaM)},
        nose_outer=nose_outer,
    )


#: Built-in holder types: (ref, slope, spread) of k_xf, k_thetaM, c_xf, c_thetaM; (median, spread) of growth.
#: The collet is the softest and most variable, the shrink fit the stiffest and most repeatable, the
#: hydraulic chuck in between with the most damping.
HOLDER_TYPES: dict[str, HolderPopulation] = {
    p.name: p for p in (
        _population("ER32", (2.8e6, 2.0, 0.15), (9.0e5, 3.0, 0.15), (0.45, 0.35), (12.0, 1.0, 0.2),
                    (6e-4, 3.0, 0.2), (0.050, 0.0)),
        _population("shrink_fit", (4.5e6, 1.8, 0.08), (1.5e6, 2.8, 0.08), (0.25, 0.35), (8.0, 1.0, 0.2),
                    (4e-4, 3.0, 0.2), (0.014, 1.0)),
        _population("hydraulic", (3.6e6, 2.2, 0.10), (1.2e6, 3.2, 0.10), (0.35, 0.35), (25.0, 1.0, 0.2),
                    (1.2e-3, 3.0, 0.2), (0.046, 0.0)),
    )
}


def _logit(p: float) -> float:
    return math.log(p / (1.0 - p))


def _value(pop: LawPopulation, name: str, x: float, z: float) -> float:
    if name in _GROWTH:
        u = _logit(pop.ref / GROWTH_CEILING) + pop.spread * z
        return GROWTH_CEILING / (1.0 + math.exp(-u))
    return pop.ref * math.exp(pop.slope * x + pop.spread * z)


def median_law(population: HolderPopulation, diameter: float) -> dict[str, float]:
    """The population median of every law parameter for a shank of ``diameter`` (m)."""
    x = math.log(diameter / D_REF)
    return {n: _value(population.laws[n], n, x, 0.0) for n in LAW_NAMES}


def draw_law(population: HolderPopulation, diameter: float, rng: np.random.Generator) -> tuple[dict, dict]:
    """One combination's true contact law, drawn from its holder type's population.

    Parameters
    ----------
    population : HolderPopulation
    diameter : float, m, tool shank diameter
    rng : numpy.random.Generator
        Consumes one standard normal per parameter, in the order of :data:`LAW_NAMES`.

    Returns
    -------
    law : dict of str to float
        ``k_xf`` (N/m) and ``k_thetaM`` (N m/rad) at l_a, ``g_xf``, ``g_thetaM``, ``c_xf`` (N s/m),
        ``c_thetaM`` (N m s/rad).
    z : dict of str to float
        The standard-normal deviates behind it (0 = the population median).
    """
    x = math.log(diameter / D_REF)
    z = dict(zip(LAW_NAMES, (float(v) for v in rng.standard_normal(len(LAW_NAMES)))))
    return {n: _value(population.laws[n], n, x, z[n]) for n in LAW_NAMES}, z
