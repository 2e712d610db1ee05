"""Unit tests of the design estimators against independent reference computations."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.design.estimators import (
    Z90,
    NoiseLevel,
    finite_difference_jacobian,
    importance_widths,
    laplace_widths,
    log_likelihoods,
    weighted_widths,
)


def test_weighted_widths_equal_and_integer_weights():
    rng = np.random.default_rng(0)
    t = rng.standard_normal((3000, 2)) * [1.0, 3.0]
    w = np.full((1, 3000), 1 / 3000)
    ref = np.mean(np.diff(np.quantile(t, [0.05, 0.95], axis=0), axis=0))
    # Hazen's plotting position vs numpy's linear rule: differ by O(1/N) of the spread
    assert weighted_widths(t, w)[0] == pytest.approx(ref, rel=5e-3)
    # integer weights = duplicated draws
    counts = rng.integers(0, 4, 3000)
    dup = np.repeat(t, counts, axis=0)
    wi = (counts / counts.sum())[None]
    ref_dup = np.mean(np.diff(np.quantile(dup, [0.05, 0.95], axis=0), axis=0))
    assert weighted_widths(t, wi)[0] == pytest.approx(ref_dup, rel=1e-2)


def test_log_likelihoods_match_the_noise_model_line_by_line():
    rng = np.random.default_rng(1)
    h = rng.standard_normal((4, 6)) + 1j * rng.standard_normal((4, 6))
    y = rng.standard_normal((3, 6)) + 1j * rng.standard_normal((3, 6))
    noise = NoiseLevel(0.05, 0.01, 0.4)
    floor2 = 0.3
    got = log_likelihoods(y, h, noise, floor2)
    ref = np.zeros((3, 4))
    for m in range(3):
        for n in range(4):
            for k in range(6):
                var = noise.scale**2 * (abs(h[n, k]) ** 2 + floor2)
                ref[m, n] += -abs(y[m, k] - h[n, k]) ** 2 / var - np.log(np.pi * var)
    np.testing.assert_allclose(got, noise.tempering * ref, rtol=1e-10)


def test_both_estimators_recover_the_conjugate_gaussian_width():
    """Linear model H = theta * a, theta ~ N(0, 1), (nearly) constant noise variance: exact posterior width known.

    |H|^2 stays below 1e-3 of the floor, so the noise variance is s^2 floor2
    to 1e-3 and the posterior precision is 1 + 2 beta sum|a|^2 / (s^2 floor2)
    = 51.  Importance tolerance 5 %: M = 200 simulated data sets, ESS about
    2000 of 20000 draws, quantile noise 1-2 %; Laplace is exact here (1e-3).
    """
    rng = np.random.default_rng(2)
    n, lines = 20000, 8
    noise = NoiseLevel(1e-3, 0.0, 0.5)
    floor2 = 1.0
    sigma2 = noise.scale**2 * floor2
    a = rng.standard_normal(lines) + 1j * rng.standard_normal(lines)
    a *= np.sqrt(50.0 * sigma2 / (2 * noise.tempering * np.sum(np.abs(a) ** 2)))
    theta = rng.standard_normal(n)
    h = theta[:, None] * a[None]
    assert np.max(np.abs(h) ** 2) < 1e-3 * floor2
    exact = 2 * Z90 / np.sqrt(51.0)
    est = importance_widths(h, theta[:, None], noise, floor2, 200, np.random.default_rng(3))
    assert not est.collapsed
    assert est.expected_width == pytest.approx(exact, rel=0.05)
    jac = np.broadcast_to(a, (50, lines))[:, :, None]
    lap = laplace_widths(jac, np.ones((50, 1, 1)), np.eye(1), np.full(lines, 1 / sigma2), noise.tempering)
    assert lap.expected_width == pytest.approx(exact, rel=1e-3)


def test_finite_difference_jacobian_of_a_batched_function():
    u = np.array([[0.3, -1.0], [1.2, 0.5]])

    def f(x):  # (n, 2) -> (n, 3)
        return np.column_stack([x[:, 0] ** 2, np.sin(x[:, 1]), x[:, 0] * x[:, 1]])

    j = finite_difference_jacobian(f, u, np.array([1e-5, 1e-5]))
    assert j.shape == (2, 3, 2)
    ref = np.array([[[2 * u0, 0], [0, np.cos(u1)], [u1, u0]] for u0, u1 in u])
    np.testing.assert_allclose(j, ref, rtol=1e-7, atol=1e-9)
