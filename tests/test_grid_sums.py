"""The start search's fused grid evaluation equals the forward model followed by the residual sums.

``ForwardModel.grid_sums`` rearranges the joint formula (for one translational joint the FRF is a Moebius map of
the rotational one) so that the grid search never forms the FRFs.  It must give the sums of :meth:`frf` for every
term that keeps the joint separable, decline (None) wherever it cannot, and the search's maps must not depend on
which path made them.  ``ForwardModel.grid_profile_sums`` does the same for the exact grid (the likelihood's own
variance of the model FRF, each noise scale profiled), which the optimum search uses once the noise is large.
"""

from __future__ import annotations

import numpy as np
import pytest

import bayes_rcsa.inference.search as search
from bayes_rcsa import identify
from bayes_rcsa.data import example_dir
from bayes_rcsa.inference.likelihood import noise_variance, weighted_sums
from bayes_rcsa.model import Configuration, ConfigurationStack
from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel, Uniform, known_terms, make_term

from test_inference_support import bench, bench_model

PRIORS = {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e4, 1e8), "g_xf": Uniform(0.0, 0.5),
          "g_thetaM": Uniform(0.0, 0.5)}
FIXED = {"c_xf": 10.0, "c_thetaM": 5e-4}
N_X, N_T = 7, 5


@pytest.fixture(scope="module")
def stack_and_model():
    cfg, camp = bench(seed=3)
    model = bench_model(cfg, camp)
    f = np.linspace(600.0, 1800.0, 97)
    stack = ConfigurationStack([model.precompute(Configuration(length), f) for length in (0.025, 0.040)])
    return stack, model


def _grid_values(rng, extra):
    kx = 10 ** np.linspace(6.0, 6.6, N_X)
    kt = 10 ** np.linspace(5.3, 6.0, N_T)
    n = N_X * N_T
    values = {"k_xf": np.repeat(kx, N_T), "k_thetaM": np.tile(kt, N_X), "g_xf": np.zeros(n), "g_thetaM": np.zeros(n),
              "c_xf": np.full(n, 10.0), "c_thetaM": np.full(n, 5e-4)}
    values.update({k: np.full(n, v) for k, v in extra.items()})
    return values


def _reference(fwd, values, data, weight):
    r = fwd.frf(values) - data
    slices = [slice(2 * s.start, 2 * s.stop) for s in fwd.stack.slices]
    return weighted_sums(r, np.repeat(weight, 2), slices).reshape(N_X, N_T, -1)


def _profile_reference(fwd, values, data, coherence, eps2):
    h = fwd.frf(values)
    v = noise_variance(h.real**2 + h.imag**2, coherence, eps2, fwd.stack.slices)
    r2 = np.abs(h - data) ** 2
    q = np.stack([np.sum(r2[:, sl] / v[:, sl], axis=1) for sl in fwd.stack.slices], axis=1)
    lv = np.stack([np.sum(np.log(v[:, sl]), axis=1) for sl in fwd.stack.slices], axis=1)
    return q.reshape(N_X, N_T, -1), lv.reshape(N_X, N_T, -1)


