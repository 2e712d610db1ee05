"""Which parameters the prior cuts the Laplace draws of: a MAP on a finite prior bound (``fit.truncated_by_prior``).

There the draws of :func:`bayes_rcsa.discrepancy.fit.laplace_draws` lie on one side of the MAP, so the MAP's mode
can lie beyond their 90 % interval without any mix-up of modes (``evaluate.mode_entries`` flags it instead of
refusing the run).  A joint on its rigid bound is drawn in its compliance and is not counted.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bayes_rcsa.data import example_dir
from bayes_rcsa.discrepancy import DiscrepancyOptions
from bayes_rcsa.discrepancy.fit import JOINT_STIFFNESSES, laplace_draws, truncated_by_prior
from bayes_rcsa.discrepancy.workflow import validate
from bayes_rcsa.io.setup import load_setup


@pytest.fixture(scope="module")
def problem():
    _, _, p = validate(load_setup(example_dir() / "setup.toml"), DiscrepancyOptions(lengths=(0.025, 0.040)))
    return p


def test_a_stiffness_on_its_lower_bound_is_truncated_and_its_draws_lie_on_one_side(problem):
    names = problem.parameters.names
    bounds = problem.priors.optimisation_bounds()
    cols = [names.index(n) for n in JOINT_STIFFNESSES]
    theta = np.array([0.5 * (lo + hi) for lo, hi in bounds])
    fit = SimpleNamespace(problem=problem, theta=theta.copy(), physical=cols, cov=np.diag([0.3**2, 0.3**2]))
    assert truncated_by_prior(fit) == []
    j = cols[0]
    lo, hi = bounds[j]
    fit.theta[j] = lo + 0.002 * (hi - lo)  # within 1 % of the range: on the (soft) bound
    assert truncated_by_prior(fit) == [names[j]]
    d = laplace_draws(fit, np.random.default_rng(3), 2000)[:, j]
    # every draw on the stiff side of the MAP but for the 0.2 % of range between it and the bound
    assert np.mean(d >= fit.theta[j]) > 0.97
    fit.theta[j] = lo + 0.03 * (hi - lo)  # 3 %: inside
    assert truncated_by_prior(fit) == []
    # a joint on its *upper* (rigid) bound is drawn in its compliance, not cut: not counted
    fit.theta[j] = theta[j]
    k = cols[1]
    fit.theta[k] = bounds[k][1]
    assert truncated_by_prior(fit) == []
