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
    everything else, unless the parameter is pinned only together with its
    partner stiffness (``k_xf`` with ``k_thetaM`` and vice versa): if its
    marginal posterior width is at least :data:`COMBINATION_RATIO` times its
    width at a fixed value of the partner, the verdict is ``identified only
    in combination with k_thetaM`` (resp. ``k_xf``).

Marginal and conditional widths
-------------------------------
For a pair of parameters with posterior covariance ``S`` (sampling
coordinates, i.e. ``log10 k`` for log-scale priors) the marginal standard
deviation of ``a`` is ``sqrt(S_aa)`` and its conditional standard deviation
at fixed ``b`` is ``sqrt(S_aa - S_ab^2 / S_bb)``; their ratio is
``1 / sqrt(1 - rho^2)`` with ``rho`` the posterior correlation.  A ratio near
1 means the data fix ``a`` on its own; a ratio of 5 (``|rho| = 0.98``) means
the posterior is a ridge: what the data fix is a combination of ``a`` and
``b`` (the *stiff* direction), while ``a`` and ``b`` separately slide along
the *sloppy* direction.  A single clamping length typically gives such a
ridge between ``k_xf`` and ``k_thetaM`` (one natural frequency per
direction, two stiffnesses); two lengths with the growth law separate them.
The ratio is invariant to the scale of each coordinate, so it is the same
in ``log10`` or ``ln`` coordinates.

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
    "COMBINATION_RATIO",
    "PARTNERS",
    "BOUND_TAIL",
    "VERDICT_RULE",
    "prior_moments",
    "prior_cdf",
    "contraction",
    "verdict",
    "conditional_width",
    "combination_statement",
    "fmt_contraction",
    "parameter_identifiability",
    "stiffness_ridge",
    "log_space",
    "ridge_analysis",
    "fisher_information",
    "transfer_errors",
    "length_key",
]

