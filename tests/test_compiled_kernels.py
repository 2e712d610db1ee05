"""One machine-code version per compiled kernel, whatever arrays the callers pass.

Numba compiles a kernel once per argument *type*, and a read-only array (``np.broadcast_to`` views) or a strided
one (a fancy-indexed slice) is another type than a fresh C-contiguous array: each such call site cost a second
compilation of about a second, several per kernel in a fresh install or a clean CI checkout (measured: four
versions of the batched tool-point kernel, three of the grid sums, three of the SDM step).  The wrappers copy
such inputs; these tests pass them on purpose and require the results of fresh arrays and a single version.
"""

from __future__ import annotations

import numpy as np

from bayes_rcsa.model import _kernels
from bayes_rcsa.stability import sdm
from bayes_rcsa.stability.cutting import CuttingConditions
from bayes_rcsa.stability.modal_fit import ModalModel


def _readonly_and_strided(rng, shape):
    """The same values three ways: fresh, read-only (broadcast view) and strided (every other column)."""
    a = rng.uniform(0.5, 2.0, shape)
    ro = np.broadcast_to(a, shape)
    wide = np.empty(shape[:-1] + (2 * shape[-1],))
    wide[..., ::2] = a
    return a, ro, wide[..., ::2]


def _jit():
    _kernels._jit()
    return _kernels._JIT


def test_model_kernels_keep_one_version_for_read_only_and_strided_inputs():
    rng = np.random.default_rng(20261130)
    n_sets, n_cfg, n_lines = 3, 2, 10
    starts = np.array([0, 4, n_lines])
    omega = np.linspace(1e3, 2e3, n_lines)
    C = rng.normal(size=(14, n_lines))
    d = rng.normal(size=(2, n_lines))
    w = rng.uniform(0.5, 1.0, n_lines)
    params = [_readonly_and_strided(rng, (n_sets, n_cfg)) for _ in range(6)]
    Z = np.broadcast_to(rng.uniform(1e2, 1e3, (1, n_lines, 2)), (1, n_lines, 2))  # read-only too
    Ct = np.broadcast_to(rng.normal(size=(n_lines, 19)) + 1j * rng.normal(size=(n_lines, 19)), (n_lines, 19))
    results = []
    for way in range(3):
        p = [v[way] for v in params]
        out = np.empty((n_sets, n_lines), dtype=complex)
        _kernels.tool_point_kernel(*p, starts, omega, C, out)
        outb = np.empty((n_sets, n_lines), dtype=complex)
        _kernels.tool_point_kernel_batched(*p, starts, omega, np.broadcast_to(C, (1, 14, n_lines)), outb)
        outt = np.empty((n_sets, n_lines), dtype=complex)
        _kernels.tool_point_kernel_tip(*p, starts, omega, Ct, Z, outt)
        rows, cols = [p[0], p[2], p[4]], [p[1], p[3], p[5]]
        q = np.empty((n_sets, n_sets, n_cfg))
        _kernels.grid_sums_kernel(*rows, *cols, starts, omega, C, d, w, q)
        q2, lv = np.empty_like(q), np.empty_like(q)
        _kernels.grid_profile_kernel(*rows, *cols, starts, omega, C, d, np.broadcast_to(w, (n_lines,)), 1e-4, q2, lv)
        results.append((out, outb, outt, q, q2, lv))
    for got in results[1:]:
        for a, b in zip(got, results[0]):
            assert np.array_equal(a, b)
    jit = _jit()
    for name in ("tool_point_kernel", "tool_point_kernel_batched", "tool_point_kernel_tip", "grid_sums_kernel",
                 "grid_profile_kernel"):
        assert len(getattr(jit, name).signatures) == 1, (name, getattr(jit, name).signatures)


def test_the_sdm_step_keeps_one_version_for_subsets_and_read_only_inputs():
    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, milling="down", feed="y", radial_immersion=0.5)
    pairs = [(ModalModel([1287.0 * a], [0.03], [1.0e6]), ModalModel([1340.0 * a], [0.03], [1.3e6])) for a in (1.0, 1.02)]
    speed = np.linspace(8000.0, 12000.0, 6)
    depth = np.full(speed.size, 2e-4)  # a read-only broadcast inside spectral_radius_batch as well
    index = np.array([0, 1, 0, 1, 1, 0])
    rho = sdm.spectral_radius_batch(pairs, index, cut, speed, depth, 20, solver="eig")
    # the same points one at a time: every step set is a strided subset of a batch
    one = [sdm.spectral_radius_batch(pairs, index[i : i + 1], cut, speed[i : i + 1], depth[i : i + 1], 20,
                                     solver="eig")[0] for i in range(speed.size)]
    np.testing.assert_allclose(rho, one, rtol=1e-9)
    modal = sdm._modal_batch(pairs, np.arange(2))
    disc, factor = sdm._discretise(cut, 20)
    steps = sdm._steps(modal.take(index), disc, factor * 60.0 / speed, depth).subset(np.array([5, 0, 2]))
    V = np.broadcast_to(np.random.default_rng(1).normal(size=(steps.dim, 1, 1)), (steps.dim, 2, steps.size))
    np.testing.assert_allclose(sdm._apply(steps, V), sdm._apply_numpy(steps, np.array(V)), rtol=1e-10, atol=1e-14)
    assert len(sdm.apply_monodromy.signatures) == 1, sdm.apply_monodromy.signatures
