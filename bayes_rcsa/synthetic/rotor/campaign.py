"""Noise-free truth, modes, exported spindle files and whole campaigns of the rotor bench.

The campaign has the same shape and directory layout as the first bench's
(:class:`bayes_rcsa.synthetic.campaign.Campaign`,
:func:`bayes_rcsa.synthetic.campaign.write_campaign`): ``spindle_<d>.csv``,
``tip_<d>_<mm>mm.csv``, ``setup.toml`` (what the user believes, hidden
effects left out) and ``truth.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from ...model.assembly import Configuration
from ...model.receptance import FRF, PointReceptance
from ..campaign import TRUTH_FORMAT, Campaign, dominant_peak, spindle_file_name, tip_file_name, write_campaign
from .build import (
    build_structure,
    exported_bearing_factors,
    fluted_truth,
    ring_resonator,
    stiffness_law_factor,
    tip_body,
    true_contact,
)
from .config import ROTOR_EFFECTS, RotorBenchConfig, front_bearing_sets
from .noise import hammer_average
from .solver import ModalSolution, modal_solution

__all__ = [
    "tool_point_solution",
    "true_tool_point_frf",
    "true_modes",
    "true_spindle_receptance",
    "exported_spindle_receptance",
    "spindle_file_modes",
    "generate_rotor_campaign",
    "write_rotor_campaign",
    "user_setup",
]

GENERATOR = "bayes_rcsa.synthetic.rotor"


def _direction(direction: str) -> str:
    if direction not in ("x", "y"):
        from ...errors import SetupError
        raise SetupError(f"direction = {direction!r}: expected 'x' or 'y'")
    return direction


def tool_point_solution(config: RotorBenchConfig, direction: str, clamping_length: float) -> ModalSolution:
    """Complex-mode expansion of the true assembly at the tool tip (dofs ``[u, θ]``).

    Parameters
    ----------
    config : RotorBenchConfig
    direction : {"x", "y"}
    clamping_length : float, m

    Returns
    -------
    ModalSolution
    """
    st, dofs = build_structure(config, _direction(direction), float(clamping_length))
    return modal_solution(st, dofs["tip"], config.mode_cutoff_hz)


def true_tool_point_frf(config: RotorBenchConfig, direction: str, clamping_length: float, frequency_hz) -> np.ndarray:
    """Noise-free tool-point receptance h = u/F of the true structure.

    Parameters
    ----------
    config : RotorBenchConfig
    direction : {"x", "y"}
    clamping_length : float, m
    frequency_hz : (n_freq,) float, Hz

    Returns
    -------
    (n_freq,) complex, m/N (convention e^{+iωt}: Im h ≤ 0)
    """
    sol = tool_point_solution(config, direction, clamping_length)
    return sol.receptance(np.asarray(frequency_hz, dtype=float))[:, 0, 0]


def _modes_of(sol: ModalSolution, band) -> list[dict]:
    lo, hi = band

    def mag(f):
        return float(np.abs(sol.receptance(np.atleast_1d(f))[0, 0, 0]))

    found = []
    modes = sol.modes()
    damped = np.array([m["damped_frequency_hz"] for m in modes])
    for j, m in enumerate(modes):
        fn, fd, zeta = m["eigenfrequency_hz"], m["damped_frequency_hz"], m["damping_ratio"]
        if not (lo <= fn <= hi):
            continue
        residue = complex(m["residues"][0, 0])
        others = np.abs(np.delete(damped, j) - fd)
        gap = float(others.min()) if others.size else np.inf
        width = min(max(4.0 * abs(zeta) * fn, 4.0), 0.45 * gap)
        a, b = max(fd - width, 1e-3), fd + width
        grid = np.linspace(a, b, 161)
        amp = np.abs(sol.receptance(grid)[:, 0, 0])
        i = int(np.argmax(amp))
        peak_hz = None
        if 0 < i < grid.size - 1:
            res = minimize_scalar(lambda f: -mag(f), bounds=(grid[i - 1], grid[i + 1]), method="bounded",
                                  options={"xatol": 1e-6 * fn})
            peak_hz = float(res.x)
        found.append({
            "eigenfrequency_hz": float(fn),
            "damped_frequency_hz": float(fd),
            "peak_hz": peak_hz,
            "damping_ratio": float(zeta),
            "peak_magnitude": mag(peak_hz if peak_hz is not None else fn),
            "residue_magnitude": float(abs(residue)),
            "modal_peak": float(abs(residue) / max(-m["pole"].real, 1e-300)),
        })
    top = max((m["modal_peak"] for m in found), default=1.0)
    for m in found:
        m["relative_prominence"] = m["modal_peak"] / top
    return found


def true_modes(config: RotorBenchConfig, direction: str, clamping_length: float, band=None) -> list[dict]:
    """Every mode of the noise-free tool-point FRF inside the band, ordered by frequency.

    Parameters
    ----------
    config : RotorBenchConfig
    direction : {"x", "y"}
    clamping_length : float, m
    band : (lo, hi) Hz or None
        Default: the campaign band ``(frequency_start, frequency_stop)``;
        a mode is in the band when its eigenfrequency is.

    Returns
    -------
    list of dict
        ``eigenfrequency_hz`` (|λ|/2π, Hz), ``damped_frequency_hz``
        (Im λ/2π), ``peak_hz`` (local maximum of |h| near the mode, refined;
        None when a neighbour masks it), ``damping_ratio``,
        ``peak_magnitude`` (|h| at the peak, m/N), ``residue_magnitude``
        (|residue of h|, m/(N s)), ``modal_peak`` (|residue|/|Re λ|, m/N: the
        mode's own peak height) and ``relative_prominence`` (modal_peak over
        the largest in the band).
    """
    band = (config.frequency_start, config.frequency_stop) if band is None else tuple(band)
    return _modes_of(tool_point_solution(config, direction, clamping_length), band)


def _spindle_block(config: RotorBenchConfig, direction: str, frequency_hz, exported: bool) -> np.ndarray:
    st, dofs = build_structure(config, _direction(direction), spindle_only=True, exported=exported)
    return modal_solution(st, dofs["flange"], config.mode_cutoff_hz).receptance(np.asarray(frequency_hz, float))


def true_spindle_receptance(config: RotorBenchConfig, direction: str, frequency_hz) -> PointReceptance:
    """True flange block of spindle + holder taper (no export error).

    Returns
    -------
    PointReceptance
        block (n_freq, 2, 2) complex: h m/N, l 1/N, n rad/N, p rad/(N m).
    """
    f = np.asarray(frequency_hz, dtype=float)
    return PointReceptance(f, _spindle_block(config, direction, f, exported=False), source="true spindle")


def exported_spindle_receptance(config: RotorBenchConfig, direction: str, frequency_hz) -> PointReceptance:
    """The flange block the user receives (``spindle_<d>.csv``).

    With ``spindle_error`` it comes from the rotor with changed bearings
    (``spindle_error_kind``; :func:`~bayes_rcsa.synthetic.rotor.build.exported_bearing_factors`),
    while the tool-point FRFs keep today's bearings; with ``spindle_rotation_omitted`` its l, n, p
    are scaled by ``1 − magnitude``.  Never contains the holder-side
    resonator, tip body or any tool.

    Parameters
    ----------
    config : RotorBenchConfig
    direction : {"x", "y"}
    frequency_hz : (n_freq,) float, Hz

    Returns
    -------
    PointReceptance
        block (n_freq, 2, 2) complex ``[[h, l], [n, p]]``.
    """
    f = np.asarray(frequency_hz, dtype=float)
    block = _spindle_block(config, direction, f, exported=True)
    m = config.magnitude("spindle_rotation_omitted")
    if m is not None:
        keep = 1.0 - m
        block[:, 0, 1] *= keep
        block[:, 1, 0] *= keep
        block[:, 1, 1] *= keep
    return PointReceptance(f, block, source=spindle_file_name(direction))


def spindle_file_modes(config: RotorBenchConfig, direction: str, n_modes: int = 6) -> list[dict]:
    """The flange modes of today's (true) spindle rotor and of the exported file's rotor, side by side.

    A diagnostic of ``spindle_error``, computed from the rotor model itself
    (the complex modes of the spindle substructure that
    :func:`~bayes_rcsa.synthetic.rotor.solver.modal_solution` expands the
    files with, their shapes at every degree of freedom): each of
    the true rotor's first ``n_modes`` modes is paired with the exported
    rotor's mode of the largest mass-weighted MAC, ``|xᴴ M y|² / (xᴴ M x ·
    yᴴ M y)``.  The share of a mode's strain energy ``Re(xᴴ K_G x) / Re(xᴴ K
    x)`` stored in the front or rear bearing sets (``K_G``: their springs
    alone, :func:`~bayes_rcsa.synthetic.rotor.config.front_bearing_sets`)
    says which sets the mode rides on.

    Parameters
    ----------
    config : RotorBenchConfig
    direction : {"x", "y"}
    n_modes : int
        How many of the lowest modes (all are listed, in or out of the band).

    Returns
    -------
    list of dict
        Per mode: ``true`` and ``exported``, each with ``eigenfrequency_hz``
        (|λ|/2π, Hz), ``damping_ratio`` (−Re λ/|λ|), ``flange_modal_peak``
        (|residue of h at the flange| / |Re λ|, m/N), ``front_energy`` and
        ``rear_energy`` (shares of the modal strain energy); ``mac``;
        ``frequency_change`` and ``damping_ratio_change`` (exported / true
        − 1); ``dominant_sets``: ``"front"`` or ``"rear"`` when that group
        holds ≥ 20 % of the true mode's strain energy and more than twice the
        other's, else ``"neither"`` (housing or shaft modes).
    """
    direction = _direction(direction)
    front = np.array(front_bearing_sets(config))

    def rotor(exported):
        st, dofs = build_structure(config, direction, spindle_only=True, exported=exported)
        sol = modal_solution(st, np.arange(st.n_dof), config.mode_cutoff_hz)
        keep = np.flatnonzero(sol.poles.imag > 0)
        keep = keep[np.argsort(np.abs(sol.poles[keep]))]
        lam, X = sol.poles[keep], sol.shapes[:, keep]      # residue of mode r between i and j: X[i, r] X[j, r]
        shares = {}
        for name, group in (("front_energy", front), ("rear_energy", ~front)):
            without, _ = build_structure(config, direction, spindle_only=True, exported=exported,
                                         bearing_stiffness=np.where(group, 0.0, 1.0))
            KG = st.K - without.K
            shares[name] = np.real(np.einsum("ir,ij,jr->r", X.conj(), KG, X)) / \
                np.real(np.einsum("ir,ij,jr->r", X.conj(), st.K, X))
        peak = np.abs(X[dofs["flange"][0]] ** 2) / np.abs(lam.real)
        return st, lam, X, shares, peak

    st0, lam0, X0, sh0, pk0 = rotor(False)
    st1, lam1, X1, sh1, pk1 = rotor(True)
    MX0, MX1 = st0.M @ X0, st1.M @ X1
    cross = np.abs(X0.conj().T @ MX1) ** 2 / np.outer(np.real(np.einsum("ir,ir->r", X0.conj(), MX0)),
                                                    np.real(np.einsum("ir,ir->r", X1.conj(), MX1)))

    def describe(lam, shares, peak, r):
        return {"eigenfrequency_hz": float(abs(lam[r]) / (2 * np.pi)), "damping_ratio": float(-lam[r].real / abs(lam[r])),
                "flange_modal_peak": float(peak[r]), "front_energy": float(shares["front_energy"][r]),
                "rear_energy": float(shares["rear_energy"][r])}

    out = []
    for r in range(min(n_modes, lam0.size)):
        j = int(np.argmax(cross[r]))
        t, e = describe(lam0, sh0, pk0, r), describe(lam1, sh1, pk1, j)
        fe, re = t["front_energy"], t["rear_energy"]
        dominant = "front" if fe >= 0.2 and fe > 2 * re else "rear" if re >= 0.2 and re > 2 * fe else "neither"
        out.append({"true": t, "exported": e, "mac": float(cross[r, j]),
                    "frequency_change": e["eigenfrequency_hz"] / t["eigenfrequency_hz"] - 1.0,
                    "damping_ratio_change": e["damping_ratio"] / t["damping_ratio"] - 1.0,
                    "dominant_sets": dominant})
    return out


def user_setup(config: RotorBenchConfig, files, configurations) -> dict:
    """What the user writes from the drawings: declared geometry, materials and priors, no hidden effect.

    Returns
    -------
    dict in the shape of the data contract's setup TOML.
    """
    def material(name):
        m = config.materials[name]
        return {"youngs_modulus": m.youngs_modulus, "density": m.density,
                "poisson_ratio": m.poisson_ratio, "loss_factor": m.loss_factor}

    ratio = config.diameter_ratio if config.fluted_declared == "effective" else 1.0
    if config.fluted_declared == "undeclared":  # one cylinder: nominal diameter over the total length, no flute
        segments = [{"length": config.tool_total_length, "diameter": config.tool_diameter}]
    else:
        segments = [
            {"length": config.flute_length, "diameter": config.tool_diameter, "diameter_ratio": ratio},
            {"length": round(config.tool_total_length - config.flute_length, 12), "diameter": config.tool_diameter},
        ]
    return {
        "name": config.name,
        "materials": {config.holder_material: material(config.holder_material),
                      config.tool_material: material(config.tool_material)},
        "spindle": {d: spindle_file_name(d) for d in config.directions},
        "holder": {
            "material": config.holder_material,
            "segments": [{"length": s.length, "outer_diameter": s.outer_diameter, "inner_diameter": s.inner_diameter}
                         for s in config.holder_segments],
        },
        "tool": {
            "material": config.tool_material,
            "total_length": config.tool_total_length,
            "segments": segments,
        },
        "contact": {
            "translational_stiffness": list(config.prior_k_xf),
            "rotational_stiffness": list(config.prior_k_thetaM),
            "growth_bound": config.growth_bound,
            "clamping_range": list(config.setup_clamping_range),
            "translational_damping": config.c_xf,
            "rotational_damping": config.c_thetaM,
        },
        "measurement": [{"file": name, "clamping_length": c.clamping_length, "direction": c.direction}
                        for name, c in zip(files, configurations)],
    }


def _effect_details(config: RotorBenchConfig) -> dict:
    eff = config.hidden_effects
    details: dict = {}
    if "contact_damping" in eff:
        details["contact_damping"] = {"factor": eff["contact_damping"]}
    if "tip_mass" in eff:
        details["tip_mass"] = {k: float(v) for k, v in tip_body(config).items()}
    if "fluted_section" in eff:
        _, geo = fluted_truth(config)
        details["fluted_section"] = {"declared": config.fluted_declared,
                                     "declared_diameter_ratio": config.diameter_ratio
                                     if config.fluted_declared == "effective" else 1.0,
                                     # one cylinder: the setup gives no flute length; the true one is here
                                     "declared_flute_length": None if config.fluted_declared == "undeclared"
                                     else config.flute_length,
                                     "true_flute_length": config.flute_length,
                                     **{k: (float(v) if not isinstance(v, str) else v) for k, v in geo.items()}}
    if "extra_mode" in eff:
        details["extra_mode"] = {k: float(v) for k, v in ring_resonator(config).items()}
        details["extra_mode"]["location"] = "ring around the collet nut (holder side)"
    if "nonlinear_stiffness_law" in eff:
        details["nonlinear_stiffness_law"] = {
            "kind": config.stiffness_law_kind, "magnitude": eff["nonlinear_stiffness_law"],
            "step_position": config.step_position if config.stiffness_law_kind == "step" else None,
            "factor_vs_linear": {f"{cl:g}": stiffness_law_factor(config, cl, config.growth)
                                 / (1 + config.growth * (cl - config.clamping_range[0])
                                    / (config.clamping_range[1] - config.clamping_range[0]))
                                 for cl in config.clamping_lengths},
        }
    if "spindle_error" in eff:
        kind = config.spindle_error_kind
        details["spindle_error"] = {"kind": kind}
        if kind == "bearing_sets":
            rear = config.spindle_error_rear
            details["spindle_error"].update({
                "front_stiffness_change": eff["spindle_error"],
                "rear_stiffness_change": eff["spindle_error"] if rear is None else float(rear),
                "damping_law": "c_exported = c_true (1 + e)^beta per set (translational and rotational)",
                "damping_exponent": float(config.spindle_error_damping_exponent),
                "front_sets": "bearing sets in the front half of the shaft (position > -shaft length / 2)"})
        else:
            details["spindle_error"]["exported_bearing_stiffness_scale"] = 1.0 + eff["spindle_error"]
        details["spindle_error"]["exported_bearings"] = exported_bearing_factors(config)
        details["spindle_error"]["flange_modes"] = {d: spindle_file_modes(config, d) for d in config.directions}
    if "spindle_rotation_omitted" in eff:
        details["spindle_rotation_omitted"] = {"kept_fraction": 1.0 - eff["spindle_rotation_omitted"]}
    if "tool_modulus" in eff:
        m = config.materials[config.tool_material]
        details["tool_modulus"] = {"declared": m.youngs_modulus, "true": m.youngs_modulus * (1 + eff["tool_modulus"])}
    if "hysteretic_joint" in eff:
        details["hysteretic_joint"] = {"loss_factor": eff["hysteretic_joint"], "viscous_damping": 0.0}
    if "slotted_holder" in eff:
        m = eff["slotted_holder"]
        details["slotted_holder"] = {"EI_scale_x": 1 - m / 5, "EI_scale_y": 1 - m, "mass_scale": 1 - m / 4,
                                     "segments": "all holder segments after the flange"}
    return details


def truth_record(config: RotorBenchConfig, measurements: list[dict]) -> dict:
    """JSON-able truth of a rotor-bench campaign (docs/synthetic.md, "Second generator")."""
    eff = dict(config.hidden_effects)
    law = config.magnitude("nonlinear_stiffness_law")
    c0 = true_contact(config, config.clamping_range[0])
    _, flute = fluted_truth(config)
    return {
        "format": TRUTH_FORMAT,
        "generator": GENERATOR,
        "name": config.name,
        "contact_model": config.contact_model,
        "law": {"kind": "linear" if law is None else config.stiffness_law_kind,
                "k_xf_at_la": config.k_xf, "k_thetaM_at_la": config.k_thetaM,
                "growth": config.growth, "growth_thetaM": config.growth_thetaM,
                "saturation": 0.0 if law is None else law,
                "clamping_range": list(config.clamping_range)},
        "damping": {"c_xf": c0["c_xf"], "c_thetaM": c0["c_thetaM"], "joint_loss_factor": c0["loss_factor"],
                    "assumed_c_xf": config.c_xf, "assumed_c_thetaM": config.c_thetaM},
        "contact": [{"clamping_length": cl, **true_contact(config, cl)} for cl in config.clamping_lengths],
        "hidden_effects": eff,
        "hidden_effect_descriptions": {n: ROTOR_EFFECTS[n].description for n in eff},
        "hidden_effect_details": _effect_details(config),
        "noise": {"relative": config.noise_relative, "floor": config.noise_floor,
                  "n_averages": config.n_averages, "resolution_hz": None,
                  "model": "mean of n hits, each with relative and floor complex normal noise; H1 coherence"},
        "frequency": {"start": config.frequency_start, "stop": config.frequency_stop,
                      "step": config.frequency_step, "n_lines": int(config.frequency_hz.size)},
        "tool": {"total_length": config.tool_total_length, "diameter": config.tool_diameter,
                 "flute_length": config.flute_length,
                 "fluted_section": {k: (float(v) if not isinstance(v, str) else v) for k, v in flute.items()},
                 "youngs_modulus": config.materials[config.tool_material].youngs_modulus
                 * (1 + eff.get("tool_modulus", 0.0))},
        "holder": {"segments": [{"length": s.length, "outer_diameter": s.outer_diameter,
                                 "inner_diameter": s.inner_diameter} for s in config.holder_segments],
                   "taper": {"gauge_diameter": config.taper.gauge_diameter, "length": config.taper.length,
                             "taper": config.taper.taper, "bore": config.taper.bore,
                             "joint_stiffness_per_length": config.taper.joint_stiffness,
                             "joint_damping_per_length": config.taper.joint_damping,
                             "joint_loss_factor": config.taper.joint_loss_factor}},
        "spindle": {
            "material": config.spindle_material,
            "segments": [{"length": s.length, "outer_diameter": s.outer_diameter, "inner_diameter": s.inner_diameter,
                          "added_mass_per_length": s.added_mass} for s in config.spindle_segments],
            "bearings": [{"name": b.name, "position": b.position, "stiffness": b.stiffness,
                          "rotational_stiffness": b.rotational_stiffness, "damping": b.damping,
                          "rotational_damping": b.rotational_damping} for b in config.bearings],
            "housing": {"mass": config.housing.mass, "rotary_inertia": config.housing.rotary_inertia,
                        "position": config.housing.position, "stiffness": config.housing.stiffness,
                        "rotational_stiffness": config.housing.rotational_stiffness,
                        "damping": config.housing.damping, "rotational_damping": config.housing.rotational_damping},
            "y_stiffness_factor": config.y_stiffness_factor,
            "y_housing_factor": config.y_housing_factor,
        },
        "measurements": measurements,
    }


def generate_rotor_campaign(config: RotorBenchConfig, rng: np.random.Generator) -> Campaign:
    """Simulate an impact-hammer campaign on the rotor bench.

    Parameters
    ----------
    config : RotorBenchConfig
    rng : numpy.random.Generator
        The only source of noise, consumed in the order of the measurements
        (directions outer, clamping lengths inner).

    Returns
    -------
    Campaign
        ``spindle`` (exported flange blocks), ``measurements`` (noisy FRFs
        with coherence), ``setup`` (user beliefs, TOML-able), ``truth``.
    """
    f = config.frequency_hz
    band = (config.frequency_start, config.frequency_stop)
    spindle = {d: exported_spindle_receptance(config, d, f) for d in config.directions}
    measurements, records = [], []
    for d in config.directions:
        for cl in config.clamping_lengths:
            cfg = Configuration(cl, d, "tool")
            name = tip_file_name(cfg)
            sol = tool_point_solution(config, d, cl)
            clean = sol.receptance(f)[:, 0, 0]
            noisy, coh = hammer_average(clean, config.noise_relative, config.noise_floor, config.n_averages, rng)
            measurements.append((cfg, FRF(f, noisy, coh, source=name)))
            fp, ap = dominant_peak(f, clean)
            records.append({"file": name, "clamping_length": cl, "direction": d,
                            "dominant_frequency_hz": fp, "dominant_peak_hz": fp, "dominant_peak_magnitude": ap,
                            "modes": _modes_of(sol, band)})
    setup = user_setup(config, [m[1].source for m in measurements], [m[0] for m in measurements])
    return Campaign(spindle=spindle, measurements=measurements, truth=truth_record(config, records),
                    setup=setup, config=config)


def write_rotor_campaign(campaign: Campaign, out_dir, overwrite: bool = False) -> Path:
    """Write a rotor campaign (same layout as :func:`bayes_rcsa.synthetic.campaign.write_campaign`).

    Returns
    -------
    Path
        ``out_dir/setup.toml``.
    """
    return write_campaign(campaign, out_dir, overwrite=overwrite)
