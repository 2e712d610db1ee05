"""summary.json: parameter, stiffness and natural-frequency summaries plus warnings.

Every statistic is computed from the posterior draws passed in (physical
units); the convergence diagnostics come from :mod:`.diagnostics`.  Values
that do not exist (R-hat of a deterministic fit, a quantile of an all-NaN
set) are written as JSON ``null``, never as a made-up number.
"""

from __future__ import annotations

import json
import math
from typing import Any, Mapping, Sequence

import numpy as np

from ..io.atomic import atomic_write_text

__all__ = [
    "parameter_summary",
    "quantiles",
    "growth_bound_warnings",
    "write_summary",
    "to_jsonable",
    "PILE_UP_FRACTION",
]

# A uniform prior puts 5 % of its mass within 5 % of a bound.  A posterior
# that is merely wide and leaning towards the bound (a weakly identified
# g_thetaM, say) keeps 10-15 % there; one pressed against the bound by the
# data keeps most of its mass there.  Five times the prior share separates
# the two.
PILE_UP_FRACTION = 0.25


def _f(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def quantiles(x: np.ndarray, suffix: str = "") -> dict[str, float | None]:
    """q05, q50, q95 of the finite values of ``x`` (``None`` if there are none)."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {f"q05{suffix}": None, f"q50{suffix}": None, f"q95{suffix}": None}
    q = np.quantile(x, [0.05, 0.5, 0.95])
    return {f"q05{suffix}": _f(q[0]), f"q50{suffix}": _f(q[1]), f"q95{suffix}": _f(q[2])}


def parameter_summary(draws: np.ndarray, rhat=None, ess_bulk=None, ess_tail=None, unit: str = "1") -> dict:
    """Mean, sd, quantiles and diagnostics of one parameter (physical units)."""
    x = np.asarray(draws, dtype=float).ravel()
    out = {"mean": _f(np.mean(x)), "sd": _f(np.std(x, ddof=1)) if x.size > 1 else 0.0}
    out.update(quantiles(x))
    out.update({
        "rhat": None if rhat is None else _f(rhat),
        "ess_bulk": None if ess_bulk is None else _f(ess_bulk),
        "ess_tail": None if ess_tail is None else _f(ess_tail),
        "unit": unit,
    })
    return out


def growth_bound_warnings(draws: Mapping[str, np.ndarray], growth_bound: float) -> list[str]:
    """Warn when a growth factor's posterior piles up against 0 or Q.

    The growth law caps the relative stiffness increase over the feasible
    range at Q.  If the data want more, the posterior presses against
    ``g = Q`` instead of the truth: a prior-data conflict that the user must
    see (the reference paper's own identified values grow 57 % between 25
    and 40 mm although its Q is 50 %).  Piling up at 0 means the data prefer
    a stiffness that *decreases* with clamping length.
    """
    out = []
    q = growth_bound
    for name in ("g_xf", "g_thetaM"):
        if name not in draws or q <= 0:
            continue
        g = np.asarray(draws[name], dtype=float).ravel()
        top = float(np.mean(g > 0.95 * q))
        bottom = float(np.mean(g < 0.05 * q))
        if top > PILE_UP_FRACTION:
            out.append(
                f"{name}: {100 * top:.0f} % of the posterior lies within 5 % of the growth bound Q = {q:g} "
                f"(uniform prior: 5 %, warning above 25 %); the data call for stiffness growth at or beyond Q (prior-data conflict). "
                f"Check the clamping lengths, or rerun with a larger contact.growth_bound to see how much growth the data support."
            )
        if bottom > PILE_UP_FRACTION:
            out.append(
                f"{name}: {100 * bottom:.0f} % of the posterior lies within 5 % of g = 0 (uniform prior: 5 %); "
                f"the data may prefer a stiffness that decreases with clamping length, which the growth law excludes."
            )
    return out


NOISE_WARNING = 0.3  # relative noise scale beyond which a measurement is effectively not fitted


def noise_scale_warnings(draws: Mapping[str, np.ndarray], observations) -> list[str]:
    """Warn when a measurement's inferred relative noise is so large that the model does not fit it.

    With one noise scale per measurement, a model that cannot fit all
    measurements at once (e.g. a prior-data conflict on the growth) may
    "give up" one of them by inflating its noise scale instead of
    compromising; a median above 30 % of |H| signals that.
    """
    out = []
    for j, obs in enumerate(observations):
        name = f"sigma_{j}"
        if name in draws:
            med = float(np.median(draws[name]))
            if med > NOISE_WARNING:
                out.append(
                    f"{name} ({obs.source}): inferred noise is {100 * med:.0f} % of |H|; the model does not fit this "
                    f"measurement together with the others (check the setup, the band and the growth bound)"
                )
    return out


def to_jsonable(obj: Any) -> Any:
    """Convert numpy types, NaN and inf to plain JSON values (NaN/inf -> null)."""
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [to_jsonable(v) for v in obj.tolist()]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _f(obj)
    return obj


def write_summary(path, summary: Mapping[str, Any]) -> None:
    """Write summary.json atomically (strict JSON: no NaN)."""
    text = json.dumps(to_jsonable(summary), indent=2, allow_nan=False)
    atomic_write_text(path, text + "\n")


def natural_frequency_entry(configuration, measured_hz: float, predicted: np.ndarray, used: bool) -> dict:
    """One ``natural_frequencies`` entry of summary.json."""
    pred = np.asarray(predicted, dtype=float).ravel()
    q = quantiles(pred, "_hz")
    entry = {
        "clamping_length": configuration.clamping_length,
        "direction": configuration.direction,
        "tool": configuration.tool,
        "mode": 1,
        "measured_hz": _f(measured_hz),
        **q,
        "used_in_fit": bool(used),
        "nan_fraction": float(np.mean(~np.isfinite(pred))) if pred.size else 1.0,
    }
    if q["q50_hz"] is not None and entry["measured_hz"] is not None:
        entry["error_q50_percent"] = 100.0 * (q["q50_hz"] - entry["measured_hz"]) / entry["measured_hz"]
    else:
        entry["error_q50_percent"] = None
    return entry


def stiffness_entry(length: float, kx: np.ndarray, kt: np.ndarray, used: bool) -> dict:
    """One ``stiffness`` entry of summary.json."""
    return {"clamping_length": length, "k_xf": quantiles(kx), "k_thetaM": quantiles(kt), "used_in_fit": bool(used)}


def tau_dict(names: Sequence[str], tau: np.ndarray) -> dict:
    return {n: _f(t) for n, t in zip(names, np.asarray(tau, dtype=float))}
