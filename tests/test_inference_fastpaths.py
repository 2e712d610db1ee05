"""The inference's fast paths give the numbers of the reference computations they replace, bit for bit.

* the sampler driver's emcee subclass, which does not copy the generator's state after every step, and the moves'
  batched accept step: the chain is the one emcee's own sampler and ``propose`` draw from the same state and seed,
  and a checkpoint stores the state emcee would have stored;
* the autocorrelation time's transforms along the contiguous axis (``_tau`` against the former layout, with a
  stuck walker too), and a converged run's final tau taken from its last check;
* the likelihood's compiled per-line terms against the numpy expressions (NaN and infinity included);
* the configuration stack's batch size without ``np.broadcast_shapes``.
"""

from __future__ import annotations

import math
import types

import numpy as np
import pytest

from bayes_rcsa.inference.checkpoint import Checkpoint
from bayes_rcsa.inference.sampler import SamplerSettings, _tau, default_moves, run_ensemble

from test_inference_support import bench, bench_model, contact_spec


class _Gaussian:
    """A correlated normal density of ``ndim`` parameters (the LogDensity protocol)."""

    def __init__(self, ndim: int = 3, rho: float = 0.8):
        self.ndim = ndim
        cov = np.full((ndim, ndim), rho) + (1 - rho) * np.eye(ndim)
        self.precision = np.linalg.inv(cov)

    def __call__(self, theta):
        theta = np.atleast_2d(theta)
        return -0.5 * np.einsum("wi,ij,wj->w", theta, self.precision, theta)

    def check_inside(self, theta, what):
        pass


def _emcees_moves(move: str = "differential"):
    """The default moves with emcee's own walker-by-walker accept step (``RedBlueMove.propose``)."""
    from emcee.moves.red_blue import RedBlueMove

    moves = default_moves(move)
    for m, _ in moves:
        m.propose = types.MethodType(RedBlueMove.propose, m)
    return moves


def _reference_chain(density, initial, seed_rng, n_steps, move: str = "differential"):
    """emcee's own EnsembleSampler and accept step from the state run_ensemble seeds: (coords per step, log
    densities, generator state after the last step)."""
    import emcee

    rstate = np.random.RandomState(int(seed_rng.integers(0, 2**32 - 1))).get_state()
    sampler = emcee.EnsembleSampler(initial.shape[0], initial.shape[1], density, moves=_emcees_moves(move),
                                    vectorize=True)
    state = emcee.State(initial, log_prob=density(initial), random_state=rstate)
    coords, log_prob = [], []
    for state in sampler.sample(state, iterations=n_steps, store=False, skip_initial_state_check=True):
        coords.append(state.coords.copy())
        log_prob.append(state.log_prob.copy())
    return np.array(coords), np.array(log_prob), sampler.random_state


def test_the_driver_draws_emcees_chain_and_checkpoints_emcees_generator_state(tmp_path):
    density = _Gaussian()
    initial = 0.1 * np.random.default_rng(0).standard_normal((16, 3))
    ref_c, ref_l, ref_state = _reference_chain(density, initial, np.random.default_rng(9), 120)
    ckpt = Checkpoint(tmp_path / "chain.h5")
    ckpt.create(16, 3, {})
    run = run_ensemble(density, SamplerSettings(n_steps=120, check_every=40, progress=False, checkpoint_interval=600.0),
                       initial=initial, rng=np.random.default_rng(9), checkpoint=ckpt)
    assert np.array_equal(run.chain, ref_c) and np.array_equal(run.log_prob, ref_l)
    stored = ckpt.read()
    assert stored.iteration == 120 and np.array_equal(stored.chain, ref_c)
    assert stored.random_state[0] == ref_state[0] and np.array_equal(stored.random_state[1], ref_state[1])
    assert tuple(stored.random_state[2:]) == tuple(ref_state[2:])


def test_the_stretch_moves_batched_accept_step_draws_emcees_chain():
    density = _Gaussian(4, 0.3)
    initial = 0.1 * np.random.default_rng(5).standard_normal((12, 4))
    ref_c, ref_l, _ = _reference_chain(density, initial, np.random.default_rng(6), 80, "stretch")
    run = run_ensemble(density, SamplerSettings(n_steps=80, check_every=40, progress=False, move="stretch"),
                       initial=initial, rng=np.random.default_rng(6))
    assert np.array_equal(run.chain, ref_c) and np.array_equal(run.log_prob, ref_l)


