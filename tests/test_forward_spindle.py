"""Spindle receptance samples as an input of the forward model: identify's summary, predict and lobes.

The reference evaluations here build one :class:`ToolPointModel` per spindle sample (the setup's
holder and tool with the sample as its spindle file) and evaluate every draw on its own sample's
model, one sample at a time -- the way the samples were used before they became an input of
:class:`ForwardModel` (``spindle.uncertainty.variant_stacks`` / ``mixed_stack_frf``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import norm

from bayes_rcsa.data import example_dir
from bayes_rcsa.errors import SetupError
from bayes_rcsa.inference.diagnostics import build_inference_data
from bayes_rcsa.store import write_posterior
from bayes_rcsa.io import load_setup
from bayes_rcsa.model import Configuration, ConfigurationStack, ToolPointModel
from bayes_rcsa.model.natural_frequencies import natural_frequency
from bayes_rcsa.model.receptance import PointReceptance
from bayes_rcsa.params import (ForwardModel, GrowthLaw, LogUniform, ModelTerm, Parameter, ParameterModel, Uniform,
                               register_term)
from bayes_rcsa.params.terms import TERMS
from bayes_rcsa.spindle import SpindleSamples, assign_samples

SETUP = example_dir() / "setup.toml"
GROWTH = GrowthLaw(0.025, 0.040, 0.5)
PRIORS = {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8), "g_xf": Uniform(0.0, 0.5),
          "g_thetaM": Uniform(0.0, 0.5)}
FIXED = {"c_xf": 10.0, "c_thetaM": 5e-4}
CONFIGS = (Configuration(0.025, "x", "tool"), Configuration(0.040, "y", "tool"))
# relative spindle-mode shifts of the stretched samples: the 20 normal quantiles of sd 2 % (symmetric, zero mean).
# A spindle whose bearings are stiffer or softer moves its flange modes, and with them the example's tool mode
# by about 40 Hz per unit shift, so the samples alone spread the mode over a 90 % width of about 2.4 Hz.
STRETCH = 0.02 * norm.ppf((np.arange(20) + 0.5) / 20)


@pytest.fixture(scope="module")
def setup():
    return load_setup(SETUP)


def _stretched(setup, stretch) -> SpindleSamples:
    """Samples S_j(f) = S(f / (1 + e_j)): the flange modes moved by the factor 1 + e_j."""
    f = setup.spindle["x"].frequency_hz
    nominal = {d: setup.spindle[d].interpolate(f) for d in ("x", "y")}
    blocks = {d: np.stack([PointReceptance(f, nominal[d]).interpolate(np.clip(f / (1 + e), f[0], f[-1]))
                           for e in stretch]) for d in nominal}
    return SpindleSamples(f, nominal, blocks, {"test": "stretched"}, source="stretched.npz")


@pytest.fixture(scope="module")
def samples(setup):
    return _stretched(setup, STRETCH)


@pytest.fixture(scope="module")
def identical(setup):
    """One sample, equal to the setup's own spindle files."""
    f = setup.spindle["x"].frequency_hz
    nominal = {d: setup.spindle[d].interpolate(f) for d in ("x", "y")}
    return SpindleSamples(f, nominal, {d: nominal[d][None] for d in nominal}, source="identical.npz")


def _variant(model: ToolPointModel, samples: SpindleSamples, j: int) -> ToolPointModel:
    return ToolPointModel(model.holder, model.tools, {**model.spindle, **samples.spindle(j)})


def _lines(setup):
    f = setup.spindle["x"].frequency_hz
    return f[(f >= 700.0) & (f <= 1400.0)]


def _values(rng, n, **extra):
    return {"k_xf": 1.8e6 * np.exp(rng.normal(0, 0.01, n)), "k_thetaM": 4.5e5 * np.exp(rng.normal(0, 0.05, n)),
            "g_xf": rng.uniform(0.4, 0.5, n), "g_thetaM": rng.uniform(0.4, 0.5, n),
            "c_xf": np.full(n, 10.0), "c_thetaM": np.full(n, 5e-4), **extra}


def _reference(pm, model, samples, configs, f, values, assignment):
    """Every set on a model built with its own sample (one plain ForwardModel per sample)."""
    n = assignment.size
    out = None
    for j in np.unique(assignment):
        rows = np.flatnonzero(assignment == j)
        variant = _variant(model, samples, int(j))
        stack = ConfigurationStack([variant.precompute(c, f) for c in configs])
        h = ForwardModel(pm, stack, variant).frf({k: np.asarray(v)[rows] for k, v in values.items()})
        out = np.empty((n, h.shape[1]), complex) if out is None else out
        out[rows] = h
    return out


