"""Cutting model and zero-order approximation (bayes_rcsa.stability.cutting / .zoa).

References written here independently of the library:
- Altintas' closed-form average directional coefficients (Manufacturing
  Automation, 2nd ed., eq. 3.46): α_xx = ½[cos2φ − 2K_rφ + K_r sin2φ] etc.,
  with H0 = N K_t α/(4π) for feed along x;
- the textbook ZOA eigenvalue Λ of a0 Λ² + a1 Λ + 1 = 0 and
  a_lim = −2π Λ_R (1 + κ²)/(N K_t), ε = π − 2 arctan κ (Altintas & Budak 1995);
- the single-DOF turning-type stability boundary a = −1/(2 K Re G),
  ωτ = 3π + 2∠G + 2πj (Tlusty), which is exact for a 4-flute slot because the
  summed directional matrix of four equally spaced teeth in a slot is constant.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import trapezoid

from bayes_rcsa.errors import DataError, SetupError
from bayes_rcsa.stability import (
    CuttingConditions,
    ModalModel,
    directional_matrix,
    interval_directional_matrices,
    mean_directional_matrix,
    oriented_eigenvalues,
    zoa_lobes,
    zoa_minimum_depth,
)
from bayes_rcsa.stability.zoa import lobe_points

KT, KR = 790e6, 230e6  # paper's Al 7050 coefficients (Pa)


def altintas_alpha(phi_st, phi_ex, kr_ratio):
    def prim(p):
        return np.array(
            [
                [np.cos(2 * p) - 2 * kr_ratio * p + kr_ratio * np.sin(2 * p), -np.sin(2 * p) - 2 * p + kr_ratio * np.cos(2 * p)],
                [-np.sin(2 * p) + 2 * p + kr_ratio * np.cos(2 * p), -np.cos(2 * p) - 2 * kr_ratio * p - kr_ratio * np.sin(2 * p)],
            ]
        )

    return 0.5 * (prim(phi_ex) - prim(phi_st))


@pytest.mark.parametrize(
    "immersion,milling", [(1.0, "down"), (0.7, "down"), (0.95, "down"), (0.3, "up"), (0.7, "up"), (0.05, "down")]
)
def test_mean_directional_matrix_matches_altintas(immersion, milling):
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=immersion, milling=milling)
    a, b = cut.angles
    ref = 4 * KT / (4 * np.pi) * altintas_alpha(a, b, KR / KT)
    np.testing.assert_allclose(mean_directional_matrix(cut), ref, rtol=1e-12, atol=1e-6 * KT)


def test_immersion_angles():
    # up milling starts at 0, down milling ends at π; 50 % immersion is a quarter turn
    up = CuttingConditions(kt=KT, kr=KR, flutes=2, radial_immersion=0.5, milling="up")
    down = CuttingConditions(kt=KT, kr=KR, flutes=2, radial_immersion=0.5, milling="down")
    assert up.angles == pytest.approx((0.0, np.pi / 2))
    assert down.angles == pytest.approx((np.pi / 2, np.pi))
    slot = CuttingConditions(kt=KT, kr=KR, flutes=2, radial_immersion=1.0)
    assert slot.angles == pytest.approx((0.0, np.pi))


def test_interval_averages_are_exact():
    cut = CuttingConditions(kt=KT, kr=KR, flutes=3, radial_immersion=0.6, milling="up")
    # 7 intervals over a revolution, against a 20001-point trapezoidal quadrature per interval
    edges = np.linspace(0.0, 2 * np.pi, 8) + 0.1
    got = interval_directional_matrices(cut, edges[:-1], edges[1:])
    for i in range(7):
        t = np.linspace(edges[i], edges[i + 1], 20001)
        ref = trapezoid(directional_matrix(cut, t), t, axis=0) / (edges[i + 1] - edges[i])
        np.testing.assert_allclose(got[i], ref, atol=2e-3 * KT)  # quadrature error at the entry/exit jumps
    # and their mean over the revolution is H0
    np.testing.assert_allclose(got.mean(axis=0), mean_directional_matrix(cut), rtol=1e-10, atol=1e-3)


def test_four_flute_slot_has_constant_directional_matrix():
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=1.0)
    t = np.linspace(0.01, 2 * np.pi - 0.01, 97)
    H = directional_matrix(cut, t)
    np.testing.assert_allclose(H, np.broadcast_to(mean_directional_matrix(cut), H.shape), atol=1e-6 * KT)
    np.testing.assert_allclose(mean_directional_matrix(cut), [[-KR, -KT], [KT, -KR]], rtol=1e-12)


def test_feed_in_y_is_the_rotated_process():
    cx = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.7, feed="x")
    cy = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.7, feed="y")
    R = np.array([[0.0, 1.0], [-1.0, 0.0]])  # feed frame (along +Y, then -X) from the machine frame
    np.testing.assert_allclose(mean_directional_matrix(cy), R.T @ mean_directional_matrix(cx) @ R, atol=1e-3)
    f = np.linspace(800, 2000, 1201)
    gx = ModalModel([1287.0], [0.02], [1.0e6]).frf(f)
    gy = ModalModel([1400.0], [0.03], [1.4e6]).frf(f)
    n = np.linspace(6000, 30000, 50)
    a_y = zoa_lobes(gx, gy, f, cy, n).depth_limit_m
    a_x_swapped = zoa_lobes(gy, gx, f, cx, n).depth_limit_m
    np.testing.assert_allclose(a_y, a_x_swapped, rtol=1e-12)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(radial_immersion=0.0),
        dict(radial_immersion=1.2),
        dict(radial_immersion=0.5, milling="climb"),
        dict(radial_immersion=0.5, feed="z"),
        dict(entry_angle=1.0),
        dict(entry_angle=2.0, exit_angle=1.0),
        dict(radial_immersion=0.5, pitch_angles=(1.0, 1.0, 1.0, 1.0)),
    ],
)
def test_invalid_cutting_conditions(kwargs):
    with pytest.raises(SetupError):
        CuttingConditions(kt=KT, kr=KR, flutes=4, **kwargs)


def test_lobe_points_match_textbook_lambda():
    rng = np.random.default_rng(3)
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.7, milling="down")
    alpha = altintas_alpha(*cut.angles, KR / KT)
    gxx = (rng.standard_normal(40) - 1j * rng.random(40)) * 1e-6
    gyy = (rng.standard_normal(40) - 1j * rng.random(40)) * 1e-6
    f = np.linspace(500, 3000, 40)
    speed, depth = lobe_points(oriented_eigenvalues(mean_directional_matrix(cut), gxx, gyy), f, 4, 3)
    a0 = gxx * gyy * (alpha[0, 0] * alpha[1, 1] - alpha[0, 1] * alpha[1, 0])
    a1 = alpha[0, 0] * gxx + alpha[1, 1] * gyy
    for sign in (1, -1):
        lam = -(a1 + sign * np.sqrt(a1**2 - 4 * a0)) / (2 * a0)
        kappa = lam.imag / lam.real
        a_ref = -2 * np.pi * lam.real * (1 + kappa**2) / (4 * KT)
        eps = np.pi - 2 * np.arctan(kappa)
        for j in range(40):
            if a_ref[j] <= 0:
                continue  # unphysical branch
            i = int(np.argmin(np.abs(depth[j] - a_ref[j])))
            assert depth[j, i] == pytest.approx(a_ref[j], rel=1e-9)
            for k in range(3):
                n_ref = 60 * 2 * np.pi * f[j] / (4 * (eps[j] + 2 * np.pi * k))
                assert speed[j, i, k] == pytest.approx(n_ref, rel=1e-9)


def test_closed_form_minimum_slotting():
    # a_lim,min = 2 k ζ (1+ζ)/(N K_t α) with α = K_r/(4 K_t) for a slot (single mode, feed direction).
    # Insperger & Stépán (2004) single-DOF milling benchmark: f_n = 922 Hz, ζ = 0.011,
    # m = 0.03993 kg (k = m ω_n^2 = 1.34e6 N/m), K_t = 6e8 Pa, K_n = 2e8 Pa.
    fn, zeta, mass = 922.0, 0.011, 0.03993
    k = mass * (2 * np.pi * fn) ** 2
    kt, kr = 6e8, 2e8
    f = np.linspace(850, 1000, 150001)  # 1 mHz lines: the minimum sits between lines otherwise
    g = ModalModel([fn], [zeta], [k]).frf(f)
    for N in (2, 4):
        cut = CuttingConditions(kt=kt, kr=kr, flutes=N, radial_immersion=1.0)
        alpha = kr / (4 * kt)
        ref = 2 * k * zeta * (1 + zeta) / (N * kt * alpha)
        got = zoa_minimum_depth(g, np.zeros_like(g), f, cut)
        assert got == pytest.approx(ref, rel=1e-4)
        # the lobe envelope on a speed grid reaches the same minimum within 2 %
        n = np.linspace(4000, 12000, 4001) * 2 / N
        env = zoa_lobes(g, np.zeros_like(g), f, cut, n).depth_limit_m
        assert env.min() == pytest.approx(ref, rel=0.02)
        assert env.min() >= ref * (1 - 1e-9)


def turning_boundary(fn, zeta, k, kr_eff, flutes, speed_rpm, lobes=8):
    """Exact boundary of m x'' + c x' + k x = −a K (x − x(t−τ)), τ = 60/(N n), by D-subdivision."""
    w = 2 * np.pi * np.linspace(fn * 1.0001, fn * 1.6, 200001)
    r = w / (2 * np.pi * fn)
    G = 1 / (k * (1 - r**2 + 2j * zeta * r))
    ok = G.real < 0
    a = -1 / (2 * kr_eff * G.real[ok])
    eps = 3 * np.pi + 2 * np.angle(G[ok])
    out = np.full(np.size(speed_rpm), np.inf)
    for j in range(lobes):
        n = 60 * w[ok] / (flutes * (eps + 2 * np.pi * j))
        assert np.all(np.diff(n) > 0)  # each 1-DOF lobe is a graph over speed here
        inside = (speed_rpm >= n[0]) & (speed_rpm <= n[-1])
        out[inside] = np.minimum(out[inside], np.interp(speed_rpm[inside], n, a))
    return out


