"""The library's fast paths give the numbers of the straightforward computation they replace, bit for bit.

Each reference below is the per-type / per-setup computation the package ran before the fast path, kept here as
the oracle (the stage-2 reference shares the package's element-by-element factors and design rows, which the fast
path did not change, and assembles everything else type by type): the coupled stage-2 posterior laid out once for all types (:class:`bayes_rcsa.library.hierarchy._Layout`
through ``HyperPosterior``), the cached tau_s quadrature of the spreads' hyperprior.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.library import hierarchy
from bayes_rcsa.library.population import _TAU_S_GRID, Hyperprior, _tau_weights


def _hyper(d: int) -> Hyperprior:
    names = ("log10_kt", "log10_kr", "log10_ct")[:d]
    return Hyperprior(names, np.linspace(6.0, 7.0, d), np.full(d, 0.8), np.full(d, 2.0), np.full(d, 0.25),
                      np.full(d, math.log(0.1 / 5.0)))


def _groups(rng, d: int, sizes) -> list:
    out = []
    for t, n in enumerate(sizes):
        B = rng.standard_normal((n, d, d)) * 0.05
        C = B @ np.swapaxes(B, 1, 2) + 1e-3 * np.eye(d)
        out.append(hierarchy.Group(f"H{t}", tuple(f"s{t}_{i}" for i in range(n)), rng.uniform(-0.7, 0.7, n),
                                   6.5 + 0.3 * rng.standard_normal((n, d)), C))
    return out


def _reference_linear_system(theta, groups, hyper):
    """The per-type assembly of the posterior precision of beta (the package's computation before the layout)."""
    T, d = len(groups), hyper.ndim
    u, tau_b = theta[:, :T * d].reshape(-1, T, d), theta[:, T * d:]
    W, K = theta.shape[0], 2 * d * T + d
    mu0 = np.concatenate([np.tile(hyper.a_mean, T), np.zeros(T * d), np.zeros(d)])
    p0 = np.concatenate([np.tile(hyper.a_sd ** -2, T), np.ones(T * d), hyper.b_sd ** -2])
    P = np.zeros((W, K, K))
    P[:, np.arange(K), np.arange(K)] = p0
    r = np.broadcast_to(p0 * mu0, (W, K)).copy()
    rest = np.zeros(W)
    ib = slice(2 * d * T, K)
    for t, g in enumerate(groups):
        n = len(g.names)
        s2 = np.exp(2.0 * u[:, t, :])
        L, logdet = hierarchy._factor(g.Ct, s2)
        y = hierarchy._forward(L, np.broadcast_to(g.mT[:, None, :], (d, W, n)))
        A = hierarchy._rows(L, y, g.x).reshape(W, n * d, 2 * d + 1)
        G = np.swapaxes(A, 1, 2) @ A
        S0, S1, S2 = G[:, :d, :d], G[:, :d, d:2 * d], G[:, d:2 * d, d:2 * d]
        g0, g1, q, ld = G[:, :d, 2 * d], G[:, d:2 * d, 2 * d], G[:, 2 * d, 2 * d], np.sum(logdet, axis=1)
        ia, idl = slice(t * d, (t + 1) * d), slice(T * d + t * d, T * d + (t + 1) * d)
        D = tau_b[:, None, :]
        P[:, ia, ia] += S0
        P[:, ia, idl] += S1 * D
        P[:, idl, ia] += (S1 * D).transpose(0, 2, 1)
        P[:, ia, ib] += S1
        P[:, ib, ia] += S1
        P[:, idl, idl] += S2 * D * tau_b[:, :, None]
        P[:, idl, ib] += S2 * tau_b[:, :, None]
        P[:, ib, idl] += S2 * D
        P[:, ib, ib] += S2
        r[:, ia] += g0
        r[:, idl] += tau_b * g1
        r[:, ib] += g1
        rest = rest - 0.5 * (q + ld + n * d * math.log(2 * math.pi))
    return P, r, rest, mu0, p0


@pytest.mark.parametrize("d, sizes", [(1, (2, 2)), (2, (3, 4, 4)), (2, (4, 4, 4)), (2, (5,)), (3, (2, 9, 4)), (3, (9, 9))])
def test_linear_system_and_log_posterior_match_the_per_type_computation_bit_for_bit(d, sizes):
    rng = np.random.default_rng(11 + d)
    groups, hyper = _groups(rng, d, sizes), _hyper(d)
    T = len(sizes)
    theta = np.concatenate([math.log(0.05) + 0.8 * rng.standard_normal((40, T * d)),
                            np.abs(0.3 * rng.standard_normal((40, d)))], axis=1)
    theta[0, 0] = 60.0  # outside the support: -inf
    theta[1, -1] = -0.1
    ref = _reference_linear_system(theta[2:], groups, hyper)
    for layout in (None, hierarchy._Layout(groups, hyper)):
        got = hierarchy._linear_system(theta[2:], groups, hyper, layout)
        for a, b in zip(ref, got):
            assert np.array_equal(a, b)
    lp = hierarchy.HyperPosterior(groups, hyper)(theta)
    assert np.array_equal(lp, hierarchy.log_posterior(theta, groups, hyper))
    assert np.all(np.isneginf(lp[:2])) and np.all(np.isfinite(lp[2:]))
    # the reference's own log posterior, from its linear system
    P, r, rest, mu0, p0 = ref
    Lp = np.linalg.cholesky(P)
    v = np.linalg.solve(Lp, r[..., None])[..., 0]
    ll = (rest - 0.5 * float(np.sum(p0 * mu0 * mu0)) + 0.5 * np.sum(v * v, axis=1) + 0.5 * float(np.sum(np.log(p0)))
          - np.sum(np.log(np.diagonal(Lp, axis1=1, axis2=2)), axis=1))
    u, tb = theta[2:, :T * d].reshape(-1, T, d), theta[2:, T * d:]
    assert np.array_equal(lp[2:], hyper.ln_prob_log_sigma(u) + hyper.ln_prob_tau_b(tb) + ll)


def test_cached_tau_s_quadrature_gives_the_direct_hyperprior_density():
    hyper = _hyper(2)
    rng = np.random.default_rng(3)
    for T in (1, 3):
        u = math.log(0.02) + rng.standard_normal((30, T, 2))
        c = hyper.ls_sd ** 2
        r = u - hyper.ls_mean
        rr = np.sum(r * r, axis=-2)[..., None]
        rs = np.sum(r, axis=-2)[..., None]
        t2 = _TAU_S_GRID ** 2
        q = (rr - c * rs * rs / (t2 + T * c)) / t2
        logdet = (T - 1) * np.log(t2) + np.log(t2 + T * c)
        ln_n = -0.5 * (q + logdet + T * math.log(2 * math.pi))
        ln_w = _tau_weights(hyper.ts_scale)
        top = np.max(ln_n + ln_w, axis=-1, keepdims=True)
        want = np.sum(top[..., 0] + np.log(np.sum(np.exp(ln_n + ln_w - top), axis=-1)), axis=-1)
        assert np.array_equal(hyper.ln_prob_log_sigma(u), want)
        assert np.array_equal(hyper.ln_prob_log_sigma(u), want)  # second call from the cache


@pytest.mark.parametrize("centred", [False, True])
def test_joint_model_batches_its_gaussian_setups_with_the_numbers_of_the_setup_by_setup_loop(centred):
    from bayes_rcsa.library.joint import JointModel, gaussian_log_likelihood

    rng = np.random.default_rng(5)
    d, n = 2, 6
    hyper = _hyper(d)
    lls = []
    for _ in range(n):
        B = 0.1 * rng.standard_normal((d, d))
        lls.append(gaussian_log_likelihood(6.5 + 0.3 * rng.standard_normal(d), B @ B.T + 0.01 * np.eye(d)))
    types, x = [0, 1, 0, 1, 2, 2], np.linspace(-0.5, 0.6, n)
    batched = JointModel(lls, types, x, hyper, centred)
    # wrapped callables are not recognised as Gaussian: the setup-by-setup loop, the reference
    looped = JointModel([lambda z, f=f: f(z) for f in lls], types, x, hyper, centred)
    assert batched._gaussian is not None and looped._gaussian is None
    theta = batched.start(rng, 30)
    theta = np.vstack([theta, theta + rng.standard_normal(theta.shape)])  # some outside the support
    got, want = batched.log_prob(theta), looped.log_prob(theta)
    assert np.any(np.isneginf(want)) and np.any(np.isfinite(want))
    assert np.array_equal(got, want)


def test_site_log_integrals_in_place_give_the_allocating_computation():
    from bayes_rcsa.library.exact import site_log_integrals

    rng = np.random.default_rng(9)
    n, H, d = 300, 2500, 2  # three blocks of hyperparameter draws, the last one partial
    z = 6.0 + 0.1 * rng.standard_normal((n, d))
    ln_prior = rng.standard_normal(n)
    mu = 6.0 + 0.1 * rng.standard_normal((H, d))
    sigma = np.exp(-2.0 + 0.5 * rng.standard_normal((H, d)))
    c = z.mean(axis=0)
    zc = z - c
    want_site, want_ess = np.empty(H), np.empty(H)
    for lo in range(0, H, 1000):
        m = mu[lo:lo + 1000] - c
        p = sigma[lo:lo + 1000] ** -2.0
        q = (zc * zc) @ p.T - 2.0 * (zc @ (m * p).T) + np.sum(m * m * p, axis=1)[None, :]
        lk = -0.5 * q - ln_prior[:, None]
        top = lk.max(axis=0)
        k = np.exp(lk - top)
        s1 = k.sum(axis=0)
        want_site[lo:lo + 1000] = top + np.log(s1 / n) - np.sum(np.log(sigma[lo:lo + 1000]), axis=1)
        want_ess[lo:lo + 1000] = s1 * s1 / np.sum(k * k, axis=0)
    got_site, got_ess = site_log_integrals(z, ln_prior, mu, sigma)
    assert np.array_equal(got_site, want_site) and np.array_equal(got_ess, want_ess)
