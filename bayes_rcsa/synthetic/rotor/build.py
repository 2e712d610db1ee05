"""The true structure of the rotor bench as a finite-element model, for one direction and clamping length.

Layout along the beam axis z (m; z = 0 at the spindle face / gauge line,
z > 0 towards the tool tip):

* spindle shaft from its rear end to z = 0, stepped hollow sections with
  non-structural mass (drawbar, motor rotor), on three or more bearing sets;
* every bearing set couples the shaft node to a rigid housing (translation
  and rotation: the housing point moves by ``u_h + (z_b − z_h) θ_h``); the
  housing sits on mounting springs to the rigid head;
* the holder taper (conical, retention-knob bore) from ``−taper.length`` to
  0, joined to the coincident spindle nodes by distributed radial springs
  (the taper joint);
* the holder outside the spindle from 0 to its tip (the declared segments);
  over the clamping length its section is the composite of the holder bore
  and the tool shank (perfect bond);
* the tool overhang from the holder tip to the tool tip, joined to the holder
  tip by the lumped contact spring–dampers (or, with
  ``contact_model = "distributed"``, the whole tool with its clamped part on
  distributed springs along the clamping length);
* hidden effects: a tip body, a ring resonator on the nut, a fluted profile,
  slots, a changed tool modulus, a hysteretic joint, ...

The exported spindle substructure is everything up to z = 0 (spindle,
bearings, housing, taper joint, holder taper); its point block at the z = 0
node of the holder is what a spindle identification would deliver.
"""

from __future__ import annotations

import math

import numpy as np

from .config import BearingSet, RotorBenchConfig, front_bearing_sets
from .sections import BeamSection, FluteProfile, composite, flute_section, tube_section
from .structure import Structure, mesh_points

__all__ = ["true_contact", "build_structure", "tip_body", "ring_resonator", "fluted_truth", "stiffness_law_factor",
           "exported_bearing_factors"]


def stiffness_law_factor(config: RotorBenchConfig, clamping_length: float, growth: float) -> float:
    """``k(l) / k(l_a)`` of the true law.

    Linear ``1 + g x`` with ``x = (l − l_a)/(l_b − l_a)``; with the
    ``nonlinear_stiffness_law`` effect either saturating,
    ``1 + g (1 − e^{−a x}) / (1 − e^{−a})`` (a = magnitude; equal to the
    linear law at l_a and l_b, stiffer in between), or a step,
    ``(1 + g x)(1 + s·[l ≥ step_position])`` (s = magnitude).
    """
    la, lb = config.clamping_range
    x = (clamping_length - la) / (lb - la)
    m = config.magnitude("nonlinear_stiffness_law")
    if m is None:
        return 1.0 + growth * x
    if config.stiffness_law_kind == "saturating":
        return 1.0 + growth * (1.0 - math.exp(-m * x)) / (1.0 - math.exp(-m))
    return (1.0 + growth * x) * (1.0 + (m if clamping_length >= config.step_position else 0.0))


def true_contact(config: RotorBenchConfig, clamping_length: float) -> dict:
    """True tool–holder joint at a clamping length.

    Returns
    -------
    dict
        ``k_xf`` (N/m), ``k_thetaM`` (N m/rad), ``c_xf`` (N s/m),
        ``c_thetaM`` (N m s/rad), ``loss_factor`` (hysteretic joint, 0 if none).
    """
    factor = config.magnitude("contact_damping") or 1.0
    eta = config.magnitude("hysteretic_joint")
    c_scale = 0.0 if eta is not None else factor
    return {
        "k_xf": config.k_xf * stiffness_law_factor(config, clamping_length, config.growth),
        "k_thetaM": config.k_thetaM * stiffness_law_factor(config, clamping_length, config.growth_thetaM),
        "c_xf": config.c_xf * c_scale,
        "c_thetaM": config.c_thetaM * c_scale,
        "loss_factor": 0.0 if eta is None else eta,
    }


