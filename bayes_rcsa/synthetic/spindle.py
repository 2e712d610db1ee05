"""The synthetic spindle: a stepped shaft on bearing spring-dampers, with the holder taper.

Geometry runs from the holder flange (z = 0, the spindle nose face where the
holder's flange sits) rearwards, i.e. towards negative z.  The holder taper
sits inside the spindle nose and bends with it (composite section over
``taper_length``).  The bearings are spring-dampers to the ground
(translational and, optionally, rotational).  The flange receptance that a
user would obtain from a spindle identification is the 2x2 point block at
z = 0 of this structure alone (:func:`flange_receptance`).

The x and y directions differ only by ``y_stiffness_factor`` on the bearing
stiffnesses (bearing and housing anisotropy), which is enough to give the
slightly different x/y tool-point frequencies seen on real machines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import SetupError
from ..model.materials import Material
from ..model.sections import SectionProperties, circular_section, composite_section
from .fe import Chain, Joint, NodeRef, assemble, mesh, receptance

__all__ = [
    "ShaftSegment",
    "Bearing",
    "SpindleModel",
    "spindle_breakpoints",
    "spindle_section",
    "bearing_joints",
    "spindle_chain",
    "flange_receptance",
]


def _check_positive(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise SetupError(f"{what} = {value!r}: expected a finite number > 0")
    return float(value)


def _check_nonnegative(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise SetupError(f"{what} = {value!r}: expected a finite number >= 0")
    return float(value)


@dataclass(frozen=True)
class ShaftSegment:
    """A uniform piece of the spindle shaft: ``length``, ``outer_diameter``, ``inner_diameter`` (m)."""

    length: float
    outer_diameter: float
    inner_diameter: float = 0.0

    def __post_init__(self) -> None:
        _check_positive(self.length, "spindle segment length")
        _check_positive(self.outer_diameter, "spindle segment outer_diameter")
        _check_nonnegative(self.inner_diameter, "spindle segment inner_diameter")
        if self.inner_diameter >= self.outer_diameter:
            raise SetupError(
                f"spindle segment inner_diameter = {self.inner_diameter!r}: expected less than "
                f"outer_diameter {self.outer_diameter!r} m"
            )


@dataclass(frozen=True)
class Bearing:
    """A bearing as spring-dampers to the ground.

    Attributes
    ----------
    position : float
        m, distance from the flange rearwards (> 0 lies behind the nose face).
    stiffness : N/m
    damping : N s/m
    rotational_stiffness : N m/rad (0: a pure radial bearing)
    rotational_damping : N m s/rad
    """

    position: float
    stiffness: float
    damping: float
    rotational_stiffness: float = 0.0
    rotational_damping: float = 0.0

    def __post_init__(self) -> None:
        _check_nonnegative(self.position, "bearing position")
        _check_positive(self.stiffness, "bearing stiffness")
        _check_nonnegative(self.damping, "bearing damping")
        _check_nonnegative(self.rotational_stiffness, "bearing rotational_stiffness")
        _check_nonnegative(self.rotational_damping, "bearing rotational_damping")


@dataclass(frozen=True)
class SpindleModel:
    """Parameters of the synthetic spindle.

    Attributes
    ----------
    material : str
        Name of the shaft material in the bench's material table.
    segments : tuple of ShaftSegment
        From the flange rearwards.
    bearings : tuple of Bearing
        At least two.
    taper_length : float
        m, length of the holder taper inside the spindle nose (0: none).
    taper_diameter : float
        m, mean diameter of the (solid) taper; it must fit the nose bore.
    y_stiffness_factor : float
        Bearing stiffness in y relative to x.
    mesh_size : float
        m, longest shaft element.
    """

    material: str
    segments: tuple[ShaftSegment, ...]
    bearings: tuple[Bearing, ...]
    taper_length: float = 0.0
    taper_diameter: float = 0.0
    y_stiffness_factor: float = 1.0
    mesh_size: float = 0.01

    def __post_init__(self) -> None:
        object.__setattr__(self, "segments", tuple(self.segments))
        object.__setattr__(self, "bearings", tuple(self.bearings))
        if not self.segments:
            raise SetupError("spindle.segments: expected at least one shaft segment")
        if len(self.bearings) < 2:
            raise SetupError(f"spindle.bearings: expected at least two bearings, got {len(self.bearings)}")
        for b in self.bearings:
            if b.position > self.length * (1 + 1e-12):
                raise SetupError(
                    f"spindle bearing at position {b.position!r} m lies beyond the shaft length {self.length!r} m"
                )
        _check_nonnegative(self.taper_length, "spindle taper_length")
        if self.taper_length > 0:
            _check_positive(self.taper_diameter, "spindle taper_diameter")
            if self.taper_length >= self.length:
                raise SetupError(
                    f"spindle taper_length = {self.taper_length!r} m: expected less than the shaft length "
                    f"{self.length!r} m"
                )
            pos = 0.0
            for seg in self.segments:
                if pos < self.taper_length and seg.inner_diameter < self.taper_diameter * (1 - 1e-9):
                    raise SetupError(
                        f"spindle taper_diameter = {self.taper_diameter!r} m does not fit the nose bore "
                        f"(inner_diameter {seg.inner_diameter!r} m within the first {self.taper_length!r} m)"
                    )
                pos += seg.length
        _check_positive(self.y_stiffness_factor, "spindle y_stiffness_factor")
        _check_positive(self.mesh_size, "spindle mesh_size")

    @property
    def length(self) -> float:
        """Shaft length, m."""
        return sum(s.length for s in self.segments)


def spindle_breakpoints(spindle: SpindleModel) -> list[float]:
    """Positions z (m, <= 0) where the mesh needs a node: steps, bearings, taper end, ends."""
    pts = [0.0]
    pos = 0.0
    for seg in spindle.segments:
        pos += seg.length
        pts.append(-pos)
    pts += [-b.position for b in spindle.bearings]
    if spindle.taper_length > 0:
        pts.append(-spindle.taper_length)
    return sorted(pts)


def spindle_section(
    spindle: SpindleModel, materials: Mapping[str, Material], taper_material: Material, z: float
) -> SectionProperties:
    """Section of the shaft (plus taper) at position ``z`` (m, -length < z < 0)."""
    depth = -float(z)
    pos = 0.0
    material = _material(materials, spindle.material)
    for seg in spindle.segments:
        if depth <= pos + seg.length:
            shaft = circular_section(material, seg.outer_diameter, seg.inner_diameter)
            if depth < spindle.taper_length:
                return composite_section(shaft, circular_section(taper_material, spindle.taper_diameter))
            return shaft
        pos += seg.length
    raise SetupError(f"z = {z!r} m lies outside the spindle shaft (length {spindle.length!r} m)")


def _material(materials: Mapping[str, Material], name: str) -> Material:
    try:
        return materials[name]
    except KeyError:
        raise SetupError(f"spindle material {name!r} is not in the material table {sorted(materials)}") from None


def bearing_joints(spindle: SpindleModel, chain: str, direction: str, stiffness_scale: float = 1.0) -> list[Joint]:
    """Bearing spring-dampers to the ground on ``chain`` for ``direction``.

    Parameters
    ----------
    spindle : SpindleModel
    chain : str
        Name of the chain carrying the shaft.
    direction : {"x", "y"}
    stiffness_scale : float
        Extra factor on every bearing stiffness (used to mimic an
        identification error in the exported flange receptance).
    """
    factor = stiffness_scale * (spindle.y_stiffness_factor if direction == "y" else 1.0)
    return [
        Joint(
            NodeRef(chain, -b.position),
            None,
            k_u=b.stiffness * factor,
            c_u=b.damping,
            k_psi=b.rotational_stiffness * factor,
            c_psi=b.rotational_damping,
        )
        for b in spindle.bearings
    ]


def spindle_chain(
    spindle: SpindleModel, materials: Mapping[str, Material], taper_material: Material, name: str = "outer"
) -> Chain:
    """The spindle shaft alone as a meshed chain from its rear end to the flange (z = 0)."""
    z = mesh(spindle_breakpoints(spindle), spindle.mesh_size)
    mid = 0.5 * (z[:-1] + z[1:])
    return Chain(name, z, tuple(spindle_section(spindle, materials, taper_material, m) for m in mid))


def flange_receptance(
    spindle: SpindleModel,
    materials: Mapping[str, Material],
    taper_material: Material,
    direction: str,
    frequency_hz,
    stiffness_scale: float = 1.0,
) -> np.ndarray:
    """2x2 point receptance of the spindle alone at the flange (z = 0).

    Parameters
    ----------
    spindle, materials, taper_material : the spindle description
    direction : {"x", "y"}
    frequency_hz : (n_freq,) Hz, > 0
    stiffness_scale : float
        Factor on the bearing stiffnesses (1: the true spindle).

    Returns
    -------
    (n_freq, 2, 2) complex, ``[[h, l], [n, p]]`` in m/N, 1/N, rad/N, rad/(N m).
    """
    chain = spindle_chain(spindle, materials, taper_material)
    model = assemble([chain], bearing_joints(spindle, chain.name, direction, stiffness_scale))
    flange = NodeRef(chain.name, 0.0)
    dofs = [model.dof(flange, "u"), model.dof(flange, "psi")]
    return receptance(model, 2 * np.pi * np.asarray(frequency_hz, dtype=float), dofs, dofs)
