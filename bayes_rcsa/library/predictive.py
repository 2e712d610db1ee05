"""Population predictive of a new combination: zero taps (draws) or one tap (a joint prior for identify).

For a known holder type ``t`` and shank diameter ``d``, every hyperparameter
draw ``(a, b, sigma)`` gives one law ``z = a + b x + sigma * eps``,
``x = ln(d / 10 mm)``, ``eps ~ N(0, I)``.  These draws are the zero-tap
posterior.  For a tap, ``identify --library`` samples the tap's likelihood
with a :class:`~bayes_rcsa.params.priors.JointNormal` prior moment-matched to
these draws (mean and covariance in the population coordinates, truncated to
the stage-1 prior box) -- the population as the prior.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from ..params.priors import JointNormal
from .population import MODEL_VERSION, SCALES, covariate, from_coordinates

__all__ = ["Population", "predictive_draws", "predictive_prior"]


@dataclass
class Population:
    """A fitted population (in memory or read from population.nc).

    Attributes
    ----------
    names : tuple of str, (d,) pooled coordinates
    draws : dict holder type -> (H, 3d) hyperparameter draws (a, b, sigma)
    box : (d, 2) stage-1 prior box in population coordinates
    growth : (l_a, l_b, Q) the growth law the stiffness refers to
    diameters : dict holder type -> (min, max) m shank diameters of its combinations
    version : str, :data:`~.population.MODEL_VERSION` of the fit
    """

    names: tuple
    draws: dict
    box: np.ndarray
    growth: tuple
    diameters: dict
    version: str = MODEL_VERSION

    @property
    def holder_types(self) -> tuple:
        return tuple(sorted(self.draws))

    def check_type(self, holder_type: str | None, where: str) -> str:
        """``holder_type`` if the population has it, else a one-line :class:`SetupError`."""
        if holder_type is None:
            raise SetupError(f"{where}: no [holder] type; the library knows {list(self.holder_types)}")
        if holder_type not in self.draws:
            raise SetupError(f"{where}: holder type {holder_type!r} is not in the library's population (known: "
                             f"{list(self.holder_types)}); fit the library with a combination of that type first")
        return holder_type


def predictive_draws(pop: Population, holder_type: str, diameter: float, rng: np.random.Generator,
                     n: int | None = None) -> tuple[np.ndarray, list[str]]:
    """Population-predictive laws of a new combination in population coordinates.

    Parameters
    ----------
    pop : Population
    holder_type : str (must be in the population)
    diameter : float, m, shank diameter
    rng : numpy Generator
    n : int or None, draws (default: one per hyperparameter draw)

    Returns
    -------
    z : (n, d), inside the stage-1 box (draws outside it are redrawn; their
        share is reported)
    warnings : list of str, e.g. a diameter outside the type's fitted range
    """
    pop.check_type(holder_type, "new setup")
    x = float(covariate(diameter, "new setup: shank diameter"))
    theta = pop.draws[holder_type]
    d = len(pop.names)
    warns = []
    lo, hi = pop.diameters.get(holder_type, (diameter, diameter))
    if not (lo * (1 - 1e-9) <= diameter <= hi * (1 + 1e-9)):
        warns.append(f"shank diameter {diameter * 1e3:g} mm lies outside the {lo * 1e3:g}-{hi * 1e3:g} mm of holder "
                     f"type {holder_type}'s combinations: the diameter slope extrapolates")
    n = theta.shape[0] if n is None else int(n)
    out = np.empty((0, d))
    n_out = n_all = 0
    while out.shape[0] < n and n_all < 100 * n:
        idx = rng.integers(0, theta.shape[0], size=n)
        t = theta[idx]
        z = t[:, :d] + t[:, d:2 * d] * x + t[:, 2 * d:] * rng.standard_normal((n, d))
        inside = np.all((z >= pop.box[:, 0]) & (z <= pop.box[:, 1]), axis=1)
        n_out += int(np.sum(~inside))
        n_all += n
        out = np.concatenate([out, z[inside]])
    if out.shape[0] < n:
        raise SetupError(f"holder type {holder_type}: the population predictive lies outside the stage-1 prior box")
    if n_out > 0.01 * n_all:
        warns.append(f"{n_out / n_all:.0%} of the population-predictive draws fell outside the stage-1 prior box and "
                     "were redrawn (the population sits at the edge of the prior)")
    return out[:n], warns


def predictive_prior(pop: Population, holder_type: str, diameter: float, rng: np.random.Generator,
                     n: int = 20000) -> tuple[JointNormal, list[str]]:
    """The joint-normal prior of a new combination's contact (moment-matched population predictive).

    Returns
    -------
    JointNormal over ``pop.names`` (log10 stiffness/damping, linear growth), truncated to the stage-1 box
    list of str, warnings
    """
    z, warns = predictive_draws(pop, holder_type, diameter, rng, n)
    cov = np.atleast_2d(np.cov(z, rowvar=False))
    joint = JointNormal.from_arrays(pop.names, z.mean(axis=0), cov, [SCALES[n_] for n_ in pop.names],
                                    pop.box[:, 0], pop.box[:, 1])
    return joint, warns


def physical(pop: Population, z: np.ndarray) -> dict[str, np.ndarray]:
    """Physical values ``{name: (n,)}`` of population coordinates."""
    return from_coordinates(pop.names, z)
