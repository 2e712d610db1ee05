"""What the data determine: contraction, verdicts, ridges, Fisher information, transfer errors.

Contraction and verdicts
------------------------
For every sampled parameter the *contraction* is ``1 - Var_post / Var_prior``
in the sampling coordinate of its prior (``log10 k`` for a log-uniform
stiffness, ``g`` itself for a growth factor; see
:mod:`bayes_rcsa.params.priors`): 0 means the data taught nothing, 1 that
they pinned the parameter down completely.  The verdict is

``not identified``
    contraction < :data:`NOT_IDENTIFIED_BELOW` (0.5): the posterior
    standard deviation is still above 70 % of the prior's;
``weakly identified``
    contraction < :data:`IDENTIFIED_FROM` (0.99, i.e. the posterior standard
    deviation above 10 % of the prior's), *or* the posterior is held by a
    finite prior bound: its 95 % quantile lies in the top 5 % of the prior
    mass (or its 5 % quantile in the bottom 5 %).  The second rule catches
    the one-sided case that contraction alone misses: a stiffness the data
    only bound from below is "contracted" to the part of a wide log-uniform
    prior above that bound, and the prior's upper limit, not the data, ends
    the posterior;
``identified``
    everything else.

Ridges
------
The posterior covariance of the contact parameters in log space
(``log10 k``, ``log10 c`` and ``log10 (1 + g)``, the last being the log of
the stiffness ratio ``k(l_b) / k(l_a)``) is eigen-decomposed.  The direction
of smallest variance is the *stiff* combination (best determined), that of
largest variance the *sloppy* one; each is named as a product of powers,
e.g. ``k_thetaM^1 k_xf^-0.3``.

Fisher information
------------------
At the maximum a posteriori point, for the complex Gaussian likelihood of
:mod:`bayes_rcsa.inference.likelihood` with tempering ``beta``::

    F = 2 beta Re(J^H diag(w_n / sigma_j(n)^2) J),     J = dH / dz

in the same log-space coordinates ``z``; ``J`` comes from central finite
differences of the vectorised forward model (one batched call).  The noise
scales are held at their MAP values (for this likelihood their Fisher block
is orthogonal to the contact parameters).  The condition number
``max eig / min eig`` measures how elongated the data's constraint is.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ..errors import SetupError

__all__ = [
    "IDENTIFIED_FROM",
    "NOT_IDENTIFIED_BELOW",
    "BOUND_TAIL",
    "VERDICT_RULE",
    "prior_moments",
    "prior_cdf",
    "contraction",
    "verdict",
    "parameter_identifiability",
    "log_space",
    "ridge_analysis",
    "fisher_information",
    "transfer_errors",
    "length_key",
]

IDENTIFIED_FROM = 0.99
NOT_IDENTIFIED_BELOW = 0.5
BOUND_TAIL = 0.05
VERDICT_RULE = (
    f"contraction = 1 - Var_post/Var_prior in the sampling coordinate; 'not identified' if contraction < "
    f"{NOT_IDENTIFIED_BELOW}; 'weakly identified' if contraction < {IDENTIFIED_FROM} or the posterior 95 % (5 %) "
    f"quantile lies in the top (bottom) {100 * BOUND_TAIL:g} % of the prior mass next to a finite prior bound; "
    f"'identified' otherwise"
)
_FD_STEP = 1e-4  # decades: central differences of an analytic model; round-off ~1e-12 relative


# -- priors ------------------------------------------------------------------


def _truncnorm(mu: float, sigma: float, lo: float, hi: float):
    from scipy.stats import truncnorm

    return truncnorm((lo - mu) / sigma, (hi - mu) / sigma, loc=mu, scale=sigma)


def prior_moments(prior, rng: np.random.Generator | None = None, n_mc: int = 200_000) -> tuple[float, float]:
    """Mean and variance of a prior's sampling coordinate.

    Exact for the uniform, log-uniform, (truncated) normal and (truncated)
    log-normal priors of :mod:`bayes_rcsa.params.priors`; other priors
    are estimated from ``n_mc`` draws, which needs ``rng``.
    """
    from ..params.priors import LogNormal, LogUniform, Normal, Uniform

    if isinstance(prior, (Uniform, LogUniform)):
        lo, hi = prior.bounds
        return 0.5 * (lo + hi), (hi - lo) ** 2 / 12.0
    if isinstance(prior, (Normal, LogNormal)):
        mu = prior.mu if isinstance(prior, Normal) else math.log(prior.median)
        lo, hi = prior.bounds
        d = _truncnorm(mu, prior.sigma, lo, hi)
        return float(d.mean()), float(d.var())
    if rng is None:
        raise SetupError(f"prior {type(prior).__name__}: its variance needs Monte Carlo draws; pass an rng")
    u = prior.sample(rng, n_mc)
    return float(np.mean(u)), float(np.var(u))


def prior_cdf(prior, u) -> np.ndarray:
    """Prior cumulative distribution of the sampling coordinate ``u`` (``NaN`` if unknown)."""
    from ..params.priors import LogNormal, LogUniform, Normal, Uniform

    u = np.asarray(u, dtype=float)
    if isinstance(prior, (Uniform, LogUniform)):
        lo, hi = prior.bounds
        return np.clip((u - lo) / (hi - lo), 0.0, 1.0)
    if isinstance(prior, (Normal, LogNormal)):
        mu = prior.mu if isinstance(prior, Normal) else math.log(prior.median)
        lo, hi = prior.bounds
        return _truncnorm(mu, prior.sigma, lo, hi).cdf(u)
    return np.full(u.shape, np.nan)


def contraction(samples, prior, rng: np.random.Generator | None = None) -> float:
    """``1 - Var_post / Var_prior`` of one sampling coordinate (samples (n,))."""
    x = np.asarray(samples, dtype=float).ravel()
    _, var_prior = prior_moments(prior, rng)
    return float(1.0 - np.var(x, ddof=1) / var_prior) if x.size > 1 else float("nan")


def verdict(c: float, bound: str | None) -> str:
    """Verdict from a contraction and the bound (``"lower"``/``"upper"``/``None``) holding the posterior."""
    if not np.isfinite(c) or c < NOT_IDENTIFIED_BELOW:
        return "not identified"
    if bound is not None or c < IDENTIFIED_FROM:
        return "weakly identified"
    return "identified"


def _bound(samples: np.ndarray, prior) -> str | None:
    lo, hi = prior.bounds
    q05, q95 = np.quantile(samples, [0.05, 0.95])
    u05, u95 = prior_cdf(prior, [q05, q95])
    if np.isfinite(hi) and u95 >= 1.0 - BOUND_TAIL and not (np.isfinite(lo) and u05 <= BOUND_TAIL):
        return "upper"
    if np.isfinite(lo) and u05 <= BOUND_TAIL and not (np.isfinite(hi) and u95 >= 1.0 - BOUND_TAIL):
        return "lower"
    if np.isfinite(lo) and np.isfinite(hi) and u05 <= BOUND_TAIL and u95 >= 1.0 - BOUND_TAIL:
        return "both"
    return None


def parameter_identifiability(theta: np.ndarray, priors, rng: np.random.Generator | None = None) -> dict:
    """Contraction and verdict of every sampled parameter.

    Parameters
    ----------
    theta : (n, ndim) posterior draws in sampling coordinates
    priors : PriorSet

    Returns
    -------
    dict of name to dict with ``contraction``, ``verdict``, ``bound``
    (``None``, ``"lower"``, ``"upper"`` or ``"both"``: the finite prior
    bound(s) the posterior reaches), ``prior_sd``, ``posterior_sd`` (sampling
    coordinate) and the posterior ``q05``/``q50``/``q95`` in physical units.
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    out = {}
    for j, name in enumerate(priors.names):
        p = priors[name]
        x = theta[:, j]
        _, var_prior = prior_moments(p, rng)
        c = contraction(x, p, rng)
        b = _bound(x, p)
        q = np.quantile(np.asarray(p.to_physical(x), dtype=float), [0.05, 0.5, 0.95])
        out[name] = {
            "contraction": c,
            "verdict": verdict(c, b),
            "bound": b,
            "prior_sd": math.sqrt(var_prior),
            "posterior_sd": float(np.std(x, ddof=1)) if x.size > 1 else float("nan"),
            "q05": float(q[0]),
            "q50": float(q[1]),
            "q95": float(q[2]),
            "prior": p.describe(),
        }
    return out


