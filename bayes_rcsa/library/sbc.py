"""Simulation-based calibration of the library's stage 2 (issue #42 item 1): is the coupled fit the posterior?

One replicate draws the hyperparameters from the :class:`~.population.Hyperprior` exactly as docs/theory.md
("Tool-library population") states the model -- per type ``a_t ~ N(a_mean, a_sd)``, the common slope
``b0 ~ N(0, b_sd)``, ``tau_b ~ HalfNormal(tb_scale)``, ``b_t = b0 + tau_b delta_t``, ``ln sigma0 ~
N(ls_mean, ls_sd)``, ``tau_s ~ HalfNormal(ts_scale)``, ``ln sigma_t ~ N(ln sigma0, tau_s)`` -- then each
combination's law ``z_s ~ N(a_t + b_t x_s, sigma_t^2)`` and its stage-1 surrogate mean ``m_s ~ N(z_s, C_s)``
(the stage-1 posterior as stage 2 sees it), fits stage 2 (:func:`~.hierarchy.fit_hyper`, its default
settings) and ranks the truth's ``a_t``, ``b_t``, ``sigma_t`` of every type and ``tau_b`` among ``n_ranked``
randomly chosen kept draws (:func:`bayes_rcsa.stats.sbc.rank_among_draws`).  Every replicate counts, converged or not.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from ..stats.sbc import rank_among_draws
from .hierarchy import Group, Stage2Settings, fit_hyper
from .population import Hyperprior

__all__ = ["Stage2SbcReplicate", "stage2_sbc_replicate", "stage2_sbc_names", "simulate_library"]


@dataclass(frozen=True)
class Stage2SbcReplicate:
    """Ranks (n_quantities,), the truth, whether the chain met its convergence rule, and its bulk ESS."""

    ranks: np.ndarray
    truth: np.ndarray
    converged: bool
    ess: float
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"ranks": [int(r) for r in self.ranks], "truth": [float(t) for t in self.truth],
                "converged": bool(self.converged), "ess": float(self.ess)}


def stage2_sbc_names(hyper: Hyperprior, n_types: int) -> list[str]:
    """Names of the ranked quantities: ``a``, ``b``, ``sigma`` of every coordinate and type, then ``tau_b``."""
    out = [f"{q}_{n}_T{t}" for t in range(n_types) for q in ("a", "b", "sigma") for n in hyper.names]
    return out + [f"tau_b_{n}" for n in hyper.names]


def simulate_library(hyper: Hyperprior, types, x, C, rng: np.random.Generator) -> tuple[np.ndarray, list]:
    """Hyperparameters, laws and stage-1 surrogate means drawn from the model (module docstring).

    Parameters
    ----------
    hyper, types, x, C, rng : as :func:`stage2_sbc_replicate`

    Returns
    -------
    truth : (n_quantities,) in :func:`stage2_sbc_names` order (``a``, ``b``, ``sigma`` per type, then ``tau_b``)
    groups : list of :class:`~.hierarchy.Group`, one per type, with the simulated surrogate means
    """
    types = np.asarray(types, dtype=int)
    x = np.asarray(x, dtype=float)
    C = np.asarray(C, dtype=float)
    d, T = hyper.ndim, int(types.max()) + 1
    if x.shape != types.shape or C.shape != (types.size, d, d) or set(types.tolist()) != set(range(T)):
        raise SetupError(f"stage2_sbc_replicate: types {types.shape}, x {x.shape}, C {C.shape}; expected (n,), (n,) "
                         f"and (n, {d}, {d}) with every type 0..T-1 present")
    a = rng.normal(hyper.a_mean, hyper.a_sd, (T, d))
    b0 = rng.normal(0.0, hyper.b_sd, d)
    tau_b = np.abs(rng.normal(0.0, hyper.tb_scale, d))
    b = b0 + tau_b * rng.standard_normal((T, d))
    ln_sigma0 = rng.normal(hyper.ls_mean, hyper.ls_sd, d)
    tau_s = abs(rng.normal(0.0, hyper.ts_scale))
    sigma = np.exp(ln_sigma0 + tau_s * rng.standard_normal((T, d)))
    z = a[types] + b[types] * x[:, None] + sigma[types] * rng.standard_normal((types.size, d))
    m = z + np.einsum("nij,nj->ni", np.linalg.cholesky(C), rng.standard_normal((types.size, d)))
    groups = [Group(f"T{t}", tuple(f"s{i}" for i in np.flatnonzero(types == t)), x[types == t], m[types == t],
                    C[types == t]) for t in range(T)]
    truth = np.concatenate([np.concatenate([a[t], b[t], sigma[t]]) for t in range(T)] + [tau_b])
    return truth, groups


def stage2_sbc_replicate(hyper: Hyperprior, types, x, C, rng: np.random.Generator,
                         settings: Stage2Settings = Stage2Settings(), n_ranked: int = 99) -> Stage2SbcReplicate:
    """One SBC replicate of stage 2.

    Parameters
    ----------
    hyper : Hyperprior, d coordinates
    types : (n,) int, the holder type (0 .. T - 1) of every combination
    x : (n,) covariate ln(d / 10 mm) of every combination
    C : (n, d, d) stage-1 surrogate covariance of every combination (known to the fit)
    rng : numpy.random.Generator (truth, data, sampler, thinning, ties)
    settings : Stage2Settings, the fit's settings (default: the library's)
    n_ranked : int, kept draws each truth is ranked among

    Returns
    -------
    Stage2SbcReplicate
    """
    truth, groups = simulate_library(hyper, types, x, C, rng)
    T = len(groups)
    fit = fit_hyper(groups, hyper, rng, settings)
    post = np.concatenate([fit.types[f"T{t}"].flat for t in range(T)] + [fit.tau_b], axis=1)
    ranks = rank_among_draws(truth, post, n_ranked, rng)
    return Stage2SbcReplicate(ranks, truth, bool(fit.quality.converged), float(fit.quality.ess), list(fit.warnings))
