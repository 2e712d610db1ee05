"""Mode-frequency bias of the final model, learned at the fitted lengths (Kennedy & O'Hagan 2001).

When no known effect explains the data, the remainder model (a smooth
statistical discrepancy on the FRF and the law's bend marginalised) widens
the FRF, but a smooth multiplicative discrepancy cannot move a sharp
resonance: at the *fitted* lengths its mode frequencies can stay off the
measured ones by many line spacings.  Those data were given to the model, so
its intervals there must cover them, and so must its intervals of the
noise-free truth.  This module adds the missing piece on the quantity the
machinist uses, the frequency of each mode:

``f_k(l) = f_model,k(l; theta) + delta_k(l)``, with the bias ``delta_k`` of
mode ``k`` (per direction, modes in frequency order among the matched ones)
a Gaussian process over clamping length with an unknown straight-line mean
(Kennedy & O'Hagan's regression mean ``h(l)^T beta`` with ``h = (1, l)`` and
a flat prior on ``beta``: universal kriging; a constant when only one
length was fitted),

* kernel ``a_k^2 exp(-(l - l')^2 / (2 lam^2))`` (squared exponential);
* the straight line carries a bias shared by every length, or changing
  steadily with it (a wrong modulus, a softer holder), unshrunk, with the
  uncertainty the noise of the measured peaks leaves, and needs no large
  amplitude to do so;
* amplitude ``a_k``: how far the bias departs from its straight line
  between lengths, *marginalised*: its posterior on a grid, from the
  restricted likelihood of the posterior-median bias's contrasts orthogonal
  to the straight line under the kernel plus the peaks' noise (Patterson &
  Thompson 1971) and a half-Cauchy prior whose scale is the measured
  peak's noise sd (Gelman 2006); each GP draw takes its own amplitude from
  it.
  Three fitted lengths leave one contrast, which cannot pin the amplitude,
  and any plug-in estimate under-covers where the departure is real.  On
  data drawn from this very model (three of four lengths fitted, 1500
  replicated campaigns, ``tests/test_modes.py``), held out / fitted, for a
  departure of 0, 1 and 2 noise sd: marginalised 0.965 / 0.913, 0.947 /
  0.904, 0.888 / 0.886; a REML plug-in floored at the noise variance 0.949 /
  0.892, 0.904 / 0.883, 0.850 / 0.870; the residual variance about the
  least-squares line (the rule before both; the line absorbs most of a
  smooth departure over two length scales) 0.939 / 0.905, 0.902 / 0.896,
  0.810 / 0.874.  With two fitted lengths nothing is left to estimate it
  from, and the amplitude is how much the bias was seen to change between
  them, measured from the measured modes' whole resonances (range² +
  the estimate's variance; the peak noise's variance where a fitted length
  lacks that estimate): the bias is assumed to bend between them by about
  as much as it changes, and the outputs say that its course is untested.
  The amplitude is estimated from the median over draws, not from every
  draw: the draws' spread is parameter uncertainty, which the draws
  themselves carry to every length, and counting it again in the bias's
  prior would count it twice.  With one fitted length the change with
  length is not seen at all, and the prior spread is the bias seen
  (``bias^2`` + noise variance);
* length scale ``lam`` = half the span of the fitted lengths (the bias may
  change its course once between the outermost fitted lengths; a longer
  scale would trust the interpolation more than two or three points allow);
* observations ``delta_k(l_i) = f_meas,k(l_i) - f_model,k(l_i; theta_d)``
  *per posterior draw* ``d`` (Kennedy & O'Hagan condition the bias on the
  parameters: a draw with a stiffer contact sits higher at every length and
  has a correspondingly lower bias, so the parameter spread shared by all
  lengths cancels), with the variance of the measured peak frequency under
  the fitted noise model (the variance, over draws, of the predictive minus
  the model frequency of the same draw).

The corrected draws are the model's mode-frequency draws plus the shift
``mu_k(l)`` and an independent Gaussian of variance ``v_k(l)``, the GP
posterior at ``l`` (including the uncertainty of ``beta``), drawn
:data:`BIAS_REPLICATES` times per posterior draw: where the parameter spread
has cancelled, the interval is that Gaussian's alone, and its 5 % and 95 %
quantiles read from 200 samples scatter by 0.15 of its sd (0.05 from
1,600).  At a fitted
length they sit on the measured frequency within its noise; between fitted
lengths they widen with the bias's variation.  Only mode frequencies are
corrected; the FRF, gap and stiffness are not.

A named physical model (or an adequate baseline) gets the same correction,
but its bias is a fraction of a line, below what the measured *peak* can
show; for it the observation is the measured mode's frequency from its whole
resonance (:mod:`.mode_shift`, ``observation="resonance"``), about ten times
more precise.  The remainder keeps the peak (``observation="peak"``): its
bias can be many lines, and its predictive interval at a fitted length must
contain the measured peak itself.
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["correct_mode_frequencies", "BIAS_RULE", "BIAS_REPLICATES"]

#: Draws of the bias's GP posterior per posterior draw (the intervals' quantiles are read from
#: n_draws x BIAS_REPLICATES samples; see the module docstring for why one is too few).
BIAS_REPLICATES = 8

BIAS_RULE = ("mode-frequency bias of the final model: per direction and mode order, a Gaussian process over clamping "
             "length with an unknown straight-line mean (flat prior; universal kriging; a constant with one "
             "fitted length), squared-exponential kernel, amplitude marginalised over its posterior (restricted likelihood "
             "of the posterior-median bias's contrasts to its line, half-Cauchy prior scaled by the observation's "
             "noise sd; two fitted lengths: the change of the bias between them seen at the measured resonances, "
             "range^2 + variance (the noise variance where a resonance estimate is missing); one "
             "fitted length: bias^2 + noise variance), length scale = half the fitted span, conditioned per "
             "posterior draw on measured - model frequency at the fitted lengths (the measured peak for the "
             "unexplained remainder, the measured mode from its whole resonance for a physical model); its "
             "posterior mean (per draw) and variance (8 Gaussian replicates per draw) are added to the model's draws")


def _quantiles(x: np.ndarray) -> dict:
    q = np.nanquantile(x, [0.05, 0.5, 0.95]) if np.isfinite(x).any() else [math.nan] * 3
    return {"q05": float(q[0]), "q50": float(q[1]), "q95": float(q[2])}


def _row_quantiles(x: np.ndarray) -> list:
    """:func:`_quantiles` of every row of ``x`` (n_rows, n): one batched call over the rows without NaN.

    The batched quantiles are the same numbers as the row-by-row ones (the same partition and interpolation
    per row; tests/test_discrepancy_fastpaths.py); a row with NaN goes through :func:`_quantiles`.
    """
    finite = np.isfinite(x).all(axis=1)
    out = [None] * x.shape[0]
    if finite.any():
        q = np.quantile(x[finite], [0.05, 0.5, 0.95], axis=1)
        for c, r in enumerate(np.flatnonzero(finite)):
            out[r] = {"q05": float(q[0, c]), "q50": float(q[1, c]), "q95": float(q[2, c])}
    for r in np.flatnonzero(~finite):
        out[r] = _quantiles(x[r])
    return out


def _row_nanstd(x: np.ndarray) -> list:
    """``float(np.nanstd(row))`` of every row of ``x`` (n_rows, n), in one call (the same per-row reductions)."""
    return [float(v) for v in np.nanstd(x, axis=1)]


def _robust_vars(values: list) -> list:
    """Each entry of ``values`` as is (a float), or :func:`_robust_var` of it (an array), the arrays batched.

    Arrays of one length without NaN share one :func:`numpy.quantile` call over their rows (the same
    partition and interpolation per row as one call each); any other goes through :func:`_robust_var`.
    """
    arrays = [k for k, v in enumerate(values) if isinstance(v, np.ndarray)]
    out = list(values)
    rows = [values[k] for k in arrays]
    if rows and len({r.shape for r in rows}) == 1 and rows[0].ndim == 1 and rows[0].size >= 2 \
            and all(np.isfinite(r).all() for r in rows):
        q = np.quantile(np.stack(rows), [0.05, 0.95], axis=1)
        for c, k in enumerate(arrays):
            out[k] = _range_variance(q[0, c], q[1, c])
        return out
    for k in arrays:
        out[k] = _robust_var(values[k])
    return out


def _robust_var(x: np.ndarray) -> float:
    """Variance of a normal with the same central 90 % range as the finite values of ``x``: ``((q95 - q05) / 3.29)^2``.

    Robust to the few draws whose noisy peak jumps to the edge of its window (which would set a plain
    variance), yet true to the 90 % range the intervals are about; a MAD would follow only the core and
    understate a peak's heavier tails.
    """
    x = x[np.isfinite(x)]
    if x.size < 2:
        return 0.0
    q05, q95 = np.quantile(x, [0.05, 0.95])
    return _range_variance(q05, q95)


def _range_variance(q05: float, q95: float) -> float:
    """Variance of the normal whose central 90 % range is ``[q05, q95]``: ``((q95 - q05) / (2 z_0.95))^2``."""
    return float(((q95 - q05) / (2.0 * 1.6448536269514722)) ** 2)


def _basis(x: np.ndarray, centre: float, scale: float, degree: int) -> np.ndarray:
    """Regression basis ``h(l)`` of the bias's mean: 1, and ``(l - centre) / scale`` for degree 1; (n, degree + 1)."""
    t = (np.asarray(x, dtype=float) - centre) / scale
    return np.column_stack([t**k for k in range(degree + 1)])


