"""The joint model of a tool library (#20, "Stage 2 is correct"): the two targets are the same distribution.

Deterministic checks, no sampling of tails: stage 2's log target (``hierarchy.log_posterior``: ``a, delta,
b0`` integrated out in closed form, ``ln sigma0`` in closed form, ``tau_s`` by quadrature) is compared with an
independent evaluation of the joint model's marginal (the dense Gaussian of all setups' surrogate means, and
the log-spread prior integrated by adaptive quadrature), and the joint sampler's density with the generative
model written out with scipy.stats in both of its parametrisations.  A prior or Jacobian mismatch between
joint.py and stage 2 fails here in milliseconds; the sampling comparison is benchmarks/library_scale.py joint
(docs/library.md, "Stage 2").

The Metropolis-within-Gibbs reference (``GibbsJoint``): each of its conditionals is checked against the joint
density (Bayes' identity ``p(x, y) = p(x) p(y | x)`` at many points), and a short run on a one-coordinate
stand-in against stage 2's target integrated on a grid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from bayes_rcsa.library.hierarchy import Group, log_posterior
from bayes_rcsa.library.joint import (GibbsJoint, JointModel, gaussian_log_likelihood, pool_runs, run_spread,
                                     sample_gibbs, sample_joint, slice_step)
from bayes_rcsa.library.population import Hyperprior, covariate

NAMES = ("k_xf", "g_xf")
HYPER = Hyperprior.from_box(NAMES, np.array([[4.0, 10.0], [0.0, 1.5]]), 1.5)
TYPES = np.array([0, 0, 1, 1])
X = covariate(np.array([0.006, 0.013, 0.009, 0.018]))


@pytest.fixture(scope="module")
def library():
    """Four setups of two types with exact Gaussian likelihoods N(m_s, C_s) (correlated, two coordinates)."""
    rng = np.random.default_rng(3)
    exact = []
    for i in range(4):
        z = np.array([7.0 + 0.2 * TYPES[i] + 1.5 * X[i], 0.6]) + np.array([0.15, 0.1]) * rng.standard_normal(2)
        C = np.array([[0.04, 0.015], [0.015, 0.02]]) * rng.uniform(0.5, 2.0)
        exact.append((z + np.linalg.cholesky(C) @ rng.standard_normal(2), C))
    groups = [Group(f"T{t}", tuple(f"s{i}" for i in np.flatnonzero(TYPES == t)), X[TYPES == t],
                    np.array([exact[i][0] for i in np.flatnonzero(TYPES == t)]),
                    np.array([exact[i][1] for i in np.flatnonzero(TYPES == t)])) for t in (0, 1)]
    return exact, groups


def _ln_spread_prior(u: np.ndarray) -> float:
    """ln p(u) of (T = 2, d) log spreads: ln sigma0 ~ N(ls_mean, ls_sd^2) and tau_s ~ HalfNormal integrated out.

    For two types the sum and the difference of the log spreads are independent given tau_s (variances
    tau_s^2 + 2 ls_sd^2 and tau_s^2 after a rotation by 45 degrees), and tau_s is integrated adaptively."""
    c, total = HYPER.ls_sd ** 2, 0.0
    for j in range(u.shape[1]):
        r = u[:, j] - HYPER.ls_mean[j]
        s, dd = (r[0] + r[1]) / math.sqrt(2), (r[0] - r[1]) / math.sqrt(2)

        def f(ts):
            return (stats.norm.pdf(s, 0, math.sqrt(ts * ts + 2 * c)) * stats.norm.pdf(dd, 0, ts)
                    * stats.halfnorm.pdf(ts, scale=HYPER.ts_scale))

        pts = [abs(dd) * k for k in (0.25, 0.5, 1.0, 2.0, 4.0)]  # the integrand's peak sits near tau_s ~ |dd|
        val = integrate.quad(f, 0.0, 6.0, points=pts, epsabs=0.0, epsrel=1e-11, limit=400)[0]
        total += math.log(val)
    return total


def _ln_marginal(exact, u: np.ndarray, tau_b: np.ndarray) -> float:
    """ln p(m_1..m_n | ln sigma, tau_b): all setups' means jointly normal, with the prior of (a, delta, b0)
    pushed through the design matrix (a dense (n d) x (n d) covariance, nothing factorised)."""
    T, d, n = 2, 2, len(exact)
    K = 2 * d * T + d
    mu0 = np.concatenate([np.tile(HYPER.a_mean, T), np.zeros(T * d), np.zeros(d)])
    var0 = np.concatenate([np.tile(HYPER.a_sd, T), np.ones(T * d), HYPER.b_sd]) ** 2
    Xd, V, m = np.zeros((n * d, K)), np.zeros((n * d, n * d)), np.zeros(n * d)
    for i, (mi, Ci) in enumerate(exact):
        t = TYPES[i]
        for j in range(d):
            Xd[i * d + j, [t * d + j, T * d + t * d + j, 2 * T * d + j]] = (1.0, tau_b[j] * X[i], X[i])
        V[i * d:(i + 1) * d, i * d:(i + 1) * d] = Ci + np.diag(np.exp(2 * u[t]))
        m[i * d:(i + 1) * d] = mi
    return float(stats.multivariate_normal(Xd @ mu0, Xd @ np.diag(var0) @ Xd.T + V).logpdf(m))


def test_stage2_log_target_is_the_marginal_of_the_joint_model(library):
    exact, groups = library
    rng = np.random.default_rng(4)
    for _ in range(5):
        u = HYPER.ls_mean + rng.normal(0.0, 1.0, (2, 2))
        # the quadrature grid of tau_s starts at 1e-3: within ~0.01 of equal log spreads (a band of ~1 % of the
        # posterior mass here) stage 2's prior density is off by up to ~10 %; the points stay outside that band
        u[1] += np.sign(u[1] - u[0]) * 0.05
        tau_b = np.abs(HYPER.tb_scale * rng.standard_normal(2))
        ref = (_ln_spread_prior(u) + float(np.sum(stats.halfnorm.logpdf(tau_b, scale=HYPER.tb_scale)))
               + _ln_marginal(exact, u, tau_b))
        got = float(log_posterior(np.concatenate([u.ravel(), tau_b])[None], groups, HYPER)[0])
        # both are exact up to rounding and the quadratures (relative 1e-9 and better): 1e-6 absolute in ln p
        assert got == pytest.approx(ref, abs=1e-6), (u, tau_b)


def _generative(exact, a, dl, b0, tb, ls0, ts, eta, z, eps=None) -> float:
    """ln p of one point of the joint model written out term by term (priors of docs/theory.md)."""
    H = HYPER
    lp = (stats.norm.logpdf(a, H.a_mean, H.a_sd).sum() + stats.norm.logpdf(dl).sum()
          + stats.norm.logpdf(b0, 0.0, H.b_sd).sum() + stats.halfnorm.logpdf(tb, scale=H.tb_scale).sum()
          + stats.norm.logpdf(ls0, H.ls_mean, H.ls_sd).sum() + stats.halfnorm.logpdf(ts, scale=H.ts_scale).sum()
          + stats.norm.logpdf(eta).sum())
    b = b0 + tb * dl
    sig = np.exp(ls0 + ts * eta)
    for i, (m, C) in enumerate(exact):
        t = TYPES[i]
        law = stats.norm.logpdf(eps[i]).sum() if eps is not None else \
            stats.norm.logpdf(z[i], a[t] + b[t] * X[i], sig[t]).sum()
        lp += law + stats.multivariate_normal(m, C).logpdf(z[i])
    return float(lp)


def test_joint_density_is_the_generative_model_in_both_parametrisations(library):
    exact, _ = library
    lls = [gaussian_log_likelihood(m, C) for m, C in exact]
    nc, ce = JointModel(lls, TYPES, X, HYPER, centred=False), JointModel(lls, TYPES, X, HYPER, centred=True)
    theta = nc.start(np.random.default_rng(5), 6)
    a, b, ls, z = nc.laws(theta)
    blocks = nc.blocks(theta)
    lp_nc, lp_ce = nc.log_prob(theta), ce.log_prob(nc.pack(*blocks[:7], z))
    for w in range(6):
        a_, dl, b0, tb, ls0, ts, eta, eps = (v[w] for v in blocks)
        # non-centred: eps is the coordinate; centred: z itself, whose density carries the Jacobian 1/sigma
        assert lp_nc[w] == pytest.approx(_generative(exact, a_, dl, b0, tb, ls0, ts, eta, z[w], eps), abs=1e-9)
        assert lp_ce[w] == pytest.approx(_generative(exact, a_, dl, b0, tb, ls0, ts, eta, z[w]), abs=1e-9)
        assert lp_nc[w] - lp_ce[w] == pytest.approx(float(np.sum(ls[w][TYPES])), abs=1e-9)
    # a negative spread of the slopes or of the spreads is outside the half-normal priors
    bad = theta[:1].copy()
    bad[0, nc.edges[3]] = -0.01
    assert np.isneginf(nc.log_prob(bad)[0])
    bad = theta[:1].copy()
    bad[0, nc.edges[5]] = -0.01
    assert np.isneginf(ce.log_prob(bad)[0])


def test_independent_runs_are_pooled_and_give_a_between_run_error(library):
    exact, _ = library
    lls = [gaussian_log_likelihood(m, C) for m, C in exact]
    rng = np.random.default_rng(6)
    out = sample_joint(lls, TYPES, X, HYPER, rng, n_steps=40, n_burn=20, n_walkers=64, n_runs=3, centred=True)
    runs = out["runs"]
    assert len(runs) == 3 and all(r["acceptance"] > 0 for r in runs)
    assert out["types"][0].shape == (3 * 40 * 64, 6) and out["tau_b"].shape == (3 * 40 * 64, 2)
    # independent starts: the runs' medians differ
    med = [np.median(r["types"][1][:, 0]) for r in runs]
    assert len(set(np.round(med, 12))) == 3
    value, se = run_spread(out, lambda d: np.median(d["types"][1][:, 0]))
    assert value == pytest.approx(np.median(out["types"][1][:, 0]))
    assert se == pytest.approx(np.std(med, ddof=1) / np.sqrt(3))
    assert pool_runs(runs[:2])["types"][0].shape[0] == 2 * 40 * 64
    with pytest.raises(ValueError, match="two runs"):
        run_spread(pool_runs(runs[:1]), lambda d: np.median(d["tau_b"]))


def test_nuisance_parameters_reach_their_setup_and_laws_start_at_given_rows(library):
    # a real fit's likelihood has parameters of its own (noise scales): sampled along, passed to its callable only
    exact, _ = library
    lls = [gaussian_log_likelihood(m, C) for m, C in exact]

    def with_noise(k):
        g = lls[k]
        return lambda z, v: g(z) + stats.norm.logpdf(v, 0.1 * k, 0.5).sum(axis=1)

    nuisance = [1, 0, 2, 0]
    plain = JointModel(lls, TYPES, X, HYPER, centred=True)
    model = JointModel([with_noise(k) if nuisance[k] else lls[k] for k in range(4)], TYPES, X, HYPER, centred=True,
                       nuisance=nuisance)
    assert model.ndim == plain.ndim + 3
    rng = np.random.default_rng(8)
    laws = [np.column_stack([m + 0.01 * rng.standard_normal((50, 2)), rng.standard_normal((50, k))])
            for (m, _), k in zip(exact, nuisance)]
    theta = model.start(rng, 10, laws)
    z = model.blocks(theta)[7]
    v = model.nuisance_of(theta)
    for k in range(4):  # each walker's law and nuisance come from one row of that setup's given draws
        rows = laws[k]
        both = np.column_stack([z[:, k, :], v[k]])
        assert all(np.any(np.all(rows == r, axis=1)) for r in both)
    expect = plain.log_prob(theta[:, :plain.ndim]) + sum(
        stats.norm.logpdf(v[k], 0.1 * k, 0.5).sum(axis=1) for k in range(4) if nuisance[k])
    np.testing.assert_allclose(model.log_prob(theta), expect, rtol=0, atol=1e-9)


# ---------------------------------------------------------------- Metropolis-within-Gibbs (GibbsJoint) ----------


def _gibbs_state(g: GibbsJoint, exact, rng, C: int) -> dict:
    st = g.start(rng, C, [m + 0.1 * rng.standard_normal((50, 2)) for m, _ in exact])
    st["u"] = HYPER.ls_mean + rng.normal(0.0, 1.0, (C, 2, 2))
    st["tau_b"] = np.abs(rng.normal(0.0, 1.0, (C, 2))) * HYPER.tb_scale
    st["a"], st["delta"], st["b0"] = rng.normal(7.0, 0.5, (C, 2, 2)), rng.normal(0, 1, (C, 2, 2)), rng.normal(0, 1, (C, 2))
    st["tau_s"], st["ls0"] = rng.uniform(0.1, 1.1, (C, 2)), rng.normal(-1.0, 1.0, (C, 2))
    return st


def _joint_lp_centred(jm: JointModel, st: dict) -> np.ndarray:
    """The joint log density in Gibbs' coordinates (u = ln sigma instead of eta: Jacobian 1 / tau_s per type)."""
    eta = (st["u"] - st["ls0"][:, None, :]) / st["tau_s"][:, None, :]
    th = jm.pack(st["a"], st["delta"], st["b0"], st["tau_b"], st["ls0"], st["tau_s"], eta, st["z"],
                 [w[:, 2:] for w, k in zip(st["w"], jm.nuisance) if k])
    return jm.log_prob(th) - jm.T * np.sum(np.log(st["tau_s"]), axis=1)


