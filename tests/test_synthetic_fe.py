"""Finite-element core of the synthetic bench: element, convergence, banded solver.

The references here are written independently of bayes_rcsa.synthetic.fe:
shape functions integrated by Gauss quadrature, the closed-form Timoshenko
frequency equation of a simply supported beam, and a pivoted dense solve.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from bayes_rcsa.model import Configuration, Material, circular_section
from bayes_rcsa.synthetic import build_assembly, default_bench_config
from bayes_rcsa.errors import ModelError
from bayes_rcsa.synthetic.fe import (
    Chain, FEModel, Joint, NodeRef, PointMass, Resonator, assemble, dense_receptance, element_mass, element_stiffness, mesh,
    receptance,
)

STEEL = Material(210e9, 7800.0, 0.3, 0.0, name="steel")


def _iie_shape_functions(L, phi, xi):
    """Friedman-Kosmatka (1993) interdependent interpolation, written out from the paper."""
    mu = 1.0 / (1.0 + phi)
    N = np.array([
        mu * (2 * xi**3 - 3 * xi**2 - phi * xi + 1 + phi),
        mu * L * (xi**3 - (2 + phi / 2) * xi**2 + (1 + phi / 2) * xi),
        -mu * (2 * xi**3 - 3 * xi**2 - phi * xi),
        mu * L * (xi**3 - (1 - phi / 2) * xi**2 - (phi / 2) * xi),
    ])
    G = np.array([
        6 * mu / L * (xi**2 - xi),
        mu * (3 * xi**2 - (4 + phi) * xi + 1 + phi),
        -6 * mu / L * (xi**2 - xi),
        mu * (3 * xi**2 - (2 - phi) * xi),
    ])
    return N, G


@pytest.mark.parametrize("diameter, length", [(0.01, 0.05), (0.05, 0.01), (0.08, 0.004)])
def test_element_mass_is_the_integral_of_the_shape_functions(diameter, length):
    sec = circular_section(STEEL, diameter)
    phi = 12 * sec.EI.real / (sec.kGA.real * length**2)
    x, w = np.polynomial.legendre.leggauss(6)  # exact for the degree-6 integrands
    xi, w = (x + 1) / 2, w / 2
    N, G = _iie_shape_functions(length, phi, xi)
    ref = length * (sec.rhoA * (N * w) @ N.T + sec.rhoI * (G * w) @ G.T)
    np.testing.assert_allclose(element_mass(length, sec), ref, rtol=1e-12, atol=1e-15 * np.abs(ref).max())


def test_element_stiffness_has_rigid_body_null_space_and_is_symmetric():
    L = 0.02
    K = element_stiffness(L, circular_section(STEEL, 0.03))
    np.testing.assert_allclose(K, K.T, rtol=1e-14)
    scale = np.abs(K).max()
    assert np.abs(K @ [1, 0, 1, 0]).max() < 1e-12 * scale  # translation
    assert np.abs(K @ [0, 1, L, 1]).max() < 1e-12 * scale * L  # rotation about node 1


def test_mass_matrix_carries_the_total_mass():
    z = mesh([0.0, 0.1, 0.3], 0.01)
    secs = tuple(circular_section(STEEL, 0.04 if m < 0.1 else 0.02) for m in 0.5 * (z[1:] + z[:-1]))
    model = assemble([Chain("b", z, secs)])
    t = np.zeros(model.n_dof)
    t[model.dofs["b"][:, 0]] = 1.0
    expected = STEEL.density * math.pi / 4 * (0.04**2 * 0.1 + 0.02**2 * 0.2)
    assert t @ model.mass @ t == pytest.approx(expected, rel=1e-12)


def test_mesh_puts_nodes_on_breakpoints_and_respects_size():
    z = mesh([0.0, 0.013, 0.05, 0.05 + 1e-13], 0.004)
    assert np.any(np.isclose(z, 0.013, atol=1e-15)) and z[0] == 0.0 and z[-1] == pytest.approx(0.05)
    assert np.diff(z).max() <= 0.004 + 1e-15
    assert np.all(np.diff(z) > 0)


@pytest.mark.parametrize("slenderness", [5.0, 20.0])
def test_simply_supported_frequencies_converge_to_timoshenko_closed_form(slenderness):
    d = 0.04
    L = slenderness * d
    sec = circular_section(STEEL, d)
    EI, kGA, rhoA, rhoI = sec.EI.real, sec.kGA.real, sec.rhoA, sec.rhoI
    exact = []
    for n in (1, 2, 3):
        k = n * math.pi / L
        # Timoshenko: (rhoI rhoA/kGA) w^4 - (rhoA + k^2 (rhoI + EI rhoA/kGA)) w^2 + EI k^4 = 0, lower root
        a, b, c = rhoI * rhoA / kGA, -(rhoA + k * k * (rhoI + EI * rhoA / kGA)), EI * k**4
        exact.append(math.sqrt((-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)))
    errors = []
    for n_el in (40, 80):
        z = mesh([0.0, L], L / n_el)
        model = assemble([Chain("b", z, (sec,) * (z.size - 1))])
        d_u = model.dofs["b"][:, 0]
        free = np.setdiff1d(np.arange(model.n_dof), [d_u[0], d_u[-1]])
        K = model.stiffness.real[np.ix_(free, free)]
        M = model.mass[np.ix_(free, free)]
        omega_fe = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True)[:3])
        errors.append(np.abs(omega_fe / exact - 1))
    # 80 elements: within 3e-4 for the first three modes even for a stubby beam
    # (observed 2e-4 for mode 3 at L/d = 5), and the error falls at least like h^2.
    assert errors[1].max() < 3e-4
    assert np.all(errors[1] <= errors[0] / 3.5)


def test_banded_solver_matches_pivoted_dense_solve_on_the_full_assembly():
    cfg = default_bench_config(hidden_effects={"tip_mass": True, "extra_mode": True}, contact_model="distributed")
    model, tip = build_assembly(cfg, Configuration(0.03, "x"))
    # Lines across the band, including both sides of the spindle and tool resonances.
    f = np.concatenate([np.linspace(500, 3500, 25), np.linspace(830, 860, 16)])
    w = 2 * np.pi * f
    dofs = [tip, tip - 1, 0]
    fast = receptance(model, w, dofs, dofs)
    ref = dense_receptance(model, w, dofs, dofs)
    # Both are backward-stable up to the damping-limited condition number; 1e-8 leaves
    # a wide margin over the observed ~1e-12.
    err = np.abs(fast - ref).max(axis=(1, 2)) / np.abs(ref).max(axis=(1, 2))
    assert err.max() < 1e-8
    assert model.bandwidth <= 6  # interleaved chains keep the band narrow


def test_banded_solver_refuses_a_zero_pivot():
    # a free, undamped DOF with no mass: Z(w) has a zero row at every line, the elimination cannot go on
    z = np.zeros((3, 3))
    k = np.diag([1e6, 0.0, 1e6]).astype(complex)
    model = FEModel(k, z, np.diag([1.0, 0.0, 1.0]), {}, {}, 1)
    with pytest.raises(ModelError, match="zero pivot"):
        receptance(model, np.array([10.0, 20.0]), [0], [0])


def test_joints_masses_and_resonators_have_the_expected_static_and_dynamic_effect():
    # A rigid-ish short beam on one grounded spring: static compliance 1/k; adding a
    # resonator (m, k_r) gives an antiresonance at sqrt(k_r/m) at its attachment.
    sec = circular_section(STEEL, 0.05)
    z = np.array([0.0, 0.01])
    chain = Chain("b", z, (sec,))
    k = 1e6
    joints = [Joint(NodeRef("b", 0.0), None, k_u=k, k_psi=1e9), Joint(NodeRef("b", 0.01), None, k_u=k, k_psi=1e9)]
    m_r, f_r = 0.3, 400.0
    k_r = m_r * (2 * np.pi * f_r) ** 2
    model = assemble([chain], joints, [PointMass(NodeRef("b", 0.01), 0.0, 0.0)],
                     [Resonator(NodeRef("b", 0.0), m_r, k_r, 0.0)])
    u0 = model.dof(NodeRef("b", 0.0))
    h = receptance(model, 2 * np.pi * np.array([1.0, f_r]), [u0], [u0])[:, 0, 0]
    assert abs(h[1]) < 1e-6 * abs(h[0])  # antiresonance of the undamped absorber
    assert h[0].real > 0
