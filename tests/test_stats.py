"""bayes_rcsa.stats: importance weights, their ESS and Pareto shape, the one noise estimator (issue #41)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sps

from bayes_rcsa.errors import ConvergenceError, DataError
from bayes_rcsa.io.frf import overlap_mask
from bayes_rcsa.stats.noise import noise_sigma, relative_noise_scale
from bayes_rcsa.stats.weights import (MIN_ESS, MIN_ESS_INTERVAL_END, MIN_ESS_UPDATE, PARETO_K_MAX,
                                      effective_sample_size, importance_reliable, normalise_log_weights, pareto_k)

PACKAGE = Path(__file__).resolve().parent.parent / "bayes_rcsa"


# ------------------------------------------------------------- weights --


def test_ess_of_equal_weights_is_n_and_of_one_weight_is_one():
    assert effective_sample_size(np.ones(250)) == pytest.approx(250.0, rel=1e-12)
    assert effective_sample_size(np.full(40, 1 / 40), normalised=True) == pytest.approx(40.0, rel=1e-12)
    one_hot = np.zeros(100)
    one_hot[17] = 3.0
    assert effective_sample_size(one_hot) == pytest.approx(1.0, rel=1e-12)
    # two equal weights among zeros: 2
    two = np.zeros(10)
    two[[2, 5]] = 0.5
    assert effective_sample_size(two) == pytest.approx(2.0, rel=1e-12)


def test_ess_is_kish_and_invariant_to_the_weights_scale():
    rng = np.random.default_rng(4)
    lw = rng.normal(0.0, 1.5, 500)
    w = normalise_log_weights(lw)
    kish = np.sum(np.exp(lw)) ** 2 / np.sum(np.exp(2 * lw))
    assert effective_sample_size(w, normalised=True) == pytest.approx(kish, rel=1e-10)
    # a constant added to every log weight (every weight scaled) changes nothing
    for c in (-700.0, -3.0, 25.0, 650.0):
        assert effective_sample_size(normalise_log_weights(lw + c), normalised=True) == pytest.approx(kish, rel=1e-10)
    assert effective_sample_size(7.5e-9 * np.exp(lw)) == pytest.approx(kish, rel=1e-10)


def test_ess_along_an_axis():
    w = np.array([[1.0, 1.0, 1.0, 1.0], [1.0, 0.0, 0.0, 0.0], [2.0, 2.0, 0.0, 0.0]])
    np.testing.assert_allclose(effective_sample_size(w, axis=1), [4.0, 1.0, 2.0])
    np.testing.assert_allclose(effective_sample_size(w.T, axis=0), [4.0, 1.0, 2.0])


def test_normalise_log_weights_is_stable_far_below_exp_range():
    lw = np.array([-1.0e4, -1.0e4 - 1.0, -1.0e4 - 2.0, -np.inf])  # exp() of each underflows to 0
    w = normalise_log_weights(lw)
    e = np.exp([0.0, -1.0, -2.0])
    np.testing.assert_allclose(w, np.append(e / e.sum(), 0.0), rtol=1e-14)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    big = normalise_log_weights(np.array([1.0e4, 1.0e4]))  # exp() overflows
    np.testing.assert_allclose(big, [0.5, 0.5])


def test_normalise_log_weights_per_row_and_without_any_weight():
    lw = np.array([[0.0, np.log(3.0)], [-np.inf, -np.inf]])
    with pytest.raises(ConvergenceError, match="the cuts contradict"):
        normalise_log_weights(lw[1], reason="every particle has zero likelihood; the cuts contradict")
    with pytest.raises(ConvergenceError):
        normalise_log_weights(lw, axis=1)
    w = normalise_log_weights(lw, axis=1, refuse=False)
    np.testing.assert_allclose(w[0], [0.25, 0.75])
    assert np.all(np.isnan(w[1]))


def test_pareto_k_recovers_a_known_tail_and_separates_light_from_heavy_tails():
    rng = np.random.default_rng(11)
    u = rng.uniform(size=20_000)
    # Pareto(alpha) weights, P(w > t) = t^-alpha: k = 1 / alpha exactly.  PSIS fits the M = 3 sqrt(S) = 424
    # largest; the fitted shape's standard error is about (1 + k) / sqrt(M) = 0.07-0.10, the tolerance 3 of them.
    assert pareto_k(-np.log(u) / 1.0) == pytest.approx(1.0, abs=0.3)
    assert pareto_k(-np.log(u) / 2.5) == pytest.approx(0.4, abs=0.2)
    assert pareto_k(-np.log(u)) > PARETO_K_MAX
    # N(0, 1) target, N(0, 2^2) proposal: bounded weights (k <= 0 in theory), far below 0.5
    y = 2.0 * rng.standard_normal(20_000)
    light = sps.norm.logpdf(y) - sps.norm(scale=2.0).logpdf(y)
    assert pareto_k(light) < 0.5
    assert importance_reliable(pareto_k(light), effective_sample_size(normalise_log_weights(light)))
    assert not importance_reliable(pareto_k(-np.log(u)), 1e6)
    assert not importance_reliable(math.nan, 1e6)
    assert not importance_reliable(0.1, MIN_ESS_INTERVAL_END - 1)


def test_pareto_smoothing_equals_arviz_psislw():
    # the package's PSIS is its own code (ArviZ's import costs seconds of start-up); it must be the published
    # algorithm ArviZ implements: the same smoothed weights and shape on light, exponential, heavy and
    # outlier-dominated weights and on sample sizes around the tail-length switch (n / 5 against 3 sqrt(n))
    import warnings

    import arviz as az

    from bayes_rcsa.stats.weights import pareto_smoothed_log_weights

    rng = np.random.default_rng(7)
    cases = [rng.normal(0, 0.3, 4000), -np.log(rng.uniform(size=25_000)) / 0.8, 5 * rng.standard_t(2, 1000),
             np.concatenate([rng.normal(size=197), [40.0, 55.0, 70.0]]), rng.normal(0, 2, 20), rng.normal(size=225)]
    for lw in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want, k_want = az.psislw(lw.copy())
        got, k = pareto_smoothed_log_weights(lw)
        # the same operations up to the order of a few sums: agreement to rounding
        np.testing.assert_allclose(np.exp(got), np.exp(np.asarray(want)), rtol=0, atol=1e-14)
        assert k == pytest.approx(float(k_want), rel=1e-12, abs=1e-14)
    tiny, k_tiny = pareto_smoothed_log_weights(np.array([0.0, 1.0, 2.0, 3.0]))  # no tail to fit
    assert math.isinf(k_tiny) and np.isclose(np.exp(tiny).sum(), 1.0)


def test_callers_use_the_shared_thresholds():
    from bayes_rcsa.cuts.update import DEFAULT_MIN_ESS
    from bayes_rcsa.design.estimators import ESS_MIN as DESIGN_ESS_MIN
    from bayes_rcsa.inference.tail_check import MIN_ESS as TAIL_MIN_ESS
    from bayes_rcsa.library.exact import SITE_ESS_MIN
    from bayes_rcsa.library.stage2 import ESS_MIN as POOLED_ESS_MIN

    assert DESIGN_ESS_MIN is MIN_ESS and POOLED_ESS_MIN is MIN_ESS and SITE_ESS_MIN is MIN_ESS
    assert TAIL_MIN_ESS is MIN_ESS_INTERVAL_END and DEFAULT_MIN_ESS is MIN_ESS_UPDATE
    # the values every output was produced with
    assert (MIN_ESS, MIN_ESS_UPDATE, MIN_ESS_INTERVAL_END, PARETO_K_MAX) == (30.0, 50.0, 1000, 0.7)


# --------------------------------------------------------------- noise --


def _modal(f, modes):
    w = 2 * np.pi * f
    h = np.zeros(f.size, complex)
    for fr, zeta, a in modes:
        wr = 2 * np.pi * fr
        h += a / (wr**2 - w**2 + 2j * zeta * wr * w)
    return h


@pytest.mark.parametrize("modes, n, rel, seed", [
    ([(1500.0, 0.01, 1.0)], 2000, 0.01, 1),
    ([(700.0, 0.02, 1.0), (2100.0, 0.01, 0.5)], 3801, 0.005, 2),
    ([(700.0, 0.02, 1.0), (2100.0, 0.01, 0.5)], 3801, 0.03, 3),
    ([(450.0, 0.02, 1.0), (900.0, 0.015, -0.6), (1400.0, 0.01, 0.8), (2800.0, 0.015, 0.7)], 2000, 0.02, 4),
])
def test_noise_estimate_recovers_the_relative_noise(modes, n, rel, seed):
    # Tolerance: 4 standard errors of the estimator.  The median of n exponential variates, under the square root,
    # has a relative standard error 0.72 / sqrt(n); overlapping differences raise it to about 0.9 / sqrt(n)
    # (measured 1.3-1.5 % at 3801 lines and 1.8-2.3 % at 2000, benchmarks/noise_estimator.py), whose bias on
    # these grids is below 1 %.  Scaling H by 1e-7 (m/N of a real tool point) must not matter.
    f = np.linspace(200.0, 4000.0, n)
    h = 1e-7 * _modal(f, modes) / np.max(np.abs(_modal(f, modes)))
    z = np.random.default_rng(seed).standard_normal((2, n))
    noisy = h + rel * np.abs(h) * (z[0] + 1j * z[1]) / math.sqrt(2.0)
    assert relative_noise_scale(noisy) == pytest.approx(rel, rel=4 * 0.9 / math.sqrt(n))
    # the noise-free FRF's own curvature reads as far less than any of these noise levels
    assert relative_noise_scale(h) < 0.1 * rel


def test_noise_estimate_refuses_or_gives_nan_as_asked():
    h = np.exp(1j * np.linspace(0.0, 1.0, 12)) * (1.0 + 0.01 * np.arange(12))
    assert np.isnan(relative_noise_scale(h[:4]))
    assert np.isfinite(relative_noise_scale(h[:5]))
    assert np.isnan(relative_noise_scale(h, min_lines=20))
    with pytest.raises(DataError, match="at least 20 lines"):
        relative_noise_scale(h, min_lines=20, strict=True)
    with pytest.raises(DataError, match="zero on every line"):
        relative_noise_scale(np.zeros(30, complex), strict=True)
    assert np.isnan(relative_noise_scale(np.zeros(30, complex)))
    with pytest.raises(DataError):
        relative_noise_scale(np.ones((5, 5), complex), strict=True)


def test_spindle_noise_estimate_is_the_shared_one_with_its_minimum():
    from bayes_rcsa.spindle.noise import estimate_relative_noise

    rng = np.random.default_rng(8)
    f = np.linspace(200.0, 4000.0, 3801)
    h = _modal(f, [(700.0, 0.02, 1.0), (2100.0, 0.01, 0.5)])
    y = h * (1.0 + 0.01 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) / math.sqrt(2.0))
    assert estimate_relative_noise(y) == relative_noise_scale(y)
    with pytest.raises(DataError):
        estimate_relative_noise(y[:19])


def test_noise_sigma_is_relative_plus_floor():
    h = np.array([3.0 + 4.0j, 0.0, -1.0])
    np.testing.assert_allclose(noise_sigma(h, 0.1, 1e-3), [0.501, 0.001, 0.101])
    np.testing.assert_allclose(noise_sigma(h, 0.1), [0.5, 0.0, 0.1])


def test_overlap_mask_keeps_x_lines_inside_both_bands():
    fx = np.arange(0.0, 101.0)
    fy = np.arange(9.5, 300.0, 0.5)
    keep = overlap_mask(fx, fy)
    np.testing.assert_array_equal(fx[keep], np.arange(10.0, 101.0))
    np.testing.assert_array_equal(overlap_mask(fy, fx), (fy >= 9.5) & (fy <= 100.0))
    assert not overlap_mask(fx, np.array([200.0, 300.0])).any()


# ---------------------------------------------------- chain convergence --


def _ar1(rng, m, n, phi):
    x = np.zeros((m, n))
    e = rng.standard_normal((m, n))
    for t in range(1, n):
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    return x


def test_rhat_and_ess_equal_arviz_on_correlated_tied_stuck_and_short_chains():
    # the package's R-hat and ESS are its own code (ArviZ's import costs seconds of start-up in every MCMC run and
    # process-pool worker); they must be the published estimators ArviZ implements.  Cases: white to strongly
    # correlated AR(1) chains from 4 draws (the shortest allowed) to 1,000, an odd number of draws (split drops the
    # middle one), rounded draws (ties share ranks), a stuck walker, a shifted walker (R-hat >> 1), a constant
    # chain, rare indicator values (tail ESS of a nearly constant chain), a walker with 10x the spread (only the
    # folded R-hat sees it), one chain (R-hat undefined) and 3 draws (nothing defined)
    import warnings

    import arviz as az

    from bayes_rcsa.stats.convergence import convergence_diagnostics, ess_bulk, ess_tail, rank_rhat

    rng = np.random.default_rng(11)
    cases = [_ar1(rng, m, n, phi) for m, n in [(2, 4), (3, 5), (4, 6), (5, 7), (8, 9), (16, 50), (32, 301), (4, 1000)]
             for phi in (0.0, 0.5, 0.95, 0.999)]
    cases.append(np.round(_ar1(rng, 10, 200, 0.9), 1))
    stuck = _ar1(rng, 10, 200, 0.5)
    stuck[3] = stuck[3, 0]
    shifted = _ar1(rng, 10, 200, 0.5)
    shifted[5] += 5.0
    cases += [stuck, shifted, np.ones((4, 50)), np.where(rng.random((6, 40)) < 0.03, 1.0, 0.0),
              rng.standard_normal((6, 40)) * np.array([1, 1, 1, 1, 1, 10.0])[:, None], _ar1(rng, 1, 100, 0.5),
              _ar1(rng, 3, 3, 0.5)]
    want = []
    for x in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = az.convert_to_dataset({"a": x})
            want.append([float(az.rhat(ds)["a"]), float(az.ess(ds, method="bulk")["a"]),
                         float(az.ess(ds, method="tail")["a"])])
    assert any(w[0] > 1.5 for w in want) and any(math.isnan(w[0]) for w in want)  # the cases reach both ends
    for x, w in zip(cases, want):
        got = [float(rank_rhat(x[None])[0]), float(ess_bulk(x[None])[0]), float(ess_tail(x[None])[0])]
        # the same operations up to the order of a few sums and the FFT length: agreement to rounding
        np.testing.assert_allclose(got, w, rtol=1e-9, equal_nan=True, err_msg=str(x.shape))
    # several quantities at once (leading axis) and the three at once give the same numbers
    same = [c for c in cases if c.shape == (16, 50)]
    stacked = np.stack(same)
    both = convergence_diagnostics(stacked)
    for k, x in enumerate(same):
        np.testing.assert_array_equal([both["rhat"][k], both["ess_bulk"][k], both["ess_tail"][k]],
                                      [rank_rhat(x[None])[0], ess_bulk(x[None])[0], ess_tail(x[None])[0]])


def test_chain_diagnostics_take_walkers_as_chains_without_arviz():
    # (n_steps, n_walkers, ndim) in, one number per coordinate out; a fresh interpreter that samples and judges a
    # chain has not imported ArviZ (or xarray)
    import subprocess
    import sys

    from bayes_rcsa.inference.diagnostics import chain_diagnostics
    from bayes_rcsa.stats.convergence import convergence_diagnostics

    rng = np.random.default_rng(12)
    chain = rng.standard_normal((60, 8, 3))
    chain[:, 0, 2] += 4.0  # one walker of coordinate 2 elsewhere
    d = chain_diagnostics(chain)
    ref = convergence_diagnostics(np.transpose(chain, (2, 1, 0)))
    for k in ("rhat", "ess_bulk", "ess_tail"):
        np.testing.assert_array_equal(d[k], ref[k])
    assert d["rhat"][2] > 1.1 > max(d["rhat"][:2])
    assert np.all(np.isnan(chain_diagnostics(chain[:3])["rhat"]))
    code = ("import sys, numpy as np; from bayes_rcsa.inference.diagnostics import chain_diagnostics; "
            "chain_diagnostics(np.random.default_rng(0).standard_normal((40, 6, 2))); "
            "print(sorted(m for m in ('arviz', 'xarray', 'pandas', 'scipy.stats') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out


# -------------------------------------------------------- architecture --

#: The formulas that live in bayes_rcsa/stats only: the ESS 1 / sum w^2, the second and third differences of the
#: noise estimate, PSIS, and R-hat/ESS of a chain.
_OWNED = {
    "effective sample size 1 / sum w^2": re.compile(r"1(\.0)?\s*/\s*np\.sum\(\s*w"),
    "second differences of an FRF": re.compile(r"\[:-2\]\s*-\s*2(\.0)?\s*\*\s*\w+\[1:-1\]"),
    "third-difference stencil": re.compile(r"-?1(\.0)?,\s*3(\.0)?,\s*-3(\.0)?,\s*1(\.0)?\]"),
    "PSIS": re.compile(r"psislw"),
    "R-hat / ESS": re.compile(r"\baz\.(rhat|ess)\(|\barviz\.(rhat|ess)\("),
    "relative noise from a median / ln 2": re.compile(r"median\(.*\)\s*/\s*(math|np)\.(sqrt\()?(math\.)?log\(2"),
}


def test_weights_and_noise_formulas_live_in_stats_only():
    found = []
    for f in sorted(PACKAGE.rglob("*.py")):
        if f.relative_to(PACKAGE).parts[0] == "stats":
            continue
        text = f.read_text()
        found += [f"{f.relative_to(PACKAGE)}: {what}" for what, rx in _OWNED.items() if rx.search(text)]
    assert not found, "use bayes_rcsa.stats instead: " + "; ".join(found)
    # each pattern matches the copy it replaced (a pattern that matches nothing checks nothing)
    replaced = {"effective sample size 1 / sum w^2": "ess = float(1.0 / np.sum(w * w))",
                "second differences of an FRF": "d2 = h[:-2] - 2.0 * h[1:-1] + h[2:]",
                "third-difference stencil": "_C3 = np.array([-1.0, 3.0, -3.0, 1.0])",
                "PSIS": "lw, k = _az().psislw(np.asarray(log_weights, dtype=float))",
                "R-hat / ESS": "bulk = az.ess(ds, method=\"bulk\")",
                "relative noise from a median / ln 2":
                    "return float(np.median(np.abs(d[ok]) / scale[ok]) / math.sqrt(math.log(2.0)))"}
    assert all(_OWNED[what].search(code) for what, code in replaced.items())