IDENTIFIED_FROM = 0.99
NOT_IDENTIFIED_BELOW = 0.5
BOUND_TAIL = 0.05
#: Marginal / conditional posterior width from which a parameter counts as fixed only together with its partner.
#: 3 means the partner explains 8/9 of its posterior variance (|rho| >= 0.943).  Single-length fits on the
#: synthetic bench give 3.5-6 (|rho| 0.96-0.99), two-length fits with the growth law 1.0-1.5.
COMBINATION_RATIO = 3.0
#: The partner of each stiffness in the ridge check: one natural frequency per direction pins a combination of both.
PARTNERS = {"k_xf": "k_thetaM", "k_thetaM": "k_xf"}
VERDICT_RULE = (
    f"contraction = (Var_prior - Var_post)/Var_prior in the sampling coordinate (shown as a percentage, or as prior width / "
    f"posterior width when above 99.9 %); 'not identified' if contraction < {100 * NOT_IDENTIFIED_BELOW:g} %; "
    f"'weakly identified' if contraction < {100 * IDENTIFIED_FROM:g} % or the posterior 95 % (5 %) "
    f"quantile lies in the top (bottom) {100 * BOUND_TAIL:g} % of the prior mass next to a finite prior bound; "
    f"'identified only in combination with <partner>' if otherwise identified but its marginal posterior width is "
    f">= {COMBINATION_RATIO:g} x its width at a fixed value of the partner stiffness; 'identified' otherwise"
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


def verdict(c: float, bound: str | None, width_ratio: float | None = None, partner: str | None = None) -> str:
    """Verdict of one parameter.

    Parameters
    ----------
    c : float
        Contraction.
    bound : {"lower", "upper", "both"} or None
        The finite prior bound holding the posterior.
    width_ratio : float, optional
        Marginal / conditional posterior width given ``partner``
        (:func:`conditional_width`).
    partner : str, optional
        Name of the partner parameter.
    """
    if not np.isfinite(c) or c < NOT_IDENTIFIED_BELOW:
        return "not identified"
    if bound is not None or c < IDENTIFIED_FROM:
        return "weakly identified"
    if partner is not None and width_ratio is not None and width_ratio >= COMBINATION_RATIO:
        return f"identified only in combination with {partner}"
    return "identified"


def conditional_width(a, b) -> dict:
    """Marginal and conditional posterior width of ``a`` given ``b``.

    Parameters
    ----------
    a, b : (n,) posterior draws of two coordinates (e.g. ``log10 k_xf`` and ``log10 k_thetaM``)

    Returns
    -------
    dict with ``correlation``, ``marginal_sd``, ``conditional_sd``
    (``sqrt(Var a - Cov(a, b)^2 / Var b)``, same unit as ``a``) and
    ``width_ratio`` (``marginal_sd / conditional_sd = 1 / sqrt(1 - rho^2)``;
    ``inf`` for a perfect ridge).
    """
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    cov = np.cov(a, b)
    sa, sb = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
    rho = float(cov[0, 1] / (sa * sb)) if sa > 0 and sb > 0 else 0.0
    rho = max(-1.0, min(1.0, rho))  # round-off of a perfect ridge only
    one_minus = 1.0 - rho * rho
    return {"correlation": rho, "marginal_sd": sa, "conditional_sd": sa * math.sqrt(one_minus),
            "width_ratio": 1.0 / math.sqrt(one_minus) if one_minus > 0 else float("inf")}


def fmt_contraction(c) -> str:
    """A contraction for text: ``78.6 %`` or, above 99.9 %, ``prior width / posterior width = 3200``.

    Parameters
    ----------
    c : float
        ``1 - Var_post / Var_prior``; its width ratio is ``1 / sqrt(1 - c)``.
    """
    if c is None or not np.isfinite(c):
        return "—"
    if c < 0.999:
        return f"{100.0 * c:.1f} %"
    if c >= 1.0:
        return "prior width / posterior width = inf"
    from ..units import num

    # two significant digits, written out (5100, not 5.1e3: no exponent in human text)
    return f"prior width / posterior width = {num(float(f'{1.0 / math.sqrt(1.0 - c):.2g}'))}"


def combination_statement(name: str, ident: Mapping, unit: str = "", ridge: Mapping | None = None) -> str:
    """Plain-language sentence for a parameter identified only in combination with its partner.

    Parameters
    ----------
    name : str
    ident : mapping
        Its entry of :func:`parameter_identifiability` (``verdict``,
        ``partner``, ``width_ratio``, ``correlation``, ``q05``, ``q95``).
    unit : str
        Physical unit of ``q05``/``q95``.
    ridge : mapping, optional
        :func:`stiffness_ridge` of the pair: names the combination the data fix.
    """
    from ..units import sci_parts
    from ..vocabulary import parameter_name
    from .report import fmt

    _, lo, hi = sci_parts(None, ident["q05"], ident["q95"], 3)
    me, partner = parameter_name(name), parameter_name(ident["partner"])
    text = (f"The {me} is identified only in combination with the {partner}: its 90 % posterior range "
            f"{lo}–{hi}{' ' + unit if unit else ''} is {fmt(ident['width_ratio'], 2)} "
            f"times wider than its range at a fixed {partner} (posterior correlation "
            f"{ident['correlation']:+.2f})")
    if ridge is not None:
        return text + f"; what the data fix is {ridge['stiff']['combination']} (±{ridge['stiff']['sd_pct']:.2g} %, 1 sd)."
    return text + f"; the data fix a combination of the {me} and the {partner}, not each alone."


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
    coordinate), ``prior_to_posterior_width`` (``prior_sd / posterior_sd``),
    the posterior ``q05``/``q50``/``q95`` in physical units and, for the
    stiffnesses of :data:`PARTNERS` when both are sampled, ``partner``,
    ``correlation``, ``conditional_sd`` and ``width_ratio`` (marginal /
    conditional width given the partner, :func:`conditional_width`).
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    names = list(priors.names)
    out = {}
    for j, name in enumerate(names):
        p = priors[name]
        x = theta[:, j]
        _, var_prior = prior_moments(p, rng)
        c = contraction(x, p, rng)
        b = _bound(x, p)
        q = np.quantile(np.asarray(p.to_physical(x), dtype=float), [0.05, 0.5, 0.95])
        partner = PARTNERS.get(name) if PARTNERS.get(name) in names else None
        cond = conditional_width(x, theta[:, names.index(partner)]) if partner is not None and x.size > 2 else None
        post_sd = float(np.std(x, ddof=1)) if x.size > 1 else float("nan")
        out[name] = {
            "contraction": c,
            "verdict": verdict(c, b, cond["width_ratio"] if cond else None, partner),
            "bound": b,
            "prior_sd": math.sqrt(var_prior),
            "posterior_sd": post_sd,
            "prior_to_posterior_width": math.sqrt(var_prior) / post_sd if post_sd > 0 else float("inf"),
            "partner": partner,
            "correlation": cond["correlation"] if cond else None,
            "conditional_sd": cond["conditional_sd"] if cond else None,
            "width_ratio": cond["width_ratio"] if cond else None,
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


def _pct(decades: float) -> float:
    """A log10 standard deviation as a relative change in per cent (``10^sd - 1``)."""
    return 100.0 * (10.0 ** decades - 1.0)


def stiffness_ridge(log_kx, log_kt, names: Sequence[str] = ("k_xf", "k_thetaM")) -> dict:
    """What the data fix about two stiffnesses, in physical terms.

    Parameters
    ----------
    log_kx, log_kt : (n,) posterior draws of ``log10 k_xf`` (N/m) and ``log10 k_thetaM`` (N m/rad)
    names : the two parameter names

    Returns
    -------
    dict with
    ``correlation``;
    ``stiff`` and ``sloppy``: the best and least determined products of
    powers of the two (largest power 1), from the eigenvectors of their
    correlation matrix (scale-free: the standardised log coordinates), with
    ``sd_pct``, one posterior standard deviation of that product as a
    relative change (%);
    ``marginal_pct``: ``{name: posterior sd (%)}``;
    ``conditional_pct``: ``{name: posterior sd at a fixed partner (%)}``;
    ``tradeoff_pct``: the change of the second stiffness (%) that goes,
    along the posterior's regression line, with a one-sd increase of the
    first;
    ``statement``: one sentence.
    """
    z = np.column_stack([np.asarray(log_kx, dtype=float).ravel(), np.asarray(log_kt, dtype=float).ravel()])
    cov = np.cov(z, rowvar=False)
    sd = np.sqrt(np.diag(cov))
    rho = float(cov[0, 1] / (sd[0] * sd[1])) if sd[0] > 0 and sd[1] > 0 else 0.0
    rho = max(-1.0, min(1.0, rho))  # round-off of a perfect ridge only
    cond = sd * math.sqrt(1.0 - rho * rho)
    # In the standardised coordinates u_i = log k_i / sd_i the covariance is [[1, rho], [rho, 1]], with
    # eigenvectors (1, 1) (variance 1 + rho) and (1, -1) (variance 1 - rho); in raw log10 coordinates
    # the eigenvectors would only say which stiffness has the larger spread.
    dirs = [(np.array([1.0, 1.0]), 1.0 + rho), (np.array([1.0, -1.0]), 1.0 - rho)]
    dirs.sort(key=lambda d: d[1])

    def entry(u, var):
        v = u / sd if np.all(sd > 0) else u  # back to log10 coordinates: a product of powers
        w = v / np.max(np.abs(v))  # largest power 1
        # sd of w . log k, in decades: w = v / max|v| and v . log k has standardised variance `var`
        dec = math.sqrt(max(var, 0.0)) / float(np.max(np.abs(v)))
        return {"combination": combination_name(w, names), "sd_decades": dec, "sd_pct": _pct(dec),
                "vector": w.tolist()}

    stiff, sloppy = entry(*dirs[0]), entry(*dirs[1])
    trade = _pct(rho * sd[1])  # regression: E[log kt | log kx + sd_x] - E[log kt] = rho sd_t
    text = (f"corr(log {names[0]}, log {names[1]}) = {rho:+.2f}; the data fix {stiff['combination']} to "
            f"±{stiff['sd_pct']:.2g} % (1 sd); along the posterior, {names[0]} +{_pct(sd[0]):.2g} % (its sd) goes with "
            f"{names[1]} {trade:+.2g} %; at a fixed {names[0]}, {names[1]} would be known to ±{_pct(cond[1]):.2g} %, "
            f"on its own it is known to ±{_pct(sd[1]):.2g} %")
    return {"correlation": rho, "stiff": stiff, "sloppy": sloppy,
            "marginal_pct": {names[0]: _pct(sd[0]), names[1]: _pct(sd[1])},
            "conditional_pct": {names[0]: _pct(cond[0]), names[1]: _pct(cond[1])},
            "tradeoff_pct": trade, "statement": text + "."}


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
