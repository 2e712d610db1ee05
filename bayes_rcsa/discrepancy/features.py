"""Unexplained features: misfit away from every measured mode, and the predicted modes near them.

When no known effect explains the data, a systematic misfit band that lies
*away* from every measured mode at a fitted length (an unmodelled resonance
of the spindle or holder, a ring of the collet nut) is a structure the model
does not have.  It couples to any mode of the real structure that comes near
it in frequency: as the clamping length changes, the tool mode sweeps past
it and veers.  The mode-frequency bias learned at the fitted lengths
(mode_bias.py) cannot anticipate that where the fitted lengths put the tool
mode far from the feature and an unmeasured length puts it close: on the
project's bench, a 0.2-kg flange resonance at 1000 Hz left the fitted modes
(858, 1078, 1200 Hz) within 1 Hz and moved the 30-mm mode (959 Hz, 4 % below
it) by 4 Hz, three times its 90 % half-width.  Such a prediction is flagged,
not trusted.

Rules:

* a *feature* is a systematic misfit band at a fitted measurement whose
  nearest edge lies more than two half-power widths from every measured mode
  of that measurement (a band on a mode is a shifted or reshaped mode, which
  the bias handles).  Two detectors find them: the baseline detection's
  bands (:func:`unexplained_features`, ``detector: "detection_bands"``) and
  the posterior-predictive scan of the final model
  (:mod:`.predictive_scan`, ``detector: "predictive_scan"``), which also
  finds a weak resonance spread over more lines than the detection's five;
* a predicted mode at a clamping length that was *not* fitted is *near* a
  feature when the feature's nearest edge lies within
  :data:`NEAR_FEATURE_REL` (10 %) of its frequency.  Two modes 10 % apart
  with the bench's coupling shift each other by well under 0.1 %; 4 % apart,
  by 0.4 %.
"""

from __future__ import annotations

import math

__all__ = ["unexplained_features", "modes_near_features", "NEAR_FEATURE_REL", "MODE_CLEARANCE_WIDTHS"]

#: Relative distance within which a predicted mode at an unmeasured length is "near" an unexplained feature.
NEAR_FEATURE_REL = 0.10
#: Half-power widths around a measured mode within which a misfit band belongs to that mode.
MODE_CLEARANCE_WIDTHS = 2.0


def _distance(f: float, lo: float, hi: float) -> float:
    """Hz from ``f`` to the band [lo, hi] (0 inside)."""
    return max(lo - f, f - hi, 0.0)


def unexplained_features(detection_measurements: list, measurements: list) -> list[dict]:
    """Misfit bands at the fitted measurements that lie away from every measured mode.

    Parameters
    ----------
    detection_measurements : list of dict, the baseline detection's per-measurement entries (``source``,
        ``direction``, ``clamping_length``, ``bands`` with ``lo_hz``/``hi_hz``)
    measurements : list of dict, an evaluation's per-measurement entries (``source``, ``modes`` with
        ``measured_hz`` and ``measured_width_hz``)

    Returns
    -------
    list of dict: ``lo_hz``, ``hi_hz``, ``source``, ``direction``, ``clamping_length``.
    """
    by_source = {(m["source"], m["direction"], round(m["clamping_length"], 12)): m for m in measurements}
    out = []
    for d in detection_measurements:
        m = by_source.get((d["source"], d["direction"], round(d["clamping_length"], 12)))
        if m is None:
            continue
        modes = [(md["measured_hz"], md.get("measured_width_hz", math.nan)) for md in m["modes"]]
        for b in d["bands"]:
            lo, hi = b["lo_hz"], b["hi_hz"]
            on_mode = any(_distance(f, lo, hi) <= MODE_CLEARANCE_WIDTHS * (w if math.isfinite(w) else 0.0)
                          for f, w in modes)
            if not on_mode:
                out.append({"lo_hz": lo, "hi_hz": hi, "source": d["source"], "direction": d["direction"],
                            "clamping_length": d["clamping_length"], "detector": "detection_bands"})
    return out


def modes_near_features(measurements: list, features: list, rel: float = NEAR_FEATURE_REL) -> list[str]:
    """Flag the modes predicted at unmeasured lengths near an unexplained feature, in place; the reasons.

    Each flagged mode gains ``near_unexplained_feature_hz`` = [lo, hi] of the nearest feature.
    """
    reasons = []
    if not features:
        return reasons
    for m in measurements:
        if m["fitted"]:
            continue
        for md in m["modes"]:
            f = md["model_hz"]
            if not math.isfinite(f):
                continue
            near = min(features, key=lambda b: _distance(f, b["lo_hz"], b["hi_hz"]))
            if _distance(f, near["lo_hz"], near["hi_hz"]) <= rel * f:
                md["near_unexplained_feature_hz"] = [near["lo_hz"], near["hi_hz"]]
                reasons.append(
                    f"{m['direction']} {1e3 * m['clamping_length']:g} mm (not fitted): the mode predicted at "
                    f"{f:.0f} Hz lies within {100 * rel:g} % of an unexplained misfit at {near['lo_hz']:.0f}-"
                    f"{near['hi_hz']:.0f} Hz ({near['source']}); an unmodelled resonance there can move it by more "
                    "than its interval")
    return reasons
