"""The parameter model, the model terms and the batched forward model (bayes_rcsa.params).

Reference computations here are written independently of the library: a
mass at a two-port's end by inverting the 4x4 receptance matrix (instead of
the Woodbury update), and the tip-mass frequency shift against the
synthetic bench's finite-element model with its own point mass.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.errors import DataError, SetupError
from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.outputs import write_outputs
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem
from bayes_rcsa.model import Configuration, ConfigurationStack
from bayes_rcsa.model.natural_frequencies import natural_frequency
from bayes_rcsa.params import (
    ForwardModel, GrowthLaw, LogNormal, LogUniform, ModelTerm, Parameter, ParameterModel, Uniform, known_terms,
    make_term, register_term,
)
from bayes_rcsa.params.terms import TERMS
from bayes_rcsa.model.coupling import add_end_impedance
from bayes_rcsa.posterior import load_posterior
from bayes_rcsa.posterior.predict import predictive_frf
from bayes_rcsa.synthetic import default_bench_config, true_tool_point_frf

from test_inference_support import bench, bench_model, contact_spec, quick_settings

PRIORS = {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e4, 1e8), "g_xf": Uniform(0.0, 0.5),
          "g_thetaM": Uniform(0.0, 0.5)}
FIXED = {"c_xf": 10.0, "c_thetaM": 5e-4}


@pytest.fixture(scope="module")
def campaign():
    return bench(seed=3)


def _values(rng, n):
    return {"k_xf": 10 ** rng.uniform(6.0, 6.6, n), "k_thetaM": 10 ** rng.uniform(5.3, 6.0, n),
            "g_xf": rng.uniform(0, 0.5, n), "g_thetaM": rng.uniform(0, 0.5, n),
            "c_xf": np.full(n, 10.0), "c_thetaM": np.full(n, 5e-4)}


# -- the parameter model ---------------------------------------------------------------------


def test_parameter_model_round_trip_and_vector_order():
    pm = ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5),
                                    {**PRIORS, "c_xf": LogNormal(10.0, 0.5, 1.0, 100.0), "sigma_0": LogUniform(1e-4, 10)},
                                    {"c_thetaM": 5e-4}, terms=["tip_mass"], n_measurements=1)
    assert pm.names == ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "sigma_0", "tip_mass_kg")
    assert pm.physical_names == ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "tip_mass_kg")
    text = json.dumps(pm.to_dict())
    back = ParameterModel.from_dict(json.loads(text))
    assert back == pm and back.to_dict() == pm.to_dict()
    theta = pm.priors.sample(np.random.default_rng(0), 7)
    a, b = pm.values(theta), back.values(theta)
    assert set(a) == set(pm.all_names)
    for n in a:
        np.testing.assert_array_equal(a[n], b[n])
    assert np.all(a["c_thetaM"] == 5e-4) and pm.unit("tip_mass_kg") == "kg"
    # contact: growth law k(l) = k(l_a) (1 + g (l - l_a)/(l_b - l_a)), written out independently
    c = pm.contact(a, [0.025, 0.0325, 0.040])
    np.testing.assert_allclose(c.k_xf[:, 1], a["k_xf"] * (1 + 0.5 * a["g_xf"]), rtol=1e-14)
    np.testing.assert_allclose(c.k_thetaM[:, 2], a["k_thetaM"] * (1 + a["g_thetaM"]), rtol=1e-14)
    bad = pm.to_dict()
    bad["terms"] = ["no_such_term"]
    with pytest.raises(DataError, match="no_such_term.*known"):
        ParameterModel.from_dict(bad)


def test_model_table_terms_and_overrides_are_validated(campaign):
    cfg, camp = campaign
    model = bench_model(cfg, camp)
    ok = build_problem(model, camp.measurements, contact_spec(camp),
                       IdentificationOptions(lengths=(0.025,), model={"terms": ["tip_mass"], "tip_mass_kg": [0.0, 0.005]}))
    pm = ok.parameters
    assert "tip_mass_kg" in pm.names and pm.priors["tip_mass_kg"] == Uniform(0.0, 0.005)
    fixed = build_problem(model, camp.measurements, contact_spec(camp),
                          IdentificationOptions(lengths=(0.025,), model={"terms": ["tip_mass"], "tip_mass_kg": 0.002}))
    assert fixed.parameters.fixed["tip_mass_kg"] == 0.002 and "tip_mass_kg" not in fixed.parameters.names
    with pytest.raises(SetupError, match=r"unknown model term 'tip_mas'.*known: .*tip_mass"):
        build_problem(model, camp.measurements, contact_spec(camp), IdentificationOptions(model={"terms": ["tip_mas"]}))
    with pytest.raises(SetupError, match="unknown parameter.*tip_mass_kg"):
        build_problem(model, camp.measurements, contact_spec(camp), IdentificationOptions(model={"tip_mass_kg": 0.001}))
    with pytest.raises(SetupError, match="both"):
        build_problem(model, camp.measurements, contact_spec(camp),
                      IdentificationOptions(priors={"c_xf": [1, 100]}, model={"c_xf": 5.0}))


# -- terms at their baseline -----------------------------------------------------------------


def test_every_registered_term_at_its_baseline_reproduces_the_baseline_frf(campaign):
    cfg, camp = campaign
    model = bench_model(cfg, camp)
    f = np.linspace(600.0, 1800.0, 240)
    stack = ConfigurationStack([model.precompute(Configuration(l), f) for l in (0.025, 0.040)])
    growth = GrowthLaw(0.025, 0.040, 0.5)
    base = ForwardModel(ParameterModel.from_priors(growth, PRIORS, FIXED), stack, model)
    values = _values(np.random.default_rng(1), 9)
    h0 = base.frf(values)
    assert len(known_terms()) >= 1
    for name in known_terms():
        term = make_term(name)
        params = term.parameters(model)
        assert params, name
        baseline = {p.name: p.baseline for p in params}
        assert all(v is not None for v in baseline.values()), (name, baseline)
        pm = ParameterModel.from_priors(growth, PRIORS, {**FIXED, **baseline}, terms=[term], model=model)
        h = ForwardModel(pm, stack, model).frf({**values, **{k: np.full(9, v) for k, v in baseline.items()}})
        # "exactly" up to round-off of a recomputed coupling (a term may rebuild a substructure)
        np.testing.assert_allclose(h, h0, rtol=1e-12, atol=0, err_msg=name)


# -- tip mass --------------------------------------------------------------------------------


def test_tip_impedance_equals_inverting_the_full_receptance_matrix(campaign):
    cfg, camp = campaign
    model = bench_model(cfg, camp)
    f = np.linspace(500.0, 3500.0, 50)
    tool = model.precompute(Configuration(0.030), f).tool
    m, j = 0.004, 0.004 * 0.004**2
    w2 = (2 * np.pi * f) ** 2
    got = add_end_impedance(tool, (-m * w2)[None, :], (-j * w2)[None, :])
    for i in range(f.size):
        # independent: the 4x4 receptance R of both ends, dynamic stiffness R^-1 plus the mass, inverted again
        r = np.block([[tool.r11[i], tool.r12[i]], [tool.r21[i], tool.r22[i]]])
        d = np.linalg.inv(r) + np.diag([0.0, 0.0, -m * w2[i], -j * w2[i]])
        ref = np.linalg.inv(d)
        np.testing.assert_allclose(got.r11[0, i], ref[:2, :2], rtol=1e-8, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(got.r12[0, i], ref[:2, 2:], rtol=1e-8, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(got.r22[0, i], ref[2:, 2:], rtol=1e-8, atol=1e-12 * np.abs(ref).max())
    # reciprocity of the loaded two-port: R21 = R12^T, R11 and R22 symmetric
    np.testing.assert_allclose(got.r21, np.swapaxes(got.r12, -1, -2), rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(got.r22, np.swapaxes(got.r22, -1, -2), rtol=1e-10, atol=1e-14)


def test_tip_mass_shift_matches_the_finite_element_bench_and_stays_passive():
    """The RCSA tip-mass term moves the tool mode as the bench's FE point mass does."""
    mass = 0.006  # kg, a large accelerometer: a shift of tens of Hz
    plain = default_bench_config(directions=("x",))
    loaded = default_bench_config(directions=("x",), hidden_effects={"tip_mass": mass})
    assert loaded.tip_mass_radius_of_gyration == pytest.approx(0.5 * plain.tool.segments[-1].diameter, rel=0.01)
    cfg, camp = bench(seed=0)
    model = bench_model(cfg, camp)
    f = np.arange(700.0, 1700.0, 1.0)
    length = 0.030
    stack = ConfigurationStack([model.precompute(Configuration(length), f)])
    from bayes_rcsa.synthetic import true_contact

    tc = true_contact(plain, length)
    contact = {"k_xf": np.array([tc["k_xf"]]), "k_thetaM": np.array([tc["k_thetaM"]]), "g_xf": np.zeros(1),
               "g_thetaM": np.zeros(1), "c_xf": np.array([tc["c_xf"]]), "c_thetaM": np.array([tc["c_thetaM"]])}
    pm = ParameterModel.from_priors(GrowthLaw(length, length), {"k_xf": PRIORS["k_xf"]},
                                    {k: float(v[0]) for k, v in contact.items() if k != "k_xf"}, terms=["tip_mass"])
    fwd = ForwardModel(pm, stack, model)
    h0 = fwd.frf({**contact, "tip_mass_kg": np.zeros(1)})[0]
    h1 = fwd.frf({**contact, "tip_mass_kg": np.array([mass])})[0]
    shift_rcsa = natural_frequency(f, h1) - natural_frequency(f, h0)
    fe0 = true_tool_point_frf(plain, Configuration(length), f)
    fe1 = true_tool_point_frf(loaded, Configuration(length), f)
    shift_fe = natural_frequency(f, fe1) - natural_frequency(f, fe0)
    assert shift_fe < -10.0  # the mass lowers the tool mode noticeably
    # measured: -115.216 Hz (RCSA) vs -115.220 Hz (FE), 4e-5 apart; the models' own mode differs by 2e-6
    # relative, so 1e-3 leaves room for the FE mesh and still catches a wrong inertia (r_g^2 moves it ~1e-2)
    assert shift_rcsa == pytest.approx(shift_fe, rel=1e-3)
    # passive point receptance (Im h <= 0 with e^{+iwt}) with the mass
    assert np.all(h1.imag <= 0)


