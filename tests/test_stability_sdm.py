"""First-order semi-discretisation (bayes_rcsa.stability.sdm).

Benchmark parameters: the single-DOF milling example of Insperger & Stépán,
"Updated semi-discretization method for periodic delay-differential equations
with discrete delay", IJNME 61 (2004) 117-141, re-used by Ding et al. (2010)
for the full-discretisation method: f_n = 922 Hz, ζ = 0.011, m = 0.03993 kg,
K_t = 6e8 Pa, K_n = 2e8 Pa, two teeth, down milling.  With four teeth in a
slot the summed directional factor is constant and the delay equation
becomes autonomous, so its boundary is known exactly (D-subdivision, coded
below independently of the library): that is the reference of the 2 % test.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from bayes_rcsa.errors import SetupError
from bayes_rcsa.stability import (
    CuttingConditions,
    ModalModel,
    default_intervals,
    sdm_depth_limit,
    sdm_stability_map,
    simulate_milling,
    spectral_radius,
    zoa_lobes,
)
from bayes_rcsa.stability.sdm import _apply, _apply_numpy, _discretise, _modal_batch, _steps, periodic_dde_radius, phi_functions

FN, ZETA, MASS = 922.0, 0.011, 0.03993
K1 = MASS * (2 * np.pi * FN) ** 2
ONE_DOF = ModalModel([FN], [ZETA], [K1])
# paper-like tool tip (Table 4: f_n ≈ 1287/1284 Hz at 25 mm clamping); k and ζ typical of a 7.94 mm end mill
PX = ModalModel([1287.0], [0.02], [1.0e6])
PY = ModalModel([1340.0], [0.03], [1.3e6])


def exact_slot_boundary(speed_rpm, flutes=4, kr=2e8, lobes=10):
    """m x'' + c x' + k x = −a K_r (x − x(t − τ)): a = −1/(2 K_r Re G), ωτ = 3π + 2∠G + 2πj."""
    w = 2 * np.pi * np.linspace(FN * 1.0001, FN * 1.6, 400001)
    r = w / (2 * np.pi * FN)
    G = 1 / (K1 * (1 - r**2 + 2j * ZETA * r))
    ok = G.real < 0
    a = -1 / (2 * kr * G.real[ok])
    eps = 3 * np.pi + 2 * np.angle(G[ok])
    out = np.full(np.size(speed_rpm), np.inf)
    for j in range(lobes):
        n = 60 * w[ok] / (flutes * (eps + 2 * np.pi * j))
        inside = (speed_rpm >= n[0]) & (speed_rpm <= n[-1])
        out[inside] = np.minimum(out[inside], np.interp(speed_rpm[inside], n, a))
    return out


def test_phi_functions_match_augmented_expm():
    rng = np.random.default_rng(5)
    for scale in (0.1, 3.0, 40.0):  # the last two need scaling and squaring
        A = rng.standard_normal((3, 4, 4)) * scale
        dt = np.array([0.5, 1.0, 0.7])
        P, G0, G1 = phi_functions(A, dt)
        for i in range(3):
            big = np.zeros((12, 12))
            big[:4, :4] = A[i]
            big[:4, 4:8] = np.eye(4)
            big[4:8, 8:] = np.eye(4)
            E = expm(big * dt[i])  # top blocks: e^{AΔt}, ∫e^{As}ds, ∫e^{As}(Δt−s)ds
            tol = 1e-10 * np.abs(E[:4]).max()
            np.testing.assert_allclose(P[i], E[:4, :4], atol=tol)
            np.testing.assert_allclose(G0[i], E[:4, 4:8], atol=tol)
            np.testing.assert_allclose(G1[i], E[:4, 8:], atol=tol)


def test_single_dof_benchmark_against_exact_boundary():
    # Insperger & Stépán parameters, four teeth in a slot: exact reference, 2 % tolerance on lobe
    # minima and flanks (0.4-1.3 % observed).  Right at a cusp where two lobes intersect the depth is
    # ill-conditioned (a 0.1 % shift in speed moves it by several %), so cusps are not used as points.
    cut = CuttingConditions(kt=6e8, kr=2e8, flutes=4, radial_immersion=1.0)
    speeds = np.array([3000.0, 3800.0, 4200.0, 5000.0, 6200.0, 8000.0, 9000.0, 11000.0])
    ref = exact_slot_boundary(speeds)
    got = sdm_depth_limit(ONE_DOF, None, cut, speeds, (0.6 * ref, 1.6 * ref), rtol=1e-5)
    np.testing.assert_allclose(got, ref, rtol=0.02)
    # the lobe minimum: a = 2kζ(1+ζ)/(N K_t α) with α = K_r/(4 K_t)
    a_min = 2 * K1 * ZETA * (1 + ZETA) / (4 * 6e8 * (2e8 / (4 * 6e8)))
    dense = np.linspace(7700, 8300, 25)  # the lowest lobe minimum lies near 8000 rpm
    coarse = sdm_stability_map(ONE_DOF, None, cut, dense, np.linspace(0.5 * a_min, 1.5 * a_min, 40))
    assert coarse.depth_limit_m.min() == pytest.approx(a_min, rel=0.02)