def _fix(st: dict, keys) -> None:
    """Every chain takes chain 0's value of ``keys`` (the conditioning variables of an identity check)."""
    for k in keys:
        st[k] = np.broadcast_to(st[k][:1], st[k].shape).copy()


def test_gibbs_conditionals_are_those_of_the_joint_density(library):
    exact, _ = library
    lls = [gaussian_log_likelihood(m, C) for m, C in exact]
    jm, g = JointModel(lls, TYPES, X, HYPER, centred=True), GibbsJoint(lls, TYPES, X, HYPER, [C for _, C in exact])
    rng = np.random.default_rng(21)
    # (u, tau_b, beta) given the laws, ls0, tau_s: ln p(joint) = collapsed(u, tau_b) + ln N(beta; conditional) + c
    st = _gibbs_state(g, exact, rng, 8)
    _fix(st, ("z", "ls0", "tau_s"))
    mean, Lp = g.beta_conditional(st["z"], st["u"], st["tau_b"])
    beta = np.concatenate([np.swapaxes(st["a"], 1, 2), np.swapaxes(st["delta"], 1, 2), st["b0"][..., None]], axis=2)
    r = np.einsum("cjlk,cjl->cjk", Lp, beta - mean)  # Lp^T (beta - mean), Lp the precision's factor
    ln_beta = (-0.5 * np.sum(r * r, axis=-1) + np.sum(np.log(np.diagonal(Lp, axis1=-2, axis2=-1)), axis=-1)
               - 0.5 * g.K * np.log(2 * np.pi))
    prior = (np.sum(stats.halfnorm.logpdf(st["tau_b"], scale=HYPER.tb_scale), axis=1)
             + np.sum(stats.norm.logpdf(st["u"], st["ls0"][:, None, :], st["tau_s"][:, None, :]), axis=(1, 2)))
    gap = _joint_lp_centred(jm, st) - (np.sum(g.collapsed(st["z"], st["u"], st["tau_b"]) + ln_beta, axis=1) + prior)
    # exact identities evaluated in floating point: 1e-8 in ln p
    np.testing.assert_allclose(gap - gap[0], 0.0, atol=1e-8)
    # (tau_s, ls0) given u and the rest: ln p(joint) = ls_collapsed(tau_s) + ln N(ls0; conditional) + c
    st = _gibbs_state(g, exact, rng, 8)
    _fix(st, ("z", "u", "a", "delta", "b0", "tau_b"))
    m, s = g.ls0_conditional(st["u"], st["tau_s"])
    gap = _joint_lp_centred(jm, st) - np.sum(g.ls_collapsed(st["u"], st["tau_s"]) + stats.norm.logpdf(st["ls0"], m, s),
                                             axis=1)
    np.testing.assert_allclose(gap - gap[0], 0.0, atol=1e-8)
    # the slice sampler's stepping out reaches tau_s ~ e^-60 and u ~ -50, where the dense covariances are singular
    # in floating point: a density (finite or -inf), never an exception
    assert not np.any(np.isnan(g.ls_collapsed(st["u"], np.full((8, 2), np.exp(-60.0)))))
    assert not np.any(np.isnan(g.collapsed(st["z"], np.full((8, 2, 2), -49.0), st["tau_b"])))