# -- log space, ridges ---------------------------------------------------------


def log_space(values: Mapping[str, np.ndarray], names: Sequence[str]) -> tuple[np.ndarray, list[str]]:
    """Contact parameters in log space.

    Parameters
    ----------
    values : {name: (n,)} physical values
    names : contact parameter names (``k_*``, ``c_*``, ``g_*``)

    Returns
    -------
    z : (n, len(names))
        ``log10 k``, ``log10 c``, ``log10(1 + g)``.
    labels : list of str
    """
    cols, labels = [], []
    for n in names:
        v = np.asarray(values[n], dtype=float)
        if n.startswith("g_"):
            cols.append(np.log10(1.0 + v))
            labels.append(f"log10(1+{n})")
        else:
            if np.any(v <= 0):
                raise SetupError(f"{n}: non-positive values have no logarithm")
            cols.append(np.log10(v))
            labels.append(f"log10 {n}")
    return np.column_stack(cols), labels


def _from_log(name: str, z):
    return 10.0 ** np.asarray(z, dtype=float) - (1.0 if name.startswith("g_") else 0.0)


def combination_name(vector: np.ndarray, names: Sequence[str], tol: float = 1e-3) -> str:
    """Name a log-space direction as a product of powers, largest power 1."""
    v = np.asarray(vector, dtype=float)
    j = int(np.argmax(np.abs(v)))
    v = v / v[j]
    order = np.argsort(-np.abs(v))
    parts = []
    for i in order:
        if abs(v[i]) < tol:
            continue
        base = f"(1+{names[i]})" if names[i].startswith("g_") else names[i]
        parts.append(f"{base}^{v[i]:.2g}")
    return " * ".join(parts)


