"""Cross-section properties of the rotor bench: circles, tubes, composites and fluted end-mill profiles.

Written for the rotor bench alone (no code shared with :mod:`bayes_rcsa.model`).

* Circular and hollow circular sections use Cowper's (1966) shear
  coefficient ``κ = 6(1+ν)(1+m²)² / ((7+6ν)(1+m²)² + (20+12ν)m²)``,
  ``m = d_i / d_o``.
* A fluted end-mill section is built as a polygon: ``n`` flutes, each a
  circular-arc gullet whose deepest point touches the core circle
  (``core_ratio × D``) and whose ends meet the outer circle, separated by
  cylindrical lands (``land_fraction`` of the pitch).  Area and second moment
  are integrated exactly over the polygon (shoelace / Green's theorem).  The
  shear coefficient is the Jourawski (shear-flow energy) estimate
  ``1/κ_J = A/I² ∫ Q(y)²/b(y) dy`` computed by slicing the polygon, scaled so
  that a full circle gives Cowper's value:
  ``κ = κ_Cowper(ν) · κ_J(profile) / κ_J(circle)``.
  With three or more equally spaced flutes the second moment is the same
  about every axis, so the helix angle does not change it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = [
    "RotorMaterial",
    "BeamSection",
    "cowper_kappa",
    "tube_section",
    "composite",
    "FluteProfile",
    "flute_polygon",
    "polygon_area_inertia",
    "jourawski_kappa",
    "flute_section",
]


@dataclass(frozen=True)
class RotorMaterial:
    """Linear elastic material with a structural loss factor.

    Attributes
    ----------
    youngs_modulus : float, Pa
    density : float, kg/m^3
    poisson_ratio : float
    loss_factor : float
        Hysteretic loss factor η: E -> E(1 + iη), G -> G(1 + iη).
    """

    youngs_modulus: float
    density: float
    poisson_ratio: float
    loss_factor: float

    @property
    def shear_modulus(self) -> float:
        """G = E / (2(1 + ν)), Pa."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True)
class BeamSection:
    """Timoshenko section properties; the stiffness terms are complex (structural damping).

    Attributes
    ----------
    EI : complex, N m^2
    kGA : complex, N (shear coefficient × G × A)
    rhoA : float, kg/m
    rhoI : float, kg m (rotary inertia per length)
    """

    EI: complex
    kGA: complex
    rhoA: float
    rhoI: float

    def __add__(self, other: "BeamSection") -> "BeamSection":
        return BeamSection(self.EI + other.EI, self.kGA + other.kGA, self.rhoA + other.rhoA, self.rhoI + other.rhoI)

    def scaled(self, stiffness: float = 1.0, mass: float = 1.0, shear: float | None = None,
               rotary: float | None = None) -> "BeamSection":
        """Section with EI × ``stiffness``, κGA × ``shear`` (default ``stiffness``), ρA × ``mass``, ρI × ``rotary`` (default ``mass``)."""
        shear = stiffness if shear is None else shear
        rotary = mass if rotary is None else rotary
        return BeamSection(self.EI * stiffness, self.kGA * shear, self.rhoA * mass, self.rhoI * rotary)


def cowper_kappa(poisson_ratio: float, diameter_ratio: float = 0.0) -> float:
    """Cowper's shear coefficient of a solid (``diameter_ratio = 0``) or hollow circle.

    Parameters
    ----------
    poisson_ratio : float
    diameter_ratio : float
        Inner over outer diameter, in [0, 1).
    """
    nu = poisson_ratio
    m2 = diameter_ratio**2
    return 6 * (1 + nu) * (1 + m2) ** 2 / ((7 + 6 * nu) * (1 + m2) ** 2 + (20 + 12 * nu) * m2)


def _from_geometry(material: RotorMaterial, area: float, inertia: float, kappa: float,
                   modulus_scale: float = 1.0) -> BeamSection:
    cplx = 1.0 + 1j * material.loss_factor
    E = material.youngs_modulus * modulus_scale * cplx
    G = material.shear_modulus * modulus_scale * cplx
    return BeamSection(E * inertia, kappa * G * area, material.density * area, material.density * inertia)


def tube_section(material: RotorMaterial, outer_diameter: float, inner_diameter: float = 0.0,
                 modulus_scale: float = 1.0) -> BeamSection:
    """Solid or hollow circular section.

    Parameters
    ----------
    material : RotorMaterial
    outer_diameter, inner_diameter : float, m
    modulus_scale : float
        Factor on E and G (the ``tool_modulus`` effect).
    """
    D, d = float(outer_diameter), float(inner_diameter)
    area = np.pi / 4 * (D**2 - d**2)
    inertia = np.pi / 64 * (D**4 - d**4)
    return _from_geometry(material, area, inertia, cowper_kappa(material.poisson_ratio, d / D), modulus_scale)


def composite(*parts: BeamSection) -> BeamSection:
    """Perfectly bonded parts bending about one neutral axis: the sum of their properties."""
    out = parts[0]
    for p in parts[1:]:
        out = out + p
    return out


@dataclass(frozen=True)
class FluteProfile:
    """Geometry of a fluted end-mill cross-section.

    Attributes
    ----------
    n_flutes : int
    core_ratio : float
        Core (web) diameter over the cutter diameter.
    land_fraction : float
        Part of each flute pitch that is cylindrical land (outer circle), in [0, 1).
    """

    n_flutes: int = 4
    core_ratio: float = 0.60
    land_fraction: float = 0.30