# -- (a) the forward model ---------------------------------------------------------------------------


def test_one_sample_equal_to_the_setup_spindle_gives_the_plain_forward_model(setup, identical, samples):
    model, f = setup.model(), _lines(setup)
    stack = ConfigurationStack([model.precompute(c, f) for c in CONFIGS])
    pm = ParameterModel.from_priors(GROWTH, PRIORS, FIXED)
    values = _values(np.random.default_rng(0), 40)
    plain, mixed = _compare_with_references(pm, model, stack, f, values, identical, samples, rtol=1e-13)
    assert np.max(np.abs(mixed - plain) / np.abs(plain)) > 0.05  # the samples do change the FRFs


def _compare_with_references(pm, model, stack, f, values, identical, samples, rtol):
    """The identical sample equals the plain forward model; several samples equal the per-sample references."""
    n = len(values["k_xf"])
    plain = ForwardModel(pm, stack, model).frf(values)
    same = ForwardModel(pm, stack, model, spindle_samples=identical).frf(values, np.zeros(n, dtype=int))
    np.testing.assert_allclose(same, plain, rtol=rtol, atol=0)
    # several samples: every set equals its evaluation on a model built with its own sample
    assignment = assign_samples(n, samples.n_samples, np.random.default_rng(3))
    mixed = ForwardModel(pm, stack, model, spindle_samples=samples).frf(values, assignment)
    np.testing.assert_allclose(mixed, _reference(pm, model, samples, CONFIGS, f, values, assignment),
                               rtol=rtol, atol=0)
    return plain, mixed


def test_bad_assignments_and_uncovered_lines_are_refused(setup, samples):
    model, f = setup.model(), _lines(setup)
    stack = ConfigurationStack([model.precompute(c, f) for c in CONFIGS])
    pm = ParameterModel.from_priors(GROWTH, PRIORS, FIXED)
    values = _values(np.random.default_rng(0), 4)
    with pytest.raises(SetupError, match="without spindle_samples"):
        ForwardModel(pm, stack, model).frf(values, np.zeros(4, dtype=int))
    fm = ForwardModel(pm, stack, model, spindle_samples=samples)
    for bad in (np.array([0, 1, 2, 20]), np.zeros(3, dtype=int), np.zeros(4)):
        with pytest.raises(SetupError, match="stretched.npz: spindle_sample must hold 4 integer"):
            fm.frf(values, bad)
    narrow = SpindleSamples(f[:50], {"x": samples.nominal["x"][:50]}, {"x": samples.samples["x"][:, :50]},
                            source="narrow.npz")
    with pytest.raises(SetupError, match=r"narrow.npz: the spindle samples cover .* needs 700-1400 Hz"):
        ForwardModel(pm, stack, model, spindle_samples=narrow)


# -- (b) model terms ---------------------------------------------------------------------------------


class _FlangeScale(ModelTerm):
    """Toy spindle term: the flange receptance scaled, S -> (1 + a) S (a softer or stiffer spindle)."""

    name = "toy_flange_scale"
    kind = "spindle"
    description = "flange receptance scaled (test-only term)"

    def parameters(self, model):
        return (Parameter("toy_flange", "1", "term", prior=Uniform(-0.3, 0.3), baseline=0.0),)

    def spindle(self, values, spindle, ctx):
        return spindle * (1.0 + self.batch(values, "toy_flange"))[..., None]


@pytest.fixture()
def flange_term():
    register_term(_FlangeScale)
    yield _FlangeScale
    TERMS.unregister(_FlangeScale.name)


@pytest.mark.parametrize("terms", [["tip_mass"], ["tip_mass", "toy_flange_scale"]])
def test_model_terms_act_on_each_sample_as_without_samples(setup, identical, flange_term, terms):
    samples = _stretched(setup, STRETCH[::4])
    model, f = setup.model(), _lines(setup)
    stack = ConfigurationStack([model.precompute(c, f) for c in CONFIGS])
    pm = ParameterModel.from_priors(GROWTH, PRIORS, FIXED, terms=terms, model=model)
    rng = np.random.default_rng(5)
    values = _values(rng, 30, tip_mass_kg=rng.uniform(0.002, 0.01, 30), toy_flange=rng.uniform(-0.2, 0.2, 30))
    plain, _ = _compare_with_references(pm, model, stack, f, values, identical, samples, rtol=1e-12)
    without = ForwardModel(pm, stack, model).frf({**values, "tip_mass_kg": np.zeros(30), "toy_flange": np.zeros(30)})
    assert np.max(np.abs(plain - without) / np.abs(without)) > 0.05  # the terms are active


# -- (c) predict, (d) lobes: from a posterior file ---------------------------------------------------


