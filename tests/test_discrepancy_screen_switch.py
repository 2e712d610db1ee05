"""The score test's switch path: a term with its switch at the baseline has exactly no effect.

A term that declares ``switch`` (a resonator's or a tip body's mass) promises that with the switch at its
baseline none of its other parameters changes the model.  The discrepancy screen relies on it to differentiate
in the switch alone over the grid of the others (a quarter of the model evaluations for the resonator); these
tests check the promise on the forward model of every such term and that the screen's numbers are bit for bit
those of differentiating in every parameter.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayes_rcsa.data import example_dir
from bayes_rcsa.discrepancy import DiscrepancyOptions
from bayes_rcsa.discrepancy import screen
from bayes_rcsa.discrepancy import workflow as W
from bayes_rcsa.discrepancy.fit import fit_baseline
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.params.terms import get_term, known_terms

SWITCHED = [n for n in known_terms() if get_term(n).switch is not None]


def test_the_resonator_and_the_tip_body_declare_their_mass_as_switch():
    assert {"extra_mode", "tip_mass"} <= set(SWITCHED)
    for name in SWITCHED:
        assert get_term(name).switch.startswith(name), name


@pytest.fixture(scope="module")
def screened():
    setup = load_setup(example_dir() / "setup.toml")
    cands, base_opts, problem = W.validate(setup, DiscrepancyOptions(lengths=(0.025, 0.040), candidates=tuple(SWITCHED)))
    return setup, base_opts, fit_baseline(problem)


@pytest.mark.parametrize("effect", SWITCHED)
def test_with_the_switch_at_its_baseline_no_other_parameter_changes_the_frf(screened, effect):
    setup, base_opts, baseline = screened
    problem = W._problem(setup, base_opts, [effect])
    pm = problem.parameters
    theta0 = screen.embed_baseline(baseline, problem)
    bounds = np.array(problem.priors.optimisation_bounds())
    switch = pm.names.index(get_term(effect).switch)
    others = [j for j, n in enumerate(pm.names) if pm[n].term == effect and j != switch]
    assert others, effect
    rng = np.random.default_rng(3)
    rows = np.repeat(theta0[None], 12, axis=0)
    for j in others:  # the other parameters anywhere in their prior, the switch at its baseline
        rows[1:11, j] = rng.uniform(bounds[j, 0], bounds[j, 1], 10)
    rows[11, switch] += 0.1 * (bounds[switch, 1] - bounds[switch, 0])  # one set switched on: the general path
    h = problem.likelihood.model_frf(rows)
    assert np.array_equal(h[1:11], np.repeat(h[:1], 10, axis=0)), effect  # exactly, not to a tolerance
    assert not np.allclose(h[11], h[0]), effect  # and the switch itself does act


@pytest.mark.parametrize("effect", SWITCHED)
def test_the_switch_path_gives_the_full_score_test_bit_for_bit(screened, effect, monkeypatch):
    setup, base_opts, baseline = screened
    problem = W._problem(setup, base_opts, [effect])
    fast = screen.score_test(baseline, problem, effect)
    calls = []
    monkeypatch.setattr(screen, "_switch_jacobians", lambda *a: calls.append(1))  # returns None: the full path
    full = screen.score_test(baseline, problem, effect)
    assert calls
    assert fast.statistic == full.statistic and fast.dof == full.dof
    assert np.array_equal(fast.start, full.start)
    assert len(fast.starts) == len(full.starts) and all(np.array_equal(a, b) for a, b in zip(fast.starts, full.starts))