def ridge_analysis(z: np.ndarray, names: Sequence[str]) -> dict:
    """Correlations and eigen-structure of posterior draws in log space.

    Parameters
    ----------
    z : (n, p) log-space draws (:func:`log_space`)
    names : p parameter names

    Returns
    -------
    dict with ``names``, ``correlation`` (p, p), ``covariance`` (p, p),
    ``eigenvalues`` (ascending, decades^2), ``sd`` (their square roots),
    ``eigenvectors`` (columns, same order), ``stiff`` and ``sloppy``
    (``{"combination", "sd", "vector"}``).
    """
    z = np.atleast_2d(np.asarray(z, dtype=float))
    cov = np.atleast_2d(np.cov(z, rowvar=False))
    sd = np.sqrt(np.diag(cov))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov / np.outer(sd, sd)
    lam, vec = np.linalg.eigh(cov)
    lam = np.clip(lam, 0.0, None)  # eigh of a PSD matrix: round-off below zero only

    def entry(k):
        return {"combination": combination_name(vec[:, k], names), "sd": float(math.sqrt(lam[k])),
                "vector": vec[:, k].tolist()}

    return {
        "names": list(names),
        "correlation": corr.tolist(),
        "covariance": cov.tolist(),
        "eigenvalues": lam.tolist(),
        "sd": np.sqrt(lam).tolist(),
        "eigenvectors": vec.tolist(),
        "stiff": entry(0),
        "sloppy": entry(lam.size - 1),
    }


# -- Fisher information ---------------------------------------------------------


