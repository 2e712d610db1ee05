"""Simulation-based calibration of the cut update (issue #42 item 1): is the re-weighted posterior the posterior?

The update's prior is the hammer posterior's draws (each equally likely) times the cutting-coefficient prior
and the boundary-width prior; its likelihood is :class:`~.likelihood.CutLikelihood`.  One replicate draws a
truth particle ``(d, u, node, w)`` from that prior, simulates the outcome of every cut from the likelihood
(chatter with probability :func:`~.likelihood.chatter_probability` at the truth's limit), runs
:func:`~.update.importance_update` on those outcomes, and ranks the truth's quantities among ``n_ranked``
of the updated particles (:func:`bayes_rcsa.stats.sbc.rank_among_draws`).  Over replicates the ranks are uniform
exactly when the update samples the posterior (Talts et al. 2018); :func:`bayes_rcsa.stats.sbc.sbc_check`
tests it.

What is ranked: the hammer draw's own quantities (``draw_values``, e.g. ``log10 k_thetaM`` of each draw: the
update moves the contact too), ``ln K_t`` and ``ln K_r`` of the particle, and the width when it is sampled.

Every replicate counts, whatever its effective sample size: dropping the replicates whose weights collapsed
would select on the simulated data, which itself breaks the uniformity SBC tests.  The ESS of each replicate
is returned so that a failure can be traced to collapsed weights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from ..stats.sbc import rank_among_draws
from .coefficients import CoefficientPrior
from .likelihood import DEFAULT_LABEL_ERROR, BoundaryWidth, CutLikelihood, chatter_probability
from .update import UpdateSettings, importance_update

__all__ = ["CutsSbcReplicate", "cuts_sbc_replicate", "cuts_sbc_names"]


@dataclass(frozen=True)
class CutsSbcReplicate:
    """One replicate: ranks (n_quantities,) in ``[0, n_ranked]``, the truth, the number of chattering cuts and
    the update's effective sample size of the hammer draws."""

    ranks: np.ndarray
    truth: np.ndarray
    n_chatter: int
    ess_draws: float

    def to_dict(self) -> dict:
        return {"ranks": [int(r) for r in self.ranks], "truth": [float(t) for t in self.truth],
                "n_chatter": int(self.n_chatter), "ess_draws": float(self.ess_draws)}


def cuts_sbc_names(draw_names, width: BoundaryWidth) -> list[str]:
    """Names of the ranked quantities, in order: the draws' quantities, ``ln_kt``, ``ln_kr`` (, ``ln_width``)."""
    return [*draw_names, "ln_kt", "ln_kr"] + (["ln_width"] if width.sampled else [])


def cuts_sbc_replicate(inverse_limits: np.ndarray, depth_m: np.ndarray, draw_values: np.ndarray,
                       prior: CoefficientPrior, width: BoundaryWidth, rng: np.random.Generator, n_ranked: int = 99,
                       label_error: float = DEFAULT_LABEL_ERROR, settings: UpdateSettings | None = None,
                       likelihood_power: float = 1.0) -> CutsSbcReplicate:
    """One SBC replicate of :func:`~.update.importance_update`.

    Parameters
    ----------
    inverse_limits : (n_nodes, n_draws, n_cuts) 1/m, the hammer draws' inverse limits at the cuts
        (:func:`~.likelihood.inverse_limits_at_cuts`)
    depth_m : (n_cuts,) m, the cuts' axial depths
    draw_values : (n_draws, k) quantities of every hammer draw to rank (e.g. log10 of its contact stiffness)
    prior, width : the update's coefficient and width priors
    rng : numpy.random.Generator (truth, outcomes, particles, resampling, thinning, ties)
    n_ranked : int, updated particles each truth is ranked among (ranks 0..n_ranked)
    label_error : float, the likelihood's (and the simulation's) label-error probability
    settings : UpdateSettings or None
    likelihood_power : float, 1 for the update; any other value re-weights with the likelihood raised to it (a
        deliberately mis-calibrated update, for showing that the check has power)

    Returns
    -------
    CutsSbcReplicate
    """
    inverse_limits = np.asarray(inverse_limits, dtype=float)
    draw_values = np.atleast_2d(np.asarray(draw_values, dtype=float))
    n_nodes, n_draws, n_cuts = inverse_limits.shape
    if draw_values.shape[0] != n_draws:
        raise SetupError(f"cuts_sbc_replicate: draw_values has {draw_values.shape[0]} rows for {n_draws} draws")
    d = int(rng.integers(n_draws))
    u, node = prior.sample(rng, 1)
    w = width.sample(rng, 1)
    with np.errstate(divide="ignore"):
        limit = 1.0 / (inverse_limits[node[0], d] * np.exp(u[0]))
    p = chatter_probability(depth_m, limit, w[0], label_error)
    chatter = rng.uniform(size=n_cuts) < p
    likelihood = CutLikelihood(inverse_limits, depth_m, chatter, label_error)
    if likelihood_power != 1.0:
        likelihood = _Powered(likelihood, likelihood_power)
    s = settings or UpdateSettings()
    res = importance_update(likelihood, prior, width, rng, s, refuse=False)
    kt, kr = prior.coefficients(u, node)
    truth = [*draw_values[d], float(np.log(kt[0])), float(np.log(kr[0]))]
    post = [draw_values[res.draw], np.log(res.kt)[:, None], np.log(res.kr)[:, None]]
    if width.sampled:
        truth.append(float(np.log(w[0])))
        post.append(np.log(res.width)[:, None])
    post = np.concatenate(post, axis=1)
    ranks = rank_among_draws(np.array(truth), post, n_ranked, rng)
    return CutsSbcReplicate(ranks, np.array(truth), int(chatter.sum()), float(res.ess_draws))


class _Powered:
    """A CutLikelihood whose pointwise log-likelihood is multiplied by ``power`` (tests of the check's power)."""

    def __init__(self, likelihood: CutLikelihood, power: float):
        self._lik = likelihood
        self._power = float(power)

    def __getattr__(self, name):
        return getattr(self._lik, name)

    def pointwise(self, draw, u, node, width) -> np.ndarray:
        return self._power * self._lik.pointwise(draw, u, node, width)
