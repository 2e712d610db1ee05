"""A joint stiffness on its rigid (upper) bound: the Laplace draws are taken in its compliance, not in log k.

The tool/holder joint is in series with the tool, so near the rigid limit the FRF changes linearly with the
joint's compliance ``c = 1/k`` and not with ``log10 k`` (the sampling coordinate).  A Gaussian in ``log10 k``
with the small curvature found at the bound put the remainder's draws decades below it, where the fit is
destroyed (rotor bench, stiffer tool: half the draws cost beta * dchi2 > 50; docs/discrepancy.md, "The
remainder's draws below a joint on its upper bound").
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from bayes_rcsa.data import example_dir
from bayes_rcsa.discrepancy import DiscrepancyOptions
from bayes_rcsa.discrepancy.fit import JOINT_STIFFNESSES, laplace_draws, rigid_side_columns
from bayes_rcsa.discrepancy.workflow import validate
from bayes_rcsa.io.setup import load_setup


@pytest.fixture(scope="module")
def problem():
    _, _, p = validate(load_setup(example_dir() / "setup.toml"), DiscrepancyOptions(lengths=(0.025, 0.040)))
    return p


def _mid(problem):
    return np.array([0.5 * (lo + hi) for lo, hi in problem.priors.optimisation_bounds()])


@pytest.mark.parametrize("name", JOINT_STIFFNESSES)
def test_the_frf_is_linear_in_the_joint_compliance_near_the_rigid_bound(problem, name):
    """The physics the draws rest on: doubling the compliance step doubles the FRF change, doubling the step in
    log10 k does not."""
    j = problem.parameters.names.index(name)
    lo, hi = problem.priors.optimisation_bounds()[j]
    mid = _mid(problem)

    def h(u):
        t = mid.copy()
        t[j] = u
        return problem.likelihood.model_frf(t[None])[0]

    h0 = h(hi)
    for s in (0.5, 2.0, 4.0):  # compliance 1.5x, 3x and 5x the rigid bound's
        ratio_c = np.linalg.norm(h(hi - math.log10(1 + 2 * s)) - h0) / np.linalg.norm(h(hi - math.log10(1 + s)) - h0)
        # 2.000-2.025 on the example (k_xf, k_thetaM); 2 % leaves room for another setup's geometry
        assert abs(ratio_c - 2.0) < 0.04, (name, s, ratio_c)
    # the same doubling in the sampling coordinate log10 k is far from linear (2.6 at 0.2 decade on the example)
    ratio_u = np.linalg.norm(h(hi - 0.4) - h0) / np.linalg.norm(h(hi - 0.2) - h0)
    assert ratio_u > 2.3, (name, ratio_u)


def test_a_joint_on_its_rigid_bound_is_drawn_from_a_gaussian_in_its_compliance(problem):
    names = problem.parameters.names
    bounds = problem.priors.optimisation_bounds()
    cols = [names.index(n) for n in JOINT_STIFFNESSES]
    theta = _mid(problem)
    sd = 0.6  # decades: the flat curvature at a near-rigid joint (rotor bench: 0.5-1.5)
    cov = np.diag([sd**2, sd**2])
    j_rigid, j_free = cols[1], cols[0]
    hi = bounds[j_rigid][1]
    theta[j_rigid] = hi - 0.002 * (hi - bounds[j_rigid][0])  # within 1 % of the range: on the bound
    assert rigid_side_columns(SimpleNamespace(problem=problem, theta=theta, physical=cols)) == [1]
    theta[j_rigid] = hi - 0.03 * (hi - bounds[j_rigid][0])  # 3 %: inside
    assert rigid_side_columns(SimpleNamespace(problem=problem, theta=theta, physical=cols)) == []
    theta[j_rigid] = hi  # exactly on it, so that the compliance step is a half-normal
    fit = SimpleNamespace(problem=problem, theta=theta, physical=cols, cov=cov)
    d = laplace_draws(fit, np.random.default_rng(11), 4000)
    assert d.shape == (4000, theta.size)
    u = d[:, j_rigid]
    assert np.all(u <= hi) and np.all(u >= bounds[j_rigid][0])
    # the same Gaussian step taken in the compliance: (c - c*) / c* = -ln(10) du, truncated at the bound
    step = (10.0 ** (theta[j_rigid] - u) - 1.0) / (math.log(10.0) * sd)
    assert np.all(step >= 0)
    # half-normal; with 4000 draws a real departure (a Gaussian in log10 k) gives p ~ 0
    assert stats.kstest(step, stats.halfnorm.cdf).pvalue > 1e-3
    # far less mass decades below the bound than the Gaussian in log10 k had (its 5 % point: 1.96 sd = 1.2 below)
    assert np.quantile(u, 0.05) > hi - math.log10(1.0 + math.log(10.0) * sd * 2.1)
    assert np.quantile(u, 0.05) > hi - 0.6
    # the joint stiffness off its bound keeps the Gaussian in log10 k (mean and sd within 4.5 standard errors)
    free = d[:, j_free]
    assert abs(free.mean() - theta[j_free]) < 4.5 * sd / math.sqrt(free.size)
    assert abs(free.std() / sd - 1.0) < 0.05


def test_a_joint_off_its_bound_keeps_the_gaussian_in_log_k(problem):
    names = problem.parameters.names
    cols = [names.index(n) for n in JOINT_STIFFNESSES]
    theta = _mid(problem)
    fit = SimpleNamespace(problem=problem, theta=theta, physical=cols, cov=np.diag([0.1**2, 0.1**2]))
    assert rigid_side_columns(fit) == []
    d = laplace_draws(fit, np.random.default_rng(12), 4000)[:, cols]
    # a symmetric Gaussian about the MAP: the compliance mapping would skew it towards the soft side
    assert np.all(np.abs(np.mean(d - theta[cols], axis=0)) < 4.5 * 0.1 / math.sqrt(4000))
    assert np.all(np.abs(stats.skew(d, axis=0)) < 0.15)