def tip_body(config: RotorBenchConfig) -> dict | None:
    """The ``tip_mass`` body: a cylinder (sensing axis radial) on the tool side, flush with the tip.

    Returns
    -------
    dict or None
        ``mass`` (kg), ``rotary_inertia`` (kg m², about its centre,
        ``m (3r² + h²)/12``), ``offset`` (m, centre relative to the tip node
        along z, ``−r``), ``diameter``, ``height`` (m).
    """
    m = config.magnitude("tip_mass")
    if m is None:
        return None
    r = config.tip_body_diameter / 2
    h = config.tip_body_height
    return {"mass": m, "rotary_inertia": m * (3 * r * r + h * h) / 12.0, "offset": -r,
            "diameter": config.tip_body_diameter, "height": h}


def ring_resonator(config: RotorBenchConfig) -> dict | None:
    """The ``extra_mode`` ring around the collet nut on a compliant fit.

    Returns
    -------
    dict or None
        ``mass`` (kg), ``rotary_inertia`` (kg m², about a diameter),
        ``position`` (m, z of its centre), ``stiffness`` (N/m),
        ``rotational_stiffness`` (N m/rad), ``damping`` (N s/m),
        ``rotational_damping`` (N m s/rad), ``frequency_hz``.
    """
    f = config.magnitude("extra_mode")
    if f is None:
        return None
    mat = config.materials[config.holder_material]
    Ro, Ri, L = config.ring_outer_diameter / 2, config.ring_inner_diameter / 2, config.ring_length
    m = mat.density * math.pi * (Ro**2 - Ri**2) * L
    J = m * (3 * (Ro**2 + Ri**2) + L**2) / 12.0
    w = 2 * math.pi * f
    wr = w * config.ring_rocking_ratio
    z = config.holder_length - config.holder_segments[-1].length / 2
    zeta = config.ring_damping_ratio
    return {"mass": m, "rotary_inertia": J, "position": z, "frequency_hz": f,
            "stiffness": m * w * w, "rotational_stiffness": J * wr * wr,
            "damping": 2 * zeta * m * w, "rotational_damping": 2 * zeta * J * wr}


def fluted_truth(config: RotorBenchConfig) -> tuple[BeamSection, dict]:
    """True section of the fluted segment and its description.

    Without ``fluted_section``: the circle of the declared effective diameter
    (``diameter_ratio × D``, or D when ``fluted_declared = "solid"``).  With
    it: the flute profile, its flute depth scaled by the magnitude
    (``core_ratio = 1 − m (1 − core_ratio₀)``).
    """
    mat = config.materials[config.tool_material]
    E_scale = 1.0 + (config.magnitude("tool_modulus") or 0.0)
    m = config.magnitude("fluted_section")
    if m is None:
        ratio = config.diameter_ratio if config.fluted_declared == "effective" else 1.0
        return tube_section(mat, ratio * config.tool_diameter, 0.0, E_scale), {"kind": "circle", "diameter_ratio": ratio}
    p = config.flute_profile
    profile = FluteProfile(p.n_flutes, 1.0 - m * (1.0 - p.core_ratio), p.land_fraction)
    sec, geo = flute_section(mat, config.tool_diameter, profile, E_scale)
    return sec, {"kind": "profile", **geo}


def _slot_factors(config: RotorBenchConfig, direction: str) -> tuple[float, float]:
    m = config.magnitude("slotted_holder")
    if m is None:
        return 1.0, 1.0
    stiff = 1.0 - m if direction == "y" else 1.0 - m / 5.0
    return stiff, 1.0 - m / 4.0


def _bearing_scale(config: RotorBenchConfig, bearing: BearingSet, index: int, exported: bool) -> float:
    m = config.magnitude("spindle_error")
    if not exported or m is None:
        return 1.0
    kind = config.spindle_error_kind
    if kind == "preload":
        return 1.0 + m
    if kind == "one_bearing":
        return 1.0 + m if index == 0 else 1.0
    if kind == "bearing_sets":
        front = front_bearing_sets(config)[index]
        rear = config.spindle_error_rear
        return 1.0 + (m if front or rear is None else rear)
    rear = max(range(len(config.bearings)), key=lambda i: -config.bearings[i].position)
    return 1.0 + m if index == rear else 1.0


