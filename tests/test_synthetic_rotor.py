"""The second synthetic bench (bayes_rcsa.synthetic.rotor): elements, solver, physics invariants, effects, files.

Tolerances are justified where they are asserted.  Runtime is kept small with
one cached campaign and coarse meshes where the property does not need a fine one.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from bayes_rcsa.errors import SetupError
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.synthetic.campaign import dominant_peak
from bayes_rcsa.synthetic.rotor import (
    ROTOR_EFFECTS,
    build_structure,
    direct_receptance,
    exported_spindle_receptance,
    generate_rotor_campaign,
    modal_solution,
    rotor_bench_config,
    true_contact,
    true_modes,
    true_spindle_receptance,
    true_tool_point_frf,
    write_rotor_campaign,
)
from bayes_rcsa.synthetic.rotor.build import exported_bearing_factors
from bayes_rcsa.synthetic.rotor.campaign import spindle_file_modes
from bayes_rcsa.synthetic.rotor.elements import element_mass, element_stiffness, element_stiffness_quadrature
from bayes_rcsa.synthetic.rotor.sections import (
    FluteProfile,
    RotorMaterial,
    cowper_kappa,
    flute_polygon,
    flute_section,
    jourawski_kappa,
    polygon_area_inertia,
    tube_section,
)
from bayes_rcsa.synthetic.rotor.structure import Structure, mesh_points

STEEL = RotorMaterial(200e9, 7850.0, 0.29, 0.0)
#: coarse but converged enough for comparisons between variants of the same mesh
FAST = dict(mesh_size=0.008, spindle_mesh_size=0.03, mode_cutoff_hz=30e3)
F_FINE = np.arange(500.0, 3500.0, 1.0)


def fast(effects=None, **kw):
    return rotor_bench_config(effects, **{**FAST, **kw})


def first_mode(config, length, direction="x"):
    """Frequency (Hz) and height (m/N) of the dominant tool-point peak, noise-free."""
    return dominant_peak(F_FINE, true_tool_point_frf(config, direction, length, F_FINE))


# --------------------------------------------------------------------------- sections, elements

def test_sections_polygon_and_shear_coefficients():
    t = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    a, ixx, iyy = polygon_area_inertia(circle)
    assert a == pytest.approx(np.pi, rel=1e-5) and ixx == pytest.approx(np.pi / 4, rel=1e-5) == iyy
    rect = np.array([[-1.0, -2.0], [1.0, -2.0], [1.0, 2.0], [-1.0, 2.0]])
    assert jourawski_kappa(rect) == pytest.approx(5 / 6, rel=1e-4)       # textbook value
    assert jourawski_kappa(circle) == pytest.approx(0.9, abs=3e-3)       # form factor 10/9
    sec, geo = flute_section(STEEL, 0.00794, FluteProfile(4, 0.60, 0.30))
    # the fluted section is not a circle of one diameter: A and I give different equivalent diameters
    assert geo["area_equivalent_diameter_ratio"] == pytest.approx(0.7956, abs=2e-3)
    assert geo["inertia_equivalent_diameter_ratio"] == pytest.approx(0.8287, abs=2e-3)
    pts = flute_polygon(0.00794, FluteProfile(4, 0.60, 0.30))
    r = np.hypot(pts[:, 0], pts[:, 1])
    assert r.min() == pytest.approx(0.3 * 0.00794, rel=1e-3) and r.max() == pytest.approx(0.00794 / 2)
    assert cowper_kappa(0.3) == pytest.approx(6 * 1.3 / 8.8)


def test_element_closed_form_equals_quadrature_and_euler_bernoulli_mass():
    for EI, kGA, L in [(3.0, 50.0, 0.7), (113.0, 2.1e6, 0.004)]:
        K = element_stiffness(EI, kGA, L).real
        np.testing.assert_allclose(K, element_stiffness_quadrature(EI, kGA, L), rtol=1e-10, atol=1e-12 * abs(K).max())
    M = element_mass(1.0, 0.0, 1.0, 0.0) * 420
    np.testing.assert_allclose(M, [[156, 22, 54, -13], [22, 4, 13, -3], [54, 13, 156, -22], [-13, -3, -22, 4]],
                               atol=1e-10)


def _cantilever(L, D, n_el, material=STEEL):
    st = Structure()
    z = mesh_points([0.0, L], L / n_el)
    nodes = st.add_nodes(z.size)
    sec = tube_section(material, D)
    st.add_beam(nodes, z, [sec] * (z.size - 1))
    # clamp: remove the root node's two dofs (exact; a penalty spring would make K ill-conditioned)
    clamped = Structure(st.n_dof - 2, st.K[2:, 2:], st.D[2:, 2:], st.C[2:, 2:], st.M[2:, 2:])
    return clamped, nodes - 2, sec


def _timoshenko_cantilever_exact(sec, L, f_guess):
    """Root of the exact clamped-free Timoshenko determinant nearest ``f_guess`` (own derivation)."""
    EI, kGA, rA, rI = sec.EI.real, sec.kGA.real, sec.rhoA, sec.rhoI

    def smin(f):
        w = 2 * np.pi * f
        lam2 = np.roots([kGA * EI, w**2 * (kGA * rI + rA * EI), rA * w**2 * (rI * w**2 - kGA)]).astype(complex)
        lam = np.concatenate([np.sqrt(lam2), -np.sqrt(lam2)])
        psi = lam + rA * w**2 / (kGA * lam)       # ψ amplitude per unit u amplitude
        e = np.exp(lam * L)
        A = np.array([np.ones(4), psi, EI * lam * psi * e, kGA * (lam - psi) * e])
        s = np.linalg.svd(A / np.abs(A).max(axis=1, keepdims=True), compute_uv=False)
        return s[-1] / s[0]

    res = minimize_scalar(smin, bounds=(0.97 * f_guess, 1.03 * f_guess), method="bounded",
                          options={"xatol": 1e-9 * f_guess})
    assert smin(res.x) < 1e-6
    return res.x


def test_cantilever_converges_to_exact_timoshenko_and_euler_bernoulli_limits():
    # stubby beam (L/D = 5): FE -> exact Timoshenko, error falling with refinement
    L, D = 0.05, 0.01
    errors = []
    for n in (4, 8, 16):
        st, nodes, sec = _cantilever(L, D, n)
        sol = modal_solution(st, nodes[-1], cutoff_hz=2e6)
        f_fe = np.sort(sol.undamped_hz)[:2]
        exact = [_timoshenko_cantilever_exact(sec, L, f) for f in f_fe]
        errors.append(abs(f_fe[1] / exact[1] - 1))
        assert abs(f_fe[0] / exact[0] - 1) < 2e-3
    # second mode: error falls like h^2 (x 1/4 per halving), 4e-4 with 16 elements
    assert errors[2] < errors[1] / 3 < errors[0] / 9 and errors[2] < 1e-3
    # Timoshenko well below Euler-Bernoulli for the stubby beam
    eb = 1.875104**2 / (2 * np.pi * L**2) * np.sqrt(sec.EI.real / sec.rhoA)
    assert f_fe[0] < 0.99 * eb   # shear and rotary inertia: about 2 % lower at L/D = 5
    # slender limit (L/D = 100): beta L = 1.875104, 4.694091
    L = 1.0
    st, nodes, sec = _cantilever(L, D, 40)
    f_fe = np.sort(modal_solution(st, nodes[-1], cutoff_hz=1e4).undamped_hz)[:2]
    scale = np.sqrt(sec.EI.real / sec.rhoA) / (2 * np.pi * L**2)
    np.testing.assert_allclose(f_fe, np.array([1.875104, 4.694091]) ** 2 * scale, rtol=1e-3)
    assert f_fe[0] < 1.875104**2 * scale   # and always below Euler-Bernoulli  # Timoshenko terms ~(βD/L)² ~ 4e-4 for mode 2
    # static tip compliance L^3/3EI + L/kGA (exact for these elements)
    st, nodes, sec = _cantilever(0.05, D, 3)
    h0 = modal_solution(st, nodes[-1], cutoff_hz=1.0).receptance([1e-6])[0, 0, 0]
    assert h0.real == pytest.approx(0.05**3 / (3 * sec.EI.real) + 0.05 / sec.kGA.real, rel=1e-8)


# --------------------------------------------------------------------------- solver and invariants

@pytest.fixture(scope="module")
def all_effects_structure():
    cfg = fast({n: True for n in ROTOR_EFFECTS})
    return build_structure(cfg, "x", 0.030)


def test_modal_superposition_matches_dense_direct_solve(all_effects_structure):
    st, dofs = all_effects_structure
    f = np.linspace(500, 3500, 13)
    io = [dofs["tip"][0], dofs["holder_tip"][0], dofs["flange"][1]]
    H_modal = modal_solution(st, io, cutoff_hz=60e3).receptance(f)
    H_direct = direct_receptance(st, io, f)
    # truncation at 60 kHz + static residual: the dynamic part of the dropped modes, (f/f_cut)^2 ~ 3e-3 of a
    # residual that is itself small, and their damping coupling; measured ~1e-5
    err = np.abs(H_modal - H_direct).max(axis=0) / np.abs(H_direct).max(axis=0)
    assert err.max() < 1e-3
    # reciprocity of the transfer receptances of the full system (direct solve of the symmetric pencil)
    np.testing.assert_allclose(H_direct[:, 0, 1], H_direct[:, 1, 0], rtol=1e-8)
    np.testing.assert_allclose(H_direct[:, 0, 2], H_direct[:, 2, 0], rtol=1e-8)


def test_flange_block_reciprocal_passive_and_static_limit():
    cfg = fast()
    f = np.linspace(500, 3500, 61)
    block = true_spindle_receptance(cfg, "x", f).block
    np.testing.assert_allclose(block[:, 0, 1], block[:, 1, 0], rtol=1e-8, atol=0)
    assert (block[:, 0, 0].imag <= 0).all() and (block[:, 1, 1].imag <= 0).all()
    # Im of the point block negative semi-definite (passive)
    eig = np.linalg.eigvalsh(block.imag)
    assert (eig <= 1e-12 * np.abs(block).max()).all()
    # static limit: modal expansion + residual equals the static FE solution
    st, dofs = build_structure(cfg, "x", spindle_only=True)
    h0 = modal_solution(st, dofs["flange"], cfg.mode_cutoff_hz).receptance([1e-6])[0]
    G = np.linalg.solve(st.K + 1j * st.D, np.eye(st.n_dof)[:, dofs["flange"]])[dofs["flange"]]
    np.testing.assert_allclose(h0, G, rtol=1e-7)   # iωC at 1e-6 Hz: ~1e-8 relative


def test_tool_point_passive_in_every_configuration():
    for effects in (None, {"contact_damping": True, "hysteretic_joint": True, "extra_mode": True, "tip_mass": True}):
        cfg = fast(effects)
        for l in (0.025, 0.040):
            h = true_tool_point_frf(cfg, "y", l, np.linspace(1, 6000, 400))
            assert (h.imag <= 0).all()


def test_static_contact_compliance_by_hand():
    # statically the joint is in series: h(k) - h(rigid) = 1/k_xf + L_o^2 / k_thetaM exactly (L_o = overhang)
    cfg = fast(c_xf=0.0, c_thetaM=0.0)
    l = 0.030
    st, d = build_structure(cfg, "x", l)
    st_r, d_r = build_structure(cfg, "x", l, rigid_contact=True)
    h = modal_solution(st, d["tip"]).receptance([1e-6])[0, 0, 0]
    h_r = modal_solution(st_r, d_r["tip"]).receptance([1e-6])[0, 0, 0]
    overhang = cfg.tool_total_length - l
    c = true_contact(cfg, l)
    hand = 1 / c["k_xf"] + overhang**2 / c["k_thetaM"]
    assert (h - h_r).real == pytest.approx(hand, rel=1e-7)


def test_rigid_contact_limit_equals_bonded_shank():
    cfg = fast(k_xf=1e13, k_thetaM=1e11)
    st, d = build_structure(cfg, "x", 0.035)
    st_r, d_r = build_structure(cfg, "x", 0.035, rigid_contact=True)
    f = np.linspace(500, 3500, 301)
    h = modal_solution(st, d["tip"], 40e3).receptance(f)[:, 0, 0]
    h_r = modal_solution(st_r, d_r["tip"], 40e3).receptance(f)[:, 0, 0]
    # the springs add 1/k ~ 1e-13 m/N and L^2/k ~ 4e-14 to a compliance ~ 1e-6: relative ~1e-7, plus the
    # extra stiff modes' truncation
    assert np.abs(h - h_r).max() / np.abs(h_r).max() < 1e-4


def test_mesh_refinement_converges():
    f = []
    for m in (0.008, 0.004, 0.002):
        cfg = rotor_bench_config(mesh_size=m, spindle_mesh_size=0.015, directions=("x",))
        modes = true_modes(cfg, "x", 0.030)
        f.append(max(modes, key=lambda x: x["modal_peak"])["eigenfrequency_hz"])
    assert abs(f[1] - f[2]) < abs(f[0] - f[2]) and abs(f[1] / f[2] - 1) < 1e-3


# --------------------------------------------------------------------------- effects

@pytest.fixture(scope="module")
def clean_modes():
    cfg = fast()
    return {l: first_mode(cfg, l) for l in (0.025, 0.030, 0.040)}


def test_tip_mass_and_softer_tool_lower_the_first_mode(clean_modes):
    for name in ("tip_mass", "tool_modulus"):
        f, _ = first_mode(fast({name: True}), 0.025)
        assert f < clean_modes[0.025][0] - 5.0, name
    assert first_mode(fast({"tool_modulus": 0.05}), 0.025)[0] > clean_modes[0.025][0]


def test_joint_damping_lowers_the_peak(clean_modes):
    for effects in ({"contact_damping": True}, {"contact_damping": 40.0}, {"hysteretic_joint": True}):
        _, a = first_mode(fast(effects), 0.040)
        assert a < 0.9 * clean_modes[0.040][1], effects


def test_fluted_profile_is_stiffer_than_declared_effective_circle(clean_modes):
    # the default profile: I-equivalent ratio 0.829 > declared 0.80, A-equivalent 0.796 ~ 0.80
    f, _ = first_mode(fast({"fluted_section": True}), 0.030)
    assert f > clean_modes[0.030][0]
    solid = fast(fluted_declared="solid")
    assert first_mode(solid, 0.030)[0] != pytest.approx(clean_modes[0.030][0], rel=1e-3)


def test_saturating_law_stiffer_in_between_equal_at_ends(clean_modes):
    cfg = fast({"nonlinear_stiffness_law": True})
    assert first_mode(cfg, 0.030)[0] > clean_modes[0.030][0] + 3.0
    assert first_mode(cfg, 0.025)[0] == pytest.approx(clean_modes[0.025][0], abs=0.05)
    step = fast({"nonlinear_stiffness_law": 0.3}, stiffness_law_kind="step")
    assert first_mode(step, 0.040)[0] > clean_modes[0.040][0] + 3.0


def test_extra_mode_adds_a_holder_side_resonance():
    cfg = fast({"extra_mode": True})
    clean = true_modes(fast(), "x", 0.030)
    modes = true_modes(cfg, "x", 0.030)
    # the ring's translation (2400 Hz) and rocking (x 1.4 = 3360 Hz) modes on its compliant fit
    assert len(modes) == len(clean) + 2
    assert any(abs(m["eigenfrequency_hz"] / 2400 - 1) < 0.15 for m in modes)
    # it couples with the holder rocking and second tool modes: the FRF changes by more than the noise
    f = np.linspace(1400, 3500, 211)
    h0, h1 = true_tool_point_frf(fast(), "x", 0.03, f), true_tool_point_frf(cfg, "x", 0.03, f)
    assert np.abs(h1 / h0 - 1).max() > 0.2
    # never in the exported spindle file
    f = np.linspace(500, 3500, 31)
    np.testing.assert_array_equal(exported_spindle_receptance(cfg, "x", f).block,
                                  exported_spindle_receptance(fast(), "x", f).block)


def test_spindle_errors_change_only_the_exported_file():
    f = np.arange(500.0, 3500.0, 2.0)
    clean = fast()
    ref = exported_spindle_receptance(clean, "x", f).block
    h_ref = dominant_peak(f, ref[:, 0, 0])
    for kind in ("preload", "one_bearing", "rear"):
        cfg = fast({"spindle_error": True}, spindle_error_kind=kind)
        block = exported_spindle_receptance(cfg, "x", f).block
        assert not np.allclose(block, ref)
        # stiffer bearings: less static compliance at the flange, spindle modes do not fall
        st0, d0 = build_structure(clean, "x", spindle_only=True)
        st1, d1 = build_structure(cfg, "x", spindle_only=True, exported=True)
        s0 = np.linalg.solve(st0.K, np.eye(st0.n_dof)[:, d0["flange"][0]])[d0["flange"][0]]
        s1 = np.linalg.solve(st1.K, np.eye(st1.n_dof)[:, d1["flange"][0]])[d1["flange"][0]]
        assert s1 < s0, kind
        f0 = modal_solution(st0, d0["flange"]).undamped_hz[:8]
        f1 = modal_solution(st1, d1["flange"]).undamped_hz[:8]
        assert (f1 >= f0 * (1 - 1e-12)).all() and (f1 > f0 * 1.001).any(), kind
    preload = exported_spindle_receptance(fast({"spindle_error": True}), "x", f).block
    assert dominant_peak(f, preload[:, 0, 0])[0] > h_ref[0]
    np.testing.assert_array_equal(true_tool_point_frf(fast({"spindle_error": True}), "x", 0.03, f[:50]),
                                  true_tool_point_frf(clean, "x", 0.03, f[:50]))
    rot = exported_spindle_receptance(fast({"spindle_rotation_omitted": 0.4}), "x", f).block
    np.testing.assert_allclose(rot[:, 0, 0], ref[:, 0, 0])
    np.testing.assert_allclose(rot[:, 1, 1], 0.6 * ref[:, 1, 1])
    np.testing.assert_allclose(rot[:, 0, 1], 0.6 * ref[:, 0, 1])


def _sets(front, rear, **kw):
    """Fast config whose exported spindle file has front sets x (1 + front), rear sets x (1 + rear)."""
    return fast({"spindle_error": front}, spindle_error_kind="bearing_sets", spindle_error_rear=rear, **kw)


def test_bearing_set_factors_reach_the_exported_file_only():
    f = np.arange(500.0, 3500.0, 2.0)
    clean, cfg = fast(), _sets(0.20, -0.10)
    # the "measured" tool point comes from today's rotor: bit for bit the clean one
    np.testing.assert_array_equal(true_tool_point_frf(cfg, "x", 0.03, f[::25]),
                                  true_tool_point_frf(clean, "x", 0.03, f[::25]))
    np.testing.assert_array_equal(true_spindle_receptance(cfg, "y", f[::25]).block,
                                  true_spindle_receptance(clean, "y", f[::25]).block)
    block, ref = exported_spindle_receptance(cfg, "x", f).block, exported_spindle_receptance(clean, "x", f).block
    # the file changes by far more than the 2 % noise near the front-bearing modes (measured up to 180 %, 2.6 kHz)
    assert np.abs(block[:, 0, 0] / ref[:, 0, 0] - 1).max() > 0.1
    sets = {b["name"]: b for b in exported_bearing_factors(cfg)}
    assert [sets[n]["group"] for n in ("front_1", "front_2", "rear")] == ["front", "front", "rear"]
    for name, e in (("front_1", 0.20), ("front_2", 0.20), ("rear", -0.10)):
        b = sets[name]
        assert b["stiffness_factor"] == b["rotational_stiffness_factor"] == pytest.approx(1 + e, rel=1e-15)
        assert b["damping_factor"] == b["rotational_damping_factor"] == pytest.approx((1 + e) ** 0.5, rel=1e-15)
    # the exported structure carries exactly these bearings: K and C differ from today's only by them
    st0, _ = build_structure(clean, "x", spindle_only=True)
    st1, _ = build_structure(cfg, "x", spindle_only=True, exported=True)
    assert not np.allclose(st1.C, st0.C) and np.array_equal(st1.M, st0.M) and np.array_equal(st1.D, st0.D)
    stiff_only = exported_bearing_factors(fast({"spindle_error": 0.2}))     # the older kinds leave damping alone
    assert all(b["damping_factor"] == 1.0 for b in stiff_only)


def test_bearing_sets_move_their_own_modes_stiffer_up_softer_down():
    rows = {}
    for label, (ef, er) in {"front": (0.2, 0.0), "rear": (0.0, 0.2), "stiff": (0.2, 0.2),
                            "soft": (-0.2, -0.2)}.items():
        rows[label] = spindle_file_modes(_sets(ef, er), "x", n_modes=5)
    # this rotor: 1.5 kHz rides on the rear set (73 % of its strain energy), 2.2 and 2.5 kHz on the front sets
    dominant = [m["dominant_sets"] for m in rows["front"]]
    assert dominant.count("rear") == 1 and dominant.count("front") == 2
    for label, own, other in (("front", "front", "rear"), ("rear", "rear", "front")):
        moved = {g: max(abs(m["frequency_change"]) for m in rows[label] if m["dominant_sets"] == g)
                 for g in ("front", "rear")}
        # the changed group's modes move by percent (+7.9 / +7.1 %), the other group's 9x / 24x less (measured)
        assert moved[own] > 0.03 and moved[own] > 3 * moved[other], (label, moved)
    for m in rows["stiff"] + rows["soft"]:
        assert m["mac"] > 0.95          # the pairing is unambiguous for +-20 %
    bearing_modes = [i for i, m in enumerate(rows["stiff"]) if m["dominant_sets"] != "neither"]
    assert all(rows["stiff"][i]["frequency_change"] > 0.01 for i in bearing_modes)
    assert all(rows["soft"][i]["frequency_change"] < -0.01 for i in bearing_modes)
    # Rayleigh: a stiffer K raises every undamped mode, a softer one lowers every one
    st0, d0 = build_structure(fast(), "x", spindle_only=True)
    f0 = modal_solution(st0, d0["flange"]).undamped_hz[:8]
    for sign in (1, -1):
        st1, d1 = build_structure(_sets(0.2 * sign, 0.15 * sign), "x", spindle_only=True, exported=True)
        f1 = modal_solution(st1, d1["flange"]).undamped_hz[:8]
        assert (sign * (f1 - f0) >= -1e-9 * f0).all() and (sign * (f1 - f0) > 1e-3 * f0).any(), sign


def test_bearing_sets_exported_file_reciprocal_and_passive():
    f = np.linspace(500, 3500, 61)
    for ef, er, beta in ((0.3, -0.3, 0.5), (-0.5, 0.5, 2.0), (0.25, 0.25, 0.0)):
        block = exported_spindle_receptance(_sets(ef, er, spindle_error_damping_exponent=beta), "y", f).block
        np.testing.assert_allclose(block[:, 0, 1], block[:, 1, 0], rtol=1e-8, atol=0)
        # data-formats.md: e^{+i w t}, so a passive point receptance has Im h <= 0 (and Im p <= 0)
        assert (block[:, 0, 0].imag <= 0).all() and (block[:, 1, 1].imag <= 0).all()
        assert (np.linalg.eigvalsh(block.imag) <= 1e-12 * np.abs(block).max()).all()


def test_bearing_sets_refusals():
    with pytest.raises(SetupError, match=r"hidden_effects.spindle_error = 0.6: .*\|e\| <= 0.5"):
        _sets(0.6, 0.0)
    with pytest.raises(SetupError, match=r"spindle_error_rear = -0.7: .*\|e\| <= 0.5"):
        _sets(0.1, -0.7)
    with pytest.raises(SetupError, match="spindle_error_rear = 0.1: only used with spindle_error_kind = 'bearing_sets'"):
        fast({"spindle_error": 0.1}, spindle_error_rear=0.1)
    with pytest.raises(SetupError, match=r"spindle_error_damping_exponent = -1: expected a number in \[0, 2\]"):
        _sets(0.1, 0.1, spindle_error_damping_exponent=-1)
    with pytest.raises(SetupError, match="spindle_error_rear = 'x'"):
        _sets(0.1, "x")
    from bayes_rcsa.synthetic.rotor.config import BearingSet
    front_only = tuple(BearingSet(f"b{i}", -0.05 * (i + 1), 5e8, 3e6, 5e3, 10.0) for i in range(3))
    with pytest.raises(SetupError, match="bearings: .* every set in the front half"):
        _sets(0.1, 0.1, bearings=front_only)
    assert _sets(0.5, -0.5).magnitude("spindle_error") == 0.5       # the limit itself is accepted


def test_bearing_sets_campaign_truth_and_setup(tmp_path):
    cfg = _sets(-0.15, 0.25, directions=("x",), clamping_lengths=(0.03,), frequency_step=10.0)
    camp = generate_rotor_campaign(cfg, np.random.default_rng(11))
    path = write_rotor_campaign(camp, tmp_path / "c")
    assert len(load_setup(path).measurements) == 1 and "spindle_error" not in path.read_text()
    detail = json.loads((path.parent / "truth.json").read_text())["hidden_effect_details"]["spindle_error"]
    assert detail["kind"] == "bearing_sets" and detail["front_stiffness_change"] == -0.15
    assert detail["rear_stiffness_change"] == 0.25 and detail["damping_exponent"] == 0.5
    by_name = {b["name"]: b for b in detail["exported_bearings"]}
    assert by_name["rear"]["stiffness"] == pytest.approx(1.25 * cfg.bearings[2].stiffness)
    assert by_name["front_1"]["damping"] == pytest.approx(0.85 ** 0.5 * cfg.bearings[0].damping)
    modes = detail["flange_modes"]["x"]
    assert modes and {"true", "exported", "frequency_change", "damping_ratio_change"} <= set(modes[0])
    # the exported file is the changed rotor's, the measurement today's
    np.testing.assert_array_equal(camp.spindle["x"].block,
                                  exported_spindle_receptance(cfg, "x", cfg.frequency_hz).block)
    np.testing.assert_array_equal(camp.measurements[0][1].frequency_hz, cfg.frequency_hz)


def test_slotted_holder_makes_y_softer_than_x(clean_modes):
    cfg = fast({"slotted_holder": 0.25})
    fx, fy = first_mode(cfg, 0.040, "x")[0], first_mode(cfg, 0.040, "y")[0]
    cx, cy = first_mode(fast(), 0.040, "x")[0], first_mode(fast(), 0.040, "y")[0]
    assert (fy - fx) < (cy - cx) - 0.5


def test_bad_configuration_is_a_setup_error():
    with pytest.raises(SetupError, match="unknown effect 'tip_mas'"):
        rotor_bench_config({"tip_mas": True})
    with pytest.raises(SetupError, match="clamping_lenghts"):
        rotor_bench_config(clamping_lenghts=(0.03,))
    with pytest.raises(SetupError, match="spindle_error_kind"):
        rotor_bench_config(spindle_error_kind="front")
    with pytest.raises(SetupError, match="hidden_effects.tip_mass"):
        rotor_bench_config({"tip_mass": "heavy"})


# --------------------------------------------------------------------------- campaign and files

@pytest.fixture(scope="module")
def campaign_dirs(tmp_path_factory):
    cfg = rotor_bench_config({"tip_mass": True, "spindle_error": True, "contact_damping": 5.0},
                             frequency_step=4.0, **FAST)
    out = []
    for k in range(2):
        camp = generate_rotor_campaign(cfg, np.random.default_rng(7))
        out.append(write_rotor_campaign(camp, tmp_path_factory.mktemp(f"rotor{k}") / "campaign"))
    return cfg, camp, out


def test_campaign_byte_identical_and_loadable(campaign_dirs):
    cfg, camp, (a, b) = campaign_dirs
    files = sorted(p.name for p in a.parent.iterdir())
    assert files == sorted(["setup.toml", "truth.json", "spindle_x.csv", "spindle_y.csv"]
                           + [f"tip_{d}_{mm}mm.csv" for d in "xy" for mm in (25, 30, 35, 40)])
    for name in files:
        assert (a.parent / name).read_bytes() == (b.parent / name).read_bytes(), name
    setup = load_setup(a)
    assert len(setup.measurements) == 8
    assert "tip_mass" not in a.read_text() and "spindle_error" not in a.read_text()


def test_truth_lists_modes_for_every_measurement(campaign_dirs):
    cfg, camp, (a, _) = campaign_dirs
    truth = json.loads((a.parent / "truth.json").read_text())
    assert truth["hidden_effects"] == {"contact_damping": 5.0, "spindle_error": 0.15, "tip_mass": 0.003}
    for m in truth["measurements"]:
        lo, hi = cfg.frequency_start, cfg.frequency_stop
        assert m["modes"] and all(lo <= x["eigenfrequency_hz"] <= hi for x in m["modes"])
        assert 800 < m["dominant_peak_hz"] < 2000
        assert any(abs(x["eigenfrequency_hz"] / m["dominant_peak_hz"] - 1) < 0.02 for x in m["modes"])
    # noise: measured FRF within a few standard deviations of the truth near the peak
    cfg_, frf = camp.measurements[0]
    clean = true_tool_point_frf(cfg, cfg_.direction, cfg_.clamping_length, frf.frequency_hz)
    rel = np.abs(frf.values - clean) / (cfg.noise_relative * np.abs(clean) + cfg.noise_floor)
    assert np.median(rel) < 2.0 and (frf.coherence <= 1).all() and frf.coherence.min() >= 0


def test_default_first_modes_in_band_and_rising():
    cfg = rotor_bench_config(directions=("x",), frequency_step=4.0)
    f = [max(true_modes(cfg, "x", l), key=lambda m: m["modal_peak"])["eigenfrequency_hz"]
         for l in cfg.clamping_lengths]
    assert 800 < f[0] < f[1] < f[2] < f[3] < 2000