def flute_polygon(diameter: float, profile: FluteProfile, n_points: int = 2880) -> np.ndarray:
    """Boundary of a fluted section, counter-clockwise.

    Parameters
    ----------
    diameter : float, m
    profile : FluteProfile
    n_points : int

    Returns
    -------
    (n_points, 2) float, m
        x, y of the boundary points (star-shaped about the axis).
    """
    R = diameter / 2
    rc = profile.core_ratio * R
    pitch = 2 * np.pi / profile.n_flutes
    alpha = 0.5 * pitch * (1.0 - profile.land_fraction)  # half angle of a gullet
    if not R * np.cos(alpha) > rc:
        raise ValueError("flute profile: core circle must lie inside the gullet chord (R cos α > r_core)")
    d = (R**2 - rc**2) / (2 * (R * np.cos(alpha) - rc))  # distance of the arc centre from the axis
    rho = d - rc  # arc radius
    phi = np.linspace(0.0, 2 * np.pi, n_points, endpoint=False)
    # angle from the nearest gullet centre (gullet centres at (k + 1/2) pitch)
    delta = np.mod(phi, pitch) - 0.5 * pitch
    r = np.full_like(phi, R)
    inside = np.abs(delta) < alpha
    dl = delta[inside]
    r[inside] = d * np.cos(dl) - np.sqrt(np.maximum(rho**2 - (d * np.sin(dl)) ** 2, 0.0))
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)])


def polygon_area_inertia(points: np.ndarray) -> tuple[float, float, float]:
    """Area and second moments of a closed polygon about the origin.

    Parameters
    ----------
    points : (n, 2) float, counter-clockwise

    Returns
    -------
    area : float, m^2
    Ixx : float, m^4 (∫ y² dA, bending in the y direction)
    Iyy : float, m^4 (∫ x² dA)
    """
    x, y = points[:, 0], points[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum()
    Ixx = (cross * (y**2 + y * y1 + y1**2)).sum() / 12.0
    Iyy = (cross * (x**2 + x * x1 + x1**2)).sum() / 12.0
    return float(area), float(Ixx), float(Iyy)


def jourawski_kappa(points: np.ndarray, n_slices: int = 1200) -> float:
    """Shear coefficient by the Jourawski shear-flow energy, ``1/κ = A/I² ∫ Q²/b dy``.

    Parameters
    ----------
    points : (n, 2) float
        Closed polygon, symmetric about y = 0.
    n_slices : int
        Number of horizontal slices (midpoint rule).

    Returns
    -------
    float
        For a rectangle 5/6; for a full circle about 0.9.
    """
    x, y = points[:, 0], points[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    ymin, ymax = y.min(), y.max()
    edges = np.linspace(ymin, ymax, n_slices + 1)
    yc = 0.5 * (edges[:-1] + edges[1:])
    dy = edges[1] - edges[0]
    b = np.empty(n_slices)
    for k, yy in enumerate(yc):
        crosses = (y - yy) * (y1 - yy) < 0
        t = (yy - y[crosses]) / (y1[crosses] - y[crosses])
        xs = np.sort(x[crosses] + t * (x1[crosses] - x[crosses]))
        b[k] = (xs[1::2] - xs[0::2]).sum()
    area = (b * dy).sum()
    ybar = (yc * b * dy).sum() / area
    yc = yc - ybar
    inertia = (yc**2 * b * dy).sum()
    # Q(y) = ∫_y^ymax y' b dy', evaluated at the slice mid-heights
    moment = yc * b * dy
    Q = np.cumsum(moment[::-1])[::-1] - 0.5 * moment
    integral = (Q**2 / np.maximum(b, 1e-300) * dy).sum()
    return float(inertia**2 / (area * integral))


@lru_cache(maxsize=64)
def _profile_geometry(diameter: float, profile: FluteProfile) -> tuple[float, float, float]:
    """Area (m²), mean second moment (m⁴) and κ_J(profile)/κ_J(circle) of a flute profile (cached)."""
    pts = flute_polygon(diameter, profile)
    area, Ixx, Iyy = polygon_area_inertia(pts)
    t = np.linspace(0.0, 2 * np.pi, pts.shape[0], endpoint=False)
    circle = 0.5 * diameter * np.column_stack([np.cos(t), np.sin(t)])
    return area, 0.5 * (Ixx + Iyy), jourawski_kappa(pts) / jourawski_kappa(circle)


def flute_section(material: RotorMaterial, diameter: float, profile: FluteProfile,
                  modulus_scale: float = 1.0) -> tuple[BeamSection, dict]:
    """Section of a fluted end mill from its profile.

    Parameters
    ----------
    material : RotorMaterial
    diameter : float, m
        Cutter (outer) diameter.
    profile : FluteProfile
    modulus_scale : float
        Factor on E and G.

    Returns
    -------
    section : BeamSection
    geometry : dict
        ``area_ratio`` (A / A_circle), ``inertia_ratio`` (I / I_circle),
        ``area_equivalent_diameter_ratio`` (√area_ratio),
        ``inertia_equivalent_diameter_ratio`` (inertia_ratio^¼), ``kappa``.
    """
    area, inertia, kappa_ratio = _profile_geometry(float(diameter), profile)
    kappa = cowper_kappa(material.poisson_ratio) * kappa_ratio
    a_circ = np.pi / 4 * diameter**2
    i_circ = np.pi / 64 * diameter**4
    geometry = {
        "n_flutes": profile.n_flutes, "core_ratio": profile.core_ratio, "land_fraction": profile.land_fraction,
        "area": area, "second_moment": inertia,
        "area_ratio": area / a_circ, "inertia_ratio": inertia / i_circ,
        "area_equivalent_diameter_ratio": float(np.sqrt(area / a_circ)),
        "inertia_equivalent_diameter_ratio": float((inertia / i_circ) ** 0.25),
        "kappa": kappa,
    }
    return _from_geometry(material, area, inertia, kappa, modulus_scale), geometry
