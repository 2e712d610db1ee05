"""Modal fits of spindle flange files, shared by the spindle terms (not a term itself).

A spindle file's flange block ``S = [[h, l], [n, p]]`` (m/N, 1/N, rad/N,
rad/(N m)) is, in the file band, a sum of lightly damped modes plus the
residuals of the modes outside it::

    S(w) = sum_r R_r / D_r(w) + R_0 - R_m / w^2,   D_r = w_r^2 - w^2 + 2 i zeta_r w_r w

with ``R_r = phi_r phi_r^T`` the (real, symmetric, positive semi-definite)
residue of mode ``r`` (``phi_r = (u_r, psi_r)``, the mass-normalised flange
translation and rotation), ``R_0`` and ``R_m`` real 2x2 residuals.

The poles ``(w_r, zeta_r)`` are common to all components and fitted by
variable projection: for given poles the residues and residuals of each
component follow by (non-negative for ``h`` and ``p``, free for ``l``)
linear least squares, relative weighting floored at a tenth of the
component's median magnitude so that anti-resonances do not dominate.  The
number of modes (at most ``max_modes``) is chosen by BIC.  Fits are cached
per file content.

:func:`fit_poles` is the projection shared with
:mod:`.spindle_rotation_omitted` (one component, ``h``);
:func:`block_modes` / :func:`model_block_modes` fit whole blocks for
:mod:`.spindle_error`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...caching import BoundedCache
from ...errors import ModelError

__all__ = ["BlockModes", "block_modes", "model_block_modes", "fit_poles", "peaks", "ZETA_BOUNDS"]

ZETA_BOUNDS = (1e-4, 0.3)
#: Fits by the exact bytes of the spindle file's lines and values (the arrays read-only).
_CACHE = BoundedCache(16)
#: Lines used for the pole search of :func:`block_modes` (a 2 Hz file is searched on every second line).
_POLE_LINES = 400


def basis(omega: np.ndarray, wr: np.ndarray, z: np.ndarray, eta: np.ndarray | None = None,
          loss_column: bool = False) -> np.ndarray:
    """Columns ``1/D_r``, 1, ``-1/w^2`` (and ``-i`` with ``loss_column``), (n, N + 2 [+ 1]) complex.

    ``D_r = w_r^2 (1 + i eta_r) - w^2 + 2 i zeta_r w_r w`` (``eta`` omitted: viscous modal damping only).
    """
    w = omega[:, None]
    d = wr[None] ** 2 - w**2 + 2j * z[None] * wr[None] * w
    if eta is not None:
        d = d + 1j * eta[None] * wr[None] ** 2
    cols = [1.0 / d, np.ones_like(w, dtype=complex), (-1.0 / w**2).astype(complex)]
    if loss_column:
        cols.append(np.full_like(w, -1j, dtype=complex))
    return np.concatenate(cols, axis=1)


def _solve(b: np.ndarray, y: np.ndarray, wt: np.ndarray, nonneg: bool):
    """Weighted linear least squares of one component on the basis ``b``; returns (residual, coefficients)."""
    bw = b * wt[:, None]
    a = np.concatenate([bw.real, bw.imag])
    yy = np.concatenate([(y * wt).real, (y * wt).imag])
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    if nonneg:
        from scipy.optimize import nnls  # lazy: reading a setup (and the CLI's error paths) needs no scipy

        c, _ = nnls(a / scale, yy)
    else:
        c = np.linalg.lstsq(a / scale, yy, rcond=None)[0]
    c = c / scale
    return a @ c - yy, c


def project(x: np.ndarray, n: int, omega: np.ndarray, comps: Sequence[tuple], full: bool = False):
    """Variable projection: poles from ``x``, linear coefficients per component.

    ``x`` holds (log w_r, log zeta_r) or, with ``full``, (log w_r, log zeta_r, log eta_r), and the basis
    then also carries a constant loss column ``-i`` (the hysteretic damping of the modes outside the band).
    ``comps`` is a sequence of ``(y (n_lines,) complex, wt (n_lines,) float, nonneg bool)``.
    Returns the stacked weighted residual, the coefficient vectors (one per component), ``w_r``, ``zeta_r``
    (and ``eta_r`` with ``full``).
    """
    wr, z = np.exp(x[:n]), np.exp(x[n:2 * n])
    eta = np.exp(x[2 * n:3 * n]) if full else None
    b = basis(omega, wr, z, eta, loss_column=full)
    res, coefs = [], []
    for y, wt, nonneg in comps:
        r, c = _solve(b, y, wt, nonneg)
        res.append(r)
        coefs.append(c)
    return (np.concatenate(res), coefs, wr, z) + ((eta,) if full else ())


def peaks(f: np.ndarray, mag: np.ndarray, n: int) -> list[float]:
    """The ``n`` largest local maxima of ``mag`` (Hz) away from the ends of the file."""
    i = np.flatnonzero((mag[1:-1] > mag[:-2]) & (mag[1:-1] >= mag[2:])) + 1
    i = i[(i > 2) & (i < f.size - 3)]
    return [float(f[j]) for j in i[np.argsort(-mag[i])][:n]]


def fit_poles(omega: np.ndarray, comps: Sequence[tuple], starts_hz: Sequence[float], full: bool = False):
    """Poles started at ``starts_hz`` refined by variable projection over all components.

    Without ``full``: viscous modal damping, poles inside the band.  With ``full``: viscous and
    hysteretic modal damping, poles within [0.5, 1.5] times the band's ends (a mode just outside the
    band still shapes its edge), a hysteretic residual.

    Returns ``(chi2, coefficients per component, w_r (N,), zeta_r (N,))`` and, with ``full``, ``eta_r (N,)``.
    """
    n = len(starts_hz)
    lo, hi = np.log(omega[0]), np.log(omega[-1])
    if full:
        lo, hi = lo + np.log(0.5), hi + np.log(1.5)
    x0 = np.concatenate([np.log(2 * np.pi * np.asarray(starts_hz, dtype=float)), np.full(n, np.log(0.02 if not full
                                                                                                   else 0.005))]
                        + ([np.full(n, np.log(0.02))] if full else []))
    if n:
        k = 3 if full else 2
        lb = np.concatenate([np.full(n, lo)] + [np.full(n, np.log(ZETA_BOUNDS[0]))] * (k - 1))
        ub = np.concatenate([np.full(n, hi)] + [np.full(n, np.log(ZETA_BOUNDS[1]))] * (k - 1))
        x0 = np.clip(x0, lb + 1e-9, ub - 1e-9)
        from scipy.optimize import least_squares

        x = least_squares(lambda v: project(v, n, omega, comps, full)[0], x0, bounds=(lb, ub), x_scale=1.0,
                          **({"max_nfev": 60, "xtol": 1e-6} if full else {})).x
    else:
        x = x0
    out = project(x, n, omega, comps, full)
    return (float(out[0] @ out[0]),) + out[1:]


def _weight(y: np.ndarray) -> np.ndarray:
    mag = np.abs(y)
    return 1.0 / np.maximum(mag, 0.1 * np.median(mag))


@dataclass(frozen=True)
class BlockModes:
    """Modal model of a spindle file's flange block.

    Attributes
    ----------
    omega : (N,) rad/s
        Natural frequencies, ascending.
    zeta : (N,)
        Viscous modal damping ratios.
    eta : (N,)
        Hysteretic modal loss factors (``D_r = w_r^2 (1 + i eta_r) - w^2 + 2 i zeta_r w_r w``).
    residue : (N, 2, 2) real
        ``R_r``: symmetric, positive semi-definite (``[[u^2, u psi], [u psi, psi^2]]`` of a real mode),
        units of ``S`` times rad^2/s^2.  (Not scaled for passivity: the fitted modes of a
        non-proportionally damped spindle may carry more damping than the file at some lines, so a
        term that adds modal changes to the file must keep passivity by its own construction.)
    rel_rms : float
        Relative RMS misfit of the fit (before ``gamma``), weighted as fitted.
    source : str
    """

    omega: np.ndarray
    zeta: np.ndarray
    eta: np.ndarray
    residue: np.ndarray
    rel_rms: float
    source: str

    @property
    def n_modes(self) -> int:
        return int(self.omega.size)

    def denominators(self, omega: np.ndarray) -> np.ndarray:
        """``D_r(w)``, (n, N) complex rad^2/s^2."""
        w = np.asarray(omega, dtype=float)[:, None]
        wr, z, e = self.omega[None], self.zeta[None], self.eta[None]
        return wr**2 * (1 + 1j * e) - w**2 + 2j * z * wr * w


def _psd(a: float, b: float, c: float) -> tuple[float, float, float]:
    """Nearest (keeping the diagonal) positive semi-definite ``[[a, b], [b, c]]`` with ``a, c >= 0``."""
    a, c = max(a, 0.0), max(c, 0.0)
    lim = np.sqrt(a * c)
    return a, float(np.clip(b, -lim, lim)), c


def block_modes(receptance, max_modes: int = 5, n_modes: int | None = None,
                start_hz: Sequence[float] | None = None) -> BlockModes:
    """Modal fit of a spindle file's whole flange block (cached per file content).

    Parameters
    ----------
    receptance : PointReceptance
        The spindle file, blocks (n, 2, 2).
    max_modes : int
        Largest mode count tried (count by BIC).
    n_modes : int, optional
        Fixed mode count (to match a second direction's file to the first).
    start_hz : sequence of float, optional
        Starting frequencies (Hz) used before the file's own peaks.

    Returns
    -------
    BlockModes

    Raises
    ------
    ModelError
        If ``h`` is zero, non-finite or the file has fewer than 8 lines.
    """
    f = np.asarray(receptance.frequency_hz, dtype=float)
    s = np.asarray(receptance.block, dtype=complex)
    key = hashlib.blake2b(f.tobytes() + s.tobytes() + repr((max_modes, n_modes, start_hz)).encode(),
                          digest_size=16).digest()
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    src = getattr(receptance, "source", "<spindle>")
    h, l, p = s[:, 0, 0], 0.5 * (s[:, 0, 1] + s[:, 1, 0]), s[:, 1, 1]
    if not np.all(np.isfinite(s)) or not np.any(np.abs(h) > 0) or f.size < 8:
        raise ModelError(f"{src}: the flange block is zero, too short or not finite; its modes cannot be fitted")
    omega = 2 * np.pi * f
    comps = [(h, _weight(h), True)]
    rot = bool(np.any(np.abs(p) > 0))
    if rot:
        comps += [(l, _weight(l), False), (p, _weight(p), True)]
    # starting poles: the largest peaks of |h| and |p| (ranked by their relative height), then a mode just
    # below the band when a magnitude falls away from its lower edge, then one above the band
    found: list[tuple[float, float]] = []
    for y in ([h, p] if rot else [h]):
        mag = np.abs(y) / np.median(np.abs(y))
        found += [(float(mag[np.argmin(abs(f - q))]), q) for q in peaks(f, mag, max_modes)]
        m = max(f.size // 10, 3)
        if mag[:3].max() > 2 * mag[:m].min() and mag[:3].max() >= mag[3:m].max():
            found.append((0.0, 0.98 * f[0]))
    starts_found, seen = [], []
    for _, q in sorted(found, key=lambda t: -t[0]):
        if all(abs(q - o) > 0.03 * o for o in seen):
            seen.append(q)
            starts_found.append(q)
    starts_found.append(1.3 * f[-1])
    cand = list(start_hz or []) + [q for q in starts_found if not start_hz]
    n_peaks = len(starts_found) - 1 if not start_hz else len(cand)  # in-band peaks and a mode below the band
    counts = [n_modes] if n_modes is not None else range(min(n_peaks, max_modes), min(max_modes, len(cand)) + 1)
    # the poles are searched on at most _POLE_LINES lines (every k-th), the final fit uses all lines
    k = max(1, int(np.ceil(f.size / _POLE_LINES)))
    sub = [(y[::k], wt[::k], nn) for y, wt, nn in comps]
    n_res = 2 * f.size * len(comps)
    best = None
    for n in counts:
        starts = sorted(cand[:n]) if len(cand) >= n else sorted(cand + list(np.geomspace(f[2], f[-3], n - len(cand))))
        _, _, wr, z, eta = fit_poles(omega[::k], sub, starts, full=True)
        res, coefs = project(np.log(np.concatenate([wr, z, eta])), n, omega, comps, full=True)[:2]
        chi2 = float(res @ res)
        # a mode with no residue in h and p (below 1e-3 of the largest) is no mode (BIC search); a fixed count keeps
        # its modes (the order matches the other file's)
        big = [c[:n] > 1e-3 * max(c[:n].max(initial=0.0), 1e-300) for c in (coefs[0], coefs[-1])]
        keep = (big[0] | big[1]) if n_modes is None else np.ones(n, dtype=bool)
        bic = n_res * np.log(max(chi2, 1e-20 * n_res) / n_res) + ((3 + len(comps)) * int(keep.sum()) + 3 * len(comps)) \
            * np.log(n_res)
        if best is None or bic < best[0]:
            best = (bic, chi2, coefs, wr, z, eta, keep, n)
    _, chi2, coefs, wr, z, eta, keep, n = best
    idx = np.flatnonzero(keep)
    idx = idx[np.argsort(wr[idx])]
    res = np.zeros((idx.size, 2, 2))
    for k, r in enumerate(idx):
        a = coefs[0][r]
        b, c = (coefs[1][r], coefs[2][r]) if rot else (0.0, 0.0)
        a, b, c = _psd(a, b, c)
        res[k] = [[a, b], [b, c]]
    out = BlockModes(omega=wr[idx], zeta=z[idx], eta=eta[idx], residue=res, rel_rms=float(np.sqrt(chi2 / n_res)),
                     source=src)
    for arr in (out.omega, out.zeta, out.eta, out.residue):
        arr.flags.writeable = False  # shared through the cache
    return _CACHE.put(key, out)


def model_block_modes(model, max_modes: int = 5) -> dict[str, BlockModes]:
    """Block modes of every spindle file of ``model`` by direction (cached per file).

    The first file (``x`` if present) chooses the count by BIC; the others are fitted with the same
    count started from its frequencies, so that mode ``r`` means the same mode in every direction.
    """
    files = dict(model.spindle)
    first = "x" if "x" in files else next(iter(files))
    ref = block_modes(files[first], max_modes=max_modes)
    out = {first: ref}
    for d, r in files.items():
        if d != first:
            out[d] = block_modes(r, max_modes=max_modes, n_modes=ref.n_modes,
                                 start_hz=list(ref.omega / (2 * np.pi)))
    return out
