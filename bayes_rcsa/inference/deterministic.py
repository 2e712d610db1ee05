"""The paper's deterministic baseline: minimise the absolute percentage FRF difference.

Objective (per the reference paper, section 2.4)::

    J(k) = 100 / n_meas * sum_j mean_{n in band_j} |H_model,n(k) - H_meas,n| / |H_meas,n|     (%)

over the band lines around the dominant peak, with each measurement
weighted equally.  The stiffness parameters (``k_xf``, ``k_thetaM`` and,
with several clamping lengths, the growth factors ``g`` in ``[0, Q]``) are
searched over their prior bounds by differential evolution (vectorised over
the population, seeded with the likelihood-grid optimum of :mod:`.search`
so that the narrow basin is not missed), then polished by Nelder-Mead in the sampling coordinates
(``log10 k``).  Noise scales play no role; sampled damping, if any, is
fitted like the stiffness.

With one clamping length this is the classical literature method whose
transfer to other lengths the paper's Tables 5-6 criticise.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

from .likelihood import FRFLikelihood

__all__ = ["DeterministicFit", "PercentageObjective", "fit_deterministic"]


@dataclass(frozen=True)
class DeterministicFit:
    """Result of :func:`fit_deterministic`.

    Attributes
    ----------
    values : dict of str to float
        Physical values of the fitted parameters (noise scales excluded).
    theta : (ndim,) full sampling vector (noise coordinates at their prior centre)
    objective : float
        Mean absolute percentage difference at the optimum, %.
    success : bool
    n_evaluations : int
    message : str
    """

    values: dict
    theta: np.ndarray
    objective: float
    success: bool
    n_evaluations: int
    message: str


class PercentageObjective:
    """J(k) of the module docstring over the non-noise coordinates.

    Parameters
    ----------
    likelihood : FRFLikelihood
        Provides the forward model, the band lines and the parameter model.
    """

    def __init__(self, likelihood: FRFLikelihood):
        self.likelihood = likelihood
        pm = likelihood.parameters
        noise = set(pm.noise_names)
        self.free = np.array([i for i, n in enumerate(pm.names) if n not in noise], dtype=int)
        bounds = pm.priors.optimisation_bounds()
        self.theta_fill = np.array([0.5 * (lo + hi) for lo, hi in bounds])
        self.bounds = [bounds[i] for i in self.free]
        self.inv_abs = 1.0 / np.abs(likelihood.data)
        self.line_weight = np.concatenate(
            [np.full(o.n_lines, 1.0 / (o.n_lines * len(likelihood.observations))) for o in likelihood.observations]
        )
        self.n_evaluations = 0

    def full(self, x: np.ndarray) -> np.ndarray:
        """(n, ndim) full sampling vectors from free coordinates (n, n_free)."""
        x = np.atleast_2d(x)
        theta = np.repeat(self.theta_fill[None, :], x.shape[0], axis=0)
        theta[:, self.free] = x
        return theta

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """J in % for free coordinates (n, n_free) -> (n,)."""
        x = np.atleast_2d(x)
        self.n_evaluations += x.shape[0]
        h = self.likelihood.model_frf(self.full(x))
        return 100.0 * (np.abs(h - self.likelihood.data) * self.inv_abs) @ self.line_weight

    def scipy(self, x: np.ndarray):
        """scipy calling convention: (n_free,) -> float, (n_free, S) -> (S,)."""
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            return float(self(x[None, :])[0])
        return self(x.T)


def fit_deterministic(likelihood: FRFLikelihood, rng: np.random.Generator, x0: np.ndarray | None = None,
                      maxiter: int = 400, popsize: int = 20, tol: float = 1e-8) -> DeterministicFit:
    """Minimise the absolute percentage FRF difference (the paper's baseline).

    Parameters
    ----------
    likelihood : FRFLikelihood
        Its observations define the bands; its parameter model the parameters.
    rng : numpy.random.Generator
        Seeds the differential evolution.
    x0 : (ndim,) full sampling vector, optional
        A starting guess placed in the initial population (e.g. the grid
        optimum of :mod:`.search`, which finds the narrow basin reliably).
    maxiter, popsize, tol : differential-evolution settings.
    """
    from scipy.optimize import differential_evolution, minimize

    obj = PercentageObjective(likelihood)
    kw = {"rng": rng} if "rng" in inspect.signature(differential_evolution).parameters else {"seed": rng}
    if x0 is not None:
        lo_b = np.array([b[0] for b in obj.bounds])
        hi_b = np.array([b[1] for b in obj.bounds])
        kw["x0"] = np.clip(np.asarray(x0, dtype=float)[obj.free], lo_b, hi_b)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        de = differential_evolution(obj.scipy, obj.bounds, maxiter=maxiter, popsize=popsize, tol=tol, polish=False,
                                    vectorized=True, updating="deferred", **kw)
        lo = np.array([b[0] for b in obj.bounds])
        hi = np.array([b[1] for b in obj.bounds])
        # Nelder-Mead copes with the kinks of |.|; out-of-bounds points are penalised, not clipped.
        penalised = lambda x: obj.scipy(x) if np.all((x >= lo) & (x <= hi)) else 1e30  # noqa: E731
        nm = minimize(penalised, de.x, method="Nelder-Mead", options={"xatol": 1e-9, "fatol": 1e-10, "maxiter": 4000})
    x = nm.x if nm.fun <= de.fun else de.x
    theta = obj.full(x)[0]
    values_all = likelihood.parameters.values(theta[None, :])
    names = [likelihood.parameters.names[i] for i in obj.free]
    values = {n: float(values_all[n][0]) for n in names}
    return DeterministicFit(values, theta, float(min(nm.fun, de.fun)), bool(de.success), obj.n_evaluations, str(de.message))