def exported_bearing_factors(config: RotorBenchConfig) -> list[dict]:
    """The exported spindle file's bearing sets relative to today's (true) ones.

    A spindle file taken on another day, at another preload or temperature,
    comes from bearings whose stiffness differs from today's, set by set and
    not in proportion.  With ``spindle_error_kind = "bearing_sets"`` the front
    sets (:func:`~bayes_rcsa.synthetic.rotor.config.front_bearing_sets`) have
    stiffness × (1 + e_front), e_front = the ``spindle_error`` magnitude, the
    rear sets × (1 + e_rear), e_rear = ``spindle_error_rear`` (None: e_front),
    translational and rotational alike.  A preload change also alters the
    rolling contacts' damping, and in the same direction: Gunduz, Dreyer and
    Singh (Mech. Syst. Signal Process. 31 (2012) 176–195, "Effect of bearing
    preloads on the modal characteristics of a shaft-bearing assembly")
    measure modal changes under controlled preloads and compare a
    preload-independent with a preload-dependent bearing damping.  Here the
    damping follows the stiffness by a power law, each set's translational and
    rotational damping × (1 + e)^β with β = ``spindle_error_damping_exponent``:
    β = 0 is preload-independent damping, β = 1 damping proportional to
    stiffness, the default β = 0.5 in between (the dashpot grows like √k, so
    the bearing's own damping ratio c / (2 √(k m)) stays put: stiffer and
    somewhat more damped).  The other kinds (``"preload"``, ``"one_bearing"``,
    ``"rear"``) change the stiffness only.

    Parameters
    ----------
    config : RotorBenchConfig

    Returns
    -------
    list of dict
        One per bearing set, in ``config.bearings`` order: ``name``,
        ``position`` (m), ``group`` (``"front"`` or ``"rear"``),
        ``stiffness_factor`` and ``rotational_stiffness_factor`` (exported /
        true), ``damping_factor`` and ``rotational_damping_factor``
        (exported / true), and the exported values ``stiffness`` (N/m),
        ``rotational_stiffness`` (N m/rad), ``damping`` (N s/m),
        ``rotational_damping`` (N m s/rad), all in the x direction (y
        stiffness × ``y_stiffness_factor`` on both rotors).  Factors are 1
        without ``spindle_error``.
    """
    front = front_bearing_sets(config)
    beta = config.spindle_error_damping_exponent
    damped = config.spindle_error_kind == "bearing_sets" and config.magnitude("spindle_error") is not None
    out = []
    for i, b in enumerate(config.bearings):
        k = _bearing_scale(config, b, i, exported=True)
        c = k ** beta if damped else 1.0
        out.append({"name": b.name, "position": b.position, "group": "front" if front[i] else "rear",
                    "stiffness_factor": k, "rotational_stiffness_factor": k,
                    "damping_factor": c, "rotational_damping_factor": c,
                    "stiffness": b.stiffness * k, "rotational_stiffness": b.rotational_stiffness * k,
                    "damping": b.damping * c, "rotational_damping": b.rotational_damping * c})
    return out


