"""Isotropic linear-elastic materials with structural (hysteretic) damping."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SetupError

__all__ = ["Material"]


@dataclass(frozen=True)
class Material:
    """An isotropic material.

    Parameters
    ----------
    youngs_modulus : float
        Young's modulus E, Pa.
    density : float
        Mass density rho, kg/m^3.
    poisson_ratio : float
        Poisson's ratio nu, dimensionless, in (-1, 0.5).
    loss_factor : float
        Structural loss factor eta >= 0; the complex moduli are
        E* = E (1 + i eta) and G* = G (1 + i eta).
    name : str
        Label used in error messages.
    """

    youngs_modulus: float
    density: float
    poisson_ratio: float = 0.3
    loss_factor: float = 0.0
    name: str = "material"

    def __post_init__(self) -> None:
        checks = [
            ("youngs_modulus", self.youngs_modulus, self.youngs_modulus > 0, "> 0"),
            ("density", self.density, self.density > 0, "> 0"),
            ("poisson_ratio", self.poisson_ratio, -1.0 < self.poisson_ratio < 0.5, "in (-1, 0.5)"),
            ("loss_factor", self.loss_factor, self.loss_factor >= 0, ">= 0"),
        ]
        for key, value, ok, expected in checks:
            if not (isinstance(value, (int, float)) and math.isfinite(value) and ok):
                raise SetupError(
                    f"material {self.name!r}: {key} = {value!r}, expected a finite number {expected}"
                )

    @property
    def shear_modulus(self) -> float:
        """Real shear modulus G = E / (2 (1 + nu)), Pa."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def complex_youngs_modulus(self) -> complex:
        """E (1 + i eta), Pa."""
        return self.youngs_modulus * (1.0 + 1j * self.loss_factor)

    @property
    def complex_shear_modulus(self) -> complex:
        """G (1 + i eta), Pa."""
        return self.shear_modulus * (1.0 + 1j * self.loss_factor)
