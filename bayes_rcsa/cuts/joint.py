"""Cut outcomes in the identification itself: ``bayes-rcsa identify ... --cuts CUTS.csv``.

:class:`CutTerm` is an extra likelihood term of the identification
(:class:`bayes_rcsa.inference.posterior.LikelihoodTerm`): at sampling
coordinates θ of the problem it predicts the draws' tool-point FRFs at every
cut setup (the problem's own parameter model and forward model, with the
contact-independent precomputation cached once), the stability limits at the
cut speeds (one method call per K_r/K_t node, vectorised over walkers) and
returns the log of the cut likelihood with the cutting coefficients and the
boundary width *integrated out* over their priors:

    L_cuts(θ) = Σ_j Σ_k ∫ p(u) p(w_k) / n_nodes  Π_c P(outcome_c | θ, u, node j, w_k) du,

the level ``u`` on a fine grid (:data:`LEVEL_GRID` points over ±5 prior
standard deviations: even 20 cuts leave the level's likelihood wider than its
spacing), the width on a few log-uniform nodes when it is sampled.  The
sampler therefore moves in the contact parameters only and needs nothing new;
after the fit :meth:`CutTerm.coefficient_draws` draws (K_t, K_r, w) for every
posterior draw from its conditional (importance sampling from the priors per
draw), which :func:`add_coefficients_to_posterior` writes into posterior.nc
so that ``lobes`` uses them.
"""

from __future__ import annotations

import math

import numpy as np

from .likelihood import CutLikelihood, inverse_limits_at_cuts

__all__ = ["CutTerm", "LEVEL_GRID", "add_coefficients_to_posterior"]

#: Points of the level grid of the integral (trapezoid over ±5 sd).
LEVEL_GRID = 161
#: Nodes of a sampled boundary width (equally probable in ln w).
WIDTH_NODES = 7