def build_structure(config: RotorBenchConfig, direction: str, clamping_length: float | None = None, *,
                    spindle_only: bool = False, exported: bool = False, rigid_contact: bool = False,
                    bearing_stiffness=None):
    """Finite-element model of the true structure.

    Parameters
    ----------
    config : RotorBenchConfig
    direction : {"x", "y"}
    clamping_length : float or None, m
        Required unless ``spindle_only``.
    spindle_only : bool
        Only the spindle substructure (shaft, bearings, housing, taper joint,
        holder taper up to the flange node at z = 0).
    exported : bool
        Apply the ``spindle_error`` bearing change (the exported file's rotor;
        :func:`exported_bearing_factors`).
    rigid_contact : bool
        Bond the tool base to the holder tip (shared node) instead of the
        contact springs (verification of the k → ∞ limit).
    bearing_stiffness : sequence of float or None
        Extra factor per bearing set on its stiffness (translational and
        rotational; 0 removes the set's springs), for energy bookkeeping;
        None: 1 for every set.

    Returns
    -------
    structure : Structure
    dofs : dict of str to (2,) int
        ``"flange"`` (holder node at z = 0) and, unless ``spindle_only``,
        ``"holder_tip"`` and ``"tip"`` (tool tip), each ``[u, θ]``.
    """
    mats = config.materials
    st = Structure()
    h = config.mesh_size
    taper = config.taper
    yfac = config.y_stiffness_factor if direction == "y" else 1.0
    hfac = config.y_housing_factor if direction == "y" else 1.0

    # --- spindle shaft -----------------------------------------------------------------
    seg_ends = np.cumsum([s.length for s in config.spindle_segments])
    z_rear = -float(seg_ends[-1])
    sp_breaks = [z_rear, 0.0] + [-float(e) for e in seg_ends] + [b.position for b in config.bearings]
    z_taper = mesh_points([-taper.length, 0.0], h)
    z_sp = mesh_points([z for z in sp_breaks if z <= -taper.length] + [-taper.length], config.spindle_mesh_size)
    z_sp = np.unique(np.round(np.r_[z_sp, z_taper, sp_breaks], 12))
    sp = st.add_nodes(z_sp.size)
    smat = mats[config.spindle_material]
    sections = []
    for z0, z1 in zip(z_sp[:-1], z_sp[1:]):
        zm = 0.5 * (z0 + z1)
        k = int(np.searchsorted(seg_ends, -zm))
        seg = config.spindle_segments[min(k, len(config.spindle_segments) - 1)]
        bore = max(seg.inner_diameter, float(taper.diameter(zm))) if zm > -taper.length else seg.inner_diameter
        sec = tube_section(smat, seg.outer_diameter, bore)
        sections.append(BeamSection(sec.EI, sec.kGA, sec.rhoA + seg.added_mass, sec.rhoI))
    st.add_beam(sp, z_sp, sections)

    # --- housing and bearings ---------------------------------------------------------------
    hs = config.housing
    hd = st.add_nodes(1)[0]
    st.add_rigid_body(hd, hs.mass, hs.rotary_inertia)
    st.add_spring([hd[0]], [1.0], hs.stiffness * hfac, hs.damping)
    st.add_spring([hd[1]], [1.0], hs.rotational_stiffness * hfac, hs.rotational_damping)
    factors = exported_bearing_factors(config) if exported else None
    for i, b in enumerate(config.bearings):
        n = int(np.argmin(np.abs(z_sp - b.position)))
        s = (factors[i]["stiffness_factor"] if exported else 1.0) * yfac
        c = factors[i]["damping_factor"] if exported else 1.0
        if bearing_stiffness is not None:
            s *= bearing_stiffness[i]
        e = b.position - hs.position
        st.add_spring([sp[n, 0], hd[0], hd[1]], [1.0, -1.0, -e], b.stiffness * s, b.damping * c)
        st.add_spring([sp[n, 1], hd[1]], [1.0, -1.0], b.rotational_stiffness * s, b.rotational_damping * c)

    # --- holder: taper, then (unless spindle_only) the outside segments -------------------------
    hmat = mats[config.holder_material]
    tmat = mats[config.tool_material]
    E_tool = 1.0 + (config.magnitude("tool_modulus") or 0.0)
    L_h = config.holder_length
    seg_z = np.r_[0.0, np.cumsum([s.length for s in config.holder_segments])]
    ring = ring_resonator(config)
    if spindle_only:
        z_h = z_taper
    else:
        breaks = list(z_taper) + list(seg_z)
        breaks.append(L_h - clamping_length)
        if ring is not None:
            breaks.append(ring["position"])
        z_h = mesh_points(breaks, h)
    hn = st.add_nodes(z_h.size)
    slot_k, slot_m = _slot_factors(config, direction)
    distributed = config.contact_model == "distributed" and not spindle_only
    shank = tube_section(tmat, config.tool_diameter, 0.0, E_tool)
    sections = []
    for z0, z1 in zip(z_h[:-1], z_h[1:]):
        zm = 0.5 * (z0 + z1)
        if zm < 0:
            sec = tube_section(hmat, float(taper.diameter(zm)), taper.bore)
        else:
            k = min(int(np.searchsorted(seg_z, zm)) - 1, len(config.holder_segments) - 1)
            seg = config.holder_segments[k]
            sec = tube_section(hmat, seg.outer_diameter, seg.inner_diameter)
            if k > 0 and (slot_k != 1.0 or slot_m != 1.0):
                sec = sec.scaled(stiffness=slot_k, mass=slot_m)
            if zm > L_h - clamping_length and not distributed:
                sec = composite(sec, shank)
        sections.append(sec)
    st.add_beam(hn, z_h, sections)
    i0 = int(np.argmin(np.abs(z_h)))
    dofs = {"flange": hn[i0]}

    # taper joint: distributed radial springs lumped to nodes by tributary length
    for i, zt in enumerate(z_taper):
        w = 0.5 * ((z_taper[i + 1] - zt) if i + 1 < z_taper.size else 0.0) + \
            0.5 * ((zt - z_taper[i - 1]) if i > 0 else 0.0)
        j = int(np.argmin(np.abs(z_sp - zt)))
        kh = int(np.argmin(np.abs(z_h - zt)))
        st.add_spring([sp[j, 0], hn[kh, 0]], [1.0, -1.0], taper.joint_stiffness * w, taper.joint_damping * w,
                      taper.joint_loss_factor)
    if spindle_only:
        return st, dofs

    dofs["holder_tip"] = hn[-1]
    # --- tool ------------------------------------------------------------------------------------
    flute_sec, _ = fluted_truth(config)
    z_tip = L_h + config.tool_total_length - clamping_length
    z_flute = z_tip - config.flute_length
    z_start = L_h - clamping_length if distributed else L_h
    z_t = mesh_points([z_start, L_h, z_flute, z_tip] + ([] if not distributed else list(z_h[z_h >= z_start])), h)
    if rigid_contact and not distributed:
        tn = np.vstack([hn[-1:], st.add_nodes(z_t.size - 1)])
    else:
        tn = st.add_nodes(z_t.size)
    sections = [flute_sec if 0.5 * (z0 + z1) > z_flute else shank for z0, z1 in zip(z_t[:-1], z_t[1:])]
    st.add_beam(tn, z_t, sections)
    dofs["tip"] = tn[-1]

    c = true_contact(config, clamping_length)
    if not rigid_contact:
        if distributed:
            inside = [i for i, z in enumerate(z_t) if z <= L_h + 1e-12]
            for i in inside:
                w = 0.5 * ((z_t[i + 1] - z_t[i]) if z_t[i + 1] <= L_h + 1e-12 else 0.0) + \
                    0.5 * ((z_t[i] - z_t[i - 1]) if i > 0 else 0.0)
                w /= clamping_length
                kh = int(np.argmin(np.abs(z_h - z_t[i])))
                st.add_spring([tn[i, 0], hn[kh, 0]], [1.0, -1.0], c["k_xf"] * w, c["c_xf"] * w, c["loss_factor"])
                st.add_spring([tn[i, 1], hn[kh, 1]], [1.0, -1.0], c["k_thetaM"] * w, c["c_thetaM"] * w,
                              c["loss_factor"])
        else:
            st.add_spring([tn[0, 0], hn[-1, 0]], [1.0, -1.0], c["k_xf"], c["c_xf"], c["loss_factor"])
            st.add_spring([tn[0, 1], hn[-1, 1]], [1.0, -1.0], c["k_thetaM"], c["c_thetaM"], c["loss_factor"])

    # --- hidden bodies ---------------------------------------------------------------------------
    body = tip_body(config)
    if body is not None:
        st.add_rigid_body(tn[-1], body["mass"], body["rotary_inertia"], body["offset"])
    if ring is not None:
        rn = st.add_nodes(1)[0]
        kh = int(np.argmin(np.abs(z_h - ring["position"])))
        st.add_rigid_body(rn, ring["mass"], ring["rotary_inertia"])
        st.add_spring([rn[0], hn[kh, 0]], [1.0, -1.0], ring["stiffness"], ring["damping"])
        st.add_spring([rn[1], hn[kh, 1]], [1.0, -1.0], ring["rotational_stiffness"], ring["rotational_damping"])
    return st, dofs
