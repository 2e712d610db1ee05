"""Unit tests of the inference building blocks (fast; no sampling runs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.errors import DataError, SetupError
from bayes_rcsa.inference.band import Band, band_mask, default_band
from bayes_rcsa.inference.checkpoint import Checkpoint
from bayes_rcsa.inference.deterministic import PercentageObjective
from bayes_rcsa.inference.likelihood import residual_correlation_length
from bayes_rcsa.params.growth import GrowthLaw
from bayes_rcsa.params.priors import LogNormal, LogUniform, Normal, PriorSet, Uniform, prior_from_spec
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.model import FRF
from bayes_rcsa.posterior import natural_frequency

from test_inference_support import bench, bench_model, contact_spec


def sdof(f, fn=1000.0, zeta=0.02, k=1e6):
    """Single-degree-of-freedom receptance (e^{+iwt}: Im h <= 0)."""
    r = f / fn
    return 1.0 / (k * (1 - r**2 + 2j * zeta * r))


# -- priors ------------------------------------------------------------------


@pytest.mark.parametrize("prior", [Uniform(-1.0, 3.0), LogUniform(1e5, 1e9), LogNormal(2e6, 0.5),
                                   Normal(0.2, 0.1, lo=0.0, hi=0.5), LogNormal(2e6, 0.5, lo=1e6, hi=1e7)])
def test_prior_density_normalised_and_samples_inside(prior):
    lo, hi = prior.optimisation_bounds()
    lo_s, hi_s = prior.bounds
    # integrate over the support (truncated normals: their own bounds; else +-5 sigma holds 1 - 6e-7)
    u = np.linspace(max(lo, lo_s), min(hi, hi_s), 200001)
    mass = np.trapezoid(np.exp(prior.ln_prob(u)), u)
    assert mass == pytest.approx(1.0, abs=1e-5)
    x = prior.sample(np.random.default_rng(1), 2000)
    assert np.all(prior.in_support(x))
    assert np.all(prior.ln_prob(np.array([lo_s - 1.0, hi_s + 1.0])[np.isfinite([lo_s, hi_s])]) == -np.inf)


def test_loguniform_maps_log10():
    p = LogUniform(1e5, 1e9)
    assert p.bounds == pytest.approx((5.0, 9.0))
    assert p.to_physical(6.5) == pytest.approx(10**6.5)
    assert p.to_sampling(2e6) == pytest.approx(math.log10(2e6))


def test_priorset_check_inside_names_parameter():
    ps = PriorSet({"k_xf": LogUniform(1e5, 1e9), "g_xf": Uniform(0, 0.5)})
    ps.check_inside(np.array([[6.0, 0.2]]))
    with pytest.raises(SetupError, match=r"walker start 1: parameter g_xf = 0\.7"):
        ps.check_inside(np.array([[6.0, 0.2], [6.0, 0.7]]), "walker start")
    with pytest.raises(SetupError, match="k_xf = 1e\\+12"):
        ps.check_inside(np.array([[12.0, 0.2]]), "walker start")


def test_prior_from_spec_tables():
    assert isinstance(prior_from_spec([1.0, 2.0], "x"), LogUniform)
    assert isinstance(prior_from_spec({"distribution": "log-normal", "median": 2e6, "sigma": 0.3}, "x"), LogNormal)
    with pytest.raises(SetupError, match="needs key 'sigma'"):
        prior_from_spec({"distribution": "normal", "mu": 1.0}, "x")
    with pytest.raises(SetupError, match="unknown distribution"):
        prior_from_spec({"distribution": "cauchy"}, "x")


# -- growth law ------------------------------------------------------------


def test_growth_law_is_exactly_the_bounded_monotone_family():
    law = GrowthLaw(0.020, 0.045, 0.5)
    lengths = np.linspace(0.020, 0.045, 26)
    rng = np.random.default_rng(0)
    g = np.concatenate([rng.uniform(0, 0.5, 200), [0.0, 0.5]])
    k = law.stiffness(np.full(g.size, 2e6), g, lengths)
    assert np.all(np.diff(k, axis=1) >= 0)
    # K(l2) - K(l1) <= Q K(l1) for every pair l1 < l2 (1e-12 relative: round-off)
    rel = (k[:, None, :] - k[:, :, None]) / k[:, :, None]
    upper = np.triu(np.ones((lengths.size, lengths.size), bool), 1)
    assert np.all(rel[:, upper] <= 0.5 * (1 + 1e-12))
    # g = Q reaches the bound exactly at (l_a, l_b); any g > Q breaks it there
    assert rel[-1, 0, -1] == pytest.approx(0.5, rel=1e-12)
    k_over = law.stiffness(np.array([2e6]), np.array([0.51]), [0.020, 0.045])
    assert k_over[0, 1] - k_over[0, 0] > 0.5 * k_over[0, 0]


def test_growth_law_rejects_lengths_outside_range():
    law = GrowthLaw(0.025, 0.040)
    law.check_lengths([0.025, 0.040])
    with pytest.raises(SetupError, match="outside the feasible clamping range"):
        law.check_lengths([0.050])


# -- band and natural frequency --------------------------------------------


def test_default_band_brackets_dominant_peak():
    f = np.arange(200.0, 3000.0, 2.0)
    h = sdof(f, 1000.0) + 0.3 * sdof(f, 2600.0, 0.05)
    b = default_band(FRF(f, h))
    assert b.lo_hz == pytest.approx(1000.0 / 1.25, abs=2.0)  # peak of |h| is within a line of f_n
    assert b.hi_hz == pytest.approx(1000.0 * 1.25, abs=3.0)
    # a close second peak of comparable height widens the band to keep both
    h2 = sdof(f, 1000.0) + sdof(f, 1150.0)
    b2 = default_band(FRF(f, h2))
    assert b2.hi_hz > 1150 * 1.2


def test_empty_band_is_an_error():
    f = np.arange(200.0, 3000.0, 2.0)
    frf = FRF(f, sdof(f), source="tip.csv")
    with pytest.raises(DataError, match="tip.csv.*contains no frequency line"):
        band_mask(frf, Band(5000.0, 6000.0, "user"))
    with pytest.raises(SetupError):
        Band(10.0, 5.0)


def test_natural_frequency_rule():
    # ln|h| exactly parabolic in f: the refinement recovers the vertex off the grid
    f = np.arange(900.0, 1100.0, 5.0)
    for f0 in (1001.3, 1003.7):
        h = np.exp(-((f - f0) / 40.0) ** 2)
        assert natural_frequency(f, h) == pytest.approx(f0, abs=1e-9)
    # SDOF: peak of |h| at fn sqrt(1 - 2 zeta^2); 2 Hz grid, refinement error < 0.05 Hz
    f = np.arange(500.0, 1500.0, 2.0)
    fn, z = 1000.0, 0.02
    assert natural_frequency(f, sdof(f, fn, z)) == pytest.approx(fn * math.sqrt(1 - 2 * z * z), abs=0.05)
    # vectorised over draws, identical to one-by-one
    fns = np.array([980.0, 1000.0, 1013.0])
    hs = np.stack([sdof(f, v, z) for v in fns])
    batch = natural_frequency(f, hs)
    assert np.array_equal(batch, [natural_frequency(f, h) for h in hs])
    # a maximum on the band edge is not a resonance inside the band
    assert np.isnan(natural_frequency(f, sdof(f, 1000.0), band=(1100.0, 1400.0)))


# -- likelihood ---------------------------------------------------------------


@pytest.fixture(scope="module")
def small_problem():
    cfg, camp = bench(seed=3, frequency_step=8.0)
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                         IdentificationOptions(lengths=(0.025, 0.040)))
    return cfg, camp, prob


def _reference_loglik(prob, theta):
    """Independent per-walker, per-line implementation of the documented likelihood."""
    out = []
    names = prob.parameters.names
    la, lb = prob.growth.l_a, prob.growth.l_b
    for t in theta:
        v = dict(zip(names, t))
        total = 0.0
        for j, obs in enumerate(prob.observations):
            l = obs.configuration.clamping_length
            kx = 10 ** v["k_xf"] * (1 + v["g_xf"] * (l - la) / (lb - la))
            kt = 10 ** v["k_thetaM"] * (1 + v["g_thetaM"] * (l - la) / (lb - la))
            h = prob.model.frf(obs.configuration, obs.frequency_hz, kx, kt, 10.0, 5e-4)
            s = 10 ** v[f"sigma_{j}"]
            hmax2 = np.max(np.abs(h) ** 2)
            for n in range(obs.n_lines):
                # proportional to the model's |H| (documented noise model), the floor from the model's band maximum
                var = s**2 * (abs(h[n]) ** 2 + 0.01**2 * hmax2) / obs.coherence[n]
                total += -abs(h[n] - obs.values[n]) ** 2 / var - math.log(math.pi * var)
        out.append(total)
    return np.array(out)


def test_likelihood_matches_reference_and_pointwise(small_problem):
    _, _, prob = small_problem
    rng = np.random.default_rng(5)
    theta = prob.priors.sample(rng, 4)
    theta[:, 0] = rng.uniform(6.1, 6.4, 4)  # near the data, where the terms are O(1), not O(1e6)
    theta[:, 1] = rng.uniform(5.4, 6.0, 4)
    theta[:, 4:] = np.log10(rng.uniform(0.01, 0.05, (4, 2)))
    ll = prob.likelihood(theta)
    ref = _reference_loglik(prob, theta)
    np.testing.assert_allclose(ll, ref, rtol=1e-10)
    pw = prob.likelihood.pointwise(theta)
    assert pw.shape == (4, prob.likelihood.n_lines)
    np.testing.assert_allclose(pw.sum(axis=1), ll, rtol=1e-10)
    tempered = prob.likelihood.with_tempering(0.25)
    np.testing.assert_allclose(tempered(theta), 0.25 * ll, rtol=1e-12)


def test_residual_correlation_length():
    rng = np.random.default_rng(0)
    n = 4000
    white = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    assert residual_correlation_length(white, [slice(0, n)]) == pytest.approx(1.0, abs=0.15)
    # AR(1) with phi = 0.8: tau = (1 + phi) / (1 - phi) = 9; the windowed estimator is within 20 %
    phi = 0.8
    e = rng.standard_normal((2, n))
    x = np.zeros(n, complex)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[0, i] + 1j * e[1, i]
    tau = residual_correlation_length(x, [slice(0, n // 2), slice(n // 2, n)])
    assert tau == pytest.approx(9.0, rel=0.2)


def test_deterministic_objective_matches_definition(small_problem):
    _, _, prob = small_problem
    obj = PercentageObjective(prob.likelihood)
    x = np.array([[6.25, 5.65, 0.45, 0.45], [6.3, 5.0, 0.1, 0.3]])
    got = obj(x)
    for i, xi in enumerate(x):
        terms = []
        for obs in prob.observations:
            l = obs.configuration.clamping_length
            s = (l - 0.025) / 0.015
            h = prob.model.frf(obs.configuration, obs.frequency_hz, 10 ** xi[0] * (1 + xi[2] * s),
                               10 ** xi[1] * (1 + xi[3] * s), 10.0, 5e-4)
            terms.append(np.mean(np.abs(h - obs.values) / np.abs(obs.values)))
        assert got[i] == pytest.approx(100 * np.mean(terms), rel=1e-12)


def test_problem_validation(small_problem):
    cfg, camp, _ = small_problem
    model, contact = bench_model(cfg, camp), contact_spec(camp)
    with pytest.raises(SetupError, match="method 'single' fits one clamping length"):
        build_problem(model, camp.measurements, contact, IdentificationOptions(method="single"))
    with pytest.raises(SetupError, match="no measurement at clamping length 33 mm"):
        build_problem(model, camp.measurements, contact, IdentificationOptions(lengths=(0.033,)))
    with pytest.raises(SetupError, match="outside the feasible clamping range"):
        build_problem(model, camp.measurements, contact, IdentificationOptions(lengths=(0.050,)))
    with pytest.raises(DataError, match="contains no frequency line"):
        build_problem(model, camp.measurements, contact, IdentificationOptions(band=(9000.0, 9500.0)))
    one = build_problem(model, camp.measurements, contact, IdentificationOptions(method="single", lengths=(0.030,)))
    assert one.parameters.names == ("k_xf", "k_thetaM", "sigma_0")  # constant contact, no growth
    assert not one.growth.has_growth


# -- checkpoint -------------------------------------------------------------


def test_checkpoint_roundtrip_mirror_and_emcee_layout(tmp_path):
    import emcee

    ck = Checkpoint(tmp_path / "chain.h5")
    ck.create(4, 3, {"fingerprint": {"a": 1}})
    rng = np.random.default_rng(0)
    rs = np.random.RandomState(7).get_state()
    a = rng.standard_normal((5, 4, 3))
    b = rng.standard_normal((3, 4, 3))
    ck.append(a, rng.standard_normal((5, 4)), np.ones(4), rs)
    ck.append(b, rng.standard_normal((3, 4)), np.ones(4), rs)
    st = ck.open()
    assert st.iteration == 8
    np.testing.assert_array_equal(st.chain, np.concatenate([a, b]))
    assert st.meta == {"fingerprint": {"a": 1}}
    np.testing.assert_array_equal(st.accepted, 2 * np.ones(4))
    r2 = np.random.RandomState()
    r2.set_state(st.random_state)
    assert r2.randint(1 << 30) == np.random.RandomState(7).randint(1 << 30)
    # emcee's own backend reads it
    be = emcee.backends.HDFBackend(str(tmp_path / "chain.h5"), read_only=True)
    assert be.iteration == 8
    np.testing.assert_array_equal(be.get_chain(), st.chain)
    # a destroyed primary is restored from the mirror
    (tmp_path / "chain.h5").write_bytes(b"garbage, as after a kill during a metadata flush")
    st2 = ck.open()
    np.testing.assert_array_equal(st2.chain, st.chain)
    assert Checkpoint._read(tmp_path / "chain.h5") is not None


def test_prior_errors_name_the_key_and_keep_the_reason():
    # a constructor's own check (sigma <= 0) must not be reported as "parameters must be numbers"
    with pytest.raises(SetupError, match=r"priors\.k_xf: log-normal .*sigma=-1"):
        prior_from_spec({"distribution": "log-normal", "median": 1e6, "sigma": -1}, "priors.k_xf")
    with pytest.raises(SetupError, match=r"priors\.k_xf = \['a', 3\]: expected a \[lo, hi\] pair of numbers"):
        prior_from_spec(["a", 3], "priors.k_xf")
    with pytest.raises(SetupError, match=r"contact\.translational_stiffness: log-uniform prior bounds"):
        prior_from_spec([5, 1], "contact.translational_stiffness")