def fisher_information(likelihood, theta_map: np.ndarray, names: Sequence[str], tempering: float = 1.0,
                       step: float = _FD_STEP) -> dict:
    """Fisher information of the contact parameters in log space at ``theta_map``.

    Parameters
    ----------
    likelihood : FRFLikelihood
        Untempered likelihood of the fit (forward model, weights, parameter model).
    theta_map : (ndim,) sampling coordinates of the MAP point
    names : contact parameters to differentiate (sampled ones)
    tempering : float
        beta of the fit.
    step : float
        Central-difference step in log10 units.

    Returns
    -------
    dict with ``names``, ``matrix`` (p, p), ``eigenvalues`` (ascending),
    ``eigenvectors`` (columns), ``condition_number`` (``inf`` if singular),
    ``stiff``/``sloppy`` combinations as in :func:`ridge_analysis`.
    """
    pm = likelihood.parameters
    priors = pm.priors
    theta_map = np.asarray(theta_map, dtype=float)
    values = pm.values(theta_map[None, :])
    z0, _ = log_space(values, names)
    z0 = z0[0]
    p = len(names)
    pts = np.repeat(theta_map[None, :], 2 * p, axis=0)
    for i, n in enumerate(names):
        j = pm.names.index(n)
        prior = priors[n]
        for s, sign in enumerate((1.0, -1.0)):
            with np.errstate(invalid="ignore", divide="ignore"):
                pts[2 * i + s, j] = float(prior.to_sampling(_from_log(n, z0[i] + sign * step)))
    h = likelihood.model_frf(pts)
    jac = (h[0::2] - h[1::2]).T / (2 * step)  # (n_lines, p)
    s2 = pm.noise(values)[0] ** 2
    wl = likelihood.weight / s2[likelihood.stack.index]
    fim = 2.0 * tempering * np.real(jac.conj().T @ (wl[:, None] * jac))
    fim = 0.5 * (fim + fim.T)
    lam, vec = np.linalg.eigh(fim)
    cond = float(lam[-1] / lam[0]) if lam[0] > 0 else float("inf")

    def entry(k):
        return {"combination": combination_name(vec[:, k], names),
                "sd": float(1.0 / math.sqrt(lam[k])) if lam[k] > 0 else float("inf"), "vector": vec[:, k].tolist()}

    return {
        "names": list(names),
        "matrix": fim.tolist(),
        "eigenvalues": lam.tolist(),
        "eigenvectors": vec.tolist(),
        "condition_number": cond,
        "stiff": entry(lam.size - 1),
        "sloppy": entry(0),
    }


# -- transfer errors --------------------------------------------------------------


def length_key(length: float) -> str:
    """JSON key of a clamping length (m), e.g. ``"0.025"``."""
    return f"{float(length):.6g}"


def transfer_errors(entries: Sequence[Mapping]) -> dict:
    """Errors of predicted natural frequencies against measurements.

    Parameters
    ----------
    entries : sequence of dict
        ``natural_frequencies`` entries of an identification summary
        (``clamping_length``, ``direction``, ``measured_hz``, ``q05_hz``,
        ``q50_hz``, ``q95_hz``, ``used_in_fit``).

    Returns
    -------
    dict with
    ``rows``: one dict per entry with the signed errors of the q05, q50 and
    q95 predictions in % of the measurement and ``measured_in_90``;
    ``transfer_error_pct``: ``{length: mean over directions of |error of the
    median| (%)}`` for the lengths *not* used in the fit;
    ``fit_error_pct``: the same for the fitted lengths.
    """
    rows = []
    for e in entries:
        m = e.get("measured_hz")
        row = {k: e.get(k) for k in ("clamping_length", "direction", "tool", "measured_hz", "q05_hz", "q50_hz", "q95_hz")}
        row["used_in_fit"] = bool(e.get("used_in_fit"))
        for q in ("q05", "q50", "q95"):
            v = e.get(f"{q}_hz")
            row[f"error_{q}_pct"] = None if v is None or m is None else 100.0 * (v - m) / m
        row["measured_in_90"] = None if m is None or e.get("q05_hz") is None else bool(e["q05_hz"] <= m <= e["q95_hz"])
        rows.append(row)

    def mean_abs(used: bool) -> dict:
        groups: dict[str, list[float]] = {}
        for r in rows:
            if r["used_in_fit"] == used and r["error_q50_pct"] is not None:
                groups.setdefault(length_key(r["clamping_length"]), []).append(abs(r["error_q50_pct"]))
        return {k: float(np.mean(v)) for k, v in sorted(groups.items(), key=lambda kv: float(kv[0]))}

    return {"rows": rows, "transfer_error_pct": mean_abs(False), "fit_error_pct": mean_abs(True)}
