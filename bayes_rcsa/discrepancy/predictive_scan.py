"""A posterior-predictive scan of the final model's residual for unexplained bands away from the modes.

The baseline detection's bands (a 5-line moving average of the standardised
residual, sized for naming) miss a weak unmodelled resonance that spreads
over more lines: on the project's bench a 0.2-kg flange resonance near
1000 Hz went undetected in 2 of 10 campaigns, which were then called usable
while their 30-mm interval missed the truth by 2.5 Hz.  A scan standardised
by the measurement's noise alone finds it, but it also flags the skirt of a
mode whose *shape* the model gets wrong (a slotted holder on the rotor
bench), which the remainder's own uncertainty already covers there.

This scan asks the posterior-predictive question instead: does the measured
FRF at a line lie where the final model, with its parameter uncertainty and
the measurement's noise, says it can?  Per line,

``z^2 = |h_meas - mean_d h_d|^2 / (var_d h_d + (sigma |mean_d h_d|)^2)``

with ``h_d`` the model FRF of posterior draw ``d`` and ``sigma`` the
measurement's own relative noise scale (:func:`.noise.relative_noise_scale`,
not the fitted scale, which absorbs misfit).  Where the remainder is unsure
of the FRF (a reshaped skirt, widely spread draws) the denominator is large;
where every draw agrees (between modes, away from anything the model has)
an unmodelled resonance stands out.  Under the model ``z^2`` is about
Exp(1) per line; windows of :data:`SCAN_WINDOWS` lines wholly away from
every measured mode (:data:`.features.MODE_CLEARANCE_WIDTHS` half-power
widths) are tested with the Gamma(w, 1) tail, Bonferroni over measurements,
windows and positions at :data:`SCAN_FALSE_ALARM` per campaign.  A significant
band that runs on into a mode's clearance *and is largest there, or keeps
growing into the clearance* is that mode's own misfit spreading out (a
reshaped skirt decays away from its mode) and is not reported; an
unmodelled resonance peaks inside its band, however close it sits to the
mode (on the rotor bench a slotted holder raises the residual over
1200-1700 Hz around a 40-Hz wide mode).  The
parameter part of the residual is correlated across lines, which makes a
window's sum heavier-tailed than Gamma: the level is nominal, and the
false-alarm rate is measured on clean campaigns (docs/discrepancy.md).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import gamma

from .features import MODE_CLEARANCE_WIDTHS

__all__ = ["predictive_z2", "predictive_window_statistic", "predictive_misfit_scan", "SCAN_WINDOWS",
           "SCAN_FALSE_ALARM", "SKIRT_LINES", "SKIRT_SMOOTH_LINES"]

#: Window lengths (lines): from a few lines to a weak resonance's skirt.
SCAN_WINDOWS = (5, 9, 17, 33)
#: Lines from a band's edge at a mode's clearance within which its largest residual marks it as that mode's skirt.
SKIRT_LINES = 5
#: Lines over which a band's level is compared with the clearance's next to it: the scan's second window, so
#: that a noise bump of a few lines in a broad skirt does not outrank the skirt's rise, while an unmodelled
#: resonance (several lines wide at half power) keeps its peak.
SKIRT_SMOOTH_LINES = 9
#: Nominal false-alarm probability per campaign (Bonferroni over measurements, windows and positions).
SCAN_FALSE_ALARM = 0.01


def predictive_z2(measured: np.ndarray, h_draws: np.ndarray, sigma: float) -> np.ndarray:
    """Squared residual per line standardised by the posterior-predictive variance.

    Parameters
    ----------
    measured : (n,) complex m/N
    h_draws : (n_draws, n) complex m/N, model FRF draws (parameter uncertainty)
    sigma : float, the measurement's own relative noise scale

    Returns
    -------
    (n,) float; NaN where the noise scale is unknown or the variance is zero.
    """
    mean = h_draws.mean(axis=0)
    var = np.mean(np.abs(h_draws - mean) ** 2, axis=0) + (sigma * np.abs(mean)) ** 2
    if not (math.isfinite(sigma) and sigma > 0):
        return np.full(measured.shape, math.nan)
    return np.where(var > 0, np.abs(measured - mean) ** 2 / np.where(var > 0, var, 1.0), math.nan)


def predictive_window_statistic(measured: np.ndarray, h_draws: np.ndarray, sigma: float,
                                windows=SCAN_WINDOWS) -> dict:
    """Each window's residual whitened by the posterior-predictive covariance of its lines.

    Under the model the residual ``r = h_meas - mean_d h_d`` over a window of ``w`` lines is complex normal
    with covariance ``C_ww = cov_d(h) + diag((sigma |mean|)^2)``, whose draws' part is correlated over many
    lines (a shared gain of the smooth FRF discrepancy, a draw that sits higher everywhere near a mode).
    ``T = r_w^H C_ww^-1 r_w`` is then exactly Gamma(w, 1), whatever that correlation: a shared shift the
    draws can make is one of the window's ``w`` directions and counts once, while a local excess that the
    rest of the window does not share (an unmodelled resonance) keeps its full weight.  Where the lines
    are independent ``T`` is the window's sum of :func:`predictive_z2`.

    Parameters
    ----------
    measured : (n,) complex m/N
    h_draws : (n_draws, n) complex m/N
    sigma : float, the measurement's own relative noise scale
    windows : odd window lengths, lines

    Returns
    -------
    {w: (n,) float}: ``T`` of the window centred on each line; NaN where the window leaves the band or the
    noise scale is unknown.
    """
    n = measured.size
    out = {w: np.full(n, math.nan) for w in windows}
    if not (math.isfinite(sigma) and sigma > 0):
        return out
    mean = h_draws.mean(axis=0)
    d = (h_draws - mean) / math.sqrt(h_draws.shape[0])
    r = measured - mean
    noise = (sigma * np.abs(mean)) ** 2
    fits = [w for w in windows if w <= n]
    if not fits:
        return out
    band = _draw_covariance_band(d, max(fits))
    for w in fits:
        start = np.arange(n - w + 1)
        idx = start[:, None] + np.arange(w)  # (n_pos, w)
        a = np.arange(w)
        lag = a[None, :] - a[:, None]  # (w, w): column minus row
        # c[p, i, j] = E[conj(r_{p+i}) r_{p+j}]: band[p + min(i, j), |j - i|], conjugated below the diagonal
        c = band[start[:, None, None] + np.minimum(a[:, None], a[None, :]), np.abs(lag)]
        c = np.where(lag >= 0, c, c.conj())
        c[:, a, a] += noise[idx]
        rw = r[idx]  # (n_pos, w)
        ok = np.all(noise[idx] > 0, axis=1)
        sol = np.linalg.solve(c[ok], rw[ok].conj()[..., None])[..., 0]
        t = np.full(start.size, math.nan)
        t[ok] = np.real(np.einsum("pi,pi->p", rw[ok], sol))
        out[w][start + w // 2] = t
    return out


def _draw_covariance_band(d: np.ndarray, width: int) -> np.ndarray:
    """``band[i, k] = sum_d conj(d[d, i]) d[d, i + k]`` for lags ``k < width`` (zero past the last line).

    Every window's covariance is a block of this band: forming it once costs ``n width n_draws`` against
    ``n w^2 n_draws`` per window length when each window's block is multiplied out on its own, and holds
    ``n width`` numbers instead of an ``(n, w, n_draws)`` stack (300 MB for 3000 lines, 33-line windows and
    200 draws).

    Parameters
    ----------
    d : (n_draws, n) complex, the draws' deviations from their mean (scaled so ``d^H d`` is the covariance)
    width : lags, >= 1

    Returns
    -------
    (n, width) complex
    """
    n = d.shape[1]
    band = np.zeros((n, width), dtype=complex)
    dc = d.conj()
    for k in range(min(width, n)):  # a loop over the window's lags; each lag is one product over lines and draws
        band[: n - k, k] = np.einsum("di,di->i", dc[:, : n - k], d[:, k:])
    return band


def predictive_misfit_scan(measurements: list, frequency_hz: list, z2: list, windows=SCAN_WINDOWS,
                           alpha: float = SCAN_FALSE_ALARM, window_statistic: list | None = None) -> list[dict]:
    """Bands at the fitted measurements where the measured FRF leaves the final model's predictive.

    Parameters
    ----------
    measurements : list of dict, an evaluation's per-measurement entries (``fitted``, ``source``,
        ``direction``, ``clamping_length``, ``modes`` with ``measured_hz`` and ``measured_width_hz``)
    frequency_hz : list of (n,) arrays, Hz, in the order of ``measurements``
    z2 : list of (n,) arrays, :func:`predictive_z2` of each measurement
    windows : window lengths, lines
    alpha : nominal false-alarm probability per campaign
    window_statistic : list of {w: (n,) float} or None
        :func:`predictive_window_statistic` of each measurement, tested instead of the window's sum of
        ``z^2`` (which treats the lines as independent); both are Gamma(w, 1) under the model.

    Returns
    -------
    list of dict: ``lo_hz``, ``hi_hz``, ``source``, ``direction``, ``clamping_length`` and ``log10_p`` (the
    band's smallest window tail probability), like :func:`.features.unexplained_features`'s.
    """
    cases = []
    for j, m in enumerate(measurements):
        f, z = np.asarray(frequency_hz[j], dtype=float), np.asarray(z2[j], dtype=float)
        if not m["fitted"] or f.size < max(windows) or not np.isfinite(z).any():
            continue
        away = np.isfinite(z)
        # distance to the nearest measured mode in its own half-power widths: the clearance's outer width
        # (between MODE_CLEARANCE_WIDTHS - 1 and MODE_CLEARANCE_WIDTHS widths) is where a skirt is compared
        widths = np.full(f.size, np.inf)
        for md in m["modes"]:
            w = md.get("measured_width_hz", math.nan)
            away &= np.abs(f - md["measured_hz"]) > MODE_CLEARANCE_WIDTHS * (w if math.isfinite(w) else 0.0)
            if math.isfinite(w) and w > 0:
                widths = np.minimum(widths, np.abs(f - md["measured_hz"]) / w)
        outer = ~away & (widths > MODE_CLEARANCE_WIDTHS - 1.0)
        ws = window_statistic[j] if window_statistic is not None else None
        cases.append((m, f, np.where(away, z, 0.0), away, np.where(np.isfinite(z), z, 0.0), outer, ws))
    n_tests = sum(c[1].size for c in cases) * len(windows)
    if not n_tests:
        return []
    log_level = math.log(alpha / n_tests)
    out = []
    for m, f, z, away, z_all, outer, ws in cases:
        best = np.zeros(f.size)  # smallest log tail probability of a significant window covering each line
        for w in windows:
            k = np.ones(w)
            total = np.convolve(z, k, mode="same") if ws is None else np.nan_to_num(ws[w], nan=0.0)
            # only windows wholly away from the modes: the lines they hold are Exp(1) under the model
            full = np.convolve(away.astype(float), k, mode="same") > w - 0.5
            lp = np.where(full, gamma.logsf(total, w), 0.0)
            for i in np.flatnonzero(lp < log_level):
                lo, hi = max(0, i - w // 2), min(f.size, i + w // 2 + 1)
                best[lo:hi] = np.minimum(best[lo:hi], lp[i])
        hot = np.flatnonzero(best < 0)
        if not hot.size:
            continue
        smooth = np.convolve(z, np.ones(min(windows)) / min(windows), mode="same")
        k = np.ones(SKIRT_SMOOTH_LINES) / SKIRT_SMOOTH_LINES
        # the level inside a clearance as well: the mode's own misfit there is not tested, only compared
        level, level_all = np.convolve(z, k, mode="same"), np.convolve(z_all, k, mode="same")
        for run in np.split(hot, np.flatnonzero(np.diff(hot) > 1) + 1):
            if _is_skirt(run, away, outer, smooth, level, level_all):
                continue
            out.append({"lo_hz": float(f[run[0]]), "hi_hz": float(f[run[-1]]), "source": m["source"],
                        "direction": m["direction"], "clamping_length": m["clamping_length"],
                        "log10_p": float(best[run].min() / math.log(10)), "detector": "predictive_scan"})
    return out


def _is_skirt(run: np.ndarray, away: np.ndarray, outer: np.ndarray, smooth: np.ndarray, level: np.ndarray,
              level_all: np.ndarray) -> bool:
    """Whether the band ``run`` (line indices) is a mode's own misfit spreading out of its clearance.

    A reshaped skirt grows towards its mode.  The band is taken for one when it touches a mode's clearance and
    either its largest smoothed ``z^2`` lies within :data:`SKIRT_LINES` of that edge, or the residual keeps
    growing past the edge: somewhere in the clearance's outer width (one half-power width, next to the band)
    ``z^2`` averaged over :data:`SKIRT_SMOOTH_LINES` lines reaches the band's largest average.  A noise bump
    in the middle of a broad skirt then no longer makes a band of its own.  An unmodelled resonance beside a
    mode peaks inside its band and falls off towards the mode, so the residual in the clearance stays below
    its peak; a misfit at the mode's own peak (inner width) is not compared.

    Parameters
    ----------
    run : (n_run,) int, the band's consecutive line indices
    away : (n,) bool, lines outside every mode's clearance
    outer : (n,) bool, lines in a clearance's outer half-power width
    smooth, level : (n,) float, ``z^2`` averaged over the scan's first window and over
        :data:`SKIRT_SMOOTH_LINES` lines, with the clearances' lines counted as 0
    level_all : (n,) float, ``level`` with the clearances' own ``z^2``
    """
    peak = run[int(np.argmax(smooth[run]))]
    top = float(np.max(level[run]))
    for edge, step, near in ((run[0] - 1, -1, peak - run[0]), (run[-1] + 1, 1, run[-1] - peak)):
        if not (0 <= edge < away.size) or away[edge]:
            continue
        if near < SKIRT_LINES:
            return True
        i = edge
        while 0 <= i < away.size and outer[i]:
            if level_all[i] >= top:
                return True
            i += step
    return False