# -- a toy term registered from this file: the extension point is one registration ----------------


class _SensorGain(ModelTerm):
    """Toy FRF term: a calibration gain error of the hammer/sensor chain, h -> (1 + a) h."""

    name = "toy_sensor_gain"
    kind = "frf"
    description = "calibration gain error of the measurement chain (test-only term)"

    def parameters(self, model):
        return (Parameter("toy_gain", "1", "term", prior=Uniform(-0.3, 0.3), baseline=0.0),)

    def frf(self, values, h, ctx):
        return h * (1.0 + np.asarray(values["toy_gain"], dtype=float))[:, None]


@pytest.fixture()
def toy_term():
    register_term(_SensorGain)
    yield _SensorGain
    TERMS.unregister(_SensorGain.name)


def test_toy_term_identify_write_reload_predict(toy_term, tmp_path):
    cfg, camp = bench(seed=5, frequency_step=1.0)
    # the measurements carry a known gain error of +12 %: the toy term should find it
    meas = [(c, type(frf)(frf.frequency_hz, 1.12 * frf.values, frf.coherence, frf.source)) for c, frf in camp.measurements]
    model = bench_model(cfg, camp)
    prob = build_problem(model, meas, contact_spec(camp),
                         IdentificationOptions(lengths=(0.025, 0.040), model={"terms": [toy_term.name]}))
    assert "toy_gain" in prob.parameters.names
    res = identify(prob, seed=4, settings=quick_settings(n_walkers=18, max_steps=400, check_every=100, ess_min=50))
    write_outputs(res, tmp_path, plots=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "toy_gain" in summary["parameters"] and summary["parameter_model"]["terms"] == [toy_term.name]
    gain = summary["parameters"]["toy_gain"]
    # the gain is confounded with the stiffness only weakly (peak position fixes k); a 90 % interval covers it
    assert gain["q05"] < 0.12 < gain["q95"], gain
    draws = load_posterior(tmp_path / "posterior.nc")
    assert draws.parameters.term_names == (toy_term.name,) and "toy_gain" in draws.sampled
    # prediction at an unmeasured length uses the term: equals the manual evaluation with the gain applied
    f = np.linspace(600.0, 1800.0, 200)
    sub = draws.subset(50, np.random.default_rng(0))
    h = predictive_frf(sub, model, Configuration(0.030), f)
    kx, kt, cx, ct = sub.contact([0.030])[:4]
    manual = model.precompute(Configuration(0.030), f).frf(kx[:, 0], kt[:, 0], cx[:, 0], ct[:, 0])
    np.testing.assert_allclose(h, manual * (1 + sub.values["toy_gain"])[:, None], rtol=1e-12)
    assert not np.allclose(h, manual)


def test_tip_kernel_equals_coupling_the_loaded_tool(campaign):
    """Compiled tip attachment after the joint == the loaded tool two-port coupled by the general 2x2 algebra."""
    from bayes_rcsa.model.coupling import attach, contact_compliance

    cfg, camp = campaign
    model = bench_model(cfg, camp)
    f = np.linspace(600.0, 1800.0, 120)
    lengths = (0.025, 0.040)
    caches = [model.precompute(Configuration(l), f) for l in lengths]
    pm = ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5), PRIORS, FIXED, terms=["tip_mass"])
    rng = np.random.default_rng(2)
    values = {**_values(rng, 6), "tip_mass_kg": rng.uniform(0.0, 0.02, 6)}
    h = ForwardModel(pm, ConfigurationStack(caches), model).frf(values)
    c = pm.contact(values, lengths)
    for i, cache in enumerate(caches):
        rg = 0.5 * model.tool("tool").segments[-1].diameter
        w2 = cache.omega**2
        m = values["tip_mass_kg"][:, None]
        loaded = add_end_impedance(cache.tool, -m * w2, -m * rg**2 * w2)  # (6, n, 2, 2) blocks
        comp = contact_compliance(cache.omega, c.k_xf[:, i], c.k_thetaM[:, i], c.c_xf[:, i], c.c_thetaM[:, i])
        ref = attach(cache.holder_tip, loaded, comp)[..., 0, 0]
        np.testing.assert_allclose(h[:, i * f.size:(i + 1) * f.size], ref, rtol=1e-9)