def test_a_converged_runs_tau_is_its_last_checks_and_equals_tau_of_the_chain():
    run = run_ensemble(_Gaussian(2, 0.5), SamplerSettings(check_every=100, max_steps=5000, progress=False),
                       initial=0.1 * np.random.default_rng(1).standard_normal((16, 2)), rng=np.random.default_rng(2))
    assert run.converged and run.tau_history[-1][0] == run.n_steps
    assert np.array_equal(run.tau, _tau(run.chain))


def _tau_reference(chain: np.ndarray, c: float = 5.0) -> np.ndarray:
    """The former ``_tau``: the transforms along the chain's step axis."""
    n, nw, nd = chain.shape
    if n < 2:
        return np.full(nd, np.nan)
    x = chain - chain.mean(axis=0, keepdims=True)
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(x, n=nfft, axis=0)
    acf = np.fft.irfft(f * np.conj(f), n=nfft, axis=0)[:n]
    with np.errstate(invalid="ignore", divide="ignore"):
        acf = acf / acf[0:1]
        rho = np.nanmean(acf, axis=1)
    taus = 2.0 * np.cumsum(rho, axis=0) - 1.0
    window = np.arange(n)[:, None] < c * taus  # Sokal's window: the first lag outside it, else the last
    k = np.where(window.all(axis=0), n - 1, window.argmin(axis=0))
    return taus[k, np.arange(nd)]


@pytest.mark.parametrize("n", [2, 17, 250, 333])
def test_tau_on_the_contiguous_axis_is_the_former_tau(n):
    rng = np.random.default_rng(n)
    for nw, nd in ((8, 1), (16, 3), (34, 6), (64, 9)):
        for stuck in (False, True):
            chain = rng.standard_normal((n, nw, nd)) + rng.uniform(0, 1) * np.cumsum(rng.standard_normal((n, nw, nd)),
                                                                                     axis=0)
            if stuck:
                chain[:, 2] = chain[0, 2]  # a walker that never moved: its acf is 0 / 0
            assert np.array_equal(_tau(chain), _tau_reference(chain), equal_nan=True), (n, nw, nd, stuck)


@pytest.fixture(scope="module")
def likelihood():
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem

    cfg, camp = bench(seed=11)
    prob = build_problem(bench_model(cfg, camp), camp.measurements, contact_spec(camp),
                         IdentificationOptions(lengths=(0.025, 0.040)))
    return prob.likelihood, np.array(prob.priors.optimisation_bounds()).T


def test_the_compiled_likelihood_terms_are_the_numpy_ones(likelihood):
    lik, (lo, hi) = likelihood
    rng = np.random.default_rng(3)
    for n in (1, 7, 16, 40):
        x = lo + (hi - lo) * rng.uniform(-0.2, 1.2, (n, lo.size))
        v = lik.parameters.values(x)
        q, var = lik._terms(v)
        q_ref, var_ref = lik._terms_numpy(lik._model_frf(v))
        assert np.array_equal(q, q_ref) and np.array_equal(var, var_ref)
    # NaN and infinite model lines propagate as through numpy (the band maximum included)
    v = lik.parameters.values(lo[None, :] + 0.5 * (hi - lo)[None, :].repeat(3, axis=0))
    h = lik._model_frf(v)
    h[0, 5], h[1, 0], h[2, 300], h[2, 10] = np.nan, np.inf, complex(np.nan, 1.0), 0.0
    from bayes_rcsa.inference.likelihood import _terms_kernel

    q, var = np.empty(h.shape), np.empty(h.shape)
    with np.errstate(all="ignore"):
        _terms_kernel()(h.view(np.float64), lik._data_f, lik._coherence_f, lik._starts_all, lik._floor_eps2, q, var)
        q_ref, var_ref = lik._terms_numpy(h.copy())
    assert np.array_equal(q, q_ref, equal_nan=True) and np.array_equal(var, var_ref, equal_nan=True)


