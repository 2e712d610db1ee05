"""The true structure of the bench: a full-assembly finite-element model with hidden effects.

Layout along the common axis z (m): the spindle shaft from ``-L_s`` to the
flange at 0, the holder from 0 to its tip at ``L_h``, the tool from
``L_h - l_c`` (shank end, ``l_c`` the clamping length) to its tip at
``L_h + (L_t - l_c)``.  Two chains of Timoshenko elements:

* ``outer``: spindle shaft (with the holder taper) and holder; bearings are
  spring-dampers from its nodes to the ground;
* ``tool``: the tool, joined to ``outer`` by the contact.

Contact models
--------------
``lumped`` (the RCSA model's physics): the clamped shank is merged with the
holder into a composite section over the clamping length, and the tool
overhang starts at the holder tip, where one spring-damper pair
``K = diag(k_xf + i w c_xf, k_thetaM + i w c_thetaM)`` joins it to the
holder.  ``distributed``: the shank is a separate beam inside the (hollow)
holder, joined at every pair of coincident nodes over the clamping length by
spring-dampers with weights ``w_i`` (trapezoidal rule, ``sum w_i = 1``), so
that the translational and rotational stiffnesses and dampings of the node
springs *sum* to k_xf, k_thetaM, c_xf, c_thetaM.  (A rigid shank
translating relative to the holder therefore feels exactly k_xf; a rigid
rotation feels k_thetaM plus the small couple of the spread translational
springs, ``sum w_i k_xf (z_i - z_c)^2``.)

Everything a user would not know (the hidden effects) is applied here; the
user's beliefs are written by :mod:`bayes_rcsa.synthetic.campaign`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import SetupError
from ..model.assembly import Configuration
from ..model.geometry import Tool, ToolSegment
from ..model.receptance import PointReceptance
from ..model.sections import SectionProperties, circular_section, composite_section
from .config import BenchConfig
from .effects import stiffness_factor
from .fe import Chain, FEModel, Joint, NodeRef, PointMass, Resonator, assemble, mesh, receptance
from .spindle import bearing_joints, flange_receptance, spindle_breakpoints, spindle_section

__all__ = [
    "true_contact",
    "true_tool",
    "build_assembly",
    "true_tool_point_frf",
    "true_spindle_receptance",
    "exported_spindle_receptance",
    "OUTER",
    "TOOL",
]

OUTER = "outer"
TOOL = "tool"


def true_contact(config: BenchConfig, clamping_length: float) -> dict[str, float]:
    """True contact parameters at one clamping length.

    Returns
    -------
    dict with k_xf (N/m), k_thetaM (N m/rad), c_xf (N s/m), c_thetaM (N m s/rad) and the joint's
    hysteretic loss factor ``eta`` (1; 0 unless the ``joint_loss_factor`` effect is hidden)
    """
    s = config.hidden_effects.get("nonlinear_stiffness_law", 0.0)
    g_theta = config.growth if config.growth_thetaM is None else config.growth_thetaM
    law = {"kind": config.stiffness_law_kind, "ramp": (config.ramp_start, config.ramp_width)}
    fx = float(stiffness_factor(clamping_length, config.clamping_range, config.growth, s, **law))
    ft = float(stiffness_factor(clamping_length, config.clamping_range, g_theta, s, **law))
    if fx <= 0 or ft <= 0:
        raise SetupError(
            f"clamping length {clamping_length!r} m: the contact law gives a non-positive stiffness factor "
            f"{min(fx, ft)!r} (too far outside clamping_range {list(config.clamping_range)!r})"
        )
    damp = config.hidden_effects.get("contact_damping", 1.0)
    return {
        "k_xf": config.k_xf * fx,
        "k_thetaM": config.k_thetaM * ft,
        "c_xf": config.c_xf * damp,
        "c_thetaM": config.c_thetaM * damp,
        "eta": config.hidden_effects.get("joint_loss_factor", 0.0),
    }


def true_tool(config: BenchConfig) -> Tool:
    """The tool as it really is: fluted segments thinner by the ``fluted_section`` magnitude."""
    tool = config.tool
    m = config.hidden_effects.get("fluted_section")
    if m is None:
        return tool
    segs = tuple(
        dataclasses.replace(s, diameter_ratio=s.diameter_ratio * (1.0 - m)) if s.diameter_ratio < 1 else s
        for s in tool.segments
    )
    return dataclasses.replace(tool, segments=segs)


def _holder_piece(config: BenchConfig, z: float):
    pos = 0.0
    for seg in config.holder_segments:
        if z <= pos + seg.length:
            return seg
        pos += seg.length
    raise SetupError(f"z = {z!r} m lies beyond the holder tip")


def _tool_piece(tool: Tool, distance_from_tip: float) -> ToolSegment:
    pos = 0.0
    for seg in tool.segments:
        if distance_from_tip <= pos + seg.length:
            return seg
        pos += seg.length
    raise SetupError(f"distance {distance_from_tip!r} m from the tool tip lies beyond the shank end")


def _tool_section(tool: Tool, distance_from_tip: float) -> SectionProperties:
    return circular_section(tool.material, _tool_piece(tool, distance_from_tip).effective_diameter)


def build_assembly(config: BenchConfig, configuration: Configuration) -> tuple[FEModel, int]:
    """Finite-element model of the true spindle-holder-tool assembly.

    Parameters
    ----------
    config : BenchConfig
    configuration : Configuration
        Clamping length (m) and direction; the tool name is not used (the
        bench has one tool).

    Returns
    -------
    model : FEModel
    tip : int
        DOF number of the lateral displacement u at the tool tip.
    """
    if configuration.direction not in ("x", "y"):
        raise SetupError(f"direction {configuration.direction!r}: expected 'x' or 'y'")
    cl = float(configuration.clamping_length)
    holder = config.holder
    tool = true_tool(config)
    if not (0 < cl < holder.bore_depth and cl < tool.total_length):
        raise SetupError(
            f"clamping length {cl!r} m: expected 0 < l < bore depth {holder.bore_depth!r} m and < tool length "
            f"{tool.total_length!r} m"
        )
    hmat = config.materials[config.holder_material]
    Lh = holder.length
    z_clamp = Lh - cl
    z_tip = Lh + tool.total_length - cl

    # Shared mesh forward of the flange, so that holder and tool nodes coincide
    # wherever both exist (needed by the distributed contact).
    fwd = [0.0, Lh, z_clamp, z_tip]
    pos = 0.0
    for seg in config.holder_segments:
        pos += seg.length
        fwd.append(pos)
    pos = 0.0
    for seg in tool.segments:
        pos += seg.length
        fwd.append(z_tip - pos)
    z_fwd = mesh(fwd, config.mesh_size)
    z_sp = mesh(spindle_breakpoints(config.spindle), config.spindle.mesh_size)

    distributed = config.contact_model == "distributed"
    z_outer = np.concatenate([z_sp[:-1], z_fwd[z_fwd <= Lh + 1e-12]])
    outer_sections = []
    for a, b in zip(z_outer[:-1], z_outer[1:]):
        m = 0.5 * (a + b)
        if m < 0:
            outer_sections.append(spindle_section(config.spindle, config.materials, hmat, m))
            continue
        hs = _holder_piece(config, m)
        sec = circular_section(hmat, hs.outer_diameter, hs.inner_diameter)
        if not distributed and m > z_clamp:
            sec = composite_section(sec, _tool_section(tool, z_tip - m))
        outer_sections.append(sec)
    outer = Chain(OUTER, z_outer, tuple(outer_sections))

    z_tool_start = z_clamp if distributed else Lh
    z_tool = z_fwd[z_fwd >= z_tool_start - 1e-12]
    tool_chain = Chain(
        TOOL, z_tool, tuple(_tool_section(tool, z_tip - 0.5 * (a + b)) for a, b in zip(z_tool[:-1], z_tool[1:]))
    )

    c = true_contact(config, cl)
    # a hysteretic joint is a complex stiffness: the assembled stiffness matrix is complex anyway
    loss = 1.0 + 1j * c["eta"]
    joints = bearing_joints(config.spindle, OUTER, configuration.direction)
    if distributed:
        zc = z_tool[z_tool <= Lh + 1e-12]
        w = np.zeros(zc.size)
        dz = np.diff(zc)
        w[:-1] += dz / 2
        w[1:] += dz / 2
        w /= w.sum()
        joints += [
            Joint(NodeRef(OUTER, z), NodeRef(TOOL, z),
                  wi * c["k_xf"] * loss, wi * c["c_xf"], wi * c["k_thetaM"] * loss, wi * c["c_thetaM"])
            for z, wi in zip(zc, w)
        ]
    else:
        joints.append(Joint(NodeRef(OUTER, Lh), NodeRef(TOOL, Lh), c["k_xf"] * loss, c["c_xf"], c["k_thetaM"] * loss,
                            c["c_thetaM"]))

    masses = []
    if "tip_mass" in config.hidden_effects:
        m = config.hidden_effects["tip_mass"]
        masses.append(PointMass(NodeRef(TOOL, z_tip), m, m * config.tip_mass_radius_of_gyration**2))
    resonators = []
    if "extra_mode" in config.hidden_effects:
        resonators.append(_extra_mode(config, Lh))

    model = assemble([outer, tool_chain], joints, masses, resonators)
    return model, model.dof(NodeRef(TOOL, z_tip), "u")


def _extra_mode(config: BenchConfig, holder_length: float) -> Resonator:
    m = config.hidden_effects["extra_mode"]
    w = 2 * math.pi * config.extra_mode_frequency
    z = 0.0 if config.extra_mode_location == "flange" else holder_length
    return Resonator(NodeRef(OUTER, z), m, m * w * w, 2 * config.extra_mode_damping_ratio * m * w)


def extra_mode_parameters(config: BenchConfig) -> dict:
    """The resonator of the ``extra_mode`` effect: mass (kg), stiffness (N/m), damping (N s/m), location."""
    r = _extra_mode(config, config.holder.length)
    return {
        "mass": r.mass,
        "stiffness": r.stiffness,
        "damping": r.damping,
        "frequency_hz": config.extra_mode_frequency,
        "damping_ratio": config.extra_mode_damping_ratio,
        "location": config.extra_mode_location,
        "z": r.node.z,
    }


def true_tool_point_frf(config: BenchConfig, configuration: Configuration, frequency_hz) -> np.ndarray:
    """Noise-free tool-point receptance of the true structure (hidden effects included).

    Parameters
    ----------
    config : BenchConfig
    configuration : Configuration
    frequency_hz : (n_freq,) Hz, > 0

    Returns
    -------
    (n_freq,) complex, m/N, h = u/F at the tool tip.
    """
    model, tip = build_assembly(config, configuration)
    return receptance(model, 2 * np.pi * np.asarray(frequency_hz, dtype=float), [tip], [tip])[:, 0, 0]


def true_spindle_receptance(config: BenchConfig, direction: str, frequency_hz) -> PointReceptance:
    """Flange receptance of the true spindle alone (no perturbation, no extra mode).

    Returns
    -------
    PointReceptance with block (n_freq, 2, 2)
    """
    f = np.asarray(frequency_hz, dtype=float)
    hmat = config.materials[config.holder_material]
    block = flange_receptance(config.spindle, config.materials, hmat, direction, f)
    return PointReceptance(f, block, source=f"synthetic spindle {direction} (true)")


def exported_spindle_receptance(config: BenchConfig, direction: str, frequency_hz) -> PointReceptance:
    """Flange receptance as exported to the user (what a spindle identification would give).

    The ``spindle_error`` effect scales the bearing stiffnesses of the
    exported spindle by (1 + magnitude); ``spindle_rotation_omitted`` keeps
    (1 - magnitude) of l, n and p.  The ``extra_mode`` resonator is never
    part of it.
    """
    f = np.asarray(frequency_hz, dtype=float)
    hmat = config.materials[config.holder_material]
    scale = 1.0 + config.hidden_effects.get("spindle_error", 0.0)
    block = flange_receptance(config.spindle, config.materials, hmat, direction, f, stiffness_scale=scale)
    keep = 1.0 - config.hidden_effects.get("spindle_rotation_omitted", 0.0)
    if keep != 1.0:
        block[:, 0, 1] *= keep
        block[:, 1, 0] *= keep
        block[:, 1, 1] *= keep
    return PointReceptance(f, block, source=f"spindle_{direction}")
