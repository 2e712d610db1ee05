"""Each generalised model term closes the gap of its effect on data from BOTH synthetic generators.

Generator 1 is the project's bench (``bayes_rcsa.synthetic``); generator 2
the independent rotor bench (``bayes_rcsa.synthetic.rotor``, written
without reading the terms).  Every case writes a small *noise-free*
campaign (4 Hz lines, 25 and 40 mm, fitted in x), loads it as a user would, and
fits the contact (k_xf, k_thetaM and their growth) by least squares on the
tool-point FRFs around the tool modes, first without and then with the
term.  The gap is the relative RMS residual, i.e. the systematic gap (there
is no noise).  A term must remove at least half of it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.model import ConfigurationStack
from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel, Uniform, make_term

STEP = 4.0
BAND = (600.0, 2000.0)  # Hz: the tool modes of both generators at 25-40 mm
LENGTHS = (0.025, 0.040)


def _rotor():
    return pytest.importorskip("bayes_rcsa.synthetic.rotor")


def write(generator: str, effects: dict, tmp_path, solid_flute: bool = False, lengths=LENGTHS, directions=("x",),
          **overrides):
    """A noise-free campaign of ``generator`` ("bench" or "rotor") written and loaded as a user would."""
    common = dict(frequency_step=STEP, noise_relative=0.0, noise_floor=1e-30, clamping_lengths=lengths,
                  directions=directions)
    if generator == "bench":
        from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

        cfg = default_bench_config(hidden_effects=effects, **common, **overrides)
        path = write_campaign(generate_campaign(cfg, np.random.default_rng(0)), tmp_path / "c")
    else:
        rotor = _rotor()
        cfg = rotor.rotor_bench_config(hidden_effects=effects, **common, **overrides)
        path = rotor.write_rotor_campaign(rotor.generate_rotor_campaign(cfg, np.random.default_rng(0)),
                                          tmp_path / "c")
    if solid_flute:  # the user declares the flutes solid
        import re

        text = path.read_text() if hasattr(path, "read_text") else open(path).read()
        new = re.sub(r"diameter_ratio\s*=\s*0\.\d+", "diameter_ratio = 1.0", text)
        assert new != text
        open(path, "w").write(new)
    return load_setup(path)


def gaps(setup, term: str | None, starts: list[dict] | None = None, max_nfev: int = 100,
         lengths=LENGTHS, held: dict | None = None, predict=None, directions=("x",)) -> tuple[float, dict]:
    """Relative RMS tool-point residual after a least-squares fit of contact (+ ``term``), and the fitted values.

    ``held``: term parameters kept at the given values.  ``predict``: clamping lengths not fitted, whose relative
    RMS residual at the fitted values is returned in the values as ``"held_out_gap"``.
    """
    model = setup.model()
    meas = [m for m in setup.measurements if m.clamping_length in lengths and m.direction in directions]
    f = meas[0].frf.frequency_hz
    sel = (f >= BAND[0]) & (f <= BAND[1])
    stack = ConfigurationStack([model.precompute(m.configuration, f[sel]) for m in meas])
    data = np.concatenate([m.frf.values[sel] for m in meas])
    spec = setup.contact
    priors = {"k_xf": LogUniform(*spec.translational_stiffness), "k_thetaM": LogUniform(*spec.rotational_stiffness),
              "g_xf": Uniform(-0.5, 1.0), "g_thetaM": Uniform(-0.5, 1.0)}
    terms = [make_term(term)] if term else []
    pm = ParameterModel.from_priors(GrowthLaw(min(lengths), max(lengths), 1.0), priors,
                                    {"c_xf": spec.translational_damping, "c_thetaM": spec.rotational_damping},
                                    terms=terms, model=model)
    fwd = ForwardModel(pm, stack, model)
    tparams = [p for t in terms for p in t.parameters(model)]
    names = ["k_xf", "k_thetaM", "g_xf", "g_thetaM"] + [p.name for p in tparams]
    lo = [np.log(spec.translational_stiffness[0]), np.log(spec.rotational_stiffness[0]), -0.5, -0.5]
    hi = [np.log(spec.translational_stiffness[1]), np.log(spec.rotational_stiffness[1]), 1.0, 1.0]
    for p in tparams:  # term parameters in their prior's sampling coordinate (an infinite bound at +-1e3)
        a, b = p.prior.bounds
        if held and p.name in held:
            a = b = float(p.prior.to_sampling(held[p.name]))
            a, b = a - 1e-6, b + 1e-6  # held within 1e-6: least squares needs lo < hi (clipped 1e-9 inside)
        lo.append(a if np.isfinite(a) else -1e3)
        hi.append(b if np.isfinite(b) else 1e3)
    lo, hi = np.array(lo), np.array(hi)

    def values(x):
        v = {n: np.array([xi]) for n, xi in zip(names, x)}
        v["k_xf"], v["k_thetaM"] = np.exp(v["k_xf"]), np.exp(v["k_thetaM"])
        for p in tparams:
            v[p.name] = np.atleast_1d(np.asarray(p.prior.to_physical(v[p.name]), dtype=float))
        v["c_xf"], v["c_thetaM"] = np.array([spec.translational_damping]), np.array([spec.rotational_damping])
        return v

    scale = np.linalg.norm(data)

    def res(x):
        return ((fwd.frf(values(x))[0] - data) / scale).view(float)

    kx, kt, g = np.meshgrid(np.geomspace(3e5, 3e7, 17), np.geomspace(3e4, 3e7, 17), (0.2, 0.5), indexing="ij")
    kx, kt, g = kx.ravel(), kt.ravel(), g.ravel()
    best = None
    for st in (starts or [{}]):
        # the best contact on a batched grid with the term at this start, then least squares from there
        st = {**st, **(held or {})}
        xt = [float(p.prior.to_sampling(st.get(p.name, p.baseline))) for p in tparams]
        grid = {"k_xf": kx, "k_thetaM": kt, "g_xf": g, "g_thetaM": g, "c_xf": np.full(kx.size, spec.translational_damping),
                "c_thetaM": np.full(kx.size, spec.rotational_damping)}
        grid.update({p.name: np.full(kx.size, float(st.get(p.name, p.baseline))) for p in tparams})
        i = int(np.argmin(np.linalg.norm(fwd.frf(grid) - data[None], axis=1)))
        x0 = np.array([np.log(kx[i]), np.log(kt[i]), g[i], g[i]] + xt, dtype=float)
        r = least_squares(res, np.clip(x0, lo + 1e-9, hi - 1e-9), bounds=(lo, hi),
                          x_scale=np.maximum(1e-3, 0.1 * (hi - lo)), max_nfev=max_nfev)
        if best is None or r.cost < best.cost:
            best = r
    out = {n: float(values(best.x)[n][0]) for n in names}
    if predict:
        other = [m for m in setup.measurements if m.clamping_length in predict and m.direction in directions]
        st2 = ConfigurationStack([model.precompute(m.configuration, f[sel]) for m in other])
        d2 = np.concatenate([m.frf.values[sel] for m in other])
        h2 = ForwardModel(pm, st2, model).frf(values(best.x))[0]
        out["held_out_gap"] = float(np.linalg.norm(h2 - d2) / np.linalg.norm(d2))
    return float(np.sqrt(2 * best.cost)), out


CASES = {
    # name: (generator, hidden effects, generator overrides, flute declared solid, term, starts of the term fit)
    "bench spindle 15 % stiffer": ("bench", {"spindle_error": 0.15}, {}, False, "spindle_error", None),
    "rotor spindle 15 % (preload)": ("rotor", {"spindle_error": 0.15}, {}, False, "spindle_error", None),
    "bench flute declared solid": ("bench", {}, {}, True, "fluted_section", None),
    "rotor flute declared solid": ("rotor", {"fluted_section": 1.0}, {"fluted_declared": "solid"}, False,
                                   "fluted_section", None),
    "bench tip body r_g 8 mm": ("bench", {"tip_mass": 0.002}, {"tip_mass_radius_of_gyration": 0.008}, False,
                                "tip_mass", [{"tip_mass_kg": 0.002}]),
    "rotor tip body on the flank": ("rotor", {"tip_mass": 0.003}, {}, False, "tip_mass",
                                    [{"tip_mass_kg": 0.002, "tip_mass_offset_m": -0.003}]),
    "bench resonator at the holder tip": ("bench", {"extra_mode": 0.2}, {"extra_mode_location": "holder_tip"}, False,
                                          "extra_mode", [{"extra_mode_mass_kg": 0.1, "extra_mode_frequency_hz": f,
                                                          "extra_mode_damping_ratio": 0.03, "extra_mode_position": 0.5}
                                                         for f in (800.0, 1400.0)]),
    # the ring around the collet nut (0.136 kg, 2.4 kHz uncoupled, also rocking on its fit): its translation
    # carries the effect in the tool-mode band; one start near the ring's frequency (a resonator's frequency
    # is a sharply peaked, multimodal coordinate; the workflow's score test grids it)
    # a hysteretic joint: the bench adds the loss factor to its viscous joint damping, the rotor bench replaces
    # the viscous joint damping by it (its author's choice, unknown to the term)
    "bench joint loss factor 0.05": ("bench", {"joint_loss_factor": 0.05}, {}, False, "joint_loss_factor", None),
    "rotor hysteretic joint": ("rotor", {"hysteretic_joint": True}, {}, False, "joint_loss_factor", None),
    # a spindle file measured in translation only: the bench's rotation comes from its in-band modes, the rotor
    # bench's mostly from bearing tilt above the file band (static flexibility of the upper modes)
    "bench spindle file without rotations": ("bench", {"spindle_rotation_omitted": 1.0}, {}, False,
                                             "spindle_rotation_omitted", None),
    "rotor spindle file without rotations": ("rotor", {"spindle_rotation_omitted": 1.0}, {}, False,
                                             "spindle_rotation_omitted", [{}, {"rotation_slope_upper_per_m": 20.0,
                                                                           "rotation_compliance_upper_urad_per_Nm": 1.0}]),
    "rotor ring on the collet nut": ("rotor", {"extra_mode": True}, {}, False, "extra_mode",
                                     [{"extra_mode_mass_kg": 0.1, "extra_mode_frequency_hz": 2400.0,
                                       "extra_mode_damping_ratio": 0.03, "extra_mode_position": 0.85}]),
}


@pytest.fixture(scope="module")
def clean_fits(tmp_path_factory):
    """Gap and contact of the clean campaign of each generator (fitted once, on first use)."""
    cache: dict = {}

    def get(generator):
        if generator not in cache:
            cache[generator] = gaps(write(generator, {}, tmp_path_factory.mktemp(generator)), None)
        return cache[generator]

    return get


@pytest.mark.parametrize("case", list(CASES))
def test_term_halves_the_systematic_gap_of_its_effect(case, tmp_path, clean_fits):
    generator, effects, overrides, solid, term, starts = CASES[case]
    setup = write(generator, effects, tmp_path, solid_flute=solid, **overrides)
    before, contact = gaps(setup, None)
    after, fitted = gaps(setup, term, starts)
    assert before > 0.01, before  # the effect is visible beyond the 2 % noise of a real campaign
    assert after <= 0.5 * before, (before, after, fitted)
    # the term does the work, not a bent contact: measured rotational stiffness within 25 % of the clean fit
    # of the same generator (the old fixed-inertia tip mass left it 2.6 times too stiff on the rotor bench)
    clean, clean_contact = clean_fits(generator)
    assert clean < 0.1 * before
    assert fitted["k_xf"] == pytest.approx(clean_contact["k_xf"], rel=0.1)
    ratio = fitted["k_thetaM"] / clean_contact["k_thetaM"]
    lo, hi = K_THETA_RATIO.get(case, (0.75, 1.25))
    assert lo <= ratio <= hi, (ratio, fitted)


#: Cases whose term shares the contact's physics in part, with the range of k_thetaM / clean fit they may end in.
#: The flange's rotational compliance and the tool-holder contact's are both between the spindle's rotation and the
#: tool's: two lengths separate them only partly.  Measured 2.0 (bench) and 1.36 (rotor) with the upper modes' part;
#: with in-band slopes alone (the term before) 3.6 and 200 (the contact on its prior bound of 1e8 N m/rad).
K_THETA_RATIO = {"bench spindle file without rotations": (0.4, 2.5), "rotor spindle file without rotations": (0.4, 2.5)}


#: Four lengths: a law's shape between the outer lengths is invisible with two.
LAW_LENGTHS = (0.025, 0.030, 0.035, 0.040)


@pytest.mark.parametrize("generator,kind", [("rotor", "step"), ("bench", "ramp")])
def test_stiffness_step_explains_a_further_contact_zone_on_both_generators(generator, kind, tmp_path):
    """A +25 % stiffness step between 30 and 35 mm (rotor: hard and multiplicative; the project's bench: an
    additive 3-mm ramp from 31.5 mm) on a linear growth of 15 %: ``stiffness_step`` halves the gap, puts the
    step between the two lengths that straddle it, and recovers the total growth."""
    setup = write(generator, {"nonlinear_stiffness_law": 0.25}, tmp_path, lengths=LAW_LENGTHS,
                  stiffness_law_kind=kind, growth=0.15)
    before, _ = gaps(setup, None, lengths=LAW_LENGTHS)
    after, fitted = gaps(setup, "stiffness_step", [{"stiffness_step_position": c, "stiffness_step_sharpness": 20.0}
                                                   for c in (0.3, 0.7)], lengths=LAW_LENGTHS)
    assert before > 0.05, before  # far beyond the 2 % noise of a real campaign
    assert after <= 0.5 * before, (before, after, fitted)
    # the measured lengths only say that the step lies between 30 and 35 mm (x = 1/3 and 2/3)
    assert 1 / 3 < fitted["stiffness_step_position"] < 2 / 3, fitted
    # total growth 25 -> 40 mm: rotor (1.15)(1.25) - 1 = 0.44, bench 0.15 + 0.25 = 0.40; the fitted k_xf's growth
    # is the model's (RCSA contact, not the bench's springs), so only within 0.1
    assert fitted["g_xf"] == pytest.approx(0.44 if kind == "step" else 0.40, abs=0.1), fitted


def test_spindle_error_s_coupling_of_close_modes_carries_to_the_lengths_not_fitted(tmp_path):
    """Rotor bench, spindle file from front bearing sets 15 % softer and a rear set 25 % stiffer than today's: the
    two front-set flange modes (2.0 and 2.5 kHz) exchange shape.  Noise-free, x and y, fitted at 25 and 40 mm over
    600-2000 Hz (the workflow's band on these campaigns is 808-1714 Hz): with their coupling the fit carries to 30
    and 35 mm a third better than with the coupling held at 0 (held-out gap 0.0101 against 0.0153; the workflow's
    campaigns: 0.012-0.014 against 0.027).  Over 600-3000 Hz, which takes in the two modes themselves, it does not
    (0.023 against 0.013): the spindle term's Limits."""
    both = ("x", "y")
    setup = write("rotor", {"spindle_error": -0.15}, tmp_path, lengths=LAW_LENGTHS, directions=both,
                  spindle_error_kind="bearing_sets", spindle_error_rear=0.25)
    names = [p.name for p in make_term("spindle_error").parameters(setup.model())]
    coupling = [n for n in names if n.endswith("_coupling_change")]
    assert coupling == ["spindle_mode3_mode4_coupling_change"], names
    kw = dict(predict=(0.030, 0.035), directions=both)
    before, _ = gaps(setup, None, **kw)
    free, fit_free = gaps(setup, "spindle_error", **kw)
    zero, fit_zero = gaps(setup, "spindle_error", held={coupling[0]: 0.0}, **kw)
    assert free <= zero + 1e-9 and free <= 0.5 * before, (before, zero, free)
    assert fit_free["held_out_gap"] <= 0.75 * fit_zero["held_out_gap"], (fit_free, fit_zero)