def test_first_order_convergence_and_default_intervals():
    # error against the exact boundary falls ~4x per doubling (O(Δt^2)); the default rule is < 1 % off
    cut = CuttingConditions(kt=6e8, kr=2e8, flutes=4, radial_immersion=1.0)
    speeds = np.array([3000.0, 5000.0])
    ref = exact_slot_boundary(speeds)
    err = []
    for m in (20, 40, 80):
        got = sdm_depth_limit(ONE_DOF, None, cut, speeds, (0.6 * ref, 1.6 * ref), intervals=m, rtol=1e-6)
        err.append(np.abs(got / ref - 1))
    err = np.array(err)
    assert np.all(err[0] / err[1] > 3.0) and np.all(err[1] / err[2] > 3.0)
    default = sdm_depth_limit(ONE_DOF, None, cut, speeds, (0.6 * ref, 1.6 * ref), rtol=1e-6)
    assert np.all(np.abs(default / ref - 1) < 0.01)


@pytest.mark.parametrize("immersion", [0.7, 0.95])
def test_limit_changes_below_one_percent_when_intervals_double(immersion):
    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=immersion, feed="y")
    speeds = np.array([5000.0, 9000.0, 24000.0])
    m = default_intervals(PX, PY, cut, speeds)
    # documented rule: at least max(30, 30 f_max T), rounded up to the ladder 30·2^(j/2)
    ladder = [30, 43, 60, 85, 120, 170, 240, 340]
    rule = [max(30, int(np.ceil(30 * 1340.0 * 60 / (4 * s)))) for s in speeds]
    assert list(m) == [min(v for v in ladder if v >= r) for r in rule]
    f = np.linspace(500, 3000, 5001)
    guess = zoa_lobes(PX.frf(f), PY.frf(f), f, cut, speeds).depth_limit_m  # ZOA brackets the SDM limit here
    bracket = (0.75 * guess, 1.3 * guess)
    a1 = sdm_depth_limit(PX, PY, cut, speeds, bracket, intervals=m, rtol=1e-4)
    a2 = sdm_depth_limit(PX, PY, cut, speeds, bracket, intervals=2 * m, rtol=1e-4)
    assert np.all(np.isfinite(a1)) and np.all(np.isfinite(a2))
    assert np.all(np.abs(a2 / a1 - 1) < 0.01)


def test_arnoldi_equals_dense_eigenvalues():
    rng = np.random.default_rng(2)
    mx = ModalModel([1287.0, 2650.0], [0.02, 0.03], [1.0e6, 6.0e6])
    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=3, radial_immersion=0.4, milling="up")
    speeds = rng.uniform(6000, 30000, 60)
    depths = rng.uniform(2e-5, 6e-4, 60)
    a = spectral_radius(mx, PY, cut, speeds, depths, 36, solver="arnoldi")
    e = spectral_radius(mx, PY, cut, speeds, depths, 36, solver="eig")
    np.testing.assert_allclose(a, e, rtol=2e-6)  # Ritz residual tolerance 1e-6
    assert np.any(e > 1) and np.any(e < 1)


def test_map_is_consistent_with_bisection():
    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, feed="y")
    speeds = np.linspace(8000, 16000, 5)
    depths = np.linspace(5e-6, 4e-4, 60)
    res = sdm_stability_map(PX, PY, cut, speeds, depths)
    np.testing.assert_array_equal(res.stable, res.spectral_radius < 1)
    lim = sdm_depth_limit(PX, PY, cut, speeds, (0.9 * res.depth_limit_m, 1.1 * res.depth_limit_m), rtol=1e-5)
    step = depths[1] - depths[0]
    # linear interpolation of ρ between grid depths: within a small part of a grid step
    assert np.all(np.abs(res.depth_limit_m - lim) < 0.25 * step)


def test_variable_pitch_limit_and_time_domain():
    tiny = np.radians([90 + 1e-4, 90 - 1e-4, 90 + 1e-4, 90 - 1e-4])
    eq = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7)
    near = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, pitch_angles=tuple(tiny))
    assert not near.equal_pitch
    speeds = np.array([15000.0])
    a_eq = sdm_depth_limit(PX, PY, eq, speeds, (4e-5, 1.6e-4), intervals=24, rtol=1e-4)
    a_near = sdm_depth_limit(PX, PY, near, speeds, (4e-5, 1.6e-4), intervals=24, rtol=1e-4)
    # the revolution-periodic path (N m intervals, per-tooth delays) reduces to the tooth-periodic one
    np.testing.assert_allclose(a_near, a_eq, rtol=1e-3)
    vp = CuttingConditions(
        kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, pitch_angles=tuple(np.radians([80.0, 100.0, 80.0, 100.0]))
    )
    a_vp = sdm_depth_limit(PX, PY, vp, speeds, (4e-5, 4e-4), intervals=24, rtol=1e-4)
    assert abs(a_vp[0] / a_eq[0] - 1) > 0.05  # the pitch variation matters at this speed
    sim = simulate_milling(PX, PY, vp, np.repeat(speeds, 2), a_vp[0] * np.array([0.85, 1.15]), periods=40)
    np.testing.assert_array_equal(sim.chatter, [False, True])


