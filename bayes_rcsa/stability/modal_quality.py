"""Spread of the modal fits over FRF draws, and where a modal fit misses the measured FRF (SDM).

The SDM method fits a modal model to every FRF draw
(:mod:`.sdm_draws`).  In measured mode the draws are realisations of the
measurement's random error (:mod:`.measured`), so the fitted natural
frequency, damping ratio and modal stiffness of each mode scatter over the
draws: :func:`modal_fit_spread` reports their median and 5-95 % range per
mode and direction.

A modal model that misses the measured FRF makes the SDM lobes wrong however
many draws are used.  :func:`modal_fit_quality` cuts the band into
:data:`QUALITY_WINDOWS` windows of equal line count and computes in each the
normalised residual

    r_w = RMS_{f in w} |G(f) - Ĝ(f)| / RMS_{all f} |G(f)|

(Ĝ: the modal model plus its residual compliance); windows with
r_w > :data:`RESIDUAL_THRESHOLD` (0.10: ten times the 1-2 % random error of a
good hammer test, well above what noise alone gives) are reported, adjacent
ones merged, with their band in Hz.
"""

from __future__ import annotations

import numpy as np

__all__ = ["modal_fit_spread", "modal_fit_quality", "RESIDUAL_THRESHOLD", "QUALITY_WINDOWS"]

RESIDUAL_THRESHOLD = 0.10
QUALITY_WINDOWS = 20


def modal_fit_spread(modal_fits) -> dict:
    """Median and 5-95 % range of f_n (Hz), ζ and k (N/m) per mode over the draws' modal fits.

    Parameters
    ----------
    modal_fits : list of (ModalFit x, ModalFit y), one pair per draw

    Returns
    -------
    dict {"x": ..., "y": ...}, each with ``n_modes`` (the most frequent mode count), ``draws_used`` (draws
    with that count; modes are matched by frequency order), ``n_draws`` and per quantity
    {"median", "q05", "q95"} lists over the modes.
    """
    out = {}
    for k, d in enumerate(("x", "y")):
        models = [pair[k].model for pair in modal_fits]
        counts = np.array([m.n_modes for m in models])
        values, freq = np.unique(counts, return_counts=True)
        n_modes = int(values[np.argmax(freq)])
        used = [m for m in models if m.n_modes == n_modes]
        entry = {"n_modes": n_modes, "draws_used": len(used), "n_draws": len(models)}
        for key, attr in (("natural_frequency_hz", "natural_frequency_hz"), ("damping_ratio", "damping_ratio"),
                          ("stiffness_n_per_m", "stiffness")):
            a = np.array([getattr(m, attr) for m in used])  # (n_used, n_modes)
            q = np.quantile(a, [0.05, 0.5, 0.95], axis=0)
            entry[key] = {"median": q[1].tolist(), "q05": q[0].tolist(), "q95": q[2].tolist()}
        out[d] = entry
    return out


def modal_fit_quality(frequency_hz, frf, fit, label: str, threshold: float = RESIDUAL_THRESHOLD,
                      windows: int = QUALITY_WINDOWS):
    """Windowed normalised residual of a modal fit and the warnings where it exceeds ``threshold``.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz
    frf : (n_freq,) complex m/N, the measured FRF the fit is judged on
    fit : ModalFit
    label : str, name of the FRF in the warning (e.g. the file)
    threshold : float, largest acceptable r_w
    windows : int, number of windows of equal line count

    Returns
    -------
    residual : (n_windows,) r_w
    bands : (n_windows, 2) Hz, first and last line of each window
    warnings : list of str (empty when every window is below ``threshold``)
    """
    f = np.asarray(frequency_hz, dtype=float)
    g = np.asarray(frf, dtype=complex)
    model = fit.model.frf(f) + fit.residual_compliance
    scale = float(np.sqrt(np.mean(np.abs(g) ** 2)))
    r2 = np.abs(g - model) ** 2 / scale**2
    edges = np.linspace(0, f.size, min(windows, f.size) + 1).round().astype(int)
    c = np.concatenate([[0.0], np.cumsum(r2)])
    resid = np.sqrt((c[edges[1:]] - c[edges[:-1]]) / np.maximum(edges[1:] - edges[:-1], 1))
    bands = np.stack([f[edges[:-1]], f[edges[1:] - 1]], axis=1)
    bad = resid > threshold
    warnings = []
    if np.any(bad):
        # merge adjacent windows into runs
        idx = np.nonzero(bad)[0]
        runs = np.split(idx, np.nonzero(np.diff(idx) > 1)[0] + 1)
        where = ", ".join(f"{bands[r[0], 0]:.0f}-{bands[r[-1], 1]:.0f} Hz (up to {resid[r].max():.2f})" for r in runs)
        warnings.append(f"the modal fit of {label} ({fit.model.n_modes} mode(s)) misses the FRF at {where}: "
                        f"normalised residual above {threshold:g}; the SDM lobes there are unreliable (try "
                        "--max-modes, or --method zoa, which uses the FRF directly)")
    return resid, bands, warnings


def measured_fit_report(measured, modal_fits, max_modes: int):
    """The modal fit of the measured FRFs (X, Y) as written to ``lobes.json``, and its warnings.

    Parameters
    ----------
    measured : (MeasuredDirection x, MeasuredDirection y)
    modal_fits : list of (ModalFit x, ModalFit y) per draw (the method's; one draw: the fits of the measured
        FRFs, reused)
    max_modes : int, largest mode count of the fit

    Returns
    -------
    report : dict {"x": ..., "y": ...}: modes, rms_relative, residual per window with its band, threshold
    warnings : list of str
    """
    from pathlib import Path

    from .modal_fit import fit_modal_model

    report, warnings = {"fitted_to": "measured FRF (mean of the hits)", "residual_threshold": RESIDUAL_THRESHOLD}, []
    for k, (d, m) in enumerate(zip(("x", "y"), measured)):
        fit = modal_fits[0][k] if len(modal_fits) == 1 else fit_modal_model(m.frequency_hz, m.mean, max_modes=max_modes,
                                                                             source=m.files[0])
        resid, bands, warn = modal_fit_quality(m.frequency_hz, m.mean, fit, Path(m.files[0]).name)
        warnings += warn
        report[d] = {
            "natural_frequency_hz": fit.model.natural_frequency_hz.tolist(),
            "damping_ratio": fit.model.damping_ratio.tolist(),
            "stiffness_n_per_m": fit.model.stiffness.tolist(),
            "rms_relative": fit.rms_relative,
            "residual_windows": {"band_hz": bands.tolist(), "normalised_residual": resid.tolist()},
        }
    return report, warnings