def _gp_weights(x_obs, noise_var, x_new, amp2, lam: float, degree: int = 1):
    """Universal-kriging weights ``W`` (..., n_obs, n_new) and posterior variances (..., n_new).

    A GP with squared-exponential kernel (amplitude² ``amp2`` Hz², a scalar or an array of amplitudes
    batched over the leading axis, length scale ``lam`` m) plus an unknown polynomial mean of ``degree`` (0: a
    constant, 1: a straight line in clamping length) under a flat prior, observed at ``x_obs`` with
    independent noise variances ``noise_var``.  The posterior mean at ``x_new`` of observations ``y`` is
    ``y @ W`` for any batch of ``y`` (n_draws, n_obs): the weights reproduce the mean's polynomial exactly, so
    a bias shared by all observations (or changing linearly) is carried unshrunk.  The variance includes the
    uncertainty of the mean's coefficients (Rasmussen & Williams 2006, eq. 2.42 with a vague prior).
    """
    x_obs, noise_var, x_new = (np.asarray(v, dtype=float) for v in (x_obs, noise_var, x_new))
    amp2 = np.asarray(amp2, dtype=float)
    s2 = amp2[..., None, None]
    # a straight line needs two distinct lengths (repeated taps at one length give one)
    degree = min(degree, np.unique(x_obs).size - 1)
    centre, scale = float(np.mean(x_obs)), max(float(np.ptp(x_obs)), lam)
    h, hs = _basis(x_obs, centre, scale, degree), _basis(x_new, centre, scale, degree)
    k = lambda a, b: s2 * np.exp(-0.5 * ((a[:, None] - b[None, :]) / lam) ** 2)  # noqa: E731
    kxx = k(x_obs, x_obs) + np.diag(noise_var) + 1e-12 * s2 * np.eye(x_obs.size)
    kxs = k(x_obs, x_new)
    a = np.linalg.solve(kxx, kxs)  # K^-1 k*   (..., n_obs, n_new)
    b = np.linalg.solve(kxx, np.broadcast_to(h, kxx.shape[:-1] + h.shape[-1:]))  # K^-1 H   (..., n_obs, p)
    m = np.swapaxes(b, -1, -2) @ h  # H^T K^-1 H (symmetric)   (..., p, p)
    r = hs.T - h.T @ a  # what the kriging weights leave of the mean's basis   (..., p, n_new)
    c = np.linalg.solve(m, r)
    w = a + b @ c
    var = amp2[..., None] - np.sum(kxs * a, axis=-2) + np.sum(r * c, axis=-2)
    return w, np.maximum(var, 0.0)  # round-off only: the GP posterior variance is >= 0 exactly


