"""Acceptance tests of rigid and elastic receptance coupling (issue 2).

References: closed-form cantilever results, the one-piece beam, and the
independent finite-element chain of ``reference_models.py`` in which the
contact is a pair of lumped springs between two nodes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from bayes_rcsa.model import (
    Material,
    Segment,
    SectionProperties,
    attach,
    circular_section,
    composite_section,
    contact_compliance,
    couple,
    elastic_coupling,
    free_free_receptances,
    rigid_coupling,
)

import reference_models as ref

STEEL = Material(200e9, 7850.0, 0.29, 0.0, "steel")
CARBIDE = Material(580e9, 14500.0, 0.22, 0.0, "carbide")
STEEL_D = Material(200e9, 7850.0, 0.29, 0.01, "steel")
CARBIDE_D = Material(580e9, 14500.0, 0.22, 0.004, "carbide")
REF_STEEL_D = ref.RefMaterial(200e9, 7850.0, 0.29, 0.01)
REF_CARBIDE_D = ref.RefMaterial(580e9, 14500.0, 0.22, 0.004)

WALL = 1e-14  # receptance of a "rigid" wall, m/N and rad/(N m): 1e-7 of the beams' compliance


def _wall(n):
    return np.broadcast_to(WALL * np.eye(2, dtype=complex), (n, 2, 2))


def _cantilever_tip(segments, omega):
    return attach(_wall(omega.size), free_free_receptances(segments, omega))


def _rel_block_err(a, b):
    """max over frequencies of ||a - b||_F / ||b||_F, arrays (n_freq, k, k)."""
    return float(np.max(np.linalg.norm(a - b, axis=(-2, -1)) / np.linalg.norm(b, axis=(-2, -1))))


def _holder_and_tool(damped=True):
    """A stepped holder-like two-port (with a composite clamped part) and a tool two-port."""
    st, cb = (STEEL_D, CARBIDE_D) if damped else (STEEL, CARBIDE)
    holder = [
        Segment(0.02, circular_section(st, 0.063)),
        Segment(0.035, circular_section(st, 0.05, 0.00794)),
        Segment(0.025, composite_section(circular_section(st, 0.05, 0.00794), circular_section(cb, 0.00794))),
    ]
    tool = [Segment(0.045, circular_section(cb, 0.00794)), Segment(0.03, circular_section(cb, 0.00794 * 0.8))]
    return holder, tool


# ------------------------------------------------------------------ item 2 --


def test_rigid_wall_gives_clamped_free_euler_bernoulli_frequency():
    """Item 2: attach() to a near-rigid wall gives beta_1 L = 1.875104 (and 4.694091)."""
    base = circular_section(STEEL, 0.01)
    eb = SectionProperties(base.EI, base.kGA * 1e6, base.rhoA, 0.0)
    L = 0.25
    c = math.sqrt(eb.EI.real / eb.rhoA) / L**2

    def stiffness(beta_l):  # 1/h at the tip; zero at resonances
        return 1.0 / _cantilever_tip([Segment(L, eb)], np.array([beta_l**2 * c]))[0, 0, 0].real

    grid = np.linspace(1.0, 5.5, 46)
    vals = np.array([stiffness(b) for b in grid])
    roots = []
    for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
        if np.sign(fa) != np.sign(fb):
            x = brentq(stiffness, a, b, xtol=1e-13)
            if abs(stiffness(x)) < 1e-3 * min(abs(fa), abs(fb)):  # not a pole (antiresonance)
                roots.append(x)
    err = np.abs(np.array(roots) / [1.875104, 4.694091] - 1)
    assert len(roots) == 2
    # kGA * 1e6 and the 1e-14 wall change beta L by < 1e-8; brief: 0.1 %.
    assert np.all(err < 1e-3), err
    assert np.all(err < 1e-6), err


def test_rigid_wall_gives_static_timoshenko_cantilever_compliance():
    """Item 2: static tip block of a clamped Timoshenko cantilever (L/d = 5):
    h = L^3/3EI + L/kGA, l = n = L^2/2EI, p = L/EI."""
    sec = circular_section(CARBIDE, 0.008)
    L = 0.04
    EI, kGA = sec.EI.real, sec.kGA.real
    tip = _cantilever_tip([Segment(L, sec)], 2 * np.pi * np.array([5.0, 10.0]))
    want = np.array([[L**3 / (3 * EI) + L / kGA, L**2 / (2 * EI)], [L**2 / (2 * EI), L / EI]])
    rel = np.abs(tip / want - 1)
    # dynamic correction (f / f_1)^2 ~ 1e-7 at 10 Hz, f_1 ~ 3.5 kHz; round-off of
    # the free-free blocks ~ eps (f_1 / f)^2 ~ 1e-9; brief: 0.5 %.
    assert np.all(rel < 5e-3), rel
    assert np.all(rel < 1e-5), rel
    # the shear term is not negligible for this stubby beam
    assert L / kGA > 0.02 * L**3 / (3 * EI)


def test_rigid_wall_stubby_timoshenko_cantilever_matches_fe():
    """Clamped-free stubby beam: first two frequencies equal the clamped FE model."""
    d, L = 0.02, 0.1
    sec = circular_section(STEEL, d)
    c = math.sqrt(sec.EI.real / sec.rhoA) / L**2

    def stiffness(omega):
        return 1.0 / _cantilever_tip([Segment(L, sec)], np.array([omega]))[0, 0, 0].real

    section = ref.tube(200e9, 7850.0, 0.29, 0.0, d)
    fe = ref.richardson(*(ref.natural_frequencies(ref.mesh([(L, section)], L / n)[0], 2, clamped_nodes=[0])
                          for n in (100, 200)))
    lib = np.array([brentq(stiffness, 0.97 * w, 1.03 * w, xtol=1e-10 * w) for w in fe])
    err = np.abs(lib / fe - 1)
    # extrapolated FE error < 1e-8; the 1e-14 m/N wall compliance itself lowers the
    # frequencies by 6e-8 and 6e-7 (the static tip compliance is only 2e-7 m/N)
    assert np.all(err < 2e-6), err
    assert np.all(lib < np.array([1.875104, 4.694091]) ** 2 * c * 0.98)  # clearly below EB


# ------------------------------------------------------------------ item 4 --


@pytest.mark.parametrize("damped", [False, True])
def test_rigid_coupling_of_two_segments_reproduces_one_piece_beam(damped):
    """Item 4: couple(A, B) equals the one-piece beam, all four blocks, 1e-6."""
    holder, tool = _holder_and_tool(damped)
    omega = 2 * np.pi * np.linspace(10.0, 20e3, 600)
    one_piece = free_free_receptances(holder + tool, omega)
    coupled = couple(free_free_receptances(holder, omega), free_free_receptances(tool, omega))
    # also split inside a uniform segment
    uniform = [Segment(0.1, circular_section(STEEL_D if damped else STEEL, 0.02))]
    halves = couple(free_free_receptances([Segment(0.037, uniform[0].section)], omega),
                    free_free_receptances([Segment(0.063, uniform[0].section)], omega))
    whole = free_free_receptances(uniform, omega)
    for got, want in ((coupled, one_piece), (halves, whole)):
        for name in ("r11", "r12", "r21", "r22"):
            err = _rel_block_err(getattr(got, name), getattr(want, name))
            # round-off of the exact dynamic stiffness ~ eps (f_1/f)^2 ~ 1e-10 at 10 Hz
            assert err < 1e-6, (name, err)


def test_coupling_is_associative_and_matches_paper_formulae():
    holder, tool = _holder_and_tool()
    omega = 2 * np.pi * np.linspace(100.0, 10e3, 200)
    a = free_free_receptances(holder[:1], omega)
    b = free_free_receptances(holder[1:], omega)
    c = free_free_receptances(tool, omega)
    comp = contact_compliance(omega, 2e6, 5e5, 10.0, 5e-4)
    left = couple(couple(a, b), c, comp)
    right = couple(a, couple(b, c, comp))
    assert _rel_block_err(left.as_matrix(), right.as_matrix()) < 1e-10
    ab = couple(a, b)
    assert np.allclose(rigid_coupling(ab.r11, ab.r12, ab.r21, ab.r22, c.r11), couple(ab, c).r11, rtol=1e-13, atol=0)
    assert np.allclose(elastic_coupling(ab.r11, ab.r12, ab.r21, ab.r22, c.r11, comp), left.r11, rtol=1e-13, atol=0)


# ------------------------------------------------------------------ item 5 --


def test_coupled_receptances_are_reciprocal_and_passive():
    """Item 5 (coupling part): R12 = R21^T, symmetric point blocks, Im G <= 0."""
    holder, tool = _holder_and_tool()
    omega = 2 * np.pi * np.linspace(10.0, 20e3, 2000)
    H, T = free_free_receptances(holder, omega), free_free_receptances(tool, omega)
    spindle = ref.default_spindle().flange_receptance(omega)
    for tp in (couple(H, T, contact_compliance(omega, 2e6, 5e5, 10.0, 5e-4)), couple(H, T)):
        G = tp.as_matrix()
        scale = np.linalg.norm(G, axis=(-2, -1))
        assert np.max(np.abs(tp.r12 - np.swapaxes(tp.r21, -1, -2)).max(axis=(-2, -1)) / scale) < 1e-10
        for point in (tp.r11, tp.r22):
            assert np.max(np.abs(point[:, 0, 1] - point[:, 1, 0]) / scale) < 1e-10
        # passive: Im G negative semi-definite, hence Im h <= 0 and Im p <= 0
        assert np.all(np.linalg.eigvalsh(G.imag) <= 1e-10 * scale[:, None])
        tip = attach(spindle, tp)
        tip_scale = np.linalg.norm(tip, axis=(-2, -1))
        assert np.max(np.abs(tip[:, 0, 1] - tip[:, 1, 0]) / tip_scale) < 1e-10
        assert np.all(np.linalg.eigvalsh(tip.imag) <= 1e-10 * tip_scale[:, None])


# ------------------------------------------------------------------ item 6 --


def test_elastic_coupling_converges_to_rigid_as_one_over_k():
    """Item 6: ||C(k) - C_rigid|| ~ 1/k, and k = inf is exactly rigid."""
    holder, tool = _holder_and_tool()
    omega = 2 * np.pi * np.linspace(100.0, 10e3, 300)
    H, T = free_free_receptances(holder, omega), free_free_receptances(tool, omega)
    rigid = couple(H, T).as_matrix()
    inf = couple(H, T, contact_compliance(omega, np.inf, np.inf)).as_matrix()
    assert np.array_equal(inf, rigid)
    ks = 10.0 ** np.arange(11, 15)
    errs = np.array([_rel_block_err(couple(H, T, contact_compliance(omega, k, 0.25 * k)).as_matrix(), rigid)
                     for k in ks])
    ratios = errs[:-1] / errs[1:]
    # First-order perturbation in 1/k: the O(1/k^2) remainder is < 3 % of the
    # difference from k = 1e11 N/m on (the per-frequency relative error peaks
    # where the joint compliance shifts the lightly damped resonances).
    assert np.all(np.abs(ratios / 10 - 1) < 0.03), (errs, ratios)
    assert errs[-1] < 1e-4


def test_elastic_coupling_matches_fe_with_lumped_contact_springs():
    """couple(A, B, K^-1) equals the FE chain beam A - springs - beam B (all blocks)."""
    st, cb = REF_STEEL_D, REF_CARBIDE_D
    holder, tool = _holder_and_tool()
    ref_holder = [(0.02, st.section(0.063)), (0.035, st.section(0.05, 0.00794)),
                  (0.025, st.section(0.05, 0.00794) + cb.section(0.00794))]
    ref_tool = [(0.045, cb.section(0.00794)), (0.03, cb.section(0.00794 * 0.8))]
    omega = 2 * np.pi * np.linspace(50.0, 20e3, 400)
    kx, kt, cx, ct = 2e6, 5e5, 10.0, 5e-4
    lib = couple(free_free_receptances(holder, omega), free_free_receptances(tool, omega),
                 contact_compliance(omega, kx, kt, cx, ct)).as_matrix()
    springs = ref.ContactSprings(kx, kt, cx, ct)

    def fe(h):
        return ref.end_receptances([*ref.mesh(ref_holder, h)[0], springs, *ref.mesh(ref_tool, h)[0]], omega)

    err = _rel_block_err(lib, ref.richardson(fe(1e-3), fe(0.5e-3)))
    # extrapolated FE O(h^4) error, amplified near the lightly damped resonances
    assert err < 1e-4, err


def test_contact_compliance_shapes_and_values():
    omega = 2 * np.pi * np.array([100.0, 1000.0])
    kx = np.array([1e6, 2e6, 4e6])
    comp = contact_compliance(omega, kx, 5e5, 10.0, 5e-4)
    assert comp.shape == (3, 2, 2, 2)
    assert comp[1, 1, 0, 0] == pytest.approx(1 / (2e6 + 1j * omega[1] * 10.0), rel=1e-15)
    assert comp[2, 0, 1, 1] == pytest.approx(1 / (5e5 + 1j * omega[0] * 5e-4), rel=1e-15)
    assert np.all(comp[..., 0, 1] == 0) and np.all(comp[..., 1, 0] == 0)
    # passive joint: Im of the compliance <= 0
    assert np.all(comp[..., 0, 0].imag <= 0) and np.all(comp[..., 1, 1].imag <= 0)