class CutTerm:
    """The cut likelihood, coefficients and width integrated out, as a function of the problem's θ.

    Parameters
    ----------
    parameters : ParameterModel of the problem (θ -> physical values)
    model : ToolPointModel of the setup
    caches : dict (length, tool, direction) -> precomputation (:func:`.frf.configuration_caches`)
    frequency_hz : (n_freq,) Hz, the lines of the caches
    cuts : CutSet
    prior : CoefficientPrior
    width : BoundaryWidth
    label_error : float
    method : str, options : MethodOptions or None
    """

    name = "cuts"

    def __init__(self, parameters, model, caches, frequency_hz, cuts, prior, width, label_error: float,
                 method: str = "zoa", options=None):
        self.parameters, self.model, self.caches = parameters, model, caches
        self.frequency_hz = np.asarray(frequency_hz, dtype=float)
        self.cuts, self.prior, self.width = cuts, prior, width
        self.label_error, self.method, self.options = label_error, method, options
        sd = prior.level_sd
        self.u = np.linspace(-5 * sd, 5 * sd, LEVEL_GRID) if sd > 0 else np.zeros(1)
        lw = -0.5 * (self.u / sd) ** 2 if sd > 0 else np.zeros(1)
        if sd > 0:  # trapezoid weights of the normal density on the grid, normalised
            lw = lw + np.log(np.r_[0.5, np.ones(LEVEL_GRID - 2), 0.5])
        self.log_u_weight = lw - np.log(np.sum(np.exp(lw)))
        if width.sampled:
            q = (np.arange(WIDTH_NODES) + 0.5) / WIDTH_NODES
            self.w = np.exp(math.log(width.lo) + q * math.log(width.hi / width.lo))
        else:
            self.w = np.array([width.lo])
        self.n_evaluations = 0

    def _likelihood(self, theta) -> CutLikelihood:
        from ..posterior.draws import PosteriorDraws
        from .data import cut_groups
        from .frf import frfs_of_draws

        values = self.parameters.values(np.atleast_2d(theta))
        draws = PosteriorDraws(self.parameters, values)
        frfs = frfs_of_draws(draws, self.model, self.caches)
        groups = cut_groups(self.cuts, frfs, self.frequency_hz)
        inv = inverse_limits_at_cuts(groups, self.cuts.n_cuts, self.prior, self.method, self.options)
        return CutLikelihood(inv, self.cuts.depth_m, self.cuts.chatter, self.label_error)

    def __call__(self, theta) -> np.ndarray:
        """(n,) log L_cuts(θ) for sampling coordinates ``theta`` (n, ndim)."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        self.n_evaluations += theta.shape[0]
        lik = self._likelihood(theta)
        n_nodes, nu, nw = lik.inverse_limits.shape[0], self.u.size, self.w.size
        per_row = n_nodes * nu * nw
        rows = max(1, int(2e5 // per_row))  # keeps the (particles x cuts) arrays near 2e5 x n_cuts
        out = np.empty(theta.shape[0])
        for s in range(0, theta.shape[0], rows):  # walkers come in batches of tens: usually one pass
            r = np.arange(s, min(s + rows, theta.shape[0]))
            # every (row, node, level, width) combination, vectorised
            d, j, k, m = np.meshgrid(r, np.arange(n_nodes), np.arange(nu), np.arange(nw), indexing="ij")
            ll = lik(d.ravel(), self.u[k.ravel()], j.ravel(), self.w[m.ravel()]).reshape(r.size, n_nodes, nu, nw)
            ll = ll + self.log_u_weight[None, None, :, None] - math.log(n_nodes * nw)
            top = np.max(ll, axis=(1, 2, 3))
            safe = np.where(np.isfinite(top), top, 0.0)
            val = safe + np.log(np.sum(np.exp(ll - safe[:, None, None, None]), axis=(1, 2, 3)))
            out[r] = np.where(np.isfinite(top), val, -np.inf)
        return out

    def coefficient_draws(self, theta, rng: np.random.Generator, candidates: int = 64, chunk: int = 256):
        """(K_t, K_r, w), each (n,), one draw per row of ``theta`` from its conditional given the cuts.

        ``candidates`` draws of (u, node, w) from their priors per row, one chosen with probability
        proportional to its likelihood (self-normalised importance sampling per row).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        out_u, out_node, out_w = [], [], []
        for s in range(0, theta.shape[0], chunk):  # bounds the FRF arrays; each chunk vectorised
            lik = self._likelihood(theta[s : s + chunk])
            n = lik.n_draws
            draw = np.repeat(np.arange(n), candidates)
            u, node = self.prior.sample(rng, draw.size)
            w = self.width.sample(rng, draw.size)
            ll = lik(draw, u, node, w).reshape(n, candidates)
            p = np.exp(ll - ll.max(axis=1, keepdims=True))
            cdf = np.cumsum(p / p.sum(axis=1, keepdims=True), axis=1)
            pick = np.minimum(np.sum(rng.uniform(size=n)[:, None] > cdf, axis=1), candidates - 1)
            idx = np.arange(n) * candidates + pick
            out_u.append(u[idx])
            out_node.append(node[idx])
            out_w.append(w[idx])
        u, node, w = np.concatenate(out_u), np.concatenate(out_node), np.concatenate(out_w)
        kt, kr = self.prior.coefficients(u, node)
        return kt, kr, w


def add_coefficients_to_posterior(path, kt, kr, width, attrs: dict) -> None:
    """Add per-draw ``cutting_kt_pa``, ``cutting_kr_pa``, ``cut_boundary_width`` to an identify posterior.nc.

    Parameters
    ----------
    path : path of the posterior.nc (rewritten atomically, everything else kept)
    kt, kr : (n_draws,) Pa, in the order of :func:`bayes_rcsa.posterior.load_posterior` (chains flattened)
    width : (n_draws,) boundary widths
    attrs : dict, attributes added to the ``posterior`` group (``cuts_file``, ``n_cuts``)
    """
    from ..stability.coefficients import COEFFICIENT_VARIABLES
    from ..store import append_to_posterior

    append_to_posterior(path, posterior_vars={COEFFICIENT_VARIABLES[0]: kt, COEFFICIENT_VARIABLES[1]: kr,
                                              "cut_boundary_width": width}, attrs=attrs)
