"""``spindle_rotation_omitted``: the spindle file lacks (part of) its rotational flange receptances.

A spindle receptance measured with a hammer and one accelerometer gives
only the translational ``h = u/F`` at the flange; ``l = u/M``,
``n = psi/F`` and ``p = psi/M`` need a moment excitation or a finite-
difference rig, and are often left at zero or taken from a crude model.
Without them RCSA treats the flange as rotationally rigid, which stiffens
the assembly.

Modal reconstruction
--------------------
The translational receptance is a sum of modes,
``h = sum_r A_r / D_r + R_0 - R_m / w^2`` with
``D_r = w_r^2 - w^2 + 2 i zeta_r w_r w`` and real residues
``A_r = u_r^2 >= 0`` (mass-normalised flange translation ``u_r`` squared; a
lightly damped spindle has nearly real modes), ``R_0`` and ``R_m`` the
residuals of the modes above and below the file.  Each mode rotates the
flange too, ``psi_r = s_r u_r``, with a *slope ratio* ``s_r`` (1/m) that the
translation alone cannot reveal.  The same modes then give the missing
receptances::

    l = n = sum_r s_r A_r / D_r,      p = sum_r s_r^2 A_r / D_r

The modes ``(w_r, zeta_r, A_r)`` are fitted to the file's ``h`` once per
spindle file (parameter independent, cached: :func:`flange_modes`): peaks of
``|h|`` as starting poles, variable projection with non-negative residues
and residuals, the number of modes (at most :data:`MAX_MODES`) by BIC.  The
term's parameters are the slope ratios of those modes.

Why per-mode slopes.  The one-lever rocking model (``psi = u / a`` for every
mode, ``S' = S + h [[0, 1/a], [1/a, 1/a^2]]``, the term's first version) is
the special case ``s_r = 1/a``; the bench spindle's two modes in the file
band have slope ratios of about 4 and 16 1/m, so no common lever fits both
(its best fit closed 28 % of the tool-point gap, this one closes it to the
noise floor).  A rotational residual for modes below the file (a rocking
mode of the nose at 468 Hz on the bench is nearly invisible in ``h``) was
tried: with the contact fixed it improves ``p``, but the workflow's contact
refit absorbs it and the evidence preferred the term without it (criterion
25.8 against 22.9), so it is left out.

Modes above the file band.  They reach the band as a static flexibility,
which for ``h`` is the fitted residual ``R_0``; for the whole block it is
the real, positive semi-definite ``sum_upper [[u^2, u psi], [u psi, psi^2]]
/ w_r^2``.  Every such block with the file's ``R_0`` is
``R_0 [[1, s_0], [s_0, s_0^2]] + [[0, 0], [0, c_0]]``, ``c_0 >= 0``: an
effective slope ratio ``s_0`` of the upper modes, and a rotational compliance
``c_0`` of modes that turn the flange without translating it (bearing tilt,
rocking of the nose), which ``h`` cannot show at all.  So::

    l = n = sum_r s_r A_r / D_r + s_0 R_0,   p = sum_r s_r^2 A_r / D_r + s_0^2 R_0 + c_0

On a spindle whose bearings give it a soft rotation (the independent rotor
bench, 500-3500 Hz, its true l and p least-squares fitted with these
parameters) the upper part carries most of ``p``: without it the best slopes
leave 44 % of ``l`` and 94 % of ``p`` unexplained (and the workflow pushed
the third mode's slope to the prior bound, then named another effect);
with it 6 % and 4 % (``s_0`` 31 1/m, ``c_0`` 0.95 urad/(N m), the in-band
slopes 6.7, 6.1 and 14.3 1/m, each within 10 % of the square root of its
``p`` coefficient: the modal structure holds).  On the project's bench,
whose spindle rotation comes from its in-band modes, the same fit gives a
small upper part (``c_0`` 0.05 urad/(N m)) and changes the misfit by less
than one percentage point.

The added block is ``[[0, l], [l, p]]``; with all parameters at baseline
(``s_r = s_0 = c_0 = 0``) it is exactly zero and the file's block is returned
unchanged.  The upper part is real, so it leaves the imaginary part, and
with it passivity, as it is.

Passivity and reciprocity
-------------------------
``l`` appears in both off-diagonal places (reciprocal).  For a
translational-only file (``l = n = p = 0``, the situation the term models)
the imaginary part of ``S'`` is::

    Im S' = diag(Im h - sum_r a_r, 0) + sum_r a_r [1, s_r]^T [1, s_r],   a_r = Im(A_r / D_r) <= 0

The second sum is negative semi-definite for every ``s_r``; the first is
too wherever the fitted modes do not carry more damping than the file,
``|sum_r a_r| <= |Im h|``.  The fitted residues are therefore scaled by the
largest common factor ``gamma <= 1`` that makes this hold at every passive
line of the file (``FlangeModes.gamma``; 0.82 on the bench, whose bearing
dampers make the modes slightly complex; a warning below
:data:`GAMMA_WARN`).  Hence ``S'`` is passive at the file's lines for *all*
slope ratios; between lines it inherits the linear interpolation of the
file.  A file that already carries rotational receptances receives the
modal block on top; its passivity is then not guaranteed by construction
(the term exists for files without them): on the bench's complete spindle
file the largest positive eigenvalue of ``Im S'`` over the whole prior is
0.54 % of the line's largest eigenvalue magnitude.  (Requiring it would
mean scaling by the Schur complement of the file's imaginary block, which is
zero for a rank-one file such as a crude one-lever model: the term would be
unable to correct exactly the files it is meant for.)

Limits
------
* Modes with a resonance inside the file band get a slope each; the modes
  above it one static block (``s_0``, ``c_0``: the upper modes' rotation
  is not resolved mode by mode, which a static flexibility cannot show
  anyway); modes *below* the band act through ``R_m`` in ``h`` only (no
  rotation attributed: a rotational mass residual was tried, see above).
  An in-band mode that hardly moves the flange in translation (a rocking
  mode) is invisible, except through ``c_0`` once it lies above the band.
  On the project's bench the best slopes reproduce the true ``l`` within
  8 % and ``p`` within 12 % over 600-1500 Hz; on the rotor bench, with the
  upper block, within 6 % and 4 % over 500-3500 Hz.
* The flange's rotational compliance and the tool-holder contact's act on
  the same rotation between spindle and tool; two clamping lengths separate
  them only in part (noise-free fits of contact and term: the contact's
  rotational stiffness 2.0 and 1.36 times its clean-data value on the two
  benches, 3.6 and 200 times with in-band slopes alone).
* Modes closer than a half-power bandwidth are fitted as one; a file
  without any resonance gets one slope on its quasi-static part
  ``R_0 - R_m / w^2``.
* The identified ``s_r`` is an effective flange slope ratio of the fitted
  mode, not a measured mode shape; slopes of modes far from the tool mode
  are weakly determined (wide posterior).

Parameters
----------
``rotation_slope_mode{r}_per_m`` (1/m), one per fitted mode ``r = 1..N`` (N <= 3, ascending frequency)
    Flange slope ratio ``psi_r / u_r`` of mode ``r`` of the first spindle
    file (``x``); the other direction's file is fitted with the same number
    of modes, started from the first file's frequencies and matched by
    frequency order.  Prior uniform on ``[-S_MAX, S_MAX]``, ``S_MAX = 50``
    1/m: a mode rocking about a pivot at least 2 cm behind the flange (the
    front bearing cannot be closer; the first version's lever prior started
    at the same 2 cm), well above the bending wavenumber of a 50-100 mm
    spindle nose (< 20 1/m below 5 kHz).  Baseline 0.
``rotation_slope_upper_per_m`` (1/m)
    ``s_0``, the effective slope ratio of the modes above the file band
    (their static flexibility ``R_0`` in ``h``); the same prior, baseline 0.
``rotation_compliance_upper_urad_per_Nm`` (urad/(N m) = 1e-6 rad/(N m))
    ``c_0``, the rotational compliance of upper modes that do not translate
    the flange.  Prior uniform on ``[0, C_MAX]``, ``C_MAX = 20``: a flange
    rotational stiffness down to 5e4 N m/rad, below the softest spindle
    nose (two front bearing sets of 50 N/um 50 mm apart give about 6e4 N m/rad
    in series with nothing else); baseline 0 (a physical bound).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ... import messages
from ...caching import BoundedCache
from ...errors import ModelError
from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import ModelTerm
from .flange_modal import fit_poles, peaks

__all__ = ["SpindleRotationOmitted", "FlangeModes", "flange_modes", "model_flange_modes", "MAX_MODES", "S_MAX",
           "C_MAX", "GAMMA_WARN", "UPPER_SLOPE", "UPPER_COMPLIANCE"]

#: Largest number of spindle modes given a slope ratio (the workflow's evidence pays for every parameter).
MAX_MODES = 3
#: Bound of the slope-ratio prior, 1/m (pivot >= 2 cm behind the flange).
S_MAX = 50.0
#: Bound of the upper modes' rotational compliance prior, urad/(N m) (flange rotational stiffness >= 5e4 N m/rad).
C_MAX = 20.0
#: Names of the upper modes' (above the file band) slope ratio and rotational compliance.
UPPER_SLOPE = "rotation_slope_upper_per_m"
UPPER_COMPLIANCE = "rotation_compliance_upper_urad_per_Nm"
#: Below this residue scale the fitted modes carry clearly more damping than the file: warn.
GAMMA_WARN = 0.5
#: Fits by the exact bytes of the spindle file's lines and values (the arrays read-only).
_CACHE = BoundedCache(16)


@dataclass(frozen=True)
class FlangeModes:
    """Modal model of a file's translational flange receptance ``h``.

    Attributes
    ----------
    omega : (N,) rad/s
        Natural frequencies, ascending.
    zeta : (N,)
        Damping ratios.
    residue : (N,) m/(N s^2) = 1/kg
        ``gamma * A_r``, non-negative.
    residual_static : float m/N
        ``R_0`` (modes above the file).
    residual_mass : float m rad^2/(N s^2)
        ``R_m`` (modes below the file), term ``-R_m / w^2``.
    gamma : float
        Residue scale that keeps ``Im h - sum_r a_r`` passive (see the module docstring).
    rel_rms : float
        Relative RMS misfit of the fit (before ``gamma``), weighted as fitted.
    source : str
    """

    omega: np.ndarray
    zeta: np.ndarray
    residue: np.ndarray
    residual_static: float
    residual_mass: float
    gamma: float
    rel_rms: float
    source: str

    @property
    def n_modes(self) -> int:
        return int(self.omega.size)

    def mode_terms(self, omega: np.ndarray) -> np.ndarray:
        """``gamma A_r / D_r(w)``, (n, N) complex m/N; for N = 0 one quasi-static column ``R_0 - R_m / w^2``."""
        w = np.asarray(omega, dtype=float)[:, None]
        if self.n_modes == 0:
            return (self.residual_static - self.residual_mass / w**2).astype(complex)
        wr, z = self.omega[None], self.zeta[None]
        return self.residue[None] / (wr**2 - w**2 + 2j * z * wr * w)


def flange_modes(receptance, max_modes: int = MAX_MODES, n_modes: int | None = None,
                 start_hz: list[float] | None = None) -> FlangeModes:
    """Modal fit of a spindle file's translational receptance (cached per file content).

    Parameters
    ----------
    receptance : PointReceptance
        The spindle file (``h`` = ``block[:, 0, 0]``).
    max_modes : int
        Largest mode count tried; the count is chosen by BIC.
    n_modes : int, optional
        Fixed mode count instead (used to match a second direction's file to the first).
    start_hz : list of float, optional
        Starting frequencies (Hz) used before the file's own peaks.

    Returns
    -------
    FlangeModes

    Raises
    ------
    ModelError
        If the file's translational receptance is zero or non-finite.
    """
    f = np.asarray(receptance.frequency_hz, dtype=float)
    h = np.asarray(receptance.block, dtype=complex)[:, 0, 0]
    key = hashlib.blake2b(f.tobytes() + h.tobytes() + repr((max_modes, n_modes, start_hz)).encode(),
                          digest_size=16).digest()
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    src = getattr(receptance, "source", "<spindle>")
    mag = np.abs(h)
    if not np.all(np.isfinite(h)) or not np.any(mag > 0) or f.size < 8:
        raise ModelError(f"{src}: the translational flange receptance h is zero, too short or not finite; "
                         "spindle_rotation_omitted needs its modes")
    omega = 2 * np.pi * f
    # relative weighting, floored at a tenth of the median so that anti-resonances do not dominate
    wt = 1.0 / np.maximum(mag, 0.1 * np.median(mag))
    n_res = 2 * f.size
    found = peaks(f, mag, max(max_modes, n_modes or 0))
    candidates = (list(start_hz or []) + [p for p in found if not start_hz])
    counts = [n_modes] if n_modes is not None else range(0, min(max_modes, len(candidates)) + 1)
    best = None
    for n in counts:
        starts = sorted(candidates[:n]) if len(candidates) >= n else sorted(candidates + list(
            np.geomspace(f[2], f[-3], n - len(candidates))))
        chi2, (c,), wr, z = fit_poles(omega, [(h, wt, True)], starts)
        # a zero residue is no mode (BIC search); a fixed count keeps its modes so that the slopes match by order
        keep = c[:n] > 0 if n_modes is None else np.ones(n, dtype=bool)
        bic = n_res * np.log(max(chi2, 1e-300) / n_res) + (3 * int(keep.sum()) + 2) * np.log(n_res)
        if best is None or bic < best[0]:
            best = (bic, chi2, c, wr, z, keep, n)
    _, chi2, c, wr, z, keep, n = best
    order = np.argsort(wr[keep])
    wr, z, a = wr[keep][order], z[keep][order], c[:n][keep][order]
    # gamma: the fitted modes may not carry more damping than the file at any (passive) line
    ia = (a[None] / (wr[None] ** 2 - omega[:, None] ** 2 + 2j * z[None] * wr[None] * omega[:, None])).imag.sum(axis=1)
    ok = (h.imag <= 0) & (ia < 0)
    gamma = float(min(1.0, np.min(-h.imag[ok] / -ia[ok]))) if np.any(ok) else 1.0
    if gamma < GAMMA_WARN:
        messages.warn(f"{src}: the modal fit of h carries more damping than the file at some lines; its residues "
                      f"are scaled by {gamma:.2f} to keep the reconstructed spindle block passive", stacklevel=2)
    for arr in (wr, z, a):
        arr.flags.writeable = False  # shared through the cache
    out = FlangeModes(omega=wr, zeta=z, residue=gamma * a, residual_static=float(c[n]), residual_mass=float(c[n + 1]),
                      gamma=gamma, rel_rms=float(np.sqrt(chi2 / n_res)), source=src)
    out.residue.flags.writeable = False
    return _CACHE.put(key, out)


def model_flange_modes(model) -> dict[str, FlangeModes]:
    """Flange modes of every spindle file of ``model`` by direction (cached).

    The first file (``x`` if present) chooses the mode count by BIC; the
    others are fitted with the same count, started from its frequencies, so
    that slope ``r`` means the same mode in every direction.
    """
    files = dict(model.spindle)
    first = "x" if "x" in files else next(iter(files))
    ref = flange_modes(files[first])
    out = {first: ref}
    for d, r in files.items():
        if d != first:
            out[d] = flange_modes(r, n_modes=ref.n_modes, start_hz=list(ref.omega / (2 * np.pi)))
    return out


def _slope_names(n: int) -> list[str]:
    return [f"rotation_slope_mode{r + 1}_per_m" for r in range(max(n, 1))]


@register_term
class SpindleRotationOmitted(ModelTerm):
    """Restores rotational flange receptances from the modes of the translational one (spindle kind)."""

    name = "spindle_rotation_omitted"
    kind = "spindle"
    description = ("the spindle file lacks its rotational receptances (only translation was measured): the flange "
                   "is softer in rotation than the file says")

    def __init__(self) -> None:
        self._ctx_cache: tuple | None = None  # (ctx, per-line mode terms (n_lines, N))

    def __getstate__(self) -> dict:
        # the per-context cache holds the whole model: rebuilt on first use after unpickling
        return {**self.__dict__, "_ctx_cache": None}

    def parameters(self, model) -> tuple[Parameter, ...]:
        modes = model_flange_modes(model)
        ref = next(iter(modes.values()))
        out = []
        for r, name in enumerate(_slope_names(ref.n_modes)):
            at = (f"mode {r + 1} at {ref.omega[r] / (2 * np.pi):.0f} Hz" if ref.n_modes
                  else "the quasi-static compliance")
            out.append(Parameter(name, unit="1/m", role="term", prior=Uniform(-S_MAX, S_MAX),
                                 label=f"flange slope ratio psi/u of {at} [1/m]", baseline=0.0, term=self.name,
                                 description=f"flange rotation per unit flange translation of the spindle's {at}"))
        out.append(Parameter(UPPER_SLOPE, unit="1/m", role="term", prior=Uniform(-S_MAX, S_MAX),
                             label="flange slope ratio psi/u of the modes above the file [1/m]", baseline=0.0,
                             term=self.name, description="effective flange rotation per unit flange translation of "
                             "the spindle modes above the file band (their static flexibility in h)"))
        out.append(Parameter(UPPER_COMPLIANCE, unit="urad/(N m)", role="term", prior=Uniform(0.0, C_MAX),
                             label="flange rotational compliance of the modes above the file [urad/(N m)]",
                             baseline=0.0, term=self.name,
                             description="static rotational compliance of spindle modes above the file band that "
                             "turn the flange without translating it (bearing tilt, rocking of the nose)"))
        return tuple(out)

    def _line_terms(self, ctx) -> tuple[np.ndarray, np.ndarray]:
        """Parameter-independent modal terms ``gamma A_r / D_r`` (n_lines, N) and the static residual ``R_0`` of
        each line's file (n_lines,) m/N, on the context's lines, cached."""
        if self._ctx_cache is not None and self._ctx_cache[0] is ctx:
            return self._ctx_cache[1], self._ctx_cache[2]
        modes = model_flange_modes(ctx.model)
        n = next(iter(modes.values())).n_modes
        omega = np.asarray(ctx.omega, dtype=float)
        terms = np.zeros((omega.size, max(n, 1)), dtype=complex)
        r0 = np.zeros(omega.size)
        for j, cfg in enumerate(ctx.configurations):  # a few configurations, each vectorised over its lines
            lines = np.flatnonzero(np.asarray(ctx.line_config) == j)
            m = modes[cfg.direction] if cfg.direction in modes else next(iter(modes.values()))
            terms[lines] = m.mode_terms(omega[lines])
            # with no resonance in the file the quasi-static column already holds R_0
            r0[lines] = m.residual_static if m.n_modes else 0.0
        self._ctx_cache = (ctx, terms, r0)
        return terms, r0

    def spindle(self, values: Mapping[str, np.ndarray], spindle: np.ndarray, ctx) -> np.ndarray:
        """Flange blocks with the modal rotational receptances added, (n_sets, n_lines, 2, 2)."""
        terms, r0 = self._line_terms(ctx)
        s = np.stack([np.asarray(values[k], dtype=float) for k in _slope_names(terms.shape[1])], axis=-1)  # (n_sets, N)
        s0 = np.asarray(values[UPPER_SLOPE], dtype=float)[..., None]  # (n_sets, 1)
        c0 = 1e-6 * np.asarray(values[UPPER_COMPLIANCE], dtype=float)[..., None]  # rad/(N m)
        add_l = s @ terms.T + s0 * r0  # (n_sets, n_lines)
        add_p = (s**2) @ terms.T + s0**2 * r0 + c0
        src = np.asarray(spindle)
        out = np.broadcast_to(src, np.broadcast_shapes(src.shape, add_l.shape + (2, 2))).astype(complex, copy=True)
        out[..., 0, 1] += add_l
        out[..., 1, 0] += add_l
        out[..., 1, 1] += add_p
        return out