@pytest.fixture(scope="module")
def posterior(tmp_path_factory):
    """posterior.nc of 4 x 100 draws around the example's contact (tool mode 90 % interval about 1 Hz)."""
    pm = ParameterModel.from_priors(GROWTH, {**PRIORS, "sigma_0": LogUniform(1e-4, 10)}, FIXED, n_measurements=1)
    rng = np.random.default_rng(0)
    shape = (4, 100)
    post = {"k_xf": 1.8e6 * np.exp(rng.normal(0, 0.001, shape)), "k_thetaM": 4.5e5 * np.exp(rng.normal(0, 0.02, shape)),
            "g_xf": rng.normal(0.45, 0.0005, shape), "g_thetaM": rng.normal(0.45, 0.01, shape),
            "sigma_0": rng.uniform(0.02, 0.025, shape)}
    idata = build_inference_data(post, np.zeros(shape), np.zeros(shape + (3,)), np.ones(3, complex),
                                 {"fit_clamping_length": np.array([0.025, 0.040])}, {"fit_clamping_length": ["fm"]},
                                 {"fm": ["a", "b"]}, {"method": "multi", "parameter_model": json.dumps(pm.to_dict())})
    return write_posterior(idata, tmp_path_factory.mktemp("post") / "posterior.nc")


@pytest.fixture(scope="module")
def predictions(setup, posterior, samples):
    from bayes_rcsa.posterior.prediction_outputs import run_prediction

    kw = dict(directions=["x"], max_draws=300, seed=1)
    plain = run_prediction(setup, posterior, [0.025, 0.040], **kw)
    mixed = run_prediction(setup, posterior, [0.025, 0.040], spindle_samples=samples, **kw)
    return plain, mixed


def test_predict_with_spindle_samples_widens_the_natural_frequency_interval(setup, predictions, samples):
    from bayes_rcsa.posterior.prediction_outputs import frequencies_document

    plain, mixed = predictions
    # the same draws (the assignment has a stream of its own)
    for name, v in plain.draws.values.items():
        np.testing.assert_array_equal(mixed.draws.values[name], v)
    assert "spindle_uncertainty" not in plain.meta and plain.prediction.spindle_uncertainty is None
    assert mixed.meta["spindle_uncertainty"] == {"file": "stretched.npz", "n_samples": 20, "directions": ["x", "y"]}
    assert frequencies_document(mixed)["spindle_uncertainty"]["n_samples"] == 20
    model = setup.model()
    median = {k: np.median(v) for k, v in plain.draws.values.items()}
    checked = 0
    for a, b in zip(plain.prediction.modes, mixed.prediction.modes):
        if not a.dominant:
            continue
        cfg = a.configuration
        w_plain = a.natural_frequency_hz["q95"] - a.natural_frequency_hz["q05"]
        w_mixed = b.natural_frequency_hz["q95"] - b.natural_frequency_hz["q05"]
        # the spindle samples' own spread of the tool mode: the median contact on each sample's model
        f = _measured_lines(setup, cfg)  # the lines predict uses at a measured length
        kx, kt, cx, ct = plain.draws.parameters.contact({k: np.atleast_1d(v) for k, v in median.items()},
                                                        [cfg.clamping_length])[:4]
        fn = np.array([natural_frequency(f, _variant(model, samples, j).frf(cfg, f, kx[0, 0], kt[0, 0], cx[0, 0],
                                                                           ct[0, 0]), a.band_hz)
                       for j in range(samples.n_samples)])
        w_spindle = np.quantile(fn, 0.95) - np.quantile(fn, 0.05)
        assert w_spindle > 1.5 * w_plain  # by construction: the spindle dominates
        # independent contributions add in variance: width ~ sqrt(w_plain^2 + w_spindle^2); the 90 % widths of 300
        # draws carry ~10 % Monte Carlo error and the 20-sample spread is not Gaussian, hence +-25 %
        expected = np.hypot(w_plain, w_spindle)
        assert 0.75 * expected < w_mixed < 1.25 * expected, (cfg, w_plain, w_spindle, w_mixed)
        assert w_mixed > 1.5 * w_plain
        # zero-mean mode shifts: the median moves by a small fraction of the spindle spread
        assert abs(b.natural_frequency_hz["q50"] - a.natural_frequency_hz["q50"]) < 0.15 * w_spindle
        checked += 1
    assert checked == 2


def _measured_lines(setup, cfg):
    for m in setup.measurements:
        if m.configuration == cfg:
            f = m.frf.frequency_hz
            s = setup.spindle[cfg.direction].frequency_hz
            return f[(f >= s[0]) & (f <= s[-1])]
    raise AssertionError(cfg)


