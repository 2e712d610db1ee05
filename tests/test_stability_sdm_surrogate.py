"""SDM on many FRF draws: the surrogate from exact draws (bayes_rcsa.stability.sdm_draws) against every draw exact.

The draws are realisations of a measured two-direction modal tool's FRFs with 2 % random error per line (seeded),
what ``bayes-rcsa lobes`` draws from measured files.  The surrogate must reproduce the exact per-draw limits within its
own stated tolerance, keep the exact draws' limits as computed, report its leave-one-out check, and compute every
draw exactly (with a warning) when the check fails.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from bayes_rcsa.stability import CuttingConditions, ModalModel
from bayes_rcsa.stability import sdm_draws
from bayes_rcsa.stability.methods import STABILITY_METHODS, MethodOptions

F = np.arange(600.0, 3000.0, 6.0)
CUT = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.5, milling="down", feed="y")
SPEEDS = np.linspace(9000, 16000, 8)
# the rule at a smaller scale (cost: every draw is also computed exactly here): 8 exact draws, surrogate above 16
MIN_DRAWS, EXACT = 16, 8
N_DRAWS = MIN_DRAWS + 8


@pytest.fixture(autouse=True)
def _small_rule(monkeypatch):
    monkeypatch.setattr(sdm_draws, "SURROGATE_MIN_DRAWS", MIN_DRAWS)
    monkeypatch.setattr(sdm_draws, "EXACT_DRAWS", EXACT)


def _draws(n, seed):
    """Realisations of a measured two-mode FRF pair: the FRF times (1 + complex random error of 2 % per line),
    like the coherence-derived error of a 5-average hammer test (bayes_rcsa.stability.measured)."""
    rng = np.random.default_rng(seed)
    hx = ModalModel([1287, 2210], [0.02, 0.03], [1.0e6, 4.0e6]).frf(F)
    hy = ModalModel([1340, 2290], [0.03, 0.02], [1.3e6, 5.0e6]).frf(F)
    noise = rng.normal(0.0, 0.02 / np.sqrt(2), (2, n, F.size, 2))
    gx = hx * (1 + noise[0, ..., 0] + 1j * noise[0, ..., 1])
    gy = hy * (1 + noise[1, ..., 0] + 1j * noise[1, ..., 1])
    return gx, gy


@pytest.fixture(scope="module")
def both():
    gx, gy = _draws(N_DRAWS, 11)
    sdm = STABILITY_METHODS.get("sdm")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sdm_draws, "SURROGATE_MIN_DRAWS", MIN_DRAWS)
        mp.setattr(sdm_draws, "EXACT_DRAWS", EXACT)
        sur = sdm.depth_limits(gx, gy, F, CUT, SPEEDS, MethodOptions())
    exact = sdm.depth_limits(gx, gy, F, CUT, SPEEDS, MethodOptions(exact=True))
    return gx, gy, sur, exact


def test_the_surrogate_reproduces_every_draws_exact_limit_within_its_tolerance(both):
    _, _, sur, exact = both
    info = sur.info["surrogate"]
    assert info["exact_draws"] == EXACT and info["draws"] == N_DRAWS
    assert "surrogate" not in exact.info and len(exact.modal_fits) == N_DRAWS
    a, b = sur.depth_limit_m, exact.depth_limit_m
    assert a.shape == b.shape == (N_DRAWS, SPEEDS.size) and np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    rel = np.abs(a - b) / b
    # the surrogate's own acceptance rule (leave-one-out 95 % point <= SURROGATE_TOLERANCE) held here, so the
    # draws it did not compute must agree with their exact limits to the same order
    assert info["loo_relative_error"]["q95"] <= sdm_draws.SURROGATE_TOLERANCE
    assert np.quantile(rel, 0.95) <= sdm_draws.SURROGATE_TOLERANCE
    # what the decision reads is the distribution over the draws at each speed: its 5 % point (the envelope) and
    # median move by far less than single pairs (one pair off by x moves a quantile by at most x, mostly not at all)
    for q in (0.05, 0.5):
        qa, qb = np.quantile(a, q, axis=0), np.quantile(b, q, axis=0)
        assert np.max(np.abs(qa - qb) / qb) <= sdm_draws.SURROGATE_TOLERANCE, q
    # and it is not the zero-order limit itself: SDM and ZOA differ here by more than the surrogate's error
    from bayes_rcsa.stability import zoa_lobes

    gx, gy = both[0], both[1]
    zoa = np.atleast_2d(zoa_lobes(gx, gy, F, CUT, SPEEDS).depth_limit_m)
    assert np.median(np.abs(zoa - b) / b) > np.median(rel)


def test_the_exact_draws_keep_their_exact_limits(both):
    _, _, sur, exact = both
    sub = np.unique(np.round(np.linspace(0, N_DRAWS - 1, EXACT)).astype(int))
    # 2 %: each draw's modal fit is refined from the nominal fit of the draws' mean, here of the exact subset's
    # mean, there of all draws' mean; with 2 % random error per line the two refits of one draw end a fraction of
    # a per cent apart in their modes (fit precision, not the method), which moves an SDM limit by up to ~1 %
    np.testing.assert_allclose(sur.depth_limit_m[sub], exact.depth_limit_m[sub], rtol=0.02)
    # limits at other speeds (the recommendation's fine checks) follow the same rule
    s = np.array([10500.0, 12345.0])
    np.testing.assert_allclose(sur.limits_at(s)[sub], exact.limits_at(s)[sub], rtol=0.02)
    assert np.quantile(np.abs(sur.limits_at(s) - exact.limits_at(s)) / exact.limits_at(s), 0.95) \
        <= sdm_draws.SURROGATE_TOLERANCE


def test_a_failed_check_computes_every_draw_exactly_and_says_so(both, monkeypatch):
    gx, gy, _, exact = both
    monkeypatch.setattr(sdm_draws, "SURROGATE_TOLERANCE", -1.0)  # no surrogate can pass
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = STABILITY_METHODS.get("sdm").depth_limits(gx, gy, F, CUT, SPEEDS, MethodOptions())
    assert any("SDM surrogate not accurate enough" in str(w.message) and f"every one of the {N_DRAWS} draws"
               in str(w.message) for w in caught)
    assert "surrogate" not in res.info
    np.testing.assert_allclose(res.depth_limit_m, exact.depth_limit_m, rtol=1e-9)


def test_few_draws_or_a_variable_pitch_are_always_exact(monkeypatch):
    # the rule's two conditions, without the cost of many exact draws: a surrogate call would fail the test
    def no_surrogate(*a, **k):
        raise AssertionError("the surrogate was used")

    monkeypatch.setattr(sdm_draws, "SURROGATE_MIN_DRAWS", 2)
    monkeypatch.setattr(sdm_draws, "_surrogate", no_surrogate)
    gx, gy = _draws(3, 12)
    sdm = STABILITY_METHODS.get("sdm")
    res = sdm.depth_limits(gx[:2], gy[:2], F, CUT, SPEEDS[:1], MethodOptions())  # not more than the threshold
    assert len(res.modal_fits) == 2
    pitch = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.5, milling="down", feed="y",
                              pitch_angles=tuple(np.deg2rad([80.0, 100.0, 80.0, 100.0])))
    res = sdm.depth_limits(gx, gy, F, pitch, SPEEDS[:1], MethodOptions())  # no zero-order limit to scale
    assert len(res.modal_fits) == 3
    with pytest.raises(AssertionError, match="the surrogate was used"):
        sdm.depth_limits(gx, gy, F, CUT, SPEEDS[:1], MethodOptions())


def test_the_run_time_estimate_follows_the_surrogate_rule():
    # what `lobes` prints before an SDM run: 500 draws cost 12 exact draws' time with the surrogate, all 500 with
    # --sdm-exact (the estimate printed before a minutes-long run must say minutes)
    sdm = STABILITY_METHODS.get("sdm")
    fast, slow = sdm.estimate_seconds(500, 400, 1501), sdm.estimate_seconds(500, 400, 1501, exact=True)
    assert fast == pytest.approx(sdm_draws._exact_seconds(sdm_draws.EXACT_DRAWS, 400, 1501))
    assert slow == pytest.approx(sdm_draws._exact_seconds(500, 400, 1501)) and slow > 20 * fast
    assert sdm.estimate_seconds(10, 400, 1501) == sdm.estimate_seconds(10, 400, 1501, exact=True)
