"""Zero-order approximation (Altintas & Budak 1995) of milling stability, directly on complex FRFs.

Theory (equal pitch, straight flutes)
-------------------------------------
Averaging the time-periodic directional matrix over a revolution gives the
constant ``H0`` of :func:`~bayes_rcsa.stability.cutting.mean_directional_matrix`
(Pa), so the regenerative force is ``F = a H0 (q(t) - q(t - τ))`` with the
tooth period τ = 60/(N n).  With the tool receptance ``G = diag(G_xx, G_yy)``
(m/N; cross receptances neglected) a harmonic chatter solution at ω exists when

    det(I - a (1 - e^{-iωτ}) H0 G(ω)) = 0.

Let μ be an eigenvalue of the oriented FRF matrix ``Φ = H0 G`` (1/m); then
``a (1 - e^{-iωτ}) = 1/μ``.  Requiring a real depth gives, with
κ = Im μ / Re μ,

    a_lim = 1 / (2 Re μ)              (only Re μ > 0 is physical)
    ω τ   = ε + 2 k π,  ε = π + 2 arctan κ ∈ (0, 2π),  k = 0, 1, 2, ...
    n     = 60 ω / (N (ε + 2 k π))    (rpm)

This is the textbook result a_lim = -2π Λ_R (1 + κ_Λ^2)/(N K_t) with
Λ = -N K_t/(4π μ).  For a single mode (stiffness k, damping ratio ζ) in one
direction, min Re G = -1/(4 k ζ (1 + ζ)), so the absolute minimum is
a_lim = 2 k ζ (1 + ζ)/(N K_t α) with the average directional factor
α = |H0_ii|/(N K_t) (α = K_r/(4 K_t) for slotting).

Every frequency line of the FRF and every lobe k gives one (n, a_lim) point;
consecutive lines are joined by straight segments per lobe and per eigenvalue
branch, and the stability boundary on a requested speed grid is the lower
envelope of all segments.  Everything is vectorised over draws, frequency
lines and lobes.  Speeds at which no segment lies (chatter frequency outside
the FRF band) get an infinite limit: the FRFs say nothing about chatter there.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from ..errors import DataError, SetupError
from .cutting import CuttingConditions, mean_directional_matrix

__all__ = ["ZOAResult", "oriented_eigenvalues", "lobe_points", "zoa_lobes", "zoa_minimum_depth", "lobe_count"]


@dataclass(frozen=True)
class ZOAResult:
    """Zero-order stability boundary on a speed grid.

    Attributes
    ----------
    speed_rpm : (n_speed,) rpm
    depth_limit_m : (..., n_speed) m; +inf where no chatter frequency in the FRF band maps to that speed
    chatter_frequency_hz : (..., n_speed) Hz of the limiting segment (nan where depth is inf)
    lobe : (..., n_speed) int, lobe number k of the limiting segment (-1 where depth is inf)
    """

    speed_rpm: np.ndarray
    depth_limit_m: np.ndarray
    chatter_frequency_hz: np.ndarray
    lobe: np.ndarray


def _check_frfs(frf_x, frf_y, frequency_hz):
    f = np.asarray(frequency_hz, dtype=float)
    if f.ndim != 1 or f.size < 2 or np.any(np.diff(f) <= 0) or np.any(f <= 0):
        raise DataError("frequency_hz must be a strictly increasing 1-D array of positive values (>= 2 lines)")
    gx = np.asarray(frf_x, dtype=complex)
    gy = np.asarray(frf_y, dtype=complex)
    try:
        gx, gy = np.broadcast_arrays(gx, gy)
    except ValueError:
        raise DataError(f"FRF shapes {np.shape(frf_x)} and {np.shape(frf_y)} do not broadcast") from None
    if gx.shape[-1] != f.size:
        raise DataError(f"FRFs have {gx.shape[-1]} lines but frequency_hz has {f.size}")
    if not (np.all(np.isfinite(gx)) and np.all(np.isfinite(gy))):
        raise DataError("FRFs contain NaN or inf")
    return gx, gy, f


#: (draw, line) cells whose eigenvalues are formed together: about 2^16, so that the dozen complex work arrays
#: (1 MB each) stay in the processor's cache rather than streaming arrays of 100 MB through memory (4000 draws of
#: 1501 lines: ~3x faster).  Every cell's arithmetic is the same whatever the block, so the numbers are too.
_EIGEN_BLOCK_CELLS = 1 << 16


def _eigen_parts(h0, frf_x, frf_y):
    """Half trace and continuous square root of Φ = H0 diag(G_xx, G_yy), (R, F) complex each: μ = half ± root."""
    a = h0[0, 0] * frf_x
    d = h0[1, 1] * frf_y
    bc = h0[0, 1] * h0[1, 0] * frf_x * frf_y
    half_tr = 0.5 * (a + d)
    root = np.sqrt(0.25 * (a - d) ** 2 + bc)
    if root.shape[-1] > 1:
        # flip the branch wherever the principal root jumps; the running product
        # of flips turns the principal root into a continuous one.
        jump = np.abs(root[..., 1:] - root[..., :-1]) > np.abs(root[..., 1:] + root[..., :-1])
        sign = np.concatenate([np.ones(root.shape[:-1] + (1,)), np.where(jump, -1.0, 1.0)], axis=-1)
        root = root * np.cumprod(sign, axis=-1)
    return half_tr, root


def _row_blocks(n_rows: int, n_freq: int):
    """Consecutive row slices of about :data:`_EIGEN_BLOCK_CELLS` (row, line) cells each."""
    step = max(1, _EIGEN_BLOCK_CELLS // max(1, n_freq))
    return [slice(s, min(s + step, n_rows)) for s in range(0, n_rows, step)]


def oriented_eigenvalues(h0: np.ndarray, frf_x: np.ndarray, frf_y: np.ndarray) -> np.ndarray:
    """Eigenvalues of Φ = H0 diag(G_xx, G_yy), continuous along the frequency axis.

    Parameters
    ----------
    h0 : (2, 2) Pa
    frf_x, frf_y : (..., n_freq) complex, m/N

    Returns
    -------
    (..., n_freq, 2) complex, 1/m.  The square-root branch is chosen so that
    each of the two eigenvalue curves is continuous from line to line
    (cumulative sign tracking), which keeps lobe segments on one branch.
    """
    gx, gy = np.broadcast_arrays(np.asarray(frf_x), np.asarray(frf_y))
    h0 = np.asarray(h0)
    n_freq = gx.shape[-1] if gx.ndim else 1
    if gx.ndim < 2 or gx.size <= _EIGEN_BLOCK_CELLS:
        half_tr, root = _eigen_parts(h0, gx, gy)
        return np.stack([half_tr + root, half_tr - root], axis=-1)
    # many rows: block by block (rows are independent; the flips run along the lines of each row)
    gx2, gy2 = gx.reshape(-1, n_freq), gy.reshape(-1, n_freq)
    out = None
    for rows in _row_blocks(gx2.shape[0], n_freq):
        half_tr, root = _eigen_parts(h0, gx2[rows], gy2[rows])
        if out is None:
            out = np.empty((gx2.shape[0], n_freq, 2), dtype=np.result_type(half_tr, root))
        out[rows, :, 0] = half_tr + root
        out[rows, :, 1] = half_tr - root
    return out.reshape(gx.shape + (2,))


def lobe_count(frequency_hz: np.ndarray, flutes: int, min_speed_rpm: float) -> int:
    """Number of lobes K needed so that lobes k = 0..K-1 reach down to ``min_speed_rpm``.

    Lobe k at chatter frequency f lies above n = 60 f / (N (k + 1)); the
    highest line f_max therefore needs k up to 60 f_max/(N n_min).
    """
    return int(np.ceil(60.0 * float(np.max(frequency_hz)) / (flutes * float(min_speed_rpm)))) + 1


def zoa_minimum_depth(frf_x, frf_y, frequency_hz, cutting: CuttingConditions) -> np.ndarray:
    """Absolute minimum of the zero-order stability limit, min over lines of 1/(2 Re μ).

    Returns
    -------
    (...) m; +inf when no eigenvalue has a positive real part.
    """
    gx, gy, _ = _check_frfs(frf_x, frf_y, frequency_hz)
    mu = oriented_eigenvalues(mean_directional_matrix(cutting), gx, gy)
    best = np.max(mu.real, axis=(-2, -1))
    with np.errstate(divide="ignore"):
        return np.where(best > 0, 1.0 / (2.0 * np.where(best > 0, best, 1.0)), np.inf)


def zoa_lobes(
    frf_x,
    frf_y,
    frequency_hz,
    cutting: CuttingConditions,
    speed_rpm,
    max_lobes: int | None = None,
    chunk: int | None = None,
) -> ZOAResult:
    """Zero-order stability boundary a_lim(n) for one or many pairs of FRFs.

    Parameters
    ----------
    frf_x, frf_y : (..., n_freq) complex, m/N
        Direct tool-point receptances in machine X and Y (measured or
        predicted), e.g. one row per posterior draw.
    frequency_hz : (n_freq,) Hz
    cutting : CuttingConditions (equal pitch)
    speed_rpm : (n_speed,) rpm, strictly increasing
    max_lobes : int or None
        Number of lobes; default :func:`lobe_count` for the lowest speed.
    chunk : int or None
        Draws processed together; default keeps the (draws x lines x 2)
        work arrays near 4e6 elements (64 MB of complex eigenvalues).

    Returns
    -------
    ZOAResult with arrays of shape (..., n_speed).
    """
    if not cutting.equal_pitch:
        raise SetupError("the zero-order approximation here assumes equal pitch; use method 'sdm' for variable pitch")
    gx, gy, f = _check_frfs(frf_x, frf_y, frequency_hz)
    n = np.asarray(speed_rpm, dtype=float)
    if n.ndim != 1 or n.size < 1 or np.any(n <= 0) or np.any(np.diff(n) <= 0):
        raise SetupError("speed_rpm must be a strictly increasing 1-D array of positive speeds")
    batch_shape = gx.shape[:-1]
    gx = gx.reshape(-1, f.size)
    gy = gy.reshape(-1, f.size)
    K = lobe_count(f, cutting.flutes, n[0]) if max_lobes is None else int(max_lobes)
    h0 = mean_directional_matrix(cutting)
    n_draw = gx.shape[0]
    if chunk is None:
        chunk = max(1, int(4e6 // (f.size * 2)))  # the (draws x lines x 2) eigenvalue arrays stay near 64 MB
    depth = np.full((n_draw, n.size), np.inf)
    chat = np.full((n_draw, n.size), np.nan)
    lobe = np.full((n_draw, n.size), -1, dtype=int)
    for s in range(0, n_draw, chunk):
        d, c, k = _envelope(h0, gx[s : s + chunk], gy[s : s + chunk], f, cutting.flutes, n, K)
        depth[s : s + chunk], chat[s : s + chunk], lobe[s : s + chunk] = d, c, k
    return ZOAResult(
        speed_rpm=n,
        depth_limit_m=depth.reshape(batch_shape + (n.size,)),
        chatter_frequency_hz=chat.reshape(batch_shape + (n.size,)),
        lobe=lobe.reshape(batch_shape + (n.size,)),
    )


def lobe_points(mu: np.ndarray, frequency_hz: np.ndarray, flutes: int, lobes: int):
    """Speed and depth of every (line, branch, lobe) stability-boundary point.

    Parameters
    ----------
    mu : (..., n_freq, 2) complex, eigenvalues of H0 G (1/m)
    frequency_hz : (n_freq,) Hz
    flutes : int
    lobes : int, K (lobes k = 0..K-1)

    Returns
    -------
    speed_rpm : (..., n_freq, 2, K) rpm (meaningless where depth is inf)
    depth_m : (..., n_freq, 2) m, 1/(2 Re μ); +inf where Re μ <= 0 (no chatter possible)
    """
    mu_r = mu.real
    valid = mu_r > 0
    safe = np.where(valid, mu_r, 1.0)
    depth = np.where(valid, 0.5 / safe, np.inf)
    eps = np.pi + 2.0 * np.arctan(mu.imag / safe)
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    k = np.arange(lobes)
    speed = 60.0 * omega[:, None, None] / (flutes * (eps[..., None] + 2 * np.pi * k))
    return speed, depth


def _segment_ends(h0, gx, gy):
    """Depth 1/(2 Re μ) (+inf where Re μ <= 0) and phase ε of every (draw, line, branch): (D, F, 2) x2.

    The same arithmetic as :func:`lobe_points` (which also forms the speeds of every lobe; the compiled
    envelope forms them per segment instead), block by block of draws (:data:`_EIGEN_BLOCK_CELLS`), on the real
    and imaginary parts of μ = half ± root directly: a complex sum's parts are the sums of the parts, so the
    numbers are those of the stacked eigenvalues bit for bit.
    """
    gx, gy = np.broadcast_arrays(np.asarray(gx), np.asarray(gy))
    n_draw, n_freq = gx.shape
    depth = np.empty((n_draw, n_freq, 2))
    eps = np.empty((n_draw, n_freq, 2))
    for rows in _row_blocks(n_draw, n_freq):
        half_tr, root = _eigen_parts(h0, gx[rows], gy[rows])
        for b, mu_r, mu_i in ((0, half_tr.real + root.real, half_tr.imag + root.imag),
                              (1, half_tr.real - root.real, half_tr.imag - root.imag)):
            valid = mu_r > 0
            safe = np.where(valid, mu_r, 1.0)
            depth[rows, :, b] = np.where(valid, 0.5 / safe, np.inf)
            eps[rows, :, b] = np.pi + 2.0 * np.arctan(mu_i / safe)
    return depth, eps


# work (draws x (speeds + segments per lobe count)) from which the compiled envelope pays for loading numba
# (about 1 s of a process's CPU): a deterministic chart (one draw) stays in numpy, as fast as before and without
# the compiler; many draws go compiled even at a few speeds (the numpy version's cost is per segment too)
_COMPILED_ENVELOPE_CELLS = 200_000


def _compiled_envelope_loaded() -> bool:
    """Whether this process already holds the compiled envelope's machine code (an earlier large job, or the lobes
    warm-up, loaded it): small jobs then run it too, 3-6x faster than the numpy version and with the same numbers,
    as the cost the threshold avoids (loading numba and the code) is paid."""
    kernel = sys.modules.get(__name__.rpartition(".")[0] + "._zoa_kernel")
    # getattr with a default: another thread (a Dask worker's, a batch worker's) may be importing the module, which
    # sits in sys.modules half-initialised until its functions are defined; such a module counts as not loaded
    envelope = getattr(kernel, "lower_envelope", None)
    return bool(getattr(envelope, "signatures", None))


def _envelope_of_ends(depth_pts, eps, f, flutes, speeds, K, track=True):
    """Lower envelope of all lobe segments from :func:`_segment_ends`: depth (D, S) m, and with ``track`` the
    chatter frequency (D, S) Hz and the lobe number (D, S) of the limiting segment (else None, None).

    Segments join consecutive lines of one eigenvalue branch and one lobe where both ends are physical
    (Re μ > 0); each grid speed inside a segment's speed range gets the linearly interpolated depth, and the
    lowest of them is the limit.  Large jobs run the compiled loop of :mod:`._zoa_kernel`, small ones
    :func:`_envelope_numpy`; both give the same numbers bit for bit.
    """
    f = np.ascontiguousarray(f, dtype=float)
    speeds = np.ascontiguousarray(speeds, dtype=float)
    n_draw = depth_pts.shape[0]
    if n_draw * (speeds.size + 2 * f.size * int(K)) < _COMPILED_ENVELOPE_CELLS and not _compiled_envelope_loaded():
        depth, chat, lob = _envelope_numpy(depth_pts, eps, f, flutes, speeds, K)
        return (depth, chat, lob) if track else (depth, None, None)
    from ._zoa_kernel import lower_envelope

    depth = np.full((n_draw, speeds.size), np.inf)
    shape = (n_draw, speeds.size) if track else (1, 1)
    chat = np.full(shape, np.nan)
    lob = np.full(shape, -1, dtype=np.int64)
    steps = np.diff(speeds)
    uniform = bool(steps.size > 0 and np.all(np.abs(steps - steps.mean()) <= 1e-9 * steps.mean()))
    lower_envelope(np.ascontiguousarray(depth_pts), np.ascontiguousarray(eps), 2 * np.pi * f, f, int(flutes),
                   int(K), speeds, uniform, depth, chat, lob, bool(track))
    return (depth, chat, lob) if track else (depth, None, None)


def _envelope_numpy(depth_pts, eps, f, flutes, speeds, K):
    """The lower envelope in numpy: every (segment, grid speed) pair materialised, sorted by (cell, depth), the
    first of each cell kept (ties: the first segment in (line, branch, lobe) order).  Memory and time grow
    with the number of pairs (about 4 x 10^5 per draw at 25001 speeds): for small jobs.  Returns depth,
    chatter frequency and lobe number, (D, S) each."""
    n_draw = depth_pts.shape[0]
    k = np.arange(K)
    spd = 60.0 * (2 * np.pi * f)[:, None, None] / (flutes * (eps[..., None] + 2 * np.pi * k))  # as lobe_points
    a = depth_pts
    valid = np.isfinite(a)
    s0, s1 = spd[:, :-1], spd[:, 1:]
    a0, a1 = a[:, :-1, :, None], a[:, 1:, :, None]
    ok = (valid[:, :-1] & valid[:, 1:])[..., None] & np.ones(K, dtype=bool)
    i0 = np.searchsorted(speeds, np.minimum(s0, s1), side="left")
    i1 = np.searchsorted(speeds, np.maximum(s0, s1), side="right")  # exclusive
    count = np.where(ok, i1 - i0, 0)
    sel = np.nonzero(count > 0)
    cnt = count[sel]
    total = int(cnt.sum())
    depth = np.full((n_draw, speeds.size), np.inf)
    chat = np.full((n_draw, speeds.size), np.nan)
    lob = np.full((n_draw, speeds.size), -1, dtype=np.int64)
    if total == 0:
        return depth, chat, lob
    rep = np.repeat(np.arange(cnt.size), cnt)
    grid_idx = i0[sel][rep] + np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    d_idx, f_idx, b_idx, k_idx = (x[rep] for x in sel)
    x0, x1 = s0[d_idx, f_idx, b_idx, k_idx], s1[d_idx, f_idx, b_idx, k_idx]
    y0, y1 = a0[d_idx, f_idx, b_idx, 0], a1[d_idx, f_idx, b_idx, 0]
    span = x1 - x0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(span != 0, (speeds[grid_idx] - x0) / np.where(span != 0, span, 1.0), 0.0)
    val = y0 + t * (y1 - y0)
    cell = d_idx * speeds.size + grid_idx
    order = np.lexsort((val, cell))
    first = np.ones(order.size, dtype=bool)
    first[1:] = cell[order][1:] != cell[order][:-1]
    pick = order[first]
    depth.reshape(-1)[cell[pick]] = val[pick]
    chat.reshape(-1)[cell[pick]] = f[f_idx[pick]] + t[pick] * (f[f_idx[pick] + 1] - f[f_idx[pick]])
    lob.reshape(-1)[cell[pick]] = k_idx[pick]
    return depth, chat, lob


def _envelope(h0, gx, gy, f, flutes, speeds, K):
    """Lower envelope of all lobe segments for a chunk of draws: (n_draw, n_speed) x3."""
    depth_pts, eps = _segment_ends(h0, gx, gy)
    return _envelope_of_ends(depth_pts, eps, f, flutes, speeds, K)


# ----------------------------------------------------------------------------------------
# registration as a stability method (bayes_rcsa.stability.methods)
class ZOAMethod:
    """Zero-order approximation directly on the FRF draws (:func:`zoa_lobes`)."""

    name = "zoa"
    summary = "zero-order approximation on the complex FRFs (fast; accurate at moderate to full radial immersion)"

    def check(self, options) -> None:
        return None

    def estimate_seconds(self, n_draws: int, n_speeds: int, n_freq: int) -> float:
        # measured on the bundled 30 mm files (1501 lines), 500 draws x 25001 speeds, compiled envelope (issue 44):
        # about 1.5 s fixed (imports, figure), 2.5 s per 500 x 25001 (draw, speed) cells (envelope, map, order
        # statistics) and 0.5 s per 500 x 1500 (draw, line) eigenproblems
        return 1.5 + 2.5 * (n_draws * n_speeds) / (500 * 25001) + 0.5 * (n_draws * n_freq) / (500 * 1500)

    def depth_limits(self, frf_x, frf_y, frequency_hz, cutting, speeds_rpm, options, progress=None):
        from .methods import MethodResult

        if not cutting.equal_pitch:
            raise SetupError("the zero-order approximation here assumes equal pitch; use method 'sdm' for variable "
                             "pitch")
        gx, gy, f = _check_frfs(frf_x, frf_y, frequency_hz)
        gx, gy = gx.reshape(-1, f.size), gy.reshape(-1, f.size)
        n = np.asarray(speeds_rpm, dtype=float)
        if n.ndim != 1 or n.size < 1 or np.any(n <= 0) or np.any(np.diff(n) <= 0):
            raise SetupError("speed_rpm must be a strictly increasing 1-D array of positive speeds")
        # the eigenvalues once: the recommendation's checks between grid speeds (limits_at) reuse them
        ends = _segment_ends(mean_directional_matrix(cutting), gx, gy)

        def limits_at(speeds):
            s = np.asarray(speeds, dtype=float)
            return _envelope_of_ends(*ends, f, cutting.flutes, s, lobe_count(f, cutting.flutes, s[0]),
                                     track=False)[0]

        lim = limits_at(n)
        if progress is not None:
            progress(1.0)
        return MethodResult(lim, limits_at=limits_at)


def _register() -> None:
    from .methods import STABILITY_METHODS

    STABILITY_METHODS.register(ZOAMethod.name, ZOAMethod())


_register()