def test_posterior_mode_lobes_include_the_spindle_samples(posterior, samples, identical):
    from bayes_rcsa.stability import CuttingConditions, lobes_from_frf_draws
    from bayes_rcsa.stability.posterior_frf import posterior_frf_draws

    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, milling="down", feed="y")
    speeds = np.linspace(8000, 30000, 120)
    depths = np.linspace(1.9e-5, 3.2e-5, 200)  # m, around the lowest limits (20-30 um): where P(stable) changes

    def run(spindle_samples):
        rng = np.random.default_rng(5)
        frf = posterior_frf_draws(SETUP, posterior, 0.030, 60, rng, spindle_samples=spindle_samples)
        res = lobes_from_frf_draws(frf.frf_x, frf.frf_y, frf.frequency_hz, cut, speeds, depths_m=depths)
        return frf, res, rng.random()

    plain, p_plain, after_plain = run(None)
    same, p_same, after_same = run(identical)
    mixed, p_mixed, after_mixed = run(samples)
    assert after_plain == after_same == after_mixed  # the caller's stream is not consumed by the assignment
    assert "spindle_uncertainty" not in plain.source
    assert mixed.source["spindle_uncertainty"] == samples.describe()
    assert same.source["spindle_uncertainty"]["n_samples"] == 1
    # the identical sample reproduces the plain draws and map; stretched samples change them
    np.testing.assert_allclose(same.frf_x, plain.frf_x, rtol=1e-13, atol=0)
    np.testing.assert_allclose(same.frf_y, plain.frf_y, rtol=1e-13, atol=0)
    np.testing.assert_array_equal(p_same.p_stable, p_plain.p_stable)
    assert not np.array_equal(p_mixed.p_stable, p_plain.p_stable)
    # more uncertainty in the dynamics: the per-draw limits scatter more (measured: 0.26 % -> 0.70 % of the
    # limit, median over speeds) and the band of cells where stability is uncertain widens (measured 215 -> 619)
    scatter = lambda r: np.median(np.std(r.depth_limit_m, axis=0) / np.mean(r.depth_limit_m, axis=0))  # noqa: E731
    assert scatter(p_mixed) > 2 * scatter(p_plain)
    uncertain = lambda r: np.count_nonzero((r.p_stable > 0.05) & (r.p_stable < 0.95))  # noqa: E731
    assert uncertain(p_mixed) > 2 * uncertain(p_plain), (uncertain(p_mixed), uncertain(p_plain))


# -- (e) identify's summary --------------------------------------------------------------------------


@pytest.mark.parametrize("terms", [[], ["tip_mass"]])
def test_identify_summary_mixes_the_samples_as_before(setup, terms):
    from bayes_rcsa.inference.identify import _evaluation_stack, _predicted_natural_frequencies
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup

    samples = _stretched(setup, STRETCH[::4])
    options = IdentificationOptions(lengths=(0.025, 0.040), model={"terms": terms} if terms else {})
    problem = build_problem_from_setup(setup, options)
    pm = problem.parameters
    rng = np.random.default_rng(2)
    values = _values(rng, 60, **{n: np.full(60, 0.02) for n in pm.noise_names})
    theta = pm.priors.sample(rng, 60)  # the term's parameters from their prior, the contact near the example's
    for i, n in enumerate(pm.names):
        if n in values:
            theta[:, i] = pm.priors[n].to_sampling(values[n])
    stack, _, _ = _evaluation_stack(problem)
    nat = _predicted_natural_frequencies(problem, stack, theta, batch=25, spindle_samples=samples,
                                         rng=np.random.default_rng(9))
    # the old way: the same balanced assignment from the same generator, each draw on its sample's model
    assignment = assign_samples(60, samples.n_samples, np.random.default_rng(9))
    configs = [c.configuration for c in stack.caches]
    ref = np.empty_like(nat)
    for j in np.unique(assignment):
        rows = np.flatnonzero(assignment == j)
        variant = _variant(problem.model, samples, int(j))
        vstack = ConfigurationStack([variant.precompute(c.configuration, c.frequency_hz) for c in stack.caches])
        h = ForwardModel(pm, vstack, variant).frf(pm.values(theta[rows]))
        for k, (part, cache) in enumerate(zip(vstack.split(h), vstack.caches)):
            ref[rows, k] = natural_frequency(cache.frequency_hz, part)
    np.testing.assert_array_equal(nat, ref)
    plain = _predicted_natural_frequencies(problem, stack, theta, batch=25)
    assert len(configs) == nat.shape[1] and np.nanmax(np.abs(nat - plain)) > 0.5  # Hz: samples mixed in
