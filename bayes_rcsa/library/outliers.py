"""Outlier check: does a combination's own data agree with the population fitted without it?

For setup ``s`` of holder type ``t`` the leave-one-out population predictive of
its likelihood surrogate ``m_s`` is, given the hyperparameters, normal:
``N(mu, V)``, ``V = C_s + diag(sigma_t^2) (+ Var(a_t + b_t x_s))``.  Two
statistics are computed per hyperparameter draw, both exactly distributed
under that normal:

* the *contact shift* ``t = e^T V^-1 r / sqrt(e^T V^-1 e)`` ~ N(0, 1), ``r =
  m_s - mu``, ``e`` = 1 on the log-stiffness coordinates (``k_*``) and 0
  elsewhere: the generalised-least-squares estimate of a common shift of all
  the contact's log stiffnesses, in units of its standard error.  This is the
  most powerful test against the alternative the check exists for: a badly
  clamped tool, whose contact is softer (or stiffer) than its type's by a
  similar factor in every stiffness (a hidden mass at the tip, fitted by the
  contact law, looks the same way).  Two-sided: ``p_t = 2 Phi(-|t|)``.
* the *omnibus* Mahalanobis distance ``D = r^T V^-1 r`` ~ chi2(d), for any
  other disagreement (growth, damping, one stiffness against the other).

Each is averaged over the hyperparameter posterior *without* ``s`` (the
leave-one-out predictive p-values ``p_shift``, ``p_omnibus``); the setup's
p-value is ``min(1, 2 min(p_shift, p_omnibus))`` (Bonferroni over the two).
The leave-one-out posterior: for small types (``n <= exact_max``) an exact
refit of the coupled library without ``s``, with the type's mean and slope
integrated out (the predictive given the spreads is normal, so ``a, b`` enter
through their conditional mean and covariance); for larger types truncated
importance sampling of the full posterior's draws of ``(a, b, sigma)``
(weights ``1 / p(m_s | hyper)``, Ionides 2008).  A setup is flagged when ``p
< alpha / n_setups`` (Bonferroni over the library: a clean library is flagged
anywhere with probability <= alpha).  The only combination of its type cannot
be checked against a population.

A third, independent component asks whether the combination's *own* hammer
tests are reproduced by the RCSA model at all (:func:`adequacy_rows`): the
residual correlation length ``tau_r`` of its stage-1 fit at the optimum (rule 1
of the discrepancy workflow's adequacy test, :mod:`bayes_rcsa.discrepancy.detect`;
``identify`` stores it in ``summary.json``), calibrated against white
measurement noise on the same lines by a sequential Monte Carlo p-value
(Besag & Clifford 1991), ``p_adequacy``.  A hidden effect the contact law
absorbs (a tip mass, a resonator) leaves a smooth residual over many lines that
the contact parameters cannot see.  The three p-values are combined by a
weighted Bonferroni rule (:func:`combine`): ``p = min_k p_k / w_k`` with
``w_adequacy = ADEQUACY_WEIGHT`` and the rest shared equally by the contact
statistics; ``p < alpha / n_setups`` keeps the family-wise false-flag rate of
a clean library at most ``alpha``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from .hierarchy import HyperFit, Stage2Settings, _factor, _forward, fit_hyper, predictive_of_setup

__all__ = ["loo_p_values", "refit_warnings", "REFIT_SETTINGS", "flag_outliers", "draw_statistics", "shift_direction", "combine", "adequacy_p_value",
           "adequacy_rows", "stage1_residual_correlation", "ALPHA", "EXACT_MAX", "ADEQUACY_WEIGHT"]

#: Family-wise false-flag rate of a clean library.
ALPHA = 0.05
#: Types with at most this many combinations are refitted without each setup (exact leave-one-out).
EXACT_MAX = 16
#: Share of ``alpha`` given to the model-adequacy component (weighted Bonferroni, docs/library.md "Outliers"):
#: its null tail is steep (a white-noise tau_r has sd ~0.15 line), so a small share moves its threshold by ~0.1
#: line, while the contact statistics keep 0.45 of alpha each instead of 1/3.
ADEQUACY_WEIGHT = 0.1
#: Sequential Monte Carlo p-value: stop after this many simulated exceedances (Besag & Clifford 1991).
ADEQUACY_EXCEEDANCES = 20
#: Most white-noise simulations of one adequacy p-value (its smallest value is 1 / (n + 1)).
ADEQUACY_MAX_SIMULATIONS = 200_000


def shift_direction(names) -> np.ndarray | None:
    """(d,) indicator of the log-stiffness coordinates (``k_*``), the direction of a softer or stiffer contact;
    None when no stiffness is pooled (then only the omnibus statistic is used)."""
    e = np.array([1.0 if n.startswith("k_") else 0.0 for n in names])
    return e if np.any(e) else None


def draw_statistics(res: np.ndarray, V: np.ndarray, e: np.ndarray | None) -> dict:
    """Both statistics and their tail probabilities per hyperparameter draw.

    Parameters
    ----------
    res : (H, d) residual of the setup's surrogate mean from the predictive mean (coordinate units)
    V : (H, d, d) predictive covariance
    e : (d,) shift direction or None

    Returns
    -------
    dict: ``D`` (H,) Mahalanobis distance, ``p_omnibus`` (H,) ``P(chi2_d > D)``, ``t`` (H,) standardised
    shift (None without ``e``), ``p_shift`` (H,) ``2 Phi(-|t|)`` (None without ``e``), ``ll`` (H,) log
    predictive density
    """
    L = np.linalg.cholesky(V)
    y = np.linalg.solve(L, res[..., None])[..., 0]  # L^-1 r
    f = None if e is None else np.linalg.solve(L, np.broadcast_to(e, res.shape)[..., None])[..., 0]  # L^-1 e
    return _from_whitened(y, f, 2.0 * np.sum(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1))


def _diagonal_spread_statistics(res: np.ndarray, C: np.ndarray, s2: np.ndarray, e: np.ndarray | None) -> dict:
    """:func:`draw_statistics` for ``V = C + diag(s2_h)`` (the importance-sampling check of a large type): the
    Cholesky factors element by element over the draws (:func:`.hierarchy._factor`), ~50x faster than
    batched LAPACK calls on thousands of 6x6 matrices.  res (H, d), C (d, d), s2 (H, d)."""
    L, logdet = _factor(C[:, :, None], s2)
    y = np.stack([v[:, 0] for v in _forward(L, res.T[:, :, None])], axis=1)
    f = None if e is None else np.stack([v[:, 0] for v in _forward(L, np.broadcast_to(e[:, None, None],
                                                                                          (len(e),) + res.shape[:1] + (1,)))], axis=1)
    return _from_whitened(y, f, logdet[:, 0])


def _from_whitened(y: np.ndarray, f: np.ndarray | None, logdet: np.ndarray) -> dict:
    """The statistics from the whitened residual ``y = L^-1 r`` (H, d), direction ``f = L^-1 e`` (H, d) or None
    and ``ln det V`` (H,)."""
    from scipy.stats import chi2, norm

    d = y.shape[1]
    D = np.sum(y * y, axis=1)
    out = {"D": D, "p_omnibus": chi2.sf(D, d), "t": None, "p_shift": None,
           "ll": -0.5 * (D + logdet + d * math.log(2 * math.pi))}
    if f is not None:
        t = np.sum(f * y, axis=1) / np.sqrt(np.sum(f * f, axis=1))
        out["t"], out["p_shift"] = t, 2.0 * norm.sf(np.abs(t))
    return out


def _combine(p_shift: float | None, p_omnibus: float) -> float:
    """Bonferroni over the two contact statistics (the ``p_value`` of :func:`loo_p_values`)."""
    return p_omnibus if p_shift is None else min(1.0, 2.0 * min(p_shift, p_omnibus))


def _weights(p: dict) -> dict:
    """Weighted-Bonferroni weights of the available components (summing to 1): the adequacy component
    ``ADEQUACY_WEIGHT`` (all of it when no contact statistic exists), the contact statistics share the rest."""
    contact = [k for k in ("p_shift", "p_omnibus") if p.get(k) is not None]
    if p.get("p_adequacy") is None:
        return {k: 1.0 / len(contact) for k in contact}
    if not contact:
        return {"p_adequacy": 1.0}
    return {"p_adequacy": ADEQUACY_WEIGHT, **{k: (1.0 - ADEQUACY_WEIGHT) / len(contact) for k in contact}}


def combine(p_shift: float | None, p_omnibus: float | None, p_adequacy: float | None = None) -> float | None:
    """The setup's p-value: weighted Bonferroni ``min(1, min_k p_k / w_k)`` over the available components.

    Without ``p_adequacy`` this is ``min(1, 2 min(p_shift, p_omnibus))`` (the contact check alone); with it the
    adequacy component has weight ``ADEQUACY_WEIGHT`` and the contact statistics share the rest.  Valid
    p-values in, a valid p-value out: ``P(combine < a) <= sum_k w_k a = a``.  None when nothing is available.
    """
    p = {"p_shift": p_shift, "p_omnibus": p_omnibus, "p_adequacy": p_adequacy}
    w = _weights(p)
    return min(1.0, min(p[k] / v for k, v in w.items())) if w else None


#: Stopping rule of the leave-one-out refits.  They start from the full library's draws, which differ from the
#: refit's posterior by one combination's weight, and feed a screening p-value (is the left-out combination
#: surprising?), not an interval: 20 autocorrelation times and R-hat < 1.05 (about 1 + 0.8 tau / N, see
#: :data:`~.hierarchy.RHAT_MAX`, i.e. what 20 tau gives a converged ensemble) with a bulk ESS of 300, capped at
#: 3000 steps.  Stage 2's own rule (50 tau, R-hat < 1.02) made the refits of a 12-combination library take 250 s
#: instead of 9 s with the same outlier flagged; the old 250-step refits had R-hat 1.15-1.2.
REFIT_SETTINGS = Stage2Settings(n_burn=100, ess_target=300, tau_factor=20.0, rhat_max=1.05, max_steps=3000)


def loo_p_values(fit: HyperFit, hyper, rng: np.random.Generator, exact_max: int = EXACT_MAX,
                 settings: Stage2Settings = REFIT_SETTINGS,
                 n_draws: int = 1000) -> list[dict]:
    """Leave-one-out predictive p-value of every setup of the library (types in the order of ``fit.groups``).

    Parameters
    ----------
    fit : HyperFit, the coupled stage-2 posterior (``Stage2Result.fit``)
    hyper : Hyperprior
    rng : numpy Generator
    exact_max : int, types of at most this many combinations are checked by exact refits
    settings : Stage2Settings of the refits (default :data:`REFIT_SETTINGS`, a screening rule looser than stage
        2's own; whether each refit met it is kept in its row, and :func:`refit_warnings` says which did not)
    n_draws : int, refit draws (evenly thinned) the p-values average over

    Returns
    -------
    list of dict: ``name``, ``p_value`` (the combined one; None for the only
    combination of its type), ``p_shift``, ``p_omnibus`` (the two
    leave-one-out p-values), ``shift_median`` (median standardised shift
    ``t``: negative = softer than the population), ``method`` (``"exact"``,
    ``"importance"`` or ``None``), ``distance_median`` (of ``D``); for an exact refit also ``refit_converged``
    (its rule met before ``settings.max_steps``), ``refit_steps`` and ``refit_rhat_max`` (None otherwise)
    """
    e = shift_direction(hyper.names)
    out = []
    for t, g in enumerate(fit.groups):
        n, d = g.m.shape
        flat = fit.types[g.holder_type].flat
        flat = flat[:: max(1, flat.shape[0] // 4000)]  # 4000 evenly thinned draws carry the importance weights
        for i, name in enumerate(g.names):
            if n < 2:
                out.append({"name": name, "p_value": None, "p_shift": None, "p_omnibus": None, "shift_median": None,
                            "method": None, "distance_median": None, **_NO_REFIT})
                continue
            refit = dict(_NO_REFIT)
            if n <= exact_max:
                groups = tuple(gg.without(i) if k == t else gg for k, gg in enumerate(fit.groups))
                sub = fit_hyper(groups, hyper, rng, settings, start_from=fit.theta, type_draws=False)
                theta = sub.theta[:: max(1, sub.theta.shape[0] // n_draws)]
                st = draw_statistics(*predictive_of_setup(theta, groups, hyper, t, g.m[i], g.C[i], float(g.x[i])), e)
                w = np.full(theta.shape[0], 1.0 / theta.shape[0])
                method = "exact"
                refit = {"refit_converged": bool(sub.quality.converged), "refit_steps": int(sub.quality.n_steps),
                         "refit_rhat_max": float(np.max(sub.quality.rhat))}
            else:
                a, b, s = flat[:, :d], flat[:, d:2 * d], flat[:, 2 * d:]
                st = _diagonal_spread_statistics(g.m[i][None, :] - a - b * float(g.x[i]), g.C[i], s * s, e)
                w = np.exp(-st["ll"] - np.max(-st["ll"]))
                w = np.minimum(w, np.mean(w) * math.sqrt(w.size))  # truncated importance sampling
                w = w / np.sum(w)
                method = "importance"
            p_omni = float(np.sum(w * st["p_omnibus"]))
            p_shift = None if e is None else float(np.sum(w * st["p_shift"]))
            out.append({"name": name, "p_value": _combine(p_shift, p_omni), "p_shift": p_shift, "p_omnibus": p_omni,
                        "shift_median": None if e is None else float(np.median(st["t"])), "method": method,
                        "distance_median": float(np.median(st["D"])), **refit})
    return out


_NO_REFIT = {"refit_converged": None, "refit_steps": None, "refit_rhat_max": None}


def refit_warnings(p_rows: list[dict]) -> list[str]:
    """One warning naming the setups whose leave-one-out refit stopped at its step cap unconverged.

    Their p-values come from a chain shorter than the screening rule (:data:`REFIT_SETTINGS`, or the settings
    given to :func:`loo_p_values`) asks for: usable to rank, but a flag (or its absence) near the threshold is
    less certain than the p-value says.
    """
    bad = [r for r in p_rows if r.get("refit_converged") is False]
    if not bad:
        return []
    worst = max(r["refit_rhat_max"] for r in bad)
    return [f"leave-one-out refits of {len(bad)} setup(s) ({', '.join(r['name'] for r in bad)}) stopped at their "
            f"step cap ({max(r['refit_steps'] for r in bad)} steps) unconverged (R-hat up to {worst:.3f}): their "
            "outlier p-values are approximate"]


def stage1_residual_correlation(summary_path) -> tuple[float, tuple[int, ...]] | str:
    """A stage-1 fit's residual correlation length at its optimum and its lines per measurement.

    Parameters
    ----------
    summary_path : path-like, ``identify``'s ``summary.json``

    Returns
    -------
    (tau_r lines, (n_lines per measurement,)), or a str saying why they are not available (no file, a
    summary without the likelihood's residual correlation, e.g. a population-predictive one).
    """
    path = Path(summary_path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return f"no readable stage-1 summary {path} ({exc.__class__.__name__})"
    lik = doc.get("likelihood") or {}
    tau = lik.get("residual_correlation_lines")
    lines = tuple(int(m.get("n_lines", 0)) for m in doc.get("measurements_used") or ())
    if tau is None or not lines or min(lines) < 2 or not math.isfinite(float(tau)):
        return f"{path}: no residual correlation length of the stage-1 optimum (likelihood.residual_correlation_lines)"
    if lik.get("n_lines") is not None and int(lik["n_lines"]) != sum(lines):
        return f"{path}: {sum(lines)} lines in measurements_used but {lik['n_lines']} in the likelihood"
    return float(tau), lines


def adequacy_p_value(tau: float, n_lines: Sequence[int], rng: np.random.Generator, n_max: int,
                     exceedances: int = ADEQUACY_EXCEEDANCES, batch: int = 50) -> float:
    """P-value of a residual correlation length ``tau`` under white measurement noise on the same lines.

    The null: the fit's normalised residuals are independent circular complex normal per line (the
    likelihood's own noise model).  ``tau`` is compared with
    :func:`bayes_rcsa.inference.likelihood.residual_correlation_length` of simulated white residuals with the
    same lines per measurement, sequentially (Besag & Clifford 1991): simulation stops at the ``exceedances``-th
    simulated value ``>= tau`` (after ``L`` simulations: ``p = exceedances / L``) or after ``n_max`` (``p = (g +
    1) / (n_max + 1)`` with ``g`` exceedances).  Both are exact p-values under the null for any stopping point,
    so an adequate fit gets ``P(p <= a) <= a``.  The fitted parameters remove a little smooth structure from the
    real residuals, which makes the test conservative, not liberal.  Cost: a clearly adequate fit stops after
    50-150 simulations; a clearly inadequate one runs all ``n_max`` (0.12 ms each on ~400 lines).

    Parameters
    ----------
    tau : float, lines (>= 1, as ``identify`` reports it)
    n_lines : (n_meas,) lines of each measurement (autocorrelation never crosses measurements)
    rng : numpy Generator
    n_max : int, most simulations (the smallest p is ``1 / (n_max + 1)``)
    exceedances : int
    batch : int, simulations of the first vectorised draw of white residuals (each later draw twice as many,
        at most 5,000: an adequate fit stops after the first)

    Returns
    -------
    float in (0, 1]
    """
    from ..inference.likelihood import residual_correlation_length

    edges = np.concatenate([[0], np.cumsum(n_lines)])
    slices = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
    n = int(edges[-1])
    seen = hits = 0
    while seen < n_max:
        m = min(batch, n_max - seen)
        z = rng.standard_normal((m, n)) + 1j * rng.standard_normal((m, n))
        # the statistic itself, not a re-implementation: one call per simulated residual vector (early stop)
        count = hits + np.cumsum([residual_correlation_length(v, slices) >= tau for v in z])
        if count[-1] >= exceedances:
            return exceedances / (seen + int(np.argmax(count >= exceedances)) + 1)
        hits, seen, batch = int(count[-1]), seen + m, min(2 * batch, 5000)
    return (hits + 1) / (n_max + 1)


def adequacy_n_max(n_setups: int, alpha: float = ALPHA) -> int:
    """Simulations per adequacy p-value: enough that its smallest value, ``1 / (n + 1)``, lies 8x below the
    component's share of the threshold, ``ADEQUACY_WEIGHT alpha / n_setups`` (at least 2,000, at most
    ``ADEQUACY_MAX_SIMULATIONS``)."""
    need = math.ceil(8 * max(1, n_setups) / (ADEQUACY_WEIGHT * alpha))
    return int(min(ADEQUACY_MAX_SIMULATIONS, max(2000, need)))


def adequacy_rows(summaries: dict, n_setups: int, rng: np.random.Generator, alpha: float = ALPHA,
                  n_max: int | None = None) -> tuple[dict, list[str]]:
    """The model-adequacy component of every setup whose stage-1 summary is known.

    Parameters
    ----------
    summaries : dict name -> path of the setup's stage-1 ``summary.json`` or None (no hammer tests known,
        e.g. synthetic stage-1 draws)
    n_setups : int, setups of the library (for the number of simulations)
    rng : numpy Generator
    alpha : float
    n_max : int or None (:func:`adequacy_n_max`)

    Returns
    -------
    rows : dict name -> ``p_adequacy`` (None when skipped), ``residual_correlation_lines``,
        ``adequacy_skipped`` (the reason, or None)
    warnings : list of str (the smallest reachable p-value cannot reach the threshold)
    """
    n_max = adequacy_n_max(n_setups, alpha) if n_max is None else int(n_max)
    warns = []
    known = any(v is not None for v in summaries.values())
    if known and ADEQUACY_WEIGHT * alpha / max(1, n_setups) <= 1.0 / (n_max + 1):
        warns.append(f"the model-adequacy component cannot flag a setup on its own in a library of {n_setups}: "
                     f"its smallest p-value 1/{n_max + 1} (simulations) is not below its share "
                     f"{ADEQUACY_WEIGHT:g} x {alpha:g} / {n_setups} of the threshold")
    out = {}
    for name, path in summaries.items():
        got = "no stage-1 summary (hammer tests) for this setup" if path is None else stage1_residual_correlation(path)
        if isinstance(got, str):
            out[name] = {"p_adequacy": None, "residual_correlation_lines": None, "adequacy_skipped": got}
            continue
        tau, lines = got
        out[name] = {"p_adequacy": adequacy_p_value(tau, lines, rng, n_max), "residual_correlation_lines": tau,
                     "adequacy_skipped": None}
    return out, warns


#: What each component says about a flagged setup.
_CONTACT = "its contact disagrees with its holder type's population"
_ADEQUACY = "its own hammer tests are not reproduced by the model: hidden effect or bad measurement"


def _reason(r: dict, threshold: float) -> str:
    """Why a flagged row is flagged: the components whose ``p_k / w_k`` lies below the threshold."""
    w = _weights(r)
    below = {k for k, v in w.items() if r[k] / v < threshold}
    parts = []
    if below & {"p_shift", "p_omnibus"}:
        what = ""
        if r.get("shift_median") is not None and r.get("p_shift") is not None and r["p_shift"] <= r["p_omnibus"]:
            what = f", its contact looks {'softer' if r['shift_median'] < 0 else 'stiffer'} than its type's"
        c = min(r[k] / w[k] for k in below & {"p_shift", "p_omnibus"})
        parts.append(f"{_CONTACT} (leave-one-out p = {c:.2g}{what}); check the clamping (a badly clamped tool is "
                     "the usual cause)")
    if "p_adequacy" in below:
        from ..discrepancy.detect import adequacy

        tau = r["residual_correlation_lines"]
        # the discrepancy workflow's verdict on the same statistic (its rule 1: tau_r > TAU_MAX) names the misfit
        rule = adequacy(tau, (), ())[1] or [f"stage-1 residuals correlated over {tau:.1f} lines"]
        parts.append(f"{_ADEQUACY} ({rule[0]}; white noise gives ~1 line; p_adequacy = {r['p_adequacy']:.2g})")
    return "; and ".join(parts)


def flag_outliers(p_rows: list[dict], n_setups: int, alpha: float = ALPHA,
                  adequacy: dict | None = None) -> tuple[list[dict], list[str]]:
    """Flag setups whose combined p-value lies below ``alpha / n_setups``.

    Parameters
    ----------
    p_rows : list of dict from :func:`loo_p_values`
    n_setups : int
    alpha : float, family-wise false-flag rate of a clean library
    adequacy : dict name -> row of :func:`adequacy_rows`, or None (the contact statistics alone)

    Returns
    -------
    rows : list of dict, each ``p_rows`` row with ``p_contact`` (the contact statistics' combined p),
        ``p_adequacy``, ``residual_correlation_lines``, ``adequacy_skipped``, ``p_value`` (all components,
        :func:`combine`), ``threshold``, ``outlier`` and ``outlier_reason``
    warnings : list of str
    """
    threshold = alpha / max(1, n_setups)
    warns = []
    rows = []
    for r in p_rows:
        a = (adequacy or {}).get(r["name"], {"p_adequacy": None, "residual_correlation_lines": None,
                                              "adequacy_skipped": "not checked (no stage-1 summaries "
                                                                    "given, e.g. synthetic stage-1 draws)"})
        row = {**r, **a, "p_contact": r["p_value"], "threshold": threshold}
        p = combine(r.get("p_shift"), r.get("p_omnibus"), a.get("p_adequacy"))
        flagged = p is not None and p < threshold
        row.update({"p_value": p, "outlier": bool(flagged), "outlier_reason": _reason(row, threshold) if flagged
                    else None})
        rows.append(row)
        if flagged:
            warns.append(f"setup {r['name']}: outlier (p = {p:.2g} < {threshold:.2g}) -- {row['outlier_reason']}")
        if r["p_value"] is None:
            warns.append(f"setup {r['name']}: the only combination of its holder type; its contact cannot be checked "
                         "against a population")
    return rows, warns
