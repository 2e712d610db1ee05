"""A synthetic impact-hammer campaign: generate it, describe the user's beliefs and the truth, write it.

:func:`generate_campaign` runs the true finite-element structure
(:mod:`bayes_rcsa.synthetic.bench`) at every clamping length and direction,
adds measurement noise, and returns a :class:`Campaign` with

* ``spindle``: the flange receptances exported to the user (possibly
  perturbed, never containing the ``extra_mode`` resonator);
* ``measurements``: the noisy tool-point FRFs with coherence;
* ``setup``: what the user believes, as a dict in exactly the shape of the
  project's setup TOML (docs/setup.example.toml), hidden effects left out;
* ``truth``: a JSON-able record of the true parameters and hidden effects.

:func:`write_campaign` writes them as one directory (``spindle_x.csv``,
``tip_x_25mm.csv``, ..., ``setup.toml``, ``truth.json``), atomically.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SetupError
from ..io.jsonable import dumps_strict
from ..model.assembly import Configuration
from ..model.receptance import FRF, PointReceptance
from .bench import exported_spindle_receptance, extra_mode_parameters, true_contact, true_tool, true_tool_point_frf
from .config import BenchConfig
from .effects import HIDDEN_EFFECTS
from .noise import add_measurement_noise, line_average_offsets

__all__ = [
    "Campaign",
    "generate_campaign",
    "write_campaign",
    "measured_mean_frf",
    "tip_file_name",
    "spindle_file_name",
    "dominant_peak",
    "TRUTH_FORMAT",
]

TRUTH_FORMAT = "bayes_rcsa.synthetic.truth/1"


@dataclass(frozen=True)
class Campaign:
    """One synthetic campaign.

    Attributes
    ----------
    spindle : dict of direction to PointReceptance
        Flange receptances as exported to the user.
    measurements : list of (Configuration, FRF)
        Noisy tool-point FRFs (m/N) with coherence, in the order of
        ``setup["measurement"]``.
    truth : dict
        JSON-able: true contact at every clamping length, damping, law,
        hidden effects and magnitudes, noise, noise-free dominant peaks.
    setup : dict
        The user-belief setup, TOML-able, shaped like docs/setup.example.toml,
        with the file names used by :func:`write_campaign`.
    config : BenchConfig or None
        The configuration that generated it.
    """

    spindle: dict
    measurements: list
    truth: dict
    setup: dict
    config: BenchConfig | None = field(default=None, compare=False)


def _mm(length: float) -> str:
    mm = round(length * 1e3, 6)
    text = f"{mm:g}" if mm != int(mm) else str(int(mm))
    return text.replace(".", "p")


def tip_file_name(configuration: Configuration, hit: int | None = None) -> str:
    """``tip_<direction>_<clamping length in mm>mm.csv``, e.g. ``tip_x_25mm.csv`` (``25p5mm`` for 25.5 mm);
    ``tip_x_25mm_hit2.csv`` for repeated hit 2 (1-based) of a campaign with ``repeats > 1``."""
    tail = "" if hit is None else f"_hit{hit}"
    return f"tip_{configuration.direction}_{_mm(configuration.clamping_length)}mm{tail}.csv"


def spindle_file_name(direction: str) -> str:
    """``spindle_<direction>.csv``."""
    return f"spindle_{direction}.csv"


def measured_mean_frf(config: BenchConfig, configuration: Configuration, frequency_hz) -> np.ndarray:
    """Noise-free FRF as the analyser sees it: the line average if ``resolution_hz`` is set.

    Returns
    -------
    (n_freq,) complex, m/N
    """
    f = np.asarray(frequency_hz, dtype=float)
    if config.resolution_hz is None:
        return true_tool_point_frf(config, configuration, f)
    off = line_average_offsets(config.resolution_hz)
    fine = (f[:, None] + off[None, :]).ravel()
    if fine.min() <= 0:
        raise SetupError(
            f"resolution_hz = {config.resolution_hz!r}: the first line's band reaches below 0 Hz; "
            "raise frequency_start or lower the resolution"
        )
    return true_tool_point_frf(config, configuration, fine).reshape(f.size, off.size).mean(axis=1)


def dominant_peak(frequency_hz, values) -> tuple[float, float]:
    """Frequency (Hz) and magnitude (m/N) of the largest |H|, refined by a parabola through 3 lines.

    Used for the noise-free reference values in the truth record.
    """
    f = np.asarray(frequency_hz, dtype=float)
    a = np.abs(np.asarray(values))
    i = int(np.argmax(a))
    if i == 0 or i == a.size - 1:
        return float(f[i]), float(a[i])
    y0, y1, y2 = a[i - 1], a[i], a[i + 1]
    den = y0 - 2 * y1 + y2
    d = 0.5 * (y0 - y2) / den if den != 0 else 0.0
    step = 0.5 * (f[i + 1] - f[i - 1])
    return float(f[i] + d * step), float(y1 - 0.25 * (y0 - y2) * d)


def generate_campaign(config: BenchConfig, rng: np.random.Generator) -> Campaign:
    """Simulate a whole impact-hammer campaign.

    Parameters
    ----------
    config : BenchConfig
    rng : numpy.random.Generator
        Source of the measurement noise, consumed in the order of the
        measurements (directions outer, clamping lengths inner, repeated
        hits innermost).

    Returns
    -------
    Campaign
    """
    f = config.frequency_hz
    spindle = {d: exported_spindle_receptance(config, d, f) for d in config.directions}
    spindle = {d: PointReceptance(r.frequency_hz, r.block, source=spindle_file_name(d)) for d, r in spindle.items()}
    measurements = []
    peaks = []
    for d in config.directions:
        for cl in config.clamping_lengths:
            cfg = Configuration(cl, d, "tool")
            clean = measured_mean_frf(config, cfg, f)
            fp, ap = dominant_peak(f, clean)
            for hit in range(1, config.repeats + 1):
                name = tip_file_name(cfg, hit if config.repeats > 1 else None)
                noisy, coh = add_measurement_noise(clean, config.noise_relative, config.noise_floor,
                                                   config.n_averages, rng)
                measurements.append((cfg, FRF(f, noisy, coh, source=name)))
                peaks.append({"file": name, "clamping_length": cl, "direction": d,
                              "dominant_frequency_hz": fp, "dominant_peak_magnitude": ap})
    setup = user_setup(config, [m[1].source for m in measurements], [m[0] for m in measurements])
    truth = truth_record(config, peaks)
    return Campaign(spindle=spindle, measurements=measurements, truth=truth, setup=setup, config=config)


def user_setup(config: BenchConfig, files, configurations) -> dict:
    """The setup the user would write: geometry and priors as believed, no hidden effect.

    Returns
    -------
    dict in the shape of docs/setup.example.toml (TOML-able).
    """

    def material(name):
        m = config.materials[name]
        return {"youngs_modulus": m.youngs_modulus, "density": m.density,
                "poisson_ratio": m.poisson_ratio, "loss_factor": m.loss_factor}

    tool_segments = []
    for s in config.declared_tool_segments:  # one cylinder when ``tool_declared = "one_cylinder"``
        seg = {"length": s.length, "diameter": s.diameter}
        if s.diameter_ratio != 1.0:
            seg["diameter_ratio"] = s.diameter_ratio
        tool_segments.append(seg)
    materials = {}
    for name in (config.holder_material, config.tool_material):
        materials[name] = material(name)
    return {
        "name": config.name,
        "materials": materials,
        "spindle": {d: spindle_file_name(d) for d in config.directions},
        "holder": {
            "material": config.holder_material,
            "segments": [
                {"length": s.length, "outer_diameter": s.outer_diameter, "inner_diameter": s.inner_diameter}
                for s in config.holder_segments
            ],
        },
        "tool": {"material": config.tool_material, "total_length": config.tool_total_length, "segments": tool_segments},
        "contact": {
            "translational_stiffness": list(config.prior_k_xf),
            "rotational_stiffness": list(config.prior_k_thetaM),
            "growth_bound": config.growth_bound,
            "clamping_range": list(config.clamping_range),
            "translational_damping": config.c_xf,
            "rotational_damping": config.c_thetaM,
        },
        "measurement": [
            {"file": name, "clamping_length": c.clamping_length, "direction": c.direction}
            for name, c in zip(files, configurations)
        ],
    }


def truth_record(config: BenchConfig, peaks: list[dict]) -> dict:
    """JSON-able record of the truth behind a campaign (see docs/synthetic.md)."""
    effects = dict(config.hidden_effects)
    details: dict = {}
    if "tip_mass" in effects:
        m = effects["tip_mass"]
        details["tip_mass"] = {"mass": m, "rotary_inertia": m * config.tip_mass_radius_of_gyration**2,
                               "radius_of_gyration": config.tip_mass_radius_of_gyration}
    if "extra_mode" in effects:
        details["extra_mode"] = extra_mode_parameters(config)
    if "fluted_section" in effects:
        details["fluted_section"] = {
            "assumed_diameter_ratio": [s.diameter_ratio for s in config.tool_segments],
            "true_diameter_ratio": [s.diameter_ratio for s in true_tool(config).segments],
        }
    if config.tool_declared == "one_cylinder" and len(config.tool_segments) > 1:
        # the tool's fluted tip is itself hidden: the setup has one cylinder of the shank's diameter
        details.setdefault("fluted_section", {}).update(
            declared="one_cylinder",
            declared_segments=[{"length": s.length, "diameter": s.diameter} for s in config.declared_tool_segments],
            true_flute_length=sum(s.length for s in true_tool(config).segments if s.diameter_ratio < 1),
            true_segments=[{"length": s.length, "diameter": s.diameter, "diameter_ratio": s.diameter_ratio}
                           for s in true_tool(config).segments])
    if "nonlinear_stiffness_law" in effects:
        details["nonlinear_stiffness_law"] = {"kind": config.stiffness_law_kind,
                                              "saturation" if config.stiffness_law_kind == "saturating" else "ramp_jump":
                                                  effects["nonlinear_stiffness_law"]}
        if config.stiffness_law_kind == "ramp":
            details["nonlinear_stiffness_law"].update(ramp_start=config.ramp_start, ramp_width=config.ramp_width)
    if "contact_damping" in effects:
        details["contact_damping"] = {"factor": effects["contact_damping"]}
    if "spindle_error" in effects:
        details["spindle_error"] = {"exported_bearing_stiffness_scale": 1.0 + effects["spindle_error"]}
    if "spindle_rotation_omitted" in effects:
        details["spindle_rotation_omitted"] = {"kept_fraction": 1.0 - effects["spindle_rotation_omitted"]}
    saturation = effects.get("nonlinear_stiffness_law", 0.0)
    c0 = true_contact(config, config.clamping_range[0])
    return {
        "format": TRUTH_FORMAT,
        "name": config.name,
        "contact_model": config.contact_model,
        "tool_declared": config.tool_declared,
        "law": {
            "kind": config.stiffness_law_kind if saturation else "linear",
            "k_xf_at_la": config.k_xf,
            "k_thetaM_at_la": config.k_thetaM,
            "growth": config.growth,
            "growth_thetaM": config.growth if config.growth_thetaM is None else config.growth_thetaM,
            "saturation": saturation,
            "clamping_range": list(config.clamping_range),
        },
        "damping": {"c_xf": c0["c_xf"], "c_thetaM": c0["c_thetaM"],
                    "assumed_c_xf": config.c_xf, "assumed_c_thetaM": config.c_thetaM},
        "contact": [{"clamping_length": cl, **true_contact(config, cl)} for cl in config.clamping_lengths],
        "hidden_effects": effects,
        "hidden_effect_descriptions": {n: HIDDEN_EFFECTS[n].description for n in effects},
        "hidden_effect_details": details,
        "noise": {"relative": config.noise_relative, "floor": config.noise_floor,
                  "n_averages": config.n_averages, "repeats": config.repeats, "resolution_hz": config.resolution_hz},
        "frequency": {"start": config.frequency_start, "stop": config.frequency_stop,
                      "step": config.frequency_step, "n_lines": int(config.frequency_hz.size)},
        "tool": {"segments": [{"length": s.length, "diameter": s.diameter, "diameter_ratio": s.diameter_ratio}
                              for s in true_tool(config).segments]},
        "spindle": {
            "material": config.spindle.material,
            "segments": [{"length": s.length, "outer_diameter": s.outer_diameter, "inner_diameter": s.inner_diameter}
                         for s in config.spindle.segments],
            "bearings": [{"position": b.position, "stiffness": b.stiffness, "damping": b.damping,
                          "rotational_stiffness": b.rotational_stiffness, "rotational_damping": b.rotational_damping}
                         for b in config.spindle.bearings],
            "taper_length": config.spindle.taper_length,
            "taper_diameter": config.spindle.taper_diameter,
            "y_stiffness_factor": config.spindle.y_stiffness_factor,
        },
        "measurements": peaks,
    }


def write_campaign(campaign: Campaign, out_dir, overwrite: bool = False) -> Path:
    """Write a campaign as one directory, atomically.

    The files are first written to a hidden temporary directory beside
    ``out_dir``, which is then renamed onto it, so an error never leaves a
    partial campaign behind.

    Parameters
    ----------
    campaign : Campaign
    out_dir : path-like
        Must not exist or be an empty directory, unless ``overwrite``.
    overwrite : bool
        Replace an existing non-empty ``out_dir`` (only after the new one is
        complete).

    Returns
    -------
    Path
        The ``setup.toml`` inside ``out_dir``.
    """
    from ..io.frf_csv import write_frf_csv
    from ..io.receptance_csv import write_spindle_csv
    from ..io.atomic import begin_directory
    from ..io.toml_writer import dump_toml

    out_dir, tmp = begin_directory(out_dir, overwrite)
    try:
        header = [
            "synthetic impact-hammer campaign (bayes_rcsa.synthetic)",
        ]
        for d, rec in campaign.spindle.items():
            write_spindle_csv(
                tmp / spindle_file_name(d), rec,
                comments=header + [f"spindle-holder flange receptance, direction {d}; "
                                   "columns in m/N, 1/N, rad/N, rad/(N m)"],
            )
        for cfg, frf in campaign.measurements:
            write_frf_csv(
                tmp / frf.source, frf,
                comments=header + [f"tool-point FRF h = u/F (m/N), direction {cfg.direction}, "
                                   f"clamping length {cfg.clamping_length!r} m"]
                + ([f"averages = {campaign.config.n_averages}"] if campaign.config is not None else []),
            )
        text = ("# What the user believes about this synthetic campaign (hidden effects are not here;\n"
                "# see truth.json).  Generated by bayes_rcsa.synthetic.\n" + dump_toml(campaign.setup))
        (tmp / "setup.toml").write_text(text, encoding="utf-8")
        (tmp / "truth.json").write_text(
            dumps_strict(campaign.truth, nonfinite="error", indent=2, sort_keys=True) + "\n", encoding="utf-8"
        )
        _replace_dir(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out_dir / "setup.toml"


def _replace_dir(new: Path, target: Path) -> None:
    """Rename ``new`` onto ``target``; an existing ``target`` is removed only once ``new`` is in place."""
    if not target.exists():
        os.replace(new, target)
        return
    old = new.with_name(new.name + ".old")
    os.replace(target, old)
    try:
        os.replace(new, target)
    except BaseException:
        os.replace(old, target)
        raise
    with contextlib.suppress(OSError):
        shutil.rmtree(old)