def test_gibbs_law_target_is_the_joint_density_in_that_law(library):
    # setup k's Metropolis target (own likelihood with its nuisance parameters x population density) against the
    # joint density as the law and nuisance parameters of setup k vary, everything else fixed
    exact, _ = library
    base = [gaussian_log_likelihood(m, C) for m, C in exact]
    nuisance = [1, 0, 2, 0]
    lls = [(lambda z, v, f=base[k], k=k: f(z) + stats.norm.logpdf(v, 0.1 * k, 0.5).sum(axis=1)) if nuisance[k]
           else base[k] for k in range(4)]
    jm = JointModel(lls, TYPES, X, HYPER, centred=True, nuisance=nuisance)
    g = GibbsJoint(lls, TYPES, X, HYPER, [np.eye(2 + k) for k in nuisance], nuisance)
    rng = np.random.default_rng(22)
    st = g.start(rng, 8, [np.column_stack([m + 0.05 * rng.standard_normal((50, 2)), rng.standard_normal((50, k))])
                          for (m, _), k in zip(exact, nuisance)])
    for k in range(4):
        fixed = g.start(np.random.default_rng(23), 8, [w[:1] for w in st["w"]])  # one state in every chain...
        fixed["w"][k] = st["w"][k]  # ...except setup k's law and nuisance parameters
        fixed["z"] = np.stack([w[:, :2] for w in fixed["w"]], axis=1)
        _fix(fixed, ("a", "delta", "b0", "tau_b", "u", "ls0", "tau_s"))
        t = TYPES[k]
        mu = fixed["a"][:, t] + (fixed["b0"] + fixed["tau_b"] * fixed["delta"][:, t]) * X[k]
        got = g.law_log_target(k, fixed["w"][k], mu, np.exp(fixed["u"][:, t]))
        gap = _joint_lp_centred(jm, fixed) - got
        np.testing.assert_allclose(gap - gap[0], 0.0, atol=1e-8)