def test_zoa_is_exact_for_four_flute_slot():
    fn, zeta, mass = 922.0, 0.011, 0.03993
    k = mass * (2 * np.pi * fn) ** 2
    cut = CuttingConditions(kt=6e8, kr=2e8, flutes=4, radial_immersion=1.0)
    f = np.linspace(900, 1500, 60001)
    g = ModalModel([fn], [zeta], [k]).frf(f)
    n = np.linspace(3000, 12000, 301)
    got = zoa_lobes(g, np.zeros_like(g), f, cut, n).depth_limit_m
    ref = turning_boundary(fn, zeta, k, 2e8, 4, n)
    np.testing.assert_allclose(got, ref, rtol=2e-3)  # linear interpolation between 10 mHz lines


def test_zoa_vectorised_over_draws_equals_one_by_one():
    rng = np.random.default_rng(7)
    f = np.linspace(600, 3000, 2401)
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.95, milling="down", feed="y")
    gx = np.array([ModalModel([1290 * s, 2600], [0.02, 0.03], [1e6, 5e6]).frf(f) for s in rng.normal(1, 0.03, 6)])
    gy = np.array([ModalModel([1300 * s], [0.025], [1.2e6]).frf(f) for s in rng.normal(1, 0.03, 6)])
    n = np.linspace(5000, 30000, 300)
    batch = zoa_lobes(gx, gy, f, cut, n, chunk=4)
    for d in range(6):
        one = zoa_lobes(gx[d], gy[d], f, cut, n)
        np.testing.assert_array_equal(batch.depth_limit_m[d], one.depth_limit_m)
        np.testing.assert_array_equal(batch.lobe[d], one.lobe)
    assert np.all(np.isfinite(batch.depth_limit_m))


