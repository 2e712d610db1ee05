"""Growth-law uncertainty for predictions from a single-length posterior.

A posterior fitted at ONE clamping length ``l_fit`` has no growth
parameters: the identification fixes ``g_xf = g_thetaM = 0`` because data
at one length cannot tell how the contact stiffness changes with length.
Transferring such draws unchanged to another length would claim that the
stiffness *is* the same there -- a falsely confident prediction (and an
experimental design built on it would conclude that nothing can be learnt
by measuring elsewhere).

What the user does know is the feasible growth law of the setup's
``[contact]`` table (:class:`bayes_rcsa.params.GrowthLaw`):
``k(l) = k(l_a) (1 + g (l - l_a) / (l_b - l_a))`` with ``0 <= g <= Q``.
:func:`with_growth_prior` therefore gives every draw growth factors drawn
from their prior (``Uniform[0, Q]``, or the setup's ``[priors] g_xf`` /
``g_thetaM``) and re-expresses its stiffness at ``l_a`` such that the
stiffness at ``l_fit`` keeps its fitted value::

    k(l_a) = k_fit / (1 + g (l_fit - l_a) / (l_b - l_a))

so that the fit is unchanged at its own length (the data at ``l_fit`` carry
no information on ``g``: the posterior of ``g`` given those data *is* its
prior) and the predictions elsewhere carry the growth law's prior
uncertainty.  Posteriors with growth parameters (Method II) are returned
unchanged.

Wiring into predictions: see :func:`with_growth_prior` (``predict``,
``lobes --posterior`` and ``design`` call it on the loaded draws when the
setup defines a feasible range wider than the fitted length).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping

import numpy as np

from ..errors import SetupError
from ..params.growth import GrowthLaw
from ..params.model import ParameterModel, contact_parameter
from ..params.priors import Prior, Uniform, prior_from_spec
from .draws import PosteriorDraws

__all__ = ["GROWTH_NAMES", "feasible_growth_law", "growth_priors", "needs_growth_prior", "with_growth_prior",
           "transfer_draws"]

#: The growth factors a single-length fit holds at 0.
GROWTH_NAMES = ("g_xf", "g_thetaM")

_LENGTH_TOL = 1e-9  # m, decimal round-off of lengths written in files


def feasible_growth_law(setup=None, attrs: Mapping[str, Any] | None = None) -> GrowthLaw | None:
    """The feasible growth law: ``[l_a, l_b]`` and ``Q`` of the fit's setup.

    Parameters
    ----------
    setup : Setup, optional
        Its ``[contact]`` ``clamping_range`` and ``growth_bound``.
    attrs : mapping, optional
        Attributes of ``posterior.nc``; ``feasible_l_a``, ``feasible_l_b``
        and ``feasible_growth_bound`` win over the setup when present (the
        identification may record the feasible law there).

    Returns
    -------
    GrowthLaw or None
        ``None`` when neither source defines a feasible range.
    """
    attrs = dict(attrs or {})
    if all(k in attrs for k in ("feasible_l_a", "feasible_l_b", "feasible_growth_bound")):
        return GrowthLaw(float(attrs["feasible_l_a"]), float(attrs["feasible_l_b"]),
                         float(attrs["feasible_growth_bound"]))
    contact = getattr(setup, "contact", None)
    if contact is None or getattr(contact, "clamping_range", None) is None:
        return None
    l_a, l_b = (float(v) for v in contact.clamping_range)
    return GrowthLaw(l_a, l_b, float(contact.growth_bound))


def growth_priors(growth: GrowthLaw, user_priors: Mapping[str, Any] | None = None) -> dict[str, Prior]:
    """Prior of each growth factor: ``Uniform[0, Q]`` unless ``[priors]`` gives one inside ``[0, Q]``.

    Raises
    ------
    SetupError
        A ``[priors]`` growth prior reaching outside ``[0, Q]``.
    """
    user = dict(user_priors or {})
    q = growth.growth_bound
    out = {}
    for name in GROWTH_NAMES:
        prior = prior_from_spec(user[name], f"priors.{name}", "uniform") if name in user else Uniform(0.0, q)
        lo, hi = prior.bounds
        if lo < 0 or hi > q:
            raise SetupError(f"priors.{name}: support [{lo:g}, {hi:g}] must lie within [0, Q = {q:g}] (growth law)")
        out[name] = prior
    return out


def needs_growth_prior(draws: PosteriorDraws, growth: GrowthLaw | None) -> bool:
    """True if ``draws`` come from a single-length fit and ``growth`` allows growth."""
    if growth is None or not growth.has_growth or growth.growth_bound <= 0:
        return False
    own = draws.parameters.growth
    return not own.has_growth and all(not draws.parameters[n].sampled for n in GROWTH_NAMES)


def with_growth_prior(draws: PosteriorDraws, growth: GrowthLaw | None, rng: np.random.Generator,
                      user_priors: Mapping[str, Any] | None = None) -> PosteriorDraws:
    """Draws of a single-length fit with growth factors sampled from the growth law's prior.

    Parameters
    ----------
    draws : PosteriorDraws
        From :func:`~bayes_rcsa.posterior.load_posterior` or
        :func:`~bayes_rcsa.posterior.draws_from_result`.
    growth : GrowthLaw or None
        The *feasible* growth law (:func:`feasible_growth_law`); ``None`` or
        one without growth returns ``draws`` unchanged.
    rng : numpy.random.Generator
        Source of the growth factors (one independent pair per draw).
    user_priors : mapping, optional
        The setup's ``[priors]`` table (``g_xf`` / ``g_thetaM`` entries).

    Returns
    -------
    PosteriorDraws
        Same number of draws.  Its parameter model has the feasible growth
        law and sampled ``g_xf``, ``g_thetaM`` with their priors; ``k_xf``,
        ``k_thetaM`` are the stiffness at ``l_a`` chosen such that the
        stiffness at the fitted length equals the fitted draw (up to
        round-off).  A note records the change.  Draws that already have
        growth parameters (a multi-length fit) are returned unchanged.

    Raises
    ------
    SetupError
        The fitted length lies outside the feasible range, or a growth prior
        outside ``[0, Q]``.
    """
    if not needs_growth_prior(draws, growth):
        return draws
    if not isinstance(rng, np.random.Generator):
        raise SetupError("with_growth_prior needs an explicit numpy.random.Generator")
    l_fit = draws.parameters.growth.l_a
    growth.check_lengths([l_fit], "fitted clamping length")
    priors = growth_priors(growth, user_priors)
    n = draws.n_draws
    x_fit = (l_fit - growth.l_a) / (growth.l_b - growth.l_a)
    values = dict(draws.values)
    for kname, gname in (("k_xf", "g_xf"), ("k_thetaM", "g_thetaM")):
        g = np.asarray(priors[gname].to_physical(priors[gname].sample(rng, n)), dtype=float)
        values[gname] = g
        # k(l_fit) = k(l_a) (1 + g x_fit) must stay at the fitted value
        values[kname] = np.asarray(draws.values[kname], dtype=float) / (1.0 + g * x_fit)
    pm = draws.parameters
    params = [contact_parameter(p.name, priors[p.name]) if p.name in GROWTH_NAMES else p for p in pm.parameters]
    new_pm = ParameterModel(params, growth, pm.terms, pm.n_measurements)
    note = (f"growth factors g_xf, g_thetaM sampled from their prior ({priors['g_xf'].describe()}, "
            f"{priors['g_thetaM'].describe()}) over the feasible range [{growth.l_a * 1e3:.4g}, "
            f"{growth.l_b * 1e3:.4g}] mm: the fit at {l_fit * 1e3:.4g} mm alone does not determine them")
    return PosteriorDraws(new_pm, values, draws.method, draws.fit_lengths, draws.source,
                          draws.parameter_model_source, draws.notes + (note,))


def transfer_draws(draws: PosteriorDraws, setup, lengths, rng: np.random.Generator) -> PosteriorDraws:
    """Draws ready to predict at ``lengths`` (m): the one rule of ``predict`` and ``lobes --posterior``.

    * A multi-length posterior (growth identified) is returned unchanged.
    * A single-length posterior of the default method gets the growth law's
      prior (:func:`with_growth_prior`): honest intervals elsewhere,
      unchanged at its own length.
    * The literature method (``method = "single"``) asked for a constant
      contact stiffness explicitly; it keeps it, but predicting at another
      length adds a ``warning:`` note (such intervals exclude the unknown
      growth and, measured blind, rarely cover the truth; docs/design.md).
    """
    l_fit = draws.fit_lengths
    elsewhere = [l for l in lengths if all(abs(l - f) > _LENGTH_TOL for f in l_fit)]
    if draws.method == "single":
        if not elsewhere or not needs_growth_prior(draws, feasible_growth_law(setup)):
            return draws
        note = (f"warning: literature method (constant contact stiffness, fitted at "
                f"{', '.join(f'{f * 1e3:.4g}' for f in l_fit)} mm) transferred to "
                f"{', '.join(f'{l * 1e3:.4g}' for l in elsewhere)} mm: its intervals leave out how the stiffness "
                "grows with clamping length and are too narrow there; identify with the default method "
                "(growth prior) or measure a second clamping length")
        return replace(draws, notes=draws.notes + (note,))
    return with_growth_prior(draws, feasible_growth_law(setup), rng, setup.extra.get("priors"))
