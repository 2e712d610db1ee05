"""Log posterior = log prior + (tempered) log likelihood + extra likelihood terms, vectorised over walkers.

Extra likelihood terms
----------------------
Data other than the hammer-test FRFs (e.g. cutting-test outcomes,
:mod:`bayes_rcsa.cuts.joint`) enter the identification as *extra terms*:
objects with a ``name`` and ``__call__(theta) -> (n,)`` giving their log
likelihood at sampling coordinates ``theta`` (n, ndim) of the problem's
parameter vector (:class:`LikelihoodTerm`).  They are part of the problem
(:attr:`bayes_rcsa.inference.problem.Problem.extra_terms`, added with
``Problem.with_extra_terms``), and :meth:`~bayes_rcsa.inference.problem.Problem.log_posterior`
builds every :class:`LogPosterior` of a fit from it, so the start-up
optimum, the walkers' initialisation, the sampler and the tail check all see
the same posterior.  Tempering (``with_likelihood``) scales the FRF
likelihood only; extra terms enter untempered.
"""

from __future__ import annotations

from typing import Protocol, Sequence

import numpy as np

from .likelihood import FRFLikelihood
from ..params.priors import PriorSet

__all__ = ["LogPosterior", "LikelihoodTerm"]


class LikelihoodTerm(Protocol):
    """An extra log-likelihood term of the identification.

    Attributes
    ----------
    name : str, named in messages and outputs
    """

    name: str

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """(n,) log likelihood at sampling coordinates ``theta`` (n, ndim); -inf where impossible."""


class LogPosterior:
    """Unnormalised log posterior density in the sampling coordinates.

    Parameters
    ----------
    priors : PriorSet
    likelihood : FRFLikelihood
    extra_terms : sequence of LikelihoodTerm
        Added (untempered) to the log likelihood; usually a problem's
        ``extra_terms`` (:meth:`~bayes_rcsa.inference.problem.Problem.log_posterior`).

    Notes
    -----
    The likelihood is evaluated only for rows with a finite prior, so walkers
    proposed outside the support cost nothing and never reach the forward
    model with meaningless parameters.
    """

    def __init__(self, priors: PriorSet, likelihood: FRFLikelihood, extra_terms: Sequence[LikelihoodTerm] = ()):
        self.priors = priors
        self.likelihood = likelihood
        self.extra_terms = tuple(extra_terms)
        self.n_evaluations = 0

    @property
    def ndim(self) -> int:
        return self.priors.ndim

    @property
    def names(self) -> tuple[str, ...]:
        return self.priors.names

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """(n,) log posterior for theta (n, ndim); ``-inf`` outside the prior."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        lp = self.priors.ln_prob(theta)
        ok = np.isfinite(lp)
        if np.any(ok):
            sub = theta if ok.all() else theta[ok]
            self.n_evaluations += sub.shape[0]
            ll = self.likelihood(sub)
            for term in self.extra_terms:
                ll = ll + term(sub)
            lp[ok] += ll
        return lp

    def check_inside(self, theta: np.ndarray, what: str = "starting point") -> None:
        """Raise :class:`~bayes_rcsa.errors.SetupError` naming the first row of theta (n, ndim) outside the
        prior's support (:meth:`PriorSet.check_inside`)."""
        self.priors.check_inside(theta, what)

    def negative(self, theta: np.ndarray) -> np.ndarray:
        """``-log posterior`` for optimisers; accepts (ndim,) or (ndim, n) like scipy's vectorised calls."""
        theta = np.asarray(theta, dtype=float)
        if theta.ndim == 1:
            return float(-self(theta[None, :])[0])
        return -self(theta.T)

    def with_likelihood(self, likelihood: FRFLikelihood) -> "LogPosterior":
        return LogPosterior(self.priors, likelihood, self.extra_terms)