def test_input_errors():
    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7)
    with pytest.raises(SetupError):
        sdm_stability_map(PX, PY, cut, np.array([2000.0, 1000.0]), np.array([1e-4]))
    with pytest.raises(SetupError):
        sdm_stability_map(PX, PY, cut, np.array([1000.0]), np.array([0.0, 1e-4]))
    with pytest.raises(SetupError):
        sdm_stability_map(PX, PY, cut, np.array([1000.0]), np.array([1e-4]), intervals=1)
    with pytest.raises(SetupError):
        sdm_stability_map(None, None, cut, np.array([1000.0]), np.array([1e-4]))


# ------------------------------------------------------------------------------------------
# delayed Mathieu equation x'' + 0.1 x' + (3 + 0.2 cos t) x = -0.15 x(t - 2π) + sin 2t, T = τ = 2π:
# dominant multiplier |μ| = 0.35141726095354886 (SOSD.jl benchmark reference: two independent
# high-order runs agreeing to 1e-10).  The forcing sin 2t does not affect stability.
MATHIEU_MU = 0.35141726095354886
# test-only adapter: a 1-DOF oscillator with m = 1, k = 3, c = 0.1, and the interval averages of the
# periodic stiffness (current-state coefficient -0.2 cos t) and of the delayed coefficient (+0.15)
MATHIEU_MODE = ModalModel([np.sqrt(3.0) / (2 * np.pi)], [0.1 / (2 * np.sqrt(3.0))], [3.0])


def mathieu_averages(t0, t1):
    c = np.zeros((t0.size, 2, 2))
    c[:, 0, 0] = -0.2 * (np.sin(t1) - np.sin(t0)) / (t1 - t0)
    d = np.zeros((t0.size, 2, 2))
    d[:, 0, 0] = 0.15
    return c, [d]


def test_delayed_mathieu_multiplier_default_and_fine_resolution():
    T = 2 * np.pi
    # default resolution (m = 60 by the rule max(30, 30 f_max T) on the ladder): |error| 5.1e-4
    mu = periodic_dde_radius(MATHIEU_MODE, None, T, mathieu_averages, [T])
    assert abs(mu - MATHIEU_MU) < 1e-3
    # O(Δt^2): m = 40 is 1.2e-3 off, m = 2560 2.5e-7
    err = [abs(periodic_dde_radius(MATHIEU_MODE, None, T, mathieu_averages, [T], intervals=m, solver="eig") - MATHIEU_MU)
           for m in (40, 80)]
    assert 3.5 < err[0] / err[1] < 4.5
    fine = periodic_dde_radius(MATHIEU_MODE, None, T, mathieu_averages, [T], intervals=2560)
    assert abs(fine - MATHIEU_MU) < 1e-6


def test_one_dof_milling_at_k40_and_converged():
    # Insperger-Stépán 1-DOF case, 4 teeth in a slot (exact boundary).  k = 40 intervals per tooth period
    # gives 8.7, 14.5 and 26 intervals per vibration cycle at 3000, 5000 and 9000 rpm: errors 4.6, 1.6 and
    # 0.5 % (first-order scheme, O(Δt^2)); k = 640 is converged (errors / 256).
    cut = CuttingConditions(kt=6e8, kr=2e8, flutes=4, radial_immersion=1.0)
    speeds = np.array([3000.0, 5000.0, 9000.0])
    ref = exact_slot_boundary(speeds)
    k40 = sdm_depth_limit(ONE_DOF, None, cut, speeds, (0.6 * ref, 1.6 * ref), intervals=40, rtol=1e-7)
    k640 = sdm_depth_limit(ONE_DOF, None, cut, speeds, (0.6 * ref, 1.6 * ref), intervals=640, rtol=1e-7)
    e40, e640 = np.abs(k40 / ref - 1), np.abs(k640 / ref - 1)
    assert np.all(e40 < [0.05, 0.02, 0.007])
    assert np.all(e640 < 2e-4) and np.all(e40 / e640 > 150)


def test_compiled_step_equals_numpy_reference():
    mx = ModalModel([1287.0, 2650.0], [0.02, 0.03], [1.0e6, 6.0e6])
    vp = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7,
                           pitch_angles=tuple(np.radians([80.0, 100.0, 80.0, 100.0])))
    eq = CuttingConditions(kt=790e6, kr=230e6, flutes=3, radial_immersion=0.4, milling="up", feed="y")
    for cut in (eq, vp):
        disc, factor = _discretise(cut, 24)
        modal = _modal_batch([(mx, PY), (None, PY)], np.array([0, 1, 0]))  # different mode counts: padding
        st = _steps(modal, disc, factor * 60 / np.array([9000.0, 12000.0, 15000.0]), np.array([1e-4, 2e-4, 3e-4]))
        V = np.random.default_rng(0).standard_normal((st.dim, 3, 3))
        np.testing.assert_allclose(_apply(st, V), _apply_numpy(st, V), rtol=1e-12, atol=1e-12 * np.abs(V).max())