#: Amplitude grid of the marginalisation, in units of the half-Cauchy prior's scale (log-spaced; 121 points
#: over 10^-2 .. 10^2.5: far below any resolvable departure to far beyond the largest bias seen on either bench).
AMPLITUDE_GRID = np.logspace(-2.0, 2.5, 121)


@functools.lru_cache(maxsize=64)
def _contrasts(x: tuple, degree: int, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal contrasts ``P`` (n, n - degree - 1) of the fitted lengths ``x`` (m) that the polynomial mean
    cannot produce, and the unit kernel between them, ``P^T K P`` (length scale ``lam`` m).

    A function of the lengths alone (the same for every draw and every mode of a setup): cached, read-only.
    """
    xa = np.array(x, dtype=float)
    h = _basis(xa, float(np.mean(xa)), max(float(np.ptp(xa)), 1e-3), degree)
    q, _ = np.linalg.qr(h, mode="complete")
    p = q[:, h.shape[1]:]
    a = p.T @ np.exp(-0.5 * ((xa[:, None] - xa[None, :]) / lam) ** 2) @ p
    p.flags.writeable = False
    a.flags.writeable = False
    return p, a


def _change_seen2(change: tuple[np.ndarray, np.ndarray] | None) -> float | None:
    """Square of how much the bias was seen to change over the fitted lengths (Hz²), or None.

    ``change`` = (bias at each fitted length measured from the whole resonance, Hz; that estimate's variance,
    Hz²): its range squared plus the mean variance.  ``None`` when any fitted length lacks the estimate.
    """
    if change is None:
        return None
    b, v = (np.asarray(c, dtype=float) for c in change)
    if b.size == 0 or not (np.all(np.isfinite(b)) and np.all(np.isfinite(v))):
        return None
    return max(float(np.ptp(b)) ** 2 + float(np.mean(v)), 1e-12)


def _amplitude2_posterior(x: np.ndarray, y: np.ndarray, noise_var: np.ndarray, lam: float,
                          degree: int = 1, change: tuple[np.ndarray, np.ndarray] | None = None,
                          y_median: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's amplitude² (Hz²) given the per-draw biases ``y`` (n_draws, n_fitted): values and weights.

    How far the bias departs from its mean's polynomial between lengths.  Its posterior on a grid, from the
    restricted likelihood of the posterior-median bias's contrasts ``z = P^T y`` orthogonal to the polynomial,
    ``z ~ N(0, a² P^T K P + P^T N P)`` (``K`` the unit kernel of length scale ``lam`` m, ``N`` the noise
    variances; Patterson & Thompson 1971), and a half-Cauchy prior on the amplitude ``a`` with the peak noise's
    sd as its scale (Gelman 2006: a departure of the order of what the measurement resolves is typical, a much
    larger one possible).  Three fitted lengths leave one contrast, which cannot pin ``a``: a plug-in estimate
    would take the departure seen at face value and under-cover wherever it is real.

    ``change`` (optional): the bias at each fitted length measured from the measured mode's whole resonance
    (Hz, ten times more precise than the peak) and that estimate's variance (Hz²).  With two fitted lengths
    (no contrast left to estimate the amplitude from) and ``change`` given, the amplitude is how much the bias
    was seen to change over them, ``range² + variance`` (:func:`_change_seen2`), instead of the peak noise's
    variance: a bias that is the same at both lengths (a model that sits on the measured resonances, or one
    off by a constant, which the line carries) has shown no course to bend; one that changes by ``D`` Hz may
    well depart from its chord by a fair part of ``D``.  The peak noise is a property of the measurement, not
    of the model's course; as the amplitude it widened an exact model's held-out intervals as much as a wrong
    one's (rotor bench: a tool 10 % stiffer than declared held out 40/40 with z sd 0.49; with the change seen,
    z sd 0.72; docs/discrepancy.md, "Adopted: with two fitted lengths the bend is the change seen").  With
    three or more the contrasts inform the amplitude and the prior keeps the noise's scale: the change seen as
    the scale there, tried on fresh seeds, moved the tool modulus's held-out cell to 15/20 (z mean +0.77).

    Returns
    -------
    amp2 : (n_grid,) Hz²
    weights : (n_grid,) summing to 1.  With a single fitted length (tapped once or repeatedly) one value, the
        bias seen (mean bias² + noise variance); with no contrast left (two lengths and a straight line), one
        value: the change seen (``change`` given) or else the noise variance (two lengths cannot show a
        departure: the outputs say that the bias's course between them is untested).
    """
    ym = np.median(y, axis=0) if y_median is None else y_median
    noise_var = np.asarray(noise_var, dtype=float)
    nv = float(np.mean(noise_var))
    x = np.asarray(x, dtype=float)
    if np.unique(x).size < 2:  # one length (perhaps tapped repeatedly): its change with length is not seen
        return np.array([float(np.mean(ym**2)) + nv]), np.ones(1)
    degree = min(degree, np.unique(x).size - 1)
    if ym.size - degree - 1 <= 0:
        seen2 = _change_seen2(change)
        return np.array([nv if seen2 is None else seen2]), np.ones(1)
    p, a = _contrasts(tuple(x.tolist()), degree, lam)
    z = p.T @ ym
    n = p.T @ np.diag(noise_var) @ p
    scale = math.sqrt(nv) if nv > 0 else math.sqrt(float(z @ z) / max(float(np.trace(a)), 1e-12) + 1e-24)
    amp = scale * AMPLITUDE_GRID
    c = amp[:, None, None] ** 2 * a[None] + n[None]  # (n_grid, m, m)
    ll = -0.5 * (np.linalg.slogdet(c)[1] + np.einsum("i,gij,j->g", z, np.linalg.inv(c), z))
    # half-Cauchy density of the amplitude, times the grid's d(log a) = da / a
    lp = ll - np.log1p((amp / scale) ** 2) + np.log(amp)
    if not np.isfinite(lp).any():  # a degenerate contrast (e.g. noise-free and on the line): the noise's amplitude
        return np.array([max(nv, 1e-24)]), np.ones(1)
    lp = np.where(np.isfinite(lp), lp, -np.inf)
    w = np.exp(lp - lp.max())
    keep = w > 1e-8
    return amp[keep] ** 2, w[keep] / w[keep].sum()


def correct_mode_frequencies(measurements: list, draws: list, rng: np.random.Generator,
                             observation: str = "peak") -> list:
    """Bias-corrected mode-frequency intervals of every matched mode, in place; returns notes.

    Parameters
    ----------
    measurements : list of dict
        The per-measurement entries of an evaluation (``modes``, ``fitted``, ``direction``,
        ``clamping_length``); each mode gains ``bias_hz`` (mean, sd) and its ``model_interval`` /
        ``predictive_interval`` and coverage flags become the corrected ones (the uncorrected ones are kept
        under ``uncorrected_*``).
    draws : list of (model, predictive) arrays, (n_draws, n_modes_of_that_measurement) Hz
        Tracked mode frequencies in the order of each measurement's ``modes``.
    rng : numpy.random.Generator
    observation : {"peak", "resonance"}
        What the bias is measured against at a fitted length.  ``"peak"``: the measured peak
        (``measured_hz``, noise variance from the tracked predictive draws); the corrected predictive interval
        there then contains the measured peak, as the unexplained remainder's must (those data were given to
        it), whatever its bias.  ``"resonance"``: the measured mode's frequency from its whole resonance
        (``measured_fit_hz`` / ``measured_fit_sd_hz``, :mod:`.mode_shift`), about ten times more precise, which
        is what a physical model's sub-line bias needs; the peak where that estimate is missing.

    Returns
    -------
    list of str: what was corrected, or why a mode was left uncorrected (no fitted length has it).
    """
    notes = []
    groups: dict = {}
    for j, m in enumerate(measurements):
        for r, md in enumerate(sorted(range(len(m["modes"])), key=lambda i: m["modes"][i]["measured_hz"])):
            groups.setdefault((m["direction"], r), []).append((j, md))
    for (direction, r), members in sorted(groups.items()):
        fitted = [(j, i) for j, i in members if measurements[j]["fitted"]]
        if not fitted:
            notes.append(f"mode {r + 1} ({direction}) appears at no fitted length: left uncorrected")
            continue
        xl, cols, nv, res_b, res_v = [], [], [], [], []
        for j, i in fitted:
            fd, fp = draws[j][0][:, i], draws[j][1][:, i]
            md = measurements[j]["modes"][i]
            xl.append(measurements[j]["clamping_length"])
            # the measured mode's frequency from its whole resonance (mode_shift.py), known about ten times
            # better than its peak line; the peak where the resonance is too narrow or too far off for that
            f_obs, sd_obs = md.get("measured_fit_hz", math.nan), md.get("measured_fit_sd_hz", math.nan)
            whole = observation == "resonance" and math.isfinite(f_obs) and math.isfinite(sd_obs) and sd_obs > 0
            # the bias *of each draw*: a draw whose contact is stiffer sits higher at every length, and its
            # bias is correspondingly lower, so the parameter spread shared by all lengths cancels (K&O'H)
            b = (f_obs if whole else md["measured_hz"]) - fd
            finite = np.isfinite(b)
            cols.append(b if finite.all() else np.where(finite, b, np.nanmedian(b)))
            # the same bias from the whole resonance, whatever the observation: with two fitted lengths, how
            # much it changes between them is the amplitude of its departure from the line (_amplitude2_posterior)
            ok = math.isfinite(f_obs) and math.isfinite(sd_obs) and sd_obs > 0 and bool(np.isfinite(fd).any())
            res_b.append(float(np.nanmedian(f_obs - fd)) if ok else math.nan)
            res_v.append(sd_obs**2 if ok else math.nan)
            # the measured peak's noise: predictive minus model draw *of the same draw* (the noise's effect on
            # the peak alone; a difference of the two spreads is swamped by the parameter spread), from its
            # central 90 % range: a few noisy draws whose tracked peak jumps to a noise spike at the edge of the
            # mode's window would otherwise set the variance of every draw
            nv.append(sd_obs**2 if whole else fp - fd)
        nv = _robust_vars(nv)
        y, nv = np.column_stack(cols), np.array(nv)  # (n_draws, n_fitted), (n_fitted,)
        y_median = np.median(y, axis=0)  # (n_fitted,): the median draw's bias
        span = max(xl) - min(xl)
        lam = 0.5 * span if span > 0 else 0.01
        amp2, amp_w = _amplitude2_posterior(np.array(xl), y, nv, lam, change=(np.array(res_b), np.array(res_v)),
                                            y_median=y_median)
        if not np.all(amp2 > 0):
            continue
        xs = [measurements[j]["clamping_length"] for j, _ in members]
        gw, gv = _gp_weights(xl, nv, xs, amp2, lam)  # (n_grid, n_fitted, n_members), (n_grid, n_members)
        # the amplitude marginalised: each replicate of each draw takes its own amplitude from the posterior
        g = rng.choice(amp2.size, size=(y.shape[0], BIAS_REPLICATES), p=amp_w)
        means = np.einsum("do,dron->drn", y, gw[g])  # (n_draws, replicates, n_members)
        ym = y_median @ gw  # (n_grid, n_members): the median draw's bias under each amplitude
        # every member's Gaussian replicates in one call: the same stream as one call per member in turn
        normal = rng.standard_normal((len(members),) + means.shape[:2])
        shift = np.moveaxis(means, -1, 0) + np.sqrt(np.moveaxis(gv[g], -1, 0)) * normal  # (n_members, d, r)
        fd_all = np.stack([draws[j][0][:, i] for j, i in members])  # (n_members, n_draws)
        fp_all = np.stack([draws[j][1][:, i] for j, i in members])
        corrected = np.concatenate([(fd_all[:, :, None] + shift).reshape(len(members), -1),
                                    (fp_all[:, :, None] + shift).reshape(len(members), -1)])
        qs = _row_quantiles(corrected)
        sds = _row_nanstd(corrected[len(members):])
        for k, (j, i) in enumerate(members):
            md = measurements[j]["modes"][i]
            mu = means[:, :, k]
            m_k = float(amp_w @ ym[:, k])
            bias_sd = math.sqrt(float(amp_w @ gv[:, k] + amp_w @ (ym[:, k] - m_k) ** 2))
            q, qp = qs[k], qs[len(members) + k]
            fm = md["measured_hz"]
            md.update({"uncorrected_model_hz": md["model_hz"], "model_hz": q["q50"],
                       "error_pct": 100.0 * (q["q50"] - fm) / fm,
                       "uncorrected_model_interval": md["model_interval"],
                       "uncorrected_predictive_interval": md["predictive_interval"],
                       "bias_hz": {"mean": float(np.mean(mu)), "sd": bias_sd},
                       "model_interval": q, "predictive_interval": qp,
                       "predictive_sd_hz": sds[k],
                       "covered_model_90": bool(q["q05"] <= fm <= q["q95"]),
                       "covered_predictive_90": bool(qp["q05"] <= fm <= qp["q95"])})
        y = y_median
        amp_median = math.sqrt(float(amp2[min(np.searchsorted(np.cumsum(amp_w), 0.5), amp2.size - 1)]))
        source = ""
        if np.unique(xl).size == 2 and len(xl) == 2:  # the amplitude is assumed, not estimated: say from what
            source = (", the bias's change seen at the measured resonances"
                      if _change_seen2((np.array(res_b), np.array(res_v))) is not None
                      else ", the peak noise's: no resonance estimate at a fitted length")
        notes.append(f"mode {r + 1} ({direction}): bias {', '.join(f'{v:+.1f}' for v in y)} Hz at the fitted "
                     f"lengths {', '.join(f'{1e3 * v:g}' for v in xl)} mm (GP amplitude {amp_median:.1f} Hz"
                     f"{' posterior median' if amp2.size > 1 else source}, length scale {1e3 * lam:.1f} mm)")
    return notes
