"""The analytic Jacobians of the spindle modal fit (the hot path of the bootstrap) against finite differences."""

from __future__ import annotations

import numpy as np

from bayes_rcsa.spindle.smoothing import FitData, _Problem, _Scaling, n_parameters


def test_fit_jacobian_matches_central_differences():
    rng = np.random.default_rng(3)
    f = np.linspace(300.0, 3000.0, 60)
    target = (rng.standard_normal((60, 3)) + 1j * rng.standard_normal((60, 3))) * 1e-7
    weight = (rng.standard_normal((60, 3, 3)) + 1j * rng.standard_normal((60, 3, 3))) * 1e7
    data = FitData(f, target, weight)
    sc = _Scaling(f, target)
    for n in (1, 3):
        prob = _Problem(data, sc, n)
        x = rng.standard_normal(n_parameters(n)) * 0.3
        jac = prob.jacobian(x)
        h = 1e-6
        fd = np.stack([(prob.residual(x + h * e) - prob.residual(x - h * e)) / (2 * h) for e in np.eye(x.size)], axis=1)
        # central differences are accurate to O(h^2) ~ 1e-12 relative; 1e-6 leaves room for rounding
        np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
