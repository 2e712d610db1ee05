"""Warnings of the identification that keep a careless input from giving a confident wrong answer (issue #12).

Items: (2) any posterior piled up against a prior bound, (4) a band without
the tool mode, (6) implausible scale or sign named in the message.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from bayes_rcsa.inference.band import Band, band_peak_warning, default_band
from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.inference.results import noise_scale_warnings, prior_bound_warnings
from bayes_rcsa.model import FRF
from bayes_rcsa.params import GrowthLaw, LogUniform, ParameterModel

from test_inference_support import bench, bench_model, contact_spec


def _sdof(f, fn=1400.0, zeta=0.03, k=2e7):
    r = f / fn
    return 1.0 / (k * (1.0 - r**2 + 2j * zeta * r))  # e^{+iwt}: Im h <= 0


def test_prior_bound_pile_up_is_flagged_for_any_parameter():
    pm = ParameterModel.from_priors(GrowthLaw(0.03, 0.03), {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e4, 1e8),
                                                             "sigma_0": LogUniform(1e-4, 10.0)},
                                    {"g_xf": 0.0, "g_thetaM": 0.0, "c_xf": 10.0, "c_thetaM": 5e-4}, n_measurements=1)
    rng = np.random.default_rng(0)
    n = 4000
    theta = np.column_stack([rng.normal(6.3, 0.01, n), rng.uniform(4.0, 8.0, n), rng.normal(-1.7, 0.05, n)])
    # a flat posterior over the whole prior keeps ~1 % within 1 % of each bound: no warning
    assert prior_bound_warnings(theta, pm) == []
    # k_thetaM pressed against its upper bound (e.g. a non-reciprocal spindle file): 30 % in the top 1 %
    theta[:, 1] = np.where(rng.uniform(size=n) < 0.3, 8.0 - 0.03 * rng.uniform(size=n), rng.uniform(6.0, 8.0, n))
    w = prior_bound_warnings(theta, pm)
    assert len(w) == 1 and w[0].startswith("k_thetaM:") and "upper bound 1e+08 N m/rad" in w[0]
    # ... and the noise scale at its lower bound
    theta[:, 2] = -4.0 + 0.02 * rng.uniform(size=n)
    assert [x.split(":")[0] for x in prior_bound_warnings(theta, pm)] == ["k_thetaM", "sigma_0"]
    assert prior_bound_warnings(theta, pm, skip=["k_thetaM", "sigma_0"]) == []


def test_band_without_the_tool_peak_is_flagged():
    f = np.arange(500.0, 3500.0, 1.0)
    frf = FRF(f, _sdof(f), None, "tip.csv")
    assert band_peak_warning(frf, default_band(frf), 1400.0) is None  # no false alarm with the default rule
    w = band_peak_warning(frf, Band(2000.0, 3000.0, "user"), 1410.0)
    # |h| of the damped SDOF peaks at fn sqrt(1 - 2 zeta^2) = 1398.7 Hz: line 1399
    assert w is not None and "tip.csv" in w and "largest peak at 1399 Hz" in w and "--band" in w
    # the model's tool mode near another (smaller) measured peak outside the band is named too
    h2 = _sdof(f) + _sdof(f, 2600.0, 0.03, 8e7)
    w = band_peak_warning(FRF(f, h2, None, "two.csv"), Band(1200.0, 1700.0, "user"), 2550.0)
    # the sum of the two modes moves the upper peak by a few Hz from 2600 Hz
    assert w is not None and re.search(r"measured peak at 2[56]\d\d Hz next to the model's tool mode", w), w


def test_noise_message_names_the_cause():
    obs = [type("O", (), {"source": "tip_25mm.csv"})()]
    draws = {"sigma_0": np.full(100, 9.98)}
    plain = noise_scale_warnings(draws, obs)
    assert "998 % of |H|" in plain[0] and "does not fit" in plain[0]
    named = noise_scale_warnings(draws, obs, {0: "probably mm/N instead of m/N (x 1000)"})
    assert "likely cause: probably mm/N" in named[0]


@pytest.fixture(scope="module")
def campaign():
    return bench(seed=12, frequency_step=2.0)


def _deterministic(campaign, scale=1.0, band=None):
    cfg, camp = campaign
    meas = [(c, FRF(frf.frequency_hz, scale * frf.values, frf.coherence, frf.source)) for c, frf in camp.measurements]
    prob = build_problem(bench_model(cfg, camp), meas, contact_spec(camp),
                         IdentificationOptions(method="deterministic", lengths=(0.025,), band=band))
    return identify(prob, seed=1).summary["warnings"]


def test_deterministic_fit_names_units_and_band_problems(campaign):
    assert _deterministic(campaign) == []  # clean data: no false alarm
    w = _deterministic(campaign, scale=1000.0)
    assert any("likely cause" in x and "mm/N instead of m/N" in x for x in w), w
    w = _deterministic(campaign, band=(2000.0, 3000.0))
    assert any("leaves out the measurement's largest peak" in x for x in w), w
