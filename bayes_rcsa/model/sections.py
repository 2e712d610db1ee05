"""Beam cross-section properties for circular solid, hollow and composite sections.

A Timoshenko segment needs four section properties only: bending stiffness
EI, shear stiffness kappa*G*A, mass per length rho*A and rotary inertia per
length rho*I.  :class:`SectionProperties` carries exactly these, so that a
composite section (a tool shank clamped in a holder bore) is the plain sum of
its parts.

Shear coefficient
-----------------
Cowper (1966), J. Appl. Mech. 33:335, for a hollow circle with diameter
ratio m = d_i / d_o::

    kappa = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu) m^2)

which reduces to 6 (1 + nu) / (7 + 6 nu) for a solid circle (m = 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from .materials import Material

__all__ = [
    "SectionProperties",
    "cowper_shear_coefficient",
    "circular_section",
    "composite_section",
]


@dataclass(frozen=True)
class SectionProperties:
    """Timoshenko section properties (complex moduli carry structural damping).

    Attributes
    ----------
    EI : complex
        Bending stiffness, N m^2.
    kGA : complex
        Shear stiffness kappa G A, N.  ``math.inf`` is not allowed; use a
        large value for the Euler-Bernoulli limit.
    rhoA : float
        Mass per unit length, kg/m.
    rhoI : float
        Rotary inertia per unit length, kg m.  Zero drops rotary inertia.
    """

    EI: complex
    kGA: complex
    rhoA: float
    rhoI: float

    def __post_init__(self) -> None:
        for key in ("EI", "kGA"):
            v = complex(getattr(self, key))
            if not (np.isfinite(v) and v.real > 0):
                raise SetupError(f"section {key} = {v!r}: expected finite with a positive real part")
        if not (np.isfinite(self.rhoA) and self.rhoA > 0):
            raise SetupError(f"section rhoA = {self.rhoA!r}: expected a finite value > 0")
        if not (np.isfinite(self.rhoI) and self.rhoI >= 0):
            raise SetupError(f"section rhoI = {self.rhoI!r}: expected a finite value >= 0")

    def __add__(self, other: "SectionProperties") -> "SectionProperties":
        return SectionProperties(
            self.EI + other.EI, self.kGA + other.kGA, self.rhoA + other.rhoA, self.rhoI + other.rhoI
        )


def cowper_shear_coefficient(poisson_ratio: float, diameter_ratio: float = 0.0) -> float:
    """Cowper's shear coefficient of a (hollow) circular section.

    Parameters
    ----------
    poisson_ratio : float
        nu, dimensionless.
    diameter_ratio : float
        d_inner / d_outer in [0, 1).
    """
    nu, m2 = poisson_ratio, diameter_ratio**2
    return 6 * (1 + nu) * (1 + m2) ** 2 / ((7 + 6 * nu) * (1 + m2) ** 2 + (20 + 12 * nu) * m2)


def circular_section(material: Material, outer_diameter: float, inner_diameter: float = 0.0) -> SectionProperties:
    """Section properties of a solid or hollow circular section.

    Parameters
    ----------
    material : Material
    outer_diameter, inner_diameter : float
        m; ``inner_diameter = 0`` for a solid section.
    """
    if not (math.isfinite(outer_diameter) and outer_diameter > 0):
        raise SetupError(f"outer diameter {outer_diameter!r} m: expected a finite value > 0")
    if not (math.isfinite(inner_diameter) and 0 <= inner_diameter < outer_diameter):
        raise SetupError(
            f"inner diameter {inner_diameter!r} m: expected 0 <= inner < outer diameter {outer_diameter!r} m"
        )
    area = math.pi / 4 * (outer_diameter**2 - inner_diameter**2)
    inertia = math.pi / 64 * (outer_diameter**4 - inner_diameter**4)
    kappa = cowper_shear_coefficient(material.poisson_ratio, inner_diameter / outer_diameter)
    return SectionProperties(
        EI=material.complex_youngs_modulus * inertia,
        kGA=kappa * material.complex_shear_modulus * area,
        rhoA=material.density * area,
        rhoI=material.density * inertia,
    )


def composite_section(*parts: SectionProperties) -> SectionProperties:
    """Sum of sections that bend together (perfect bond, common neutral axis).

    Used for the clamped tool shank inside the holder bore.  Summing kGA
    assumes both parts shear by the same angle, the same kinematic
    assumption as summing EI.
    """
    if not parts:
        raise SetupError("composite section needs at least one part")
    total = parts[0]
    for part in parts[1:]:
        total = total + part
    return total
