"""Cross-checks of the three stability solvers on a 2-mode x/y tool (one mode per direction).

Paper-like case (Zhao et al. 2024, §2.1 and Table 2): 4-flute end mill in Al 7050,
K_t = 790 MPa, K_r = 230 MPa, feed along Y, down milling, radial immersion 70 %
and 95 %.  The modal parameters are typical of the 7.94 mm tool at 25 mm
clamping (f_n ≈ 1287 Hz, Table 4) with a distinct Y mode.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.stability import CuttingConditions, ModalModel, sdm_depth_limit, simulate_milling, zoa_lobes

PX = ModalModel([1287.0], [0.02], [1.0e6])
PY = ModalModel([1340.0], [0.03], [1.3e6])
F = np.linspace(500.0, 3000.0, 5001)


def cutting(immersion):
    return CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=immersion, milling="down", feed="y")


def local_minima(n, a):
    i = np.nonzero((a[1:-1] < a[:-2]) & (a[1:-1] <= a[2:]))[0] + 1
    return n[i], a[i]


@pytest.mark.parametrize("immersion", [0.7, 0.95])
def test_zoa_and_sdm_lobe_minima_agree_within_5_percent(immersion):
    cut = cutting(immersion)
    n = np.linspace(5000, 30000, 2001)
    zoa = zoa_lobes(PX.frf(F), PY.frf(F), F, cut, n).depth_limit_m
    n_min, a_min = local_minima(n, zoa)
    assert n_min.size >= 3  # lobes k = 0, 1, 2 at least
    for nm, am in zip(n_min, a_min):
        around = nm * np.linspace(0.98, 1.02, 5)  # the SDM minimum may sit slightly off the ZOA one
        sdm = sdm_depth_limit(PX, PY, cut, around, (0.7 * am, 1.5 * am), rtol=1e-4)
        assert np.all(np.isfinite(sdm))
        assert sdm.min() == pytest.approx(am, rel=0.05)


@pytest.mark.parametrize("immersion", [0.7, 0.95])
def test_both_solvers_agree_with_time_domain_simulation(immersion):
    cut = cutting(immersion)
    speeds = np.array([6000.0, 9000.0, 13000.0, 21000.0, 27000.0])
    a_zoa = zoa_lobes(PX.frf(F), PY.frf(F), F, cut, speeds).depth_limit_m
    a_sdm = sdm_depth_limit(PX, PY, cut, speeds, (0.6 * a_zoa, 1.6 * a_zoa), rtol=1e-4)
    factors = np.tile([0.9, 1.1], speeds.size)
    probe_n = np.concatenate([np.repeat(speeds, 2)] * 2)
    probe_a = np.concatenate([np.repeat(a_zoa, 2), np.repeat(a_sdm, 2)]) * np.tile(factors, 2)
    sim = simulate_milling(PX, PY, cut, probe_n, probe_a, periods=100, rng=np.random.default_rng(4))
    expected_chatter = np.tile(factors > 1, 2)
    agree = sim.chatter == expected_chatter
    assert agree[:10].sum() >= 9  # ZOA probes
    assert agree[10:].sum() >= 9  # SDM probes
    # the linear simulation's growth per tooth period brackets 1 at every SDM probe pair
    g = sim.growth[10:].reshape(-1, 2)
    assert np.all(g[:, 0] < 1) and np.all(g[:, 1] > 1)
