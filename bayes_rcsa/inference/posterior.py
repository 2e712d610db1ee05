"""Log posterior = log prior + (tempered) log likelihood, vectorised over walkers."""

from __future__ import annotations

import numpy as np

from .likelihood import FRFLikelihood
from ..params.priors import PriorSet

__all__ = ["LogPosterior"]


class LogPosterior:
    """Unnormalised log posterior density in the sampling coordinates.

    Parameters
    ----------
    priors : PriorSet
    likelihood : FRFLikelihood

    Notes
    -----
    The likelihood is evaluated only for rows with a finite prior, so walkers
    proposed outside the support cost nothing and never reach the forward
    model with meaningless parameters.
    """

    def __init__(self, priors: PriorSet, likelihood: FRFLikelihood):
        self.priors = priors
        self.likelihood = likelihood
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
            lp[ok] += self.likelihood(sub)
        return lp

    def negative(self, theta: np.ndarray) -> np.ndarray:
        """``-log posterior`` for optimisers; accepts (ndim,) or (ndim, n) like scipy's vectorised calls."""
        theta = np.asarray(theta, dtype=float)
        if theta.ndim == 1:
            return float(-self(theta[None, :])[0])
        return -self(theta.T)

    def with_likelihood(self, likelihood: FRFLikelihood) -> "LogPosterior":
        return LogPosterior(self.priors, likelihood)
