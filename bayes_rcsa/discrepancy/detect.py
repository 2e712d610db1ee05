"""Detect systematic disagreement between the fitted model and the measurements.

Pure functions on arrays (residuals, FRFs, lengths) plus a thin adapter,
:func:`detect_from_fit`, from a baseline :class:`~.fit.ModelFit`.

What is computed
----------------
* **Standardised posterior-predictive residuals** per line:
  ``z_n = (H_meas - E[H_model]) / sqrt(sigma_n^2 + Var[H_model])`` with the
  mean and variance of the prediction over Laplace draws of the baseline
  and ``sigma_n`` the fitted noise model (complex; ``|z|^2`` has mean 1
  when the model is adequate).
* **Per measurement**: RMS of ``|z|``, the residual correlation length
  ``tau_j`` (lines), and the *bands* where the locally averaged ``|z|^2``
  exceeds 4 over at least three lines (systematic, not single outliers).
* **Resonance diagnosis** from a local peak fit of measured and predicted
  FRFs on the same lines: natural-frequency error (model - measured, % of
  measured; the project's natural-frequency rule), peak-height ratio and
  half-power-width ratio, classified as ``shifted high/low``,
  ``too high/low``, ``too wide/narrow`` beyond documented thresholds.
* **Trend with clamping length**: least-squares slope of the frequency
  error (% per mm) over the measurements.
* **Leave-one-length-out transfer** (three or more lengths, optional): the
  baseline refitted without each length predicts its natural frequency.

Adequacy test (documented in docs/discrepancy.md)
-------------------------------------------------
The baseline is declared **inadequate** when any of

1. the pooled residual correlation length at the fit exceeds
   ``TAU_MAX = 2`` lines (white measurement noise gives 1.0-1.3 on the
   bench; a smooth discrepancy spans many lines);
2. a contact parameter piles up on a prior bound (stiffness within 1 % of
   either bound in its sampling coordinate, a growth factor at the growth
   bound ``Q``) *and* the tempered likelihood presses outwards by more than
   two standard deviations (:func:`pile_up`): the data want a value the
   model's physics does not allow;
3. a measurement's natural-frequency error exceeds ``max(0.3 %, 1 line)``
   and is more than 3 times its posterior-predictive standard deviation;
4. (three or more fitted lengths) the baseline refitted without one length
   mispredicts that length's natural frequency by more than
   ``TRANSFER_LIMIT_PCT = 1 %`` (:func:`transfer_failures`): the model does
   not carry from some lengths to another, which is what it is for.  Clean
   bench campaigns stay below 0.2 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..inference.likelihood import residual_correlation_length
from ..model.modes import find_modes, match_modes, mode_windows, track_modes

__all__ = [
    "TAU_MAX", "standardised_residuals", "systematic_bands", "peak_features", "compare_peaks",
    "length_trend", "adequacy", "Detection", "detect_from_fit",
]

#: Correlation length (lines) above which the residuals are called systematic.
TAU_MAX = 2.0
#: Thresholds of the resonance diagnosis.
SHIFT_MIN_PCT = 0.3
HEIGHT_RATIO = 0.15
WIDTH_RATIO = 0.25
#: An unmatched mode at least this fraction of its FRF's highest peak is a finding (weaker ones are listed only).
UNMATCHED_REL_HEIGHT = 0.25


def standardised_residuals(measured: np.ndarray, predicted_draws: np.ndarray, noise_sd: np.ndarray) -> np.ndarray:
    """Standardised posterior-predictive residuals.

    Parameters
    ----------
    measured : (n,) complex, m/N
    predicted_draws : (n_draws, n) complex, m/N
    noise_sd : (n,) m/N, standard deviation of the complex measurement noise

    Returns
    -------
    (n,) complex; ``E|z|^2 = 1`` under an adequate model.
    """
    mean = predicted_draws.mean(axis=0)
    var = predicted_draws.var(axis=0) if predicted_draws.shape[0] > 1 else 0.0
    return (measured - mean) / np.sqrt(noise_sd**2 + var)


def systematic_bands(frequency_hz: np.ndarray, z: np.ndarray, window: int = 5, level: float = 4.0,
                     min_lines: int = 3) -> list[tuple[float, float, float]]:
    """Frequency bands where the moving average of ``|z|^2`` exceeds ``level``.

    Returns
    -------
    list of (lo_hz, hi_hz, mean |z|^2 in the band)
    """
    q = np.abs(z) ** 2
    w = max(1, min(window, q.size))
    avg = np.convolve(q, np.ones(w) / w, mode="same")
    hot = avg > level
    out = []
    i = 0
    while i < hot.size:
        if hot[i]:
            j = i
            while j + 1 < hot.size and hot[j + 1]:
                j += 1
            if j - i + 1 >= min_lines:
                out.append((float(frequency_hz[i]), float(frequency_hz[j]), float(q[i : j + 1].mean())))
            i = j + 1
        else:
            i += 1
    return out


def peak_features(frequency_hz: np.ndarray, h: np.ndarray) -> dict:
    """Natural frequency (Hz), peak height (m/N) and half-power width (Hz) of the dominant peak of ``h`` (n,)."""
    f = np.asarray(frequency_hz, dtype=float)
    modes = find_modes(f, h)
    if not modes:
        return {"frequency_hz": math.nan, "height": float(np.abs(h).max()), "width_hz": math.nan}
    m = max(modes, key=lambda x: x.height)
    return m.as_dict()


def compare_peaks(frequency_hz: np.ndarray, measured: np.ndarray, predicted: np.ndarray,
                  predicted_f_sd=0.0, predicted_draws: np.ndarray | None = None) -> dict:
    """Resonance diagnosis of one measurement (model vs measured, same lines), mode by mode.

    The modes of both FRFs are found and matched one to one
    (:func:`bayes_rcsa.model.modes.match_modes`); a frequency error is only
    ever computed between a measured mode and *its* model mode.  The headline
    numbers belong to the measured FRF's most prominent mode and its model
    counterpart.

    Parameters
    ----------
    frequency_hz : (n,) Hz
    measured, predicted : (n,) complex, m/N
    predicted_f_sd : float, Hz
        Posterior standard deviation of the model's mode frequencies (used when ``predicted_draws`` is None).
    predicted_draws : (n_draws, n) complex or None
        Model FRF draws; each model mode's standard deviation is then tracked in its own window.

    Returns
    -------
    dict with ``frequency_error_pct`` (model - measured, of the most prominent measured mode and its match;
    NaN when that mode has no model counterpart), ``height_ratio`` and ``width_ratio`` (model / measured),
    ``significant_shift``, ``modes`` (every matched pair), ``unmatched_measured_hz``,
    ``unmatched_model_hz``, ``prominent_mode_differs`` and a list of plain-language ``findings``.
    """
    f = np.asarray(frequency_hz, dtype=float)
    mm = find_modes(f, measured)
    pm = find_modes(f, predicted)
    pairs = match_modes(pm, mm)
    if predicted_draws is not None and pm:
        tracked = track_modes(f, predicted_draws, mode_windows(pm))
        with np.errstate(invalid="ignore"):
            sd = [float(np.nanstd(tracked[:, i])) if np.isfinite(tracked[:, i]).sum() > 1 else 0.0
                  for i in range(len(pm))]
    else:
        sd = [float(predicted_f_sd)] * len(pm)
    df = float(np.median(np.diff(f))) if f.size > 1 else 0.0
    modes, findings, significant_any = [], [], False
    for i, j in pairs:
        err = 100.0 * (pm[i].frequency_hz - mm[j].frequency_hz) / mm[j].frequency_hz
        thresh = max(SHIFT_MIN_PCT, 100.0 * df / mm[j].frequency_hz)
        sig = bool(np.isfinite(err) and abs(err) > thresh and abs(err) > 3 * 100.0 * sd[i] / mm[j].frequency_hz)
        modes.append({"measured_hz": mm[j].frequency_hz, "model_hz": pm[i].frequency_hz, "frequency_error_pct": err,
                      "height_ratio": pm[i].height / mm[j].height, "significant_shift": sig,
                      "model_index": i, "measured_index": j})
        significant_any |= sig
    paired_m = {j for _, j in pairs}
    paired_p = {i for i, _ in pairs}
    unmatched_m = [mm[j].frequency_hz for j in range(len(mm)) if j not in paired_m]
    unmatched_p = [pm[i].frequency_hz for i in range(len(pm)) if i not in paired_p]
    top_m = max(range(len(mm)), key=lambda j: mm[j].height) if mm else None
    top_p = max(range(len(pm)), key=lambda i: pm[i].height) if pm else None
    head = next((m for m in modes if m["measured_index"] == top_m), None)
    # the more prominent mode differs: the measured FRF's highest peak is matched to a model mode that is
    # not the model's highest peak (or the model's highest peak is matched to another measured mode)
    differs = bool(top_m is not None and top_p is not None and len(pairs) > 0
                   and ((head is not None and head["model_index"] != top_p)
                        or any(m["model_index"] == top_p and m["measured_index"] != top_m for m in modes)))
    if head is not None:
        err, hr = head["frequency_error_pct"], head["height_ratio"]
        wr_m, wr_p = mm[top_m].width_hz, pm[head["model_index"]].width_hz
        wr = wr_p / wr_m if np.isfinite(wr_p) and np.isfinite(wr_m) else math.nan
        significant = head["significant_shift"]
    else:
        err, hr, wr, significant = math.nan, math.nan, math.nan, False
    for m in modes:
        if m["significant_shift"]:
            e = m["frequency_error_pct"]
            which = "" if len(modes) == 1 else f" (mode at {m['measured_hz']:.0f} Hz)"
            findings.append(f"model resonance {'too high' if e > 0 else 'too low'} by {abs(e):.2f} %{which}")
    if np.isfinite(hr) and abs(hr - 1) > HEIGHT_RATIO:
        findings.append(f"model peak {'too high' if hr > 1 else 'too low'} ({hr:.2f} x measured)")
    if np.isfinite(wr) and abs(wr - 1) > WIDTH_RATIO:
        findings.append(f"model peak {'too wide' if wr > 1 else 'too narrow'} ({wr:.2f} x measured)")
    if differs:
        findings.append(f"the more prominent mode differs: measured highest peak at {mm[top_m].frequency_hz:.0f} Hz, "
                        f"model highest peak at {pm[top_p].frequency_hz:.0f} Hz (a different mode)")
    # an unmatched mode is a finding only when it is strong (a weak peak near the detection threshold may be
    # found on one side and not the other without any discrepancy)
    strong_m = [mm[j].frequency_hz for j in range(len(mm))
                if j not in paired_m and mm[j].height >= UNMATCHED_REL_HEIGHT * mm[top_m].height]
    strong_p = [pm[i].frequency_hz for i in range(len(pm))
                if i not in paired_p and pm[i].height >= UNMATCHED_REL_HEIGHT * pm[top_p].height]
    for fu in strong_m:
        findings.append(f"measured mode at {fu:.0f} Hz has no model counterpart")
    for fu in strong_p:
        findings.append(f"model mode at {fu:.0f} Hz has no measured counterpart")
    return {"measured": mm[top_m].as_dict() if top_m is not None else None,
            "predicted": pm[head["model_index"]].as_dict() if head is not None else None,
            "frequency_error_pct": err, "height_ratio": hr, "width_ratio": wr,
            "significant_shift": bool(significant or significant_any), "modes": modes,
            "unmatched_measured_hz": unmatched_m, "unmatched_model_hz": unmatched_p,
            "prominent_mode_differs": differs, "findings": findings}


def length_trend(lengths_m: Sequence[float], errors_pct: Sequence[float]) -> dict | None:
    """Slope (% per mm) and intercept of the frequency error against clamping length; None with < 2 lengths."""
    x = np.asarray(lengths_m, dtype=float) * 1e3
    y = np.asarray(errors_pct, dtype=float)
    ok = np.isfinite(y)
    if np.unique(x[ok]).size < 2:
        return None
    slope, icpt = np.polyfit(x[ok], y[ok], 1)
    return {"slope_pct_per_mm": float(slope), "intercept_pct": float(icpt)}


def adequacy(tau: float, pile_up: Sequence[str], significant_shifts: Sequence[str]) -> tuple[bool, list[str]]:
    """The documented adequacy test (module docstring): adequate, and the reasons when not."""
    reasons = []
    if tau > TAU_MAX:
        reasons.append(f"residuals correlated over {tau:.1f} lines (> {TAU_MAX:g}): a smooth, systematic misfit")
    reasons += [f"{p} piles up on its prior bound" for p in pile_up]
    reasons += [f"resonance mismatch: {s}" for s in significant_shifts]
    return (not reasons), reasons


@dataclass
class Detection:
    """Result of :func:`detect_from_fit` (JSON-able via :meth:`as_dict`)."""

    adequate: bool
    reasons: list
    correlation_length: float
    measurements: list
    trend: dict | None
    pile_up: list
    transfer: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"adequate": self.adequate, "reasons": self.reasons, "correlation_length_lines": self.correlation_length,
                "measurements": self.measurements, "trend_with_clamping_length": self.trend,
                "prior_bound_pile_up": self.pile_up, "leave_one_length_out": self.transfer}


def pile_up(fit, rel: float = 0.01, z_min: float = 2.0) -> list[str]:
    """Contact/growth parameters of ``fit`` pressed against a prior bound (see the adequacy test).

    A parameter counts when its MAP lies within ``rel`` of the bound (in its
    sampling coordinate) *and* the tempered likelihood pushes outwards
    significantly: the unconstrained Gauss-Newton step beyond the bound is
    more than ``z_min`` of its own standard deviations,
    ``-g_j / sqrt(H_jj) > z_min`` with ``g = 2 beta J^T z`` and
    ``H_jj = 2 beta |J_j|^2``.  A true value merely near a bound (the bench's
    growth 0.45 against Q = 0.5, weakly identified for k_thetaM) puts the MAP
    on the bound without that pressure.
    """
    from .fit import model_floor, whitened_residuals

    pm = fit.problem.parameters
    bounds = fit.problem.priors.optimisation_bounds()
    cand = []
    for j, name in enumerate(pm.names):
        role = pm[name].role
        lo, hi = bounds[j]
        u = fit.theta[j]
        if role == "contact" and u <= lo + rel * (hi - lo):
            cand.append((j, name, -1.0))
        elif role in ("contact", "growth") and u >= hi - rel * (hi - lo):
            cand.append((j, name, 1.0))
    if not cand:
        return []
    h = np.array([-d * 1e-6 * (bounds[j][1] - bounds[j][0]) for j, _, d in cand])  # inward steps
    pts = np.repeat(fit.theta[None], len(cand) + 1, axis=0)
    for k, (j, _, _) in enumerate(cand):
        pts[k + 1, j] += h[k]
    z = whitened_residuals(fit.problem, pts, model_floor(fit.problem, fit.theta))
    out = []
    for k, (_, name, direction) in enumerate(cand):
        jac = (z[k + 1] - z[0]) / h[k]
        grad = -2 * fit.tempering * float(jac @ z[0])  # d(beta ln L)/du
        curv = 2 * fit.tempering * float(jac @ jac)
        if curv > 0 and direction * grad / np.sqrt(curv) > z_min:
            out.append(name)
    return out


def detect_from_fit(fit, rng: np.random.Generator, n_draws: int = 64) -> Detection:
    """Detection on the fitted lines of a baseline :class:`~.fit.ModelFit`."""
    from .fit import laplace_draws

    prob = fit.problem
    lik = prob.likelihood
    draws = laplace_draws(fit, rng, n_draws)
    pred = lik.model_frf(draws)
    h_map = fit.model_frf()
    var_shape = lik.variance_of(h_map)[0]
    s = prob.parameters.noise(prob.parameters.values(fit.theta[None]))[0][lik.stack.index]
    z = standardised_residuals(lik.data, pred, s * np.sqrt(var_shape))
    meas = []
    shifts = []
    for j, (obs, sl) in enumerate(zip(prob.observations, lik.stack.slices)):
        f = obs.frequency_hz
        cmp = compare_peaks(f, obs.values, h_map[sl], predicted_draws=pred[:, sl])
        entry = {
            "source": obs.source, "clamping_length": obs.configuration.clamping_length,
            "direction": obs.configuration.direction, "rms_z": float(np.sqrt(np.mean(np.abs(z[sl]) ** 2))),
            "correlation_length_lines": residual_correlation_length(z[sl], [slice(0, sl.stop - sl.start)]),
            "bands": [{"lo_hz": a, "hi_hz": b, "mean_z2": c} for a, b, c in systematic_bands(f, z[sl])],
            "resonance": cmp,
        }
        meas.append(entry)
        # a shifted resonance, a mode only one side has, or a different most prominent mode
        mode_reasons = [x for x in cmp["findings"] if x.startswith(("model resonance", "the more prominent",
                                                                  "measured mode at"))]
        shifts += [f"{obs.source}: {x}" for x in mode_reasons]
    trend = length_trend([m["clamping_length"] for m in meas], [m["resonance"]["frequency_error_pct"] for m in meas])
    piles = pile_up(fit)
    ok, reasons = adequacy(fit.correlation_length, piles, shifts)
    return Detection(ok, reasons, fit.correlation_length, meas, trend, piles)


#: Leave-one-length-out natural-frequency error (%) beyond which the baseline is inadequate (rule 4).
TRANSFER_LIMIT_PCT = 1.0


def transfer_failures(transfer, limit_pct: float = TRANSFER_LIMIT_PCT) -> list[str]:
    """Adequacy reasons from the leave-one-length-out check (rule 4 of the module docstring).

    Parameters
    ----------
    transfer : list of dict with ``left_out_mm``, ``direction``, ``source``, ``error_pct`` (entries
        with ``error`` instead, where a refit was impossible, are skipped)
    limit_pct : float, %
    """
    out = []
    for t in transfer:
        if "error_pct" in t and not math.isfinite(t["error_pct"]):
            out.append(f"leave-one-length-out: fitted without {t['left_out_mm']:g} mm, the model has no mode "
                       f"matching the most prominent measured mode of {t['source']} ({t['direction']})")
        elif "error_pct" in t and abs(t["error_pct"]) > limit_pct:
            out.append(f"leave-one-length-out: fitted without {t['left_out_mm']:g} mm, the model mispredicts "
                       f"{t['source']} ({t['direction']}) by {t['error_pct']:+.2f} % (> {limit_pct:g} %)")
    return out
