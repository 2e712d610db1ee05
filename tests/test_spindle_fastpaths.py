"""The compiled line loops of the spindle modal fit give the numbers of the numpy reference to round-off.

Problems of fewer than ``_COMPILED_LINES`` lines use the numpy reference itself; these small ones are compiled on
request (``compiled=True``).
"""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.spindle.inverse import forward_artifact, forward_jacobian
from bayes_rcsa.spindle.smoothing import (
    FitData, MeasurementData, _entries, _evaluate, _MeasurementProblem, _Problem, _Scaling, n_parameters,
)
from bayes_rcsa.spindle.substructure import ArtifactReceptances


def _data(rng, nf=80):
    f = np.linspace(300.0, 3000.0, nf)
    target = (rng.standard_normal((nf, 3)) + 1j * rng.standard_normal((nf, 3))) * 1e-7
    weight = (rng.standard_normal((nf, 3, 3)) + 1j * rng.standard_normal((nf, 3, 3))) * 1e7
    return FitData(f, target, weight)


def _reference_rows(kmat, d, row_scale):
    jac = (np.matmul(kmat, d) * row_scale[..., None]).reshape(-1, d.shape[-1])
    return np.concatenate([jac.real, jac.imag], axis=0)


@pytest.mark.parametrize("n", [0, 1, 3, 7])
def test_compiled_entries_and_whitened_jacobian_equal_the_numpy_reference(n):
    rng = np.random.default_rng(20 + n)
    data = _data(rng)
    sc = _Scaling(data.frequency_hz, data.target)
    prob = _Problem(data, sc, n, compiled=True)
    for _ in range(3):
        # spread natural frequencies across the band (and some poles close to lines): ill-conditioned Z too
        x = rng.standard_normal(n_parameters(n)) * 0.5
        ent_ref, d = _evaluate(x, n, prob.wt, sc, derivatives=True)
        ent, g = _entries(x, n, prob.wt, sc, {})
        np.testing.assert_allclose(ent, ent_ref, rtol=1e-12, atol=1e-13 * np.abs(ent_ref).max())
        ref = _reference_rows(prob.w, d, np.ones(prob.w.shape[:2]))
        np.testing.assert_allclose(prob.jacobian(x), ref, rtol=1e-10, atol=1e-13 * np.abs(ref).max())
        # the cache hands back what a fresh evaluation gives
        cached = prob.residual(x)
        prob.cache.clear()
        assert np.array_equal(prob.residual(x), cached)


def test_compiled_measurement_jacobian_equals_the_numpy_reference():
    rng = np.random.default_rng(7)
    nf, n = 70, 4
    fit = _data(rng, nf)
    sc = _Scaling(fit.frequency_hz, fit.target)
    a = (rng.standard_normal((nf, 6, 6)) + 1j * rng.standard_normal((nf, 6, 6))) * 1e-7
    ar = ArtifactReceptances(2 * np.pi * fit.frequency_hz, a + np.swapaxes(a, -1, -2))
    component = np.array([0, 1, 1, 2])
    measured = (rng.standard_normal((nf, 4)) + 1j * rng.standard_normal((nf, 4))) * 1e-7
    data = MeasurementData(ar, measured, component, rng.uniform(1e-9, 2e-9, (nf, 4)))
    prob = _MeasurementProblem(data, sc, n, compiled=True)
    for _ in range(3):
        x = rng.standard_normal(n_parameters(n)) * 0.5
        ent, d = _evaluate(x, n, prob.wt, sc, derivatives=True)
        h = forward_artifact(prob._block(ent), ar)[:, component]
        r = (h - measured) * prob.scale
        ref = np.concatenate([r.real.ravel(), r.imag.ravel()])
        np.testing.assert_allclose(prob.residual(x), ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
        k = forward_jacobian(ar, prob._block(ent))[:, component, :] * sc.entry
        ref = _reference_rows(k, d, prob.scale)
        np.testing.assert_allclose(prob.jacobian(x), ref, rtol=1e-10, atol=1e-13 * np.abs(ref).max())


def test_the_compiled_loops_are_used_from_the_line_count_up():
    from bayes_rcsa.spindle.smoothing import _COMPILED_LINES

    rng = np.random.default_rng(1)
    for nf in (_COMPILED_LINES - 1, _COMPILED_LINES):
        data = _data(rng, nf)
        assert _Problem(data, _Scaling(data.frequency_hz, data.target), 2).compiled == (nf >= _COMPILED_LINES)