def test_eigenvalue_branches_are_continuous():
    f = np.linspace(600, 3000, 4001)
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.7)
    gx = ModalModel([1290.0, 2500.0], [0.02, 0.03], [1e6, 5e6]).frf(f)
    gy = ModalModel([1330.0], [0.025], [1.2e6]).frf(f)
    mu = oriented_eigenvalues(mean_directional_matrix(cut), gx, gy)
    step = np.abs(np.diff(mu, axis=0)).max(axis=0)
    swap = np.abs(mu[1:, ::-1] - mu[:-1]).max(axis=0)
    # along each branch successive lines move less than to the other branch's value
    assert np.all(np.abs(np.diff(mu, axis=0)) <= np.abs(mu[1:, ::-1] - mu[:-1]) + 1e-12)
    assert step.max() < swap.max()


def test_band_limited_frf_gives_inf_not_a_number():
    f = np.linspace(1200, 1400, 201)
    g = ModalModel([1300.0], [0.02], [1e6]).frf(f)
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.5)
    res = zoa_lobes(g, g, f, cut, np.array([100.0, 20000.0]))
    # at 100 rpm the lobes that would reach it need k > 700; at 20000 rpm lobe k = 0 covers it
    assert np.isfinite(res.depth_limit_m[1])
    assert res.lobe[1] == 0


def test_zoa_input_errors():
    f = np.linspace(100, 200, 11)
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.5)
    with pytest.raises(DataError):
        zoa_lobes(np.ones(10), np.ones(10), f, cut, np.array([1000.0]))
    with pytest.raises(SetupError):
        zoa_lobes(np.ones(11), np.ones(11), f, cut, np.array([2000.0, 1000.0]))
    vp = CuttingConditions(kt=KT, kr=KR, flutes=2, radial_immersion=0.5, pitch_angles=(2.8, 2 * np.pi - 2.8))
    with pytest.raises(SetupError):
        zoa_lobes(np.ones(11), np.ones(11), f, vp, np.array([1000.0]))
