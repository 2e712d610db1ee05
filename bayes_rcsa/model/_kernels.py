"""Compiled inner loop of the batched tool-point FRF (the sampler's hot path).

One fused loop over (parameter set, configuration, frequency line) evaluates

    h = t22 - (p (e11 Kt + 1) Kx + q (e00 Kx + 1) Kt - r Kx Kt)
              / ((e00 Kx + 1)(e11 Kt + 1) - g Kx Kt)

with Kx = k_xf + i (w c_xf + h_xf) and Kt = k_thetaM + i (w c_thetaM + h_thetaM)
(viscous damping c and a rate-independent, hysteretic loss h = eta k).  This is the
elastic-coupling formula of :mod:`bayes_rcsa.model.assembly` multiplied
through by Kx Kt so that each line needs a single real division; numpy would
need about fifteen full-size temporaries for the same expression, which makes
it memory-bound (see benchmarks/forward.py for the comparison).
"""

from __future__ import annotations

import numpy as np

__all__ = ["grid_profile_kernel", "grid_sums_kernel", "pack_coefficients", "tool_point_kernel", "tool_point_kernel_batched", "tool_point_kernel_tip",
           "tip_coefficients"]

_ORDER = ("t22", "e00", "e11", "g", "p", "q", "r")


def pack_coefficients(arrays: dict) -> np.ndarray:
    """Pack the cached complex coefficients into a (14, n_lines) real array."""
    n = arrays["t22"].size
    out = np.empty((14, n))
    for i, name in enumerate(_ORDER):
        out[2 * i] = arrays[name].real
        out[2 * i + 1] = arrays[name].imag
    return out


def tip_coefficients(E, T12, T21, T22) -> np.ndarray:
    """Per-line constants of :func:`tool_point_kernel_tip`, (n_lines, 19) complex.

    Columns: ``det E``, ``E11``, ``E00``, ``T22`` (00, 01, 10, 11), ``N``, ``U``, ``V`` (same order).

    Parameters
    ----------
    E : (n_lines, 2, 2) complex, holder-tip receptance plus the tool's T11
    T12, T21, T22 : (n_lines, 2, 2) complex, tool-overhang blocks
    """
    e00, e01, e10, e11 = E[:, 0, 0], E[:, 0, 1], E[:, 1, 0], E[:, 1, 1]
    adj = np.empty_like(E)
    adj[:, 0, 0], adj[:, 0, 1], adj[:, 1, 0], adj[:, 1, 1] = e11, -e01, -e10, e00
    n = np.einsum("nij,njk,nkl->nil", T21, adj, T12)
    u = T21[:, :, 0, None] * T12[:, None, 0, :]
    v = T21[:, :, 1, None] * T12[:, None, 1, :]
    cols = [e00 * e11 - e01 * e10, e11, e00] + [m[:, i, k] for m in (T22, n, u, v) for i in (0, 1) for k in (0, 1)]
    return np.ascontiguousarray(np.column_stack(cols))


# The compiled loops live in ._kernels_jit and are loaded on the first call: importing numba (and scipy
# through it) costs about 0.3-0.6 s, which every process reading a setup file paid before, even to report
# an error.  The indirection costs one global lookup per call (microseconds of numba dispatch follow).
_JIT = None


def _jit():
    global _JIT
    if _JIT is None:
        from . import _kernels_jit

        _JIT = _kernels_jit
    return _JIT


def _inputs(*arrays):
    """Every input array writeable and C-contiguous (copied where not).

    Numba compiles one machine-code version per argument type, and a read-only or strided array is another
    type: each such call site cost a second compilation of about a second (several per kernel in a fresh
    install or a clean CI checkout, where nothing is cached yet).  The copies are of inputs only, never of
    the ``out`` arrays the kernels fill.
    """
    return [a if a.flags.writeable and a.flags.c_contiguous else np.array(a, order="C") for a in arrays]


def tool_point_kernel(kx, kt, cx, ct, hx, ht, starts, omega, C, out) -> None:
    """Fill ``out`` (n_sets, n_lines) complex with the tool-point receptance (compiled; see
    :func:`._kernels_jit.tool_point_kernel` for the shapes)."""
    (_JIT or _jit()).tool_point_kernel(*_inputs(kx, kt, cx, ct, hx, ht, starts, omega, C), out)


def tool_point_kernel_batched(kx, kt, cx, ct, hx, ht, starts, omega, CB, out) -> None:
    """:func:`tool_point_kernel` with coefficients per parameter set, ``CB`` (B, 14, n_lines), B = 1 or n_sets."""
    (_JIT or _jit()).tool_point_kernel_batched(*_inputs(kx, kt, cx, ct, hx, ht, starts, omega, CB), out)


def tool_point_kernel_tip(kx, kt, cx, ct, hx, ht, starts, omega, C, Z, out) -> None:
    """Tool-point receptance with a diagonal dynamic stiffness ``Z`` attached at the tool tip (compiled; see
    :func:`._kernels_jit.tool_point_kernel_tip`)."""
    (_JIT or _jit()).tool_point_kernel_tip(*_inputs(kx, kt, cx, ct, hx, ht, starts, omega, C, Z), out)


def grid_sums_kernel(kx, cx, hx, kt, ct, ht, starts, omega, C, d, w, q) -> None:
    """Weighted squared residual sums on a separable contact grid, ``q`` (n_x, n_t, n_configs) (compiled; see
    :func:`._kernels_jit.grid_sums_kernel`)."""
    (_JIT or _jit()).grid_sums_kernel(*_inputs(kx, cx, hx, kt, ct, ht, starts, omega, C, d, w), q)


def grid_profile_kernel(kx, cx, hx, kt, ct, ht, starts, omega, C, d, coherence, eps2, q, lv) -> None:
    """The likelihood's ``sum |h - d|^2 / v`` and ``sum ln v`` per configuration on a separable contact grid
    (compiled; see :func:`._kernels_jit.grid_profile_kernel`)."""
    (_JIT or _jit()).grid_profile_kernel(*_inputs(kx, cx, hx, kt, ct, ht, starts, omega, C, d, coherence), float(eps2),
                                         q, lv)