def test_the_stacks_batch_size_fast_path_matches_broadcasting(likelihood):
    lik, _ = likelihood
    stack = lik.stack
    rng = np.random.default_rng(4)
    kx, kt = 10 ** rng.uniform(6.5, 7.5, (5, 2)), 10 ** rng.uniform(4.5, 5.5, (5, 2))
    full = stack.frf(kx, kt, np.full((5, 2), 10.0), np.full((5, 2), 5e-4), np.zeros((5, 2)), np.zeros((5, 2)))
    assert np.array_equal(stack.frf(kx, kt, 10.0, 5e-4), full)
    assert np.array_equal(stack.frf(kx, kt, np.full(5, 10.0), 5e-4, 0.0, np.zeros((1, 2))), full)
    with pytest.raises(ValueError):
        stack.frf(kx, kt[:3])


def _natural_frequency_reference(f, h):
    """The former rule's evaluation: the log of every line, then the three around the maximum."""
    with np.errstate(divide="ignore"):
        y = np.log(np.abs(h))
    i = np.argmax(np.abs(h), axis=-1)
    ic = np.clip(i, 1, f.size - 2)
    y0, y1, y2 = (np.take_along_axis(y, (ic + k)[..., None], axis=-1)[..., 0] for k in (-1, 0, 1))
    u0, u2 = f[ic - 1] - f[ic], f[ic + 1] - f[ic]
    d0, d2 = y0 - y1, y2 - y1
    det = u0 * u2 * (u0 - u2)
    a, b = (d0 * u2 - d2 * u0) / det, (d2 * u0**2 - d0 * u2**2) / det
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = np.where(a < 0, -b / (2 * a), 0.0)
    out = f[ic] + np.where(np.isfinite(shift), shift, 0.0)
    return np.where((i == 0) | (i == f.size - 1), np.nan, out)


def test_natural_frequency_logs_three_lines_with_the_numbers_of_logging_all():
    from bayes_rcsa.model.natural_frequencies import natural_frequency

    rng = np.random.default_rng(7)
    for k in range(60):
        f = np.unique(rng.uniform(100.0, 5000.0, rng.integers(3, 300)))
        shape = tuple(rng.integers(1, 5, k % 3)) + (f.size,)
        h = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
        if k % 3 == 0:
            h[..., rng.integers(0, f.size)] = 0.0  # ln 0 = -inf next to the maximum
        if k % 4 == 0:
            h[..., 0] = 100.0  # the maximum on the band edge: NaN
        if k % 5 == 0:
            h = np.abs(h)
        assert np.array_equal(natural_frequency(f, h), _natural_frequency_reference(f, h), equal_nan=True)


def _snooker_reference(s, c, random, gamma=1.7):
    """The snooker proposal walker by walker with np.linalg.norm (the former evaluation's operations)."""
    ns, nd = s.shape
    idx = [random.randint(len(c[j]), size=ns) for j in range(3)]
    order = np.argsort(random.rand(ns, 3), axis=1)
    q, factor = s.copy(), np.zeros(ns)
    for i in range(ns):
        z, z1, z2 = (c[k][idx[k][i]] for k in order[i])
        norm = np.linalg.norm((s[i] - z)[None, :], axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            e = (s[i] - z)[None, :] / norm[:, None]
            qi = s[i][None, :] + gamma * e * np.sum(e * (z1 - z2)[None, :], axis=1, keepdims=True)
            fi = (nd - 1.0) * (np.log(np.linalg.norm(qi - z[None, :], axis=1)) - np.log(norm))
        if np.isfinite(fi[0]):
            q[i], factor[i] = qi[0], fi[0]
    return q, factor


def test_the_snooker_proposal_is_the_walker_by_walker_reference():
    from bayes_rcsa.inference.sampler import snooker_move

    move, rng = snooker_move(), np.random.default_rng(8)
    for k in range(200):
        n, nd = int(rng.integers(1, 12)), int(rng.integers(1, 8))
        c = [rng.standard_normal((int(rng.integers(1, 12)), nd)) for _ in range(3)]
        s = rng.standard_normal((n, nd))
        if k % 4 == 0:
            s[0] = c[0][0]
            c[1][:], c[2][:] = c[0][0], c[0][0]  # a walker on top of every z: it stays
        seed = int(rng.integers(0, 2**31))
        got, ref = np.random.RandomState(seed), np.random.RandomState(seed)
        q, f = move.get_proposal(s, c, got)
        q_ref, f_ref = _snooker_reference(s, c, ref)
        assert np.array_equal(q, q_ref) and np.array_equal(f, f_ref) and got.rand() == ref.rand()