def test_slice_step_samples_its_target():
    # 4000 independent half-normal(2) targets in ln v (with the Jacobian), from a far start: after 25 updates the
    # draws are the target's (quantiles within 4 binomial standard errors at these sizes: ~0.03 in probability)
    rng = np.random.default_rng(24)

    def f(y):
        return stats.halfnorm.logpdf(np.exp(y), scale=2.0) + y

    y = np.full(4000, 3.0)
    for _ in range(25):
        y, stuck = slice_step(y, f, 1.0, rng)
        assert stuck == 0
    p = stats.halfnorm.cdf(np.exp(y), scale=2.0)
    for q in (0.05, 0.5, 0.95):
        assert abs(np.mean(p < q) - q) < 4 * np.sqrt(q * (1 - q) / 4000)


def test_gibbs_chain_reproduces_stage2_target_on_a_small_library():
    """One coordinate, two types of two setups with exact Gaussian likelihoods: stage 2's target is exact here (the
    test above) and three-dimensional, (ln sigma_1, ln sigma_2, ln tau_b), so it is integrated on a grid."""
    hyper = Hyperprior.from_box(("k_xf",), np.array([[4.0, 10.0]]), 1.5)
    rng = np.random.default_rng(11)
    m = 7.0 + 0.2 * TYPES + 1.5 * X + 0.15 * rng.standard_normal(4)
    var = (0.1 * rng.uniform(0.7, 1.4, 4)) ** 2
    groups = [Group(f"T{t}", tuple(f"s{i}" for i in np.flatnonzero(TYPES == t)), X[TYPES == t], m[TYPES == t, None],
                    var[TYPES == t, None, None]) for t in (0, 1)]
    q = np.array([0.05, 0.5, 0.95])
    N, lo, hi, ylo, yhi = 40, -7.0, 1.0, -8.0, 1.0  # grid mass within one cell of its edges: 2e-4
    u, y = lo + (np.arange(N) + 0.5) * (hi - lo) / N, ylo + (np.arange(N) + 0.5) * (yhi - ylo) / N
    U1, U2, Y = np.meshgrid(u, u, y, indexing="ij")
    lp = log_posterior(np.column_stack([U1.ravel(), U2.ravel(), np.exp(Y.ravel())]), groups, hyper) + Y.ravel()
    w = np.exp(lp - lp.max()).reshape(N, N, N)
    target = []
    for ax, grid in enumerate((u, u, y)):  # each marginal's CDF at the cell edges, interpolated: ln of the quantile
        marg = w.sum(axis=tuple(i for i in range(3) if i != ax))
        h = grid[1] - grid[0]
        target.append(np.interp(q, np.concatenate([[0.0], np.cumsum(marg) / marg.sum()]),
                                np.concatenate([[grid[0] - h / 2], grid + h / 2])))
    lls = [gaussian_log_likelihood(m[i:i + 1], var[i] * np.eye(1)) for i in range(4)]
    laws = [m[i] + np.sqrt(var[i]) * rng.standard_normal((500, 1)) for i in range(4)]
    out = sample_gibbs(lls, TYPES, X, hyper, np.random.default_rng(12), laws, n_iter=300, n_burn=100, n_chains=32,
                       law_steps=2)
    assert out["stuck"] == 0 and np.all(np.abs(out["law_acceptance"] - 0.3) < 0.1)
    ch = np.log(out["chains"][:, :, [2, 5, 6]])  # ln sigma of both types, ln tau_b
    got = np.quantile(ch.reshape(-1, 3), q, axis=0).T
    se = np.quantile(ch.reshape(8, -1, 3), q, axis=1).std(axis=1, ddof=1).T / np.sqrt(8)  # 8 groups of 4 chains
    # Monte Carlo error (4 se, from independent groups of chains) plus the grid's error (a 40-point grid moves
    # these quantiles by <= 0.03 in ln against a 100-point one)
    assert np.all(np.abs(got - np.array(target)) < 4 * se + 0.03), (got, np.array(target), se)