def test_fused_sums_equal_the_forward_model_for_every_term_that_keeps_the_joint_separable(stack_and_model):
    stack, model = stack_and_model
    rng = np.random.default_rng(11)
    growth = GrowthLaw(0.025, 0.040, 0.5)
    base = ForwardModel(ParameterModel.from_priors(growth, PRIORS, FIXED), stack, model)
    h0 = base.frf({k: v[:1] for k, v in _grid_values(rng, {}).items()})[0]
    data = h0 * (1 + 0.05 * rng.standard_normal(h0.size)) + 0.02 * np.abs(h0).max() * rng.standard_normal(h0.size)
    weight = rng.uniform(0.5, 2.0, h0.size)
    coherence = rng.uniform(0.6, 1.0, h0.size)
    fused, profiled = {}, {}
    for name in (None, *known_terms()):
        extra, terms = {}, []
        if name is not None:
            term = make_term(name)
            terms = [term]
            for p in term.parameters(model):
                # off the baseline (where every term is the plain joint): a draw from the term's own prior
                u = p.prior.sample(np.random.default_rng(5), 1)
                extra[p.name] = float(p.prior.to_physical(u)[0])
        pm = ParameterModel.from_priors(growth, PRIORS, {**FIXED, **extra}, terms=terms, model=model)
        fwd = ForwardModel(pm, stack, model)
        values = _grid_values(rng, extra)
        got = fwd.grid_sums(values, N_X, N_T, data, weight)
        fused[name] = got is not None
        if got is not None:
            # the same formula in another order: agreement to rounding of sums of ~100 squares
            np.testing.assert_allclose(got, _reference(fwd, values, data, weight), rtol=1e-9, atol=0, err_msg=str(name))
        sums = fwd.grid_profile_sums(values, N_X, N_T, data, coherence, 1e-4)
        profiled[name] = sums is not None
        if sums is not None:
            q_ref, lv_ref = _profile_reference(fwd, values, data, coherence, 1e-4)
            np.testing.assert_allclose(sums[0], q_ref, rtol=1e-9, atol=0, err_msg=str(name))
            # sums of ~50 logs of (m/N)^2 values near -40: absolute rounding of a few 1e-12
            np.testing.assert_allclose(sums[1], lv_ref, rtol=1e-12, atol=1e-9, err_msg=str(name))
    # the plain joint and the joint terms that act per joint take the fused path; terms that change a substructure,
    # the spindle or the FRF itself decline it (a test that always got None would prove nothing)
    assert fused[None] and fused["contact_damping"] and fused["joint_loss_factor"]
    assert not fused["tip_mass"] and not fused["extra_mode"] and not fused["statistical_discrepancy"]
    assert profiled == fused


def test_a_joint_that_couples_rows_and_columns_is_declined(stack_and_model):
    stack, model = stack_and_model
    pm = ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5), {**PRIORS, "c_xf": LogUniform(1.0, 100.0)},
                                    {"c_thetaM": 5e-4})
    fwd = ForwardModel(pm, stack, model)
    values = _grid_values(np.random.default_rng(2), {})
    h = fwd.frf({k: v[:1] for k, v in values.items()})[0]
    assert fwd.grid_sums(values, N_X, N_T, h, np.ones(h.size)) is not None  # the same grid, separable
    values["c_xf"] = values["c_xf"] * (1 + values["k_thetaM"] / values["k_thetaM"].max())  # c_xf varies by column
    h = fwd.frf({k: v[:1] for k, v in values.items()})[0]
    assert fwd.grid_sums(values, N_X, N_T, h, np.ones(h.size)) is None


def test_search_maps_agree_between_the_fused_and_the_chunked_path_and_chunks_do_not_matter(monkeypatch):
    calls = []
    original = search._length_maps

    def recording(*args, **kwargs):
        out = original(*args, **kwargs)
        calls.append((args, kwargs, out))
        return out

    monkeypatch.setattr(search, "_length_maps", recording)
    identify(example_dir() / "setup.toml", lengths=(0.03,), method="deterministic", plots=False)
    assert calls
    args, kwargs, fused = calls[0]
    n_points = args[1].size * args[2].size
    assert n_points > 3 * 1024  # the default chunk really cuts this grid
    # the exact grid (model variance, noise scales profiled within bounds, one of them binding)
    bounds = [(0.01, 0.02), (1e-4, 1.0)][: len(args[0].observations)]
    exact_fused = original(*args, **{**kwargs, "noise_bounds": bounds})
    monkeypatch.setattr(ForwardModel, "grid_sums", lambda *a, **k: None)
    monkeypatch.setattr(ForwardModel, "grid_profile_sums", lambda *a, **k: None)
    exact_chunked = original(*args, **{**kwargs, "noise_bounds": bounds})
    for length in exact_fused:
        np.testing.assert_allclose(exact_fused[length], exact_chunked[length], rtol=1e-10, atol=1e-7)
        assert np.argmax(exact_fused[length]) == np.argmax(exact_chunked[length])
    chunked = {chunk: original(*args, **{**kwargs, "chunk_sets": chunk}) for chunk in (1024, 97, n_points)}
    for length in fused:
        # the chunked path: every grid point's arithmetic is the same in any chunk, so bit for bit
        for chunk in (97, n_points):
            assert np.array_equal(chunked[chunk][length], chunked[1024][length]), (chunk, length)
        # fused against chunked: log-likelihoods of a few hundred lines, rounding only
        np.testing.assert_allclose(fused[length], chunked[1024][length], rtol=1e-10, atol=1e-8)
        assert np.argmax(fused[length]) == np.argmax(chunked[1024][length])
