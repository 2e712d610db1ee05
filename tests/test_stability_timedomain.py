"""Time-domain milling simulation (bayes_rcsa.stability.timedomain)."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.stability import CuttingConditions, ModalModel, simulate_milling, zoa_lobes

MX = ModalModel([1287.0], [0.02], [1.0e6])
MY = ModalModel([1340.0], [0.03], [1.3e6])
KT, KR = 790e6, 230e6


def test_static_deflection_of_a_four_flute_slot():
    # Four teeth in a slot: the summed static force is constant, F = a f_z (-K_r, K_t) in the feed
    # frame, so a stable cut settles at q = (-a f_z K_r / k_x, a f_z K_t / k_y) exactly.
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=1.0, feed="x")
    a, fz = 2e-5, 5e-5
    sim = simulate_milling(MX, MY, cut, [12000.0], [a], feed_per_tooth=fz, periods=80, initial_amplitude=0.0)
    assert not sim.chatter[0]
    np.testing.assert_allclose(sim.samples[0, -1], [-a * fz * KR / 1.0e6, a * fz * KT / 1.3e6], rtol=1e-4)  # transient left
    # feeding along Y turns the force: F_machine = (−F_normal, F_feed) -> q = (−a f_z K_t/k_x, −a f_z K_r/k_y)
    cut_y = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=1.0, feed="y")
    sim_y = simulate_milling(MX, MY, cut_y, [12000.0], [a], feed_per_tooth=fz, periods=80, initial_amplitude=0.0)
    np.testing.assert_allclose(sim_y.samples[0, -1], [-a * fz * KT / 1.0e6, -a * fz * KR / 1.3e6], rtol=1e-4)


def test_nonlinear_model_saturates_but_still_flags_chatter():
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.5, milling="up")
    f = np.linspace(500, 3000, 2501)
    lim = zoa_lobes(MX.frf(f), MY.frf(f), f, cut, np.array([10000.0])).depth_limit_m[0]
    sim = simulate_milling(MX, MY, cut, [10000.0, 10000.0], lim * np.array([0.6, 2.0]), periods=120, nonlinear=True)
    np.testing.assert_array_equal(sim.chatter, [False, True])
    assert sim.residual[0] < 1e-4 and sim.residual[1] > 1e-2  # decaying transient vs sustained chatter
    assert sim.samples.shape == (2, 120, 2) and np.all(np.isfinite(sim.samples))


def test_input_errors():
    cut = CuttingConditions(kt=KT, kr=KR, flutes=4, radial_immersion=0.5)
    from bayes_rcsa.errors import SetupError

    with pytest.raises(SetupError):
        simulate_milling(MX, MY, cut, [-1.0], [1e-4])
    with pytest.raises(SetupError):
        simulate_milling(None, None, cut, [1000.0], [1e-4])
