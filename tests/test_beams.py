"""Acceptance tests of the exact Timoshenko beam receptances (issue 2).

The library side (``bayes_rcsa.model``) is compared with closed-form
Euler-Bernoulli results and with the independent finite-element reference in
``reference_models.py`` (Friedman-Kosmatka elements, consistent mass).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from bayes_rcsa.errors import SetupError
from bayes_rcsa.model import (
    Material,
    Segment,
    SectionProperties,
    circular_section,
    composite_section,
    cowper_shear_coefficient,
    free_free_receptances,
    segment_dynamic_stiffness,
)

import reference_models as ref

STEEL = Material(200e9, 7850.0, 0.29, 0.0, "steel")
STEEL_DAMPED = Material(200e9, 7850.0, 0.29, 0.01, "steel")
CARBIDE_DAMPED = Material(580e9, 14500.0, 0.22, 0.004, "carbide")

# Free-free Euler-Bernoulli eigenvalues beta_n L (cosh x cos x = 1).
FREE_FREE_BETA_L = np.array([4.730041, 7.853205, 10.995608])


def _real_roots(fun, grid):
    """Zero crossings of a real function that may also change sign through poles.

    Each sign change on ``grid`` is refined with Brent's method; brackets
    whose limit is a pole (|f| grows instead of vanishing) are dropped.
    """
    values = np.array([fun(x) for x in grid])
    roots = []
    for a, b, fa, fb in zip(grid[:-1], grid[1:], values[:-1], values[1:]):
        if np.sign(fa) == np.sign(fb):
            continue
        x = brentq(fun, a, b, xtol=1e-13 * b, rtol=1e-15, maxiter=200)
        if abs(fun(x)) < 1e-3 * min(abs(fa), abs(fb)):  # a pole would leave |f| large
            roots.append(x)
    return np.array(roots)


def _end_point_stiffness(segments):
    """1/h11 at end 1 of a free-free beam as a real function of omega (undamped)."""

    def fun(omega):
        # undamped: h is real up to round-off (checked on the scan grid in the tests)
        return 1.0 / free_free_receptances(segments, np.array([omega])).r11[0, 0, 0].real

    return fun


def _omega_from_beta_l(beta_l, section, length):
    return beta_l**2 * math.sqrt(section.EI.real / section.rhoA) / length**2


def _relative_block_error(a, b):
    """max over frequencies of ||a - b||_F / ||b||_F for (n_freq, k, k) arrays."""
    num = np.linalg.norm(a - b, axis=(-2, -1))
    den = np.linalg.norm(b, axis=(-2, -1))
    return float(np.max(num / den))


# ------------------------------------------------------------------ item 1 --


def test_free_free_euler_bernoulli_limit_frequencies():
    """Item 1: G -> infinity and rhoI = 0 reproduce the free-free EB eigenvalues."""
    base = circular_section(STEEL, 0.01)
    eb = SectionProperties(EI=base.EI, kGA=base.kGA * 1e6, rhoA=base.rhoA, rhoI=0.0)
    L = 0.3
    seg = [Segment(L, eb)]
    grid = _omega_from_beta_l(np.linspace(3.0, 12.0, 181), eb, L)
    h = free_free_receptances(seg, grid).r11[:, 0, 0]
    assert np.all(np.abs(h.imag) <= 1e-9 * np.abs(h))  # undamped: real
    roots = _real_roots(_end_point_stiffness(seg), grid)
    assert roots.size == 3
    beta_l = np.sqrt(roots * L**2 / math.sqrt(eb.EI.real / eb.rhoA))
    err = np.abs(beta_l / FREE_FREE_BETA_L - 1)
    # Shear flexibility kGA*1e6 leaves ~(beta r)^2 / 1e6 ~ 1e-9 of the frequencies;
    # the reference values are rounded to 7 digits; brief: 0.1 %.
    assert np.all(err < 1e-3), err
    assert np.all(err < 1e-6), err  # what the exact model actually achieves


def test_free_free_frequencies_are_roots_of_dynamic_stiffness_determinant():
    """The segment dynamic stiffness is singular at the free-free natural frequencies."""
    sec = circular_section(STEEL, 0.01)
    L = 0.3
    seg = Segment(L, sec)
    roots = _real_roots(_end_point_stiffness([seg]), _omega_from_beta_l(np.linspace(3.0, 12.0, 91), sec, L))
    K = segment_dynamic_stiffness(seg, roots)
    s = np.linalg.svd(K, compute_uv=False)
    assert np.all(s[:, -1] / s[:, 0] < 1e-9)
    # symmetric (reciprocal) dynamic stiffness at arbitrary frequencies
    K = segment_dynamic_stiffness(seg, np.linspace(10.0, 2e5, 50))
    assert np.max(np.abs(K - np.swapaxes(K, -1, -2))) <= 1e-10 * np.max(np.abs(K))


# ------------------------------------------------------------------ item 3 --


def test_stubby_timoshenko_beam_matches_fe_reference():
    """Item 3: L/d = 5; Timoshenko frequencies lie clearly below Euler-Bernoulli
    and agree with a 200-element Friedman-Kosmatka FE model."""
    d, L = 0.02, 0.10
    lib_sec = circular_section(STEEL, d)
    grid = _omega_from_beta_l(np.linspace(3.0, 12.0, 181), lib_sec, L)
    lib = _real_roots(_end_point_stiffness([Segment(L, lib_sec)]), grid)
    assert lib.size >= 3
    lib = lib[:3]

    section = ref.tube(200e9, 7850.0, 0.29, 0.0, d)
    coarse, fine = (ref.natural_frequencies(ref.mesh([(L, section)], L / n)[0], 3, skip=2) for n in (100, 200))
    fe = ref.richardson(coarse, fine)  # two rigid-body modes skipped
    eb = _omega_from_beta_l(FREE_FREE_BETA_L, lib_sec, L)

    err = np.abs(lib / fe - 1)
    # Richardson-extrapolated FE error is O(h^4), ~1e-8 for the third mode; brief: 0.5 %.
    assert np.all(err < 5e-3), err
    assert np.all(err < 1e-7), err
    drop = 1 - lib / eb
    # Shear and rotary inertia lower the modes of a stubby beam by several per cent.
    assert np.all(drop > 0.03), drop
    assert np.all(np.diff(drop) > 0)  # increasingly so for higher modes


def test_stepped_damped_beam_receptances_match_fe_reference():
    """All four end blocks of a damped three-step beam (composite middle part)
    equal the FE reference, including frequencies close to resonances."""
    lib_segments = [
        Segment(0.04, circular_section(STEEL_DAMPED, 0.05)),
        Segment(0.03, composite_section(circular_section(STEEL_DAMPED, 0.04, 0.012),
                                        circular_section(CARBIDE_DAMPED, 0.012))),
        Segment(0.06, circular_section(CARBIDE_DAMPED, 0.012)),
    ]
    steel = ref.RefMaterial(200e9, 7850.0, 0.29, 0.01)
    carbide = ref.RefMaterial(580e9, 14500.0, 0.22, 0.004)
    ref_segments = [
        (0.04, steel.section(0.05)),
        (0.03, steel.section(0.04, 0.012) + carbide.section(0.012)),
        (0.06, carbide.section(0.012)),
    ]
    omega = 2 * np.pi * np.linspace(20.0, 20e3, 400)
    lib = free_free_receptances(lib_segments, omega).as_matrix()
    fe = ref.richardson(*(ref.end_receptances(ref.mesh(ref_segments, h)[0], omega) for h in (1e-3, 0.5e-3)))
    # Friedman-Kosmatka elements have constant shear strain, so the FE
    # receptances converge as h^2; Richardson extrapolation leaves O(h^4) ~ 1e-9
    # off resonance, amplified near resonances by the quality factor 1/eta ~ 250.
    assert _relative_block_error(lib, fe) < 1e-4


# ------------------------------------------------------- rigid-body limit --


def test_free_free_low_frequency_is_rigid_body_mass_line():
    """At omega << omega_1 a free-free beam moves as a rigid body.

    With mass m, centroidal inertia J = m L^2/12 + rhoI L and generalised
    forces (F, M) at an end, u_end = u_c -+ theta L/2 gives
    omega^2 h11 -> -(1/m + L^2/(4J)),  omega^2 l11 = omega^2 n11 -> +L/(2J),
    omega^2 p11 -> -1/J,  omega^2 h12 -> -1/m + L^2/(4J); for EB (rhoI=0)
    h11 -> -4/(m omega^2) and h12 -> +2/(m omega^2).
    """
    sec = circular_section(STEEL, 0.03)
    L = 0.2
    m = sec.rhoA * L
    J = m * L**2 / 12 + sec.rhoI * L
    omega1 = _omega_from_beta_l(FREE_FREE_BETA_L[0], sec, L)
    omega = np.array([1e-3, 3e-3]) * omega1
    tp = free_free_receptances([Segment(L, sec)], omega)
    a, c = L / 2, L * L / 4
    end1 = np.array([[-(1 / m + c / J), a / J], [a / J, -1 / J]])
    end2 = np.array([[-(1 / m + c / J), -a / J], [-a / J, -1 / J]])
    transfer = np.array([[-1 / m + c / J, a / J], [-a / J, -1 / J]])  # u1, psi1 <- F2, M2
    w2 = omega[:, None, None] ** 2
    for got, want in ((tp.r11, end1), (tp.r22, end2), (tp.r12, transfer), (tp.r21, transfer.T)):
        rel = np.abs(w2 * got - want) / np.abs(want)
        # elastic residual flexibility is O((omega/omega_1)^2) of the mass line
        assert np.all(rel[0] < 1e-4), rel


def _free_free_eb_roots(n):
    """First n roots of cosh x cos x = 1 (x > 0), written as cos x = 1/cosh x."""
    fun = lambda x: math.cos(x) - 2 * math.exp(-x) / (1 + math.exp(-2 * x))  # noqa: E731
    return np.array([brentq(fun, (k + 0.5) * math.pi - 0.3, (k + 0.5) * math.pi + 0.3 + 0.5 * (k == 1))
                     for k in range(1, n + 1)])


def test_free_free_euler_bernoulli_end_receptance_low_frequency_expansion():
    """EB limit: h11 = -4/(m w^2) + sum_n 4/(m (w_n^2 - w^2)) (every mass-normalised
    free-free mode has phi_n(end)^2 = 4/m), so
    -m w^2 h11 / 4 = 1 - C r^2 + O(r^4),  C = (beta_1 L)^4 sum_n (beta_n L)^-4,  r = w/w_1,
    and m w^2 h12 / 2 = 1 - C' r^2,  C' = 2 (beta_1 L)^4 sum_n (-1)^n (beta_n L)^-4."""
    sec = circular_section(STEEL, 0.03)
    # kGA * 1e3: the shear part of the residual flexibility, ~4e-3/1e3 of C,
    # is negligible, while the low-frequency round-off of the exact dynamic
    # stiffness (which grows with kGA L^2 / EI) stays below 1e-5 of C.
    eb = SectionProperties(sec.EI, sec.kGA * 1e3, sec.rhoA, 0.0)
    L = 0.2
    m = eb.rhoA * L
    x = _free_free_eb_roots(400)
    assert x[0] == pytest.approx(FREE_FREE_BETA_L[0], abs=1e-6)
    C = x[0] ** 4 * np.sum(x**-4.0)
    # phi_n(0) phi_n(L) = 4 (-1)^(n+1) / m: symmetric and antisymmetric modes alternate
    C_transfer = 2 * x[0] ** 4 * np.sum((-1.0) ** np.arange(1, x.size + 1) * x**-4.0)
    r = 1e-2  # low enough for O(r^4) ~ 1e-8, high enough to stay clear of round-off
    omega = np.array([r * _omega_from_beta_l(x[0], eb, L)])
    tp = free_free_receptances([Segment(L, eb)], omega)
    got = (1 + tp.r11[0, 0, 0].real * m * omega[0] ** 2 / 4) / r**2
    assert got == pytest.approx(C, rel=1e-3)
    got_transfer = (1 - tp.r12[0, 0, 0].real * m * omega[0] ** 2 / 2) / r**2
    assert got_transfer == pytest.approx(C_transfer, rel=1e-3)


def test_free_free_receptances_are_reciprocal_and_passive():
    """Two-port reciprocity and passivity of a damped stepped beam."""
    segs = [Segment(0.05, circular_section(STEEL_DAMPED, 0.04)),
            Segment(0.08, circular_section(CARBIDE_DAMPED, 0.01))]
    omega = 2 * np.pi * np.geomspace(10.0, 5e4, 2000)
    tp = free_free_receptances(segs, omega)
    G = tp.as_matrix()
    scale = np.linalg.norm(G, axis=(-2, -1))[:, None, None]
    # Round-off grows like eps (omega_1 / omega)^2 towards low frequency (the
    # rigid-body part cancels in the dynamic stiffness); ~1e-12 at 10 Hz here.
    assert np.max(np.abs(G - np.swapaxes(G, -1, -2)) / scale) < 1e-10
    # passive: Im G negative semi-definite (hence Im h <= 0, Im p <= 0)
    eig = np.linalg.eigvalsh(G.imag)
    assert np.all(eig <= 1e-10 * scale[:, 0, :])


# ------------------------------------------------------------------ item 8 --


@pytest.mark.parametrize(
    "length, diameter, freq_hz, eta",
    [(1.0, 0.005, 50e3, 0.002), (2.0, 0.001, 200e3, 0.05)],  # second: e^{beta L} ~ e^{2000} overflows naively
)
def test_long_thin_segment_at_high_frequency_is_finite_and_reciprocal(length, diameter, freq_hz, eta):
    """Item 8: no overflow, reciprocity, and the semi-infinite limit."""
    mat = Material(200e9, 7850.0, 0.29, eta, "steel")
    sec = circular_section(mat, diameter)
    omega = 2 * np.pi * np.array([0.5 * freq_hz, freq_hz])
    with np.errstate(over="raise", invalid="raise", divide="raise"):  # underflow is harmless
        tp = free_free_receptances([Segment(length, sec)], omega)
    G = tp.as_matrix()
    assert np.all(np.isfinite(G))
    scale = np.abs(G).max()
    assert np.max(np.abs(G - np.swapaxes(G, -1, -2))) < 1e-10 * scale
    if eta >= 0.01:
        # Bending waves decay as exp(-beta eta z / 4), beta ~ 700-1000 /m, i.e. by
        # more than e^-17 along the beam, so the end looks like that of a
        # semi-infinite beam: half the length gives the same point receptance
        # and the transfer receptance is negligible.
        half = free_free_receptances([Segment(length / 2, sec)], omega)
        assert np.max(np.abs(half.r11 - tp.r11) / np.abs(tp.r11)) < 1e-6
        assert np.max(np.abs(tp.r12)) < 1e-6 * np.max(np.abs(tp.r11))


# -------------------------------------------------------------- sections --


def test_cowper_shear_coefficient_known_values():
    """Cowper (1966): solid circle 6(1+nu)/(7+6nu); thin tube 2(1+nu)/(4+3nu)."""
    for nu in (0.22, 0.29, 0.3):
        assert cowper_shear_coefficient(nu) == pytest.approx(6 * (1 + nu) / (7 + 6 * nu), rel=1e-14)
        assert cowper_shear_coefficient(nu, 1 - 1e-9) == pytest.approx(2 * (1 + nu) / (4 + 3 * nu), rel=1e-7)
        assert cowper_shear_coefficient(nu, 0.4) == pytest.approx(ref.cowper_kappa(nu, 0.4), rel=1e-14)
    assert cowper_shear_coefficient(0.3) == pytest.approx(0.886, abs=5e-4)


def test_circular_section_matches_reference_formulae():
    mat = Material(210e9, 7800.0, 0.3, 0.003, "s")
    for d_out, d_in in ((0.05, 0.0), (0.05, 0.02), (0.00794, 0.0)):
        lib = circular_section(mat, d_out, d_in)
        want = ref.tube(210e9, 7800.0, 0.3, 0.003, d_out, d_in)
        for key in ("EI", "kGA", "rhoA", "rhoI"):
            assert getattr(lib, key) == pytest.approx(getattr(want, key), rel=1e-13), key


def test_composite_section_sums_parts():
    """A bore filled by a shank of the same material bends and weighs like a solid
    shaft (EI, rhoA, rhoI add exactly); every property is the plain sum."""
    mat = Material(200e9, 7850.0, 0.29, 0.002, "steel")
    hollow = circular_section(mat, 0.05, 0.00794)
    core = circular_section(mat, 0.00794)
    solid = circular_section(mat, 0.05)
    comp = composite_section(hollow, core)
    for key in ("EI", "rhoA", "rhoI"):
        assert getattr(comp, key) == pytest.approx(getattr(solid, key), rel=1e-13), key
    assert comp.kGA == pytest.approx(hollow.kGA + core.kGA, rel=1e-15)
    third = circular_section(CARBIDE_DAMPED, 0.004)
    comp3 = composite_section(hollow, core, third)
    for key in ("EI", "kGA", "rhoA", "rhoI"):
        want = getattr(hollow, key) + getattr(core, key) + getattr(third, key)
        assert getattr(comp3, key) == pytest.approx(want, rel=1e-15), key
    assert composite_section(hollow) == hollow


def test_reference_element_is_the_closed_form_timoshenko_element():
    """Self-check of the reference: quadrature of the Friedman-Kosmatka shape
    functions reproduces the closed-form locking-free stiffness, and the mass
    matrix carries the element mass."""
    sec = ref.tube(200e9, 7850.0, 0.29, 0.0, 0.03)
    for h in (1e-3, 1e-2, 0.1):
        K, M = ref.fk_element(sec, h)
        Kc = ref.fk_closed_form_stiffness(sec, h)
        assert np.max(np.abs(K - Kc)) < 1e-12 * np.max(np.abs(Kc))
        rigid = np.array([1.0, 0.0, 1.0, 0.0])
        assert rigid @ M @ rigid == pytest.approx(sec.rhoA * h, rel=1e-13)
        assert np.allclose(K @ rigid, 0, atol=1e-12 * np.max(np.abs(Kc)))


def test_accurate_close_to_the_shear_cutoff_frequency():
    """Near omega_c = sqrt(kGA / rhoI) one pair of wavenumbers tends to zero and
    the exponential basis degenerates; the receptances must stay accurate."""
    d, L = 0.063, 0.05  # holder flange: cut-off ~ 30 kHz
    sec = circular_section(STEEL, d)
    omega_c = math.sqrt(sec.kGA.real / sec.rhoI)
    omega = omega_c * (1 + np.array([-1e-2, -1e-6, -1e-10, 1e-10, 1e-6, 1e-2]))
    lib = free_free_receptances([Segment(L, sec)], omega).as_matrix()
    section = ref.tube(200e9, 7850.0, 0.29, 0.0, d)
    fe = ref.richardson(*(ref.end_receptances(ref.mesh([(L, section)], h)[0], omega) for h in (0.5e-3, 0.25e-3)))
    assert np.all(np.isfinite(lib))
    assert _relative_block_error(lib, fe) < 1e-7  # extrapolated FE ~4e-9


def test_invalid_frequencies_are_rejected():
    seg = [Segment(0.1, circular_section(STEEL, 0.01))]
    for bad in ([0.0, 10.0], [-1.0], [np.nan], [[10.0]]):
        with pytest.raises(SetupError):
            free_free_receptances(seg, np.array(bad))
    with pytest.raises(SetupError):
        Segment(0.0, seg[0].section)
