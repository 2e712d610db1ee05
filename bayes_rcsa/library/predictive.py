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

from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from ..params.priors import JointNormal, Normal
from ..params.terms.law_shape_uncertainty import BEND
from .population import MODEL_VERSION, SCALES, SHAPE_COORDINATES, covariate, from_coordinates

__all__ = ["Population", "predictive_draws", "predictive_prior", "contact_names", "law_shape_prior", "LAW_SHAPE"]


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
    counts : dict holder type -> number of its combinations pooled (empty when not recorded)
    """

    names: tuple
    draws: dict
    box: np.ndarray
    growth: tuple
    diameters: dict
    version: str = MODEL_VERSION
    counts: dict = field(default_factory=dict)

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


def contact_names(pop: Population) -> tuple:
    """The pooled contact coordinates of ``pop`` (its names without the law's shape), in the population's order."""
    return tuple(n for n in pop.names if n not in SHAPE_COORDINATES)


def predictive_prior(pop: Population, holder_type: str, diameter: float, rng: np.random.Generator,
                     n: int = 20000, names=None) -> tuple[JointNormal, list[str]]:
    """The joint-normal prior of a new combination's contact (moment-matched population predictive).

    Parameters
    ----------
    pop, holder_type, diameter, rng : as :func:`predictive_draws`
    n : int, predictive draws the moments are taken from
    names : sequence of str or None
        The coordinates of the prior, a subset of ``pop.names`` (default all).  The moments of a subset are
        the rows and columns of the full ones: the marginal of the moment-matched normal.

    Returns
    -------
    JointNormal over ``names`` (log10 stiffness/damping, linear growth), truncated to the stage-1 box
    list of str, warnings

    Raises
    ------
    SetupError
        A name the population does not pool.
    """
    names = pop.names if names is None else tuple(names)
    missing = [n_ for n_ in names if n_ not in pop.names]
    if missing or not names:
        raise SetupError(f"predictive prior over {list(names)}: the population pools {list(pop.names)}")
    z, warns = predictive_draws(pop, holder_type, diameter, rng, n)
    cols = [pop.names.index(n_) for n_ in names]
    z = z[:, cols]
    cov = np.atleast_2d(np.cov(z, rowvar=False))
    joint = JointNormal.from_arrays(names, z.mean(axis=0), cov, [SCALES[n_] for n_ in names],
                                    pop.box[cols, 0], pop.box[cols, 1])
    return joint, warns


#: The parameter of the law's shape (term ``law_shape_uncertainty``) and its physics envelope, u in [0, 1].
LAW_SHAPE = BEND
LAW_SHAPE_RANGE = (0.0, 1.0)


def law_shape_prior(pop: Population, holder_type: str, diameter: float, rng: np.random.Generator,
                    n: int = 20000) -> tuple[Normal | None, dict, list[str]]:
    """The prior of a setup's law bend ``u`` (``law_shape_bend``) from a library's population.

    The population-predictive draws of ``u`` for the holder type and shank diameter (inside [0, 1]: the
    predictive is truncated to the stage-1 box) give the mean and sd of a normal truncated to [0, 1], as
    :func:`predictive_prior` moment-matches the contact.  Where the predictive reaches an end of [0, 1] the
    truncated normal is not its exact match: a predictive piled near 0 with mean 0.075 and sd 0.073 (a development
    library of benchmarks/library_law_shape.py) gives a truncated normal of mean 0.095 and sd 0.058, 90 % within
    0.01-0.20, against the predictive's 0.01-0.21.

    Parameters
    ----------
    pop : Population
    holder_type : str
    diameter : float, m, shank diameter
    rng : numpy Generator
    n : int, predictive draws

    Returns
    -------
    prior : :class:`~bayes_rcsa.params.priors.Normal` on [0, 1], or None when ``pop`` does not pool the bend
    info : dict
        ``source`` (``"library"``, or ``"envelope"`` with ``reason`` when ``prior`` is None), ``holder_type``,
        ``shank_diameter_m``, ``n_combinations`` (of that holder type in the library; None when not recorded),
        ``mean``, ``sd``, ``q05``, ``q95`` of the predictive (1)
    warnings : list of str (e.g. the diameter outside the type's fitted range)

    Raises
    ------
    SetupError
        A holder type the population does not know, an implausible diameter.
    """
    pop.check_type(holder_type, "law shape prior")
    if LAW_SHAPE not in pop.names:
        return None, {"source": "envelope", "reason": (f"the library does not pool {LAW_SHAPE} (its setups lack the "
                                                       "term law_shape_uncertainty or were fitted at fewer than three "
                                                       "clamping lengths)")}, []
    z, warns = predictive_draws(pop, holder_type, diameter, rng, n)
    u = z[:, pop.names.index(LAW_SHAPE)]
    mean, sd = float(np.mean(u)), float(np.std(u, ddof=1))
    q05, q95 = (float(v) for v in np.quantile(u, [0.05, 0.95]))
    lo, hi = LAW_SHAPE_RANGE
    info = {"source": "library", "holder_type": holder_type, "shank_diameter_m": float(diameter),
            "n_combinations": pop.counts.get(holder_type), "mean": mean, "sd": sd, "q05": q05, "q95": q95}
    return Normal(mean, sd, lo, hi), info, warns


def physical(pop: Population, z: np.ndarray) -> dict[str, np.ndarray]:
    """Physical values ``{name: (n,)}`` of population coordinates."""
    return from_coordinates(pop.names, z)
