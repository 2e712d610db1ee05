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
from ..io.jsonable import to_jsonable

__all__ = [
    "parameter_summary",
    "quantiles",
    "growth_bound_warnings",
    "prior_bound_warnings",
    "noise_scale_warnings",
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


def noise_scale_warnings(draws: Mapping[str, np.ndarray], observations, causes: Mapping[int, str] | None = None) -> list[str]:
    """Warn when a measurement's inferred relative noise is so large that the model does not fit it.

    With one noise scale per measurement, a model that cannot fit all
    measurements at once (e.g. a prior-data conflict on the growth) may
    "give up" one of them by inflating its noise scale instead of
    compromising; a median above 30 % of |H| signals that.  ``causes``
    maps a measurement index to a likely cause found by comparing the
    measurement with the model (units, sign convention; see
    :func:`bayes_rcsa.io.checks.likely_cause`), which is then named.
    """
    out = []
    causes = causes or {}
    for j, obs in enumerate(observations):
        name = f"sigma_{j}"
        if name in draws:
            med = float(np.median(draws[name]))
            if med > NOISE_WARNING:
                cause = causes.get(j)
                why = (f"likely cause: {cause}" if cause else
                       "the model does not fit this measurement together with the others (check the setup, the band "
                       "and the growth bound)")
                out.append(f"{name} ({obs.source}): inferred noise is {100 * med:.0f} % of |H|; {why}")
    return out


# Share of draws within BOUND_WINDOW of a finite prior bound (in the sampling coordinate, as a fraction of the
# prior's range) above which a posterior is said to pile up against the bound.  A flat posterior keeps 1 % there;
# one that merely leans towards the bound keeps a few per cent; one pressed against it by the data most of its mass.
BOUND_WINDOW = 0.01
BOUND_FRACTION = 0.10


def prior_bound_warnings(theta: np.ndarray, parameters, skip: Sequence[str] = ()) -> list[str]:
    """Warn for every sampled parameter whose posterior piles up against a finite prior bound.

    Rule: more than :data:`BOUND_FRACTION` (10 %) of the draws lie within
    :data:`BOUND_WINDOW` (1 %) of the prior's range (sampling coordinate,
    e.g. log10 k; the optimiser's range for unbounded priors) from a finite
    bound.  The result is then set by the prior, not the data: widen the
    prior, or check the data and the model (a non-reciprocal spindle file,
    for instance, sends k_thetaM to a bound).

    Parameters
    ----------
    theta : (n, ndim) sampling coordinates of the draws
    parameters : ParameterModel
    skip : names already warned about (e.g. growth factors by :func:`growth_bound_warnings`)
    """
    theta = np.atleast_2d(theta)
    out = []
    for j, name in enumerate(parameters.names):
        if name in skip:
            continue
        prior = parameters.priors[name]
        lo, hi = prior.bounds
        o_lo, o_hi = prior.optimisation_bounds()
        width = o_hi - o_lo
        if not (np.isfinite(width) and width > 0):
            continue
        u = theta[:, j]
        for side, bound, near in (("lower", lo, u < lo + BOUND_WINDOW * width), ("upper", hi, u > hi - BOUND_WINDOW * width)):
            if not np.isfinite(bound):
                continue
            frac = float(np.mean(near))
            if frac > BOUND_FRACTION:
                value = float(prior.to_physical(bound))
                unit = parameters.unit(name)
                out.append(
                    f"{name}: {100 * frac:.0f} % of the posterior lies within 1 % of the prior range from its {side} bound "
                    f"{value:.4g}{'' if unit == '1' else ' ' + unit} (warning above {100 * BOUND_FRACTION:.0f} %): the "
                    f"bound, not the data, limits it; widen the prior or check the data (e.g. a non-reciprocal spindle "
                    f"file, the units of the measurement)"
                )
    return out


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
