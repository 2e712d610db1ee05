"""The files of the lobes job: ``lobes.json``, ``p_stable.npz`` and ``lobes.png``.

``lobes.json`` keys:

- ``spindle_speed_rpm`` (n_speed,), ``depth_limit_m`` {q05, q50, q95} (``null`` where no limit lies
  inside the analysed range: ZOA - no chatter frequency of the FRF band maps to the speed; SDM - the
  cut is still stable far above the zero-order guess);
- ``recommended``: the robust point (:meth:`Recommendation.as_dict`: speed, depth, P(stable) at the
  point and over its neighbourhood, tolerances, margins in rpm and m, ``binding_limit``) or ``null``
  with ``recommended_note``;
- ``pointwise_optimum``: the optimum at P(stable) >= level without tolerance or margin;
- ``alternatives``: the best robust point of each of the three largest stable pockets;
- ``robust_envelope``: {``confidence`` (= level), ``depth_limit_m`` (n_speed,)}: the depth below which
  P(stable) >= confidence at each speed (the lower (1 - confidence) quantile over the draws; the limit
  itself when deterministic);
- ``median_recommended``: the robust point at P(stable) >= 0.5 with the same tolerances, and
  ``confidence_cost`` {``depth_m``, ``relative``}: the depth the confidence costs against it;
- ``uncertainty`` (measured mode): the random-error model per direction, or why there is none;
  ``modal_fit_spread`` (SDM with several draws): median and 5-95 % of f_n, ζ, k per mode;
- ``p_stable_map``: the resolution of the P(stable) map in ``p_stable.npz`` (``speeds`` x ``depths``, the
  full grid) and of the map the figure shows (``display_columns`` columns, the block mean of
  ``display_speed_block`` consecutive speeds; in the npz as ``display_speed_rpm``/``display_p_stable``).
  The map is for display and for reading off P(stable); the recommendation and the envelope are computed
  from the per-draw limits, so they do not depend on either resolution;
- ``level``, ``method``, ``n_draws``, ``deterministic``, ``depth_grid_m`` {min, max, count},
  ``cutting`` (coefficients, geometry, tolerance), ``source``, ``warnings``, ``modal_fit`` (SDM) and,
  with cutting tests, ``tests`` and ``test_error``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .compare import stable_at, test_error
from .plots import display_blocks, display_map, plot_lobes

__all__ = ["lobes_document", "write_lobes_outputs"]

_NOTES = ("depth_limit_m quantiles are over draws: q05 is the depth 95 % of the draws consider stable; "
          "null = no limit inside the analysed range (zoa: no chatter frequency of the FRF band maps to that speed; "
          "sdm: still stable far above the zero-order guess). mrr_index = depth_m * spindle_speed_rpm. "
          "The recommended point holds P(stable) >= level over its whole neighbourhood (speed window x depths up "
          "to depth_checked_m, and cutting-force level within its tolerance); binding_limit names what sets its depth.")


def _finite_list(a):
    return [float(v) if np.isfinite(v) else None for v in np.asarray(a, dtype=float)]


def _map_resolution(res) -> dict:
    """The ``p_stable_map`` entry: the full and the displayed resolution of the P(stable) map."""
    n_speed, n_depth = int(np.size(res.speed_rpm)), int(np.size(res.depth_m))
    block = display_blocks(n_speed)
    return {"file": "p_stable.npz", "speeds": n_speed, "depths": n_depth,
            "display_columns": -(-n_speed // block), "display_speed_block": block,
            "note": "recommendation and envelope come from the per-draw limits, not from this map"}


def lobes_document(res, cutting, source: dict, tests=None, warnings=(), max_depth=None, flute_length=None) -> dict:
    """The JSON-able content of ``lobes.json`` for a ProbabilisticLobes result (keys: module notes)."""
    q = res.quantiles
    phi_in, phi_out = cutting.angles
    rec = res.recommended
    out = {
        "spindle_speed_rpm": [float(v) for v in res.speed_rpm],
        "depth_limit_m": {"q05": _finite_list(q[0.05]), "q50": _finite_list(q[0.5]), "q95": _finite_list(q[0.95])},
        "recommended": None if rec is None else rec.as_dict(),
        "pointwise_optimum": None if res.pointwise is None else {
            "spindle_speed_rpm": res.pointwise.spindle_speed_rpm, "depth_m": res.pointwise.depth_m,
            "p_stable": res.pointwise.p_stable, "mrr_index": res.pointwise.mrr_index},
        "alternatives": res.alternatives,
        "level": res.level,
        "method": res.method,
        "n_draws": int(res.depth_limit_m.shape[0]),
        "deterministic": bool(res.depth_limit_m.shape[0] == 1),
        "depth_grid_m": {"min": float(res.depth_m[0]), "max": float(res.depth_m[-1]), "count": int(res.depth_m.size)},
        "p_stable_map": _map_resolution(res),
        "depth_limits_m": {"max_depth": max_depth, "flute_length": flute_length},
        "cutting": {
            "kt_pa": cutting.kt,
            "kr_pa": cutting.kr,
            "flutes": cutting.flutes,
            "radial_immersion": cutting.radial_immersion,
            "milling": cutting.milling,
            "entry_angle_deg": math.degrees(phi_in),
            "exit_angle_deg": math.degrees(phi_out),
            "feed": cutting.feed,
            "pitch_deg": [math.degrees(v) for v in cutting.pitches],
        },
        "source": source,
        "warnings": list(warnings),
        "notes": _NOTES,
    }
    if res.envelope is not None:
        out["robust_envelope"] = {"confidence": res.level, "depth_limit_m": _finite_list(res.envelope)}
    med = res.median_recommended
    out["median_recommended"] = None if med is None else med.as_dict()
    if med is not None and rec is not None:
        out["confidence_cost"] = {"depth_m": med.depth_m - rec.depth_m,
                                  "relative": (med.depth_m - rec.depth_m) / med.depth_m if med.depth_m > 0 else None,
                                  "median_speed_rpm": med.spindle_speed_rpm}
    if "uncertainty" in source:
        out["uncertainty"] = {**source["uncertainty"], "deterministic": bool(source.get("deterministic")),
                              "note": source.get("deterministic_note", "")}
    if rec is None:
        out["recommended_note"] = res.note
    if res.method_info:
        out["method_info"] = res.method_info
    if res.modal_fits:
        fx, fy = res.modal_fits[0]
        out["modal_fit"] = {
            d: {
                "natural_frequency_hz": fit.model.natural_frequency_hz.tolist(),
                "damping_ratio": fit.model.damping_ratio.tolist(),
                "stiffness_n_per_m": fit.model.stiffness.tolist(),
                "rms_relative": fit.rms_relative,
            }
            for d, fit in (("x", fx), ("y", fy))
        }
        if len(res.modal_fits) > 1:
            from .modal_quality import modal_fit_spread

            out["modal_fit_spread"] = modal_fit_spread(res.modal_fits)
    if tests is not None:
        ts, td, tst = tests
        per_draw = np.array([stable_at(res.speed_rpm, lim, ts, td) for lim in res.depth_limit_m])
        p_test = per_draw.mean(axis=0)
        predicted = p_test >= 0.5
        out["tests"] = [
            {"spindle_speed_rpm": float(s), "depth_m": float(d), "outcome": "stable" if o else "chatter",
             "p_stable": float(p), "predicted": "stable" if pr else "chatter"}
            for s, d, o, p, pr in zip(ts, td, tst, p_test, predicted)
        ]
        out["test_error"] = test_error(predicted, tst)
    return out


def _dumps(document: dict) -> str:
    """JSON text with one top-level key per line, each value in compact form (the C encoder: the per-speed lists
    of a fine grid would take ten times longer with ``indent``)."""
    items = [f" {json.dumps(k)}: {json.dumps(v)}" for k, v in document.items()]
    return "{\n" + ",\n".join(items) + "\n}\n"


def write_lobes_outputs(outdir, res, document: dict, tests=None, title: str = "", max_depth=None,
                        plots: bool = True) -> Path:
    """Write lobes.png (unless not ``plots``), p_stable.npz and lobes.json into ``outdir`` (each atomically; the
    figure first, as the step most likely to fail).  Returns the path of lobes.json."""
    from ..io.atomic import atomic_path, atomic_write_text

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    if plots:
        plot_lobes(outdir / "lobes.png", res, tests, title, max_depth=max_depth)
    with atomic_path(outdir / "p_stable.npz") as tmp:
        with open(tmp, "wb") as fh:
            shown_speed, shown_p, _ = display_map(res.speed_rpm, res.p_stable)
            np.savez(fh, spindle_speed_rpm=res.speed_rpm, depth_m=res.depth_m, p_stable=res.p_stable,
                     display_speed_rpm=shown_speed, display_p_stable=shown_p)
    atomic_write_text(outdir / "lobes.json", _dumps(document))
    return outdir / "lobes.json"
