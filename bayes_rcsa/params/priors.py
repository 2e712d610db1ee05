"""Prior distributions of the identification, each a small self-describing object.

Every prior works in its own *sampling coordinate* ``u``, the coordinate the
sampler moves in, and maps it to the physical value ``x``:

===============  =====================  ===========================
prior            sampling coordinate u  density of u
===============  =====================  ===========================
Uniform(lo, hi)  x                      uniform on [lo, hi]
LogUniform       log10 x                uniform on [log10 lo, log10 hi]
LogNormal        ln x                   normal(ln median, sigma)
Normal           x                      normal(mu, sigma)
===============  =====================  ===========================

A log-uniform stiffness is therefore sampled as a uniform ``log10 k``, which
is what makes ensemble moves efficient over several decades.  ``ln_prob`` is
the log density *of u* (the Jacobian of the physical-to-sampling map is part
of the prior's definition, so nothing else has to add it).

:class:`PriorSet` is an ordered collection that sums the log densities of a
whole parameter vector, draws from it and checks that user-supplied starting
points lie in its support.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import SetupError

__all__ = [
    "Prior",
    "Uniform",
    "LogUniform",
    "LogNormal",
    "Normal",
    "PriorSet",
    "prior_from_spec",
]


class Prior:
    """Base class: a one-dimensional prior with its sampling coordinate.

    Subclasses implement :meth:`ln_prob`, :meth:`sample`, :meth:`to_physical`,
    :meth:`to_sampling` and the :attr:`bounds` of the sampling coordinate.
    """

    kind = "prior"

    @property
    def bounds(self) -> tuple[float, float]:
        """(lo, hi) of the sampling coordinate; ``-inf``/``inf`` if unbounded."""
        raise NotImplementedError

    def ln_prob(self, u: np.ndarray) -> np.ndarray:
        """Log density of the sampling coordinate, ``-inf`` outside the support.

        Parameters
        ----------
        u : (...) float

        Returns
        -------
        (...) float
        """
        raise NotImplementedError

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` independent draws of the sampling coordinate, shape (n,)."""
        raise NotImplementedError

    def to_physical(self, u):
        raise NotImplementedError

    def to_sampling(self, x):
        raise NotImplementedError

    def in_support(self, u) -> np.ndarray:
        lo, hi = self.bounds
        u = np.asarray(u, dtype=float)
        return np.isfinite(u) & (u >= lo) & (u <= hi)

    def optimisation_bounds(self) -> tuple[float, float]:
        """Finite bounds of the sampling coordinate for a global optimiser."""
        return self.bounds

    def describe(self) -> dict:
        """JSON-serialisable description (for summary.json)."""
        raise NotImplementedError


@dataclass(frozen=True)
class Uniform(Prior):
    """Uniform on [lo, hi]; the sampling coordinate is the value itself."""

    lo: float
    hi: float
    kind = "uniform"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and self.lo < self.hi):
            raise SetupError(f"uniform prior bounds [{self.lo!r}, {self.hi!r}]: expected finite lo < hi")

    @property
    def bounds(self):
        return (float(self.lo), float(self.hi))

    def ln_prob(self, u):
        u = np.asarray(u, dtype=float)
        return np.where(self.in_support(u), -math.log(self.hi - self.lo), -np.inf)

    def sample(self, rng, n):
        return rng.uniform(self.lo, self.hi, size=n)

    def to_physical(self, u):
        return u

    def to_sampling(self, x):
        return x

    def describe(self):
        return {"distribution": "uniform", "lo": self.lo, "hi": self.hi}


@dataclass(frozen=True)
class LogUniform(Prior):
    """Log-uniform on [lo, hi] (lo > 0); the sampling coordinate is log10 x."""

    lo: float
    hi: float
    kind = "log-uniform"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and 0 < self.lo < self.hi):
            raise SetupError(f"log-uniform prior bounds [{self.lo!r}, {self.hi!r}]: expected finite 0 < lo < hi")

    @property
    def bounds(self):
        return (math.log10(self.lo), math.log10(self.hi))

    def ln_prob(self, u):
        lo, hi = self.bounds
        u = np.asarray(u, dtype=float)
        return np.where(self.in_support(u), -math.log(hi - lo), -np.inf)

    def sample(self, rng, n):
        lo, hi = self.bounds
        return rng.uniform(lo, hi, size=n)

    def to_physical(self, u):
        return 10.0 ** np.asarray(u, dtype=float)

    def to_sampling(self, x):
        return np.log10(np.asarray(x, dtype=float))

    def describe(self):
        return {"distribution": "log-uniform", "lo": self.lo, "hi": self.hi}


@dataclass(frozen=True)
class LogNormal(Prior):
    """Log-normal with ``median`` and ``sigma`` (of ln x); sampling coordinate ln x.

    Optional ``lo``/``hi`` truncate the support (physical units); the
    optimiser uses them, or ``median * exp(+-5 sigma)`` when absent.
    """

    median: float
    sigma: float
    lo: float | None = None
    hi: float | None = None
    kind = "log-normal"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.median) and self.median > 0 and math.isfinite(self.sigma) and self.sigma > 0):
            raise SetupError(f"log-normal prior median={self.median!r}, sigma={self.sigma!r}: expected both finite and > 0")
        lo, hi = self.lo, self.hi
        if (lo is not None and lo <= 0) or (lo is not None and hi is not None and lo >= hi):
            raise SetupError(f"log-normal prior truncation [{lo!r}, {hi!r}]: expected 0 < lo < hi")

    @property
    def bounds(self):
        return (
            math.log(self.lo) if self.lo is not None else -math.inf,
            math.log(self.hi) if self.hi is not None else math.inf,
        )

    def _norm(self) -> float:
        # log of the probability mass kept by the truncation
        from scipy.special import ndtr

        lo, hi = self.bounds
        mu = math.log(self.median)
        mass = ndtr((hi - mu) / self.sigma) - ndtr((lo - mu) / self.sigma)
        return math.log(mass)

    def ln_prob(self, u):
        u = np.asarray(u, dtype=float)
        mu = math.log(self.median)
        z = (u - mu) / self.sigma
        with np.errstate(invalid="ignore"):
            lp = -0.5 * z * z - math.log(self.sigma * math.sqrt(2 * math.pi)) - self._norm()
        return np.where(self.in_support(u), lp, -np.inf)

    def sample(self, rng, n):
        lo, hi = self.bounds
        out = np.empty(0)
        # Rejection is fine: the truncation keeps a non-negligible mass by construction.
        while out.size < n:
            u = rng.normal(math.log(self.median), self.sigma, size=2 * n)
            out = np.concatenate([out, u[(u >= lo) & (u <= hi)]])
        return out[:n]

    def to_physical(self, u):
        return np.exp(np.asarray(u, dtype=float))

    def to_sampling(self, x):
        return np.log(np.asarray(x, dtype=float))

    def optimisation_bounds(self):
        lo, hi = self.bounds
        mu = math.log(self.median)
        return (max(lo, mu - 5 * self.sigma), min(hi, mu + 5 * self.sigma))

    def describe(self):
        return {"distribution": "log-normal", "median": self.median, "sigma": self.sigma, "lo": self.lo, "hi": self.hi}


@dataclass(frozen=True)
class Normal(Prior):
    """Normal(mu, sigma), optionally truncated to [lo, hi]; sampling coordinate x."""

    mu: float
    sigma: float
    lo: float | None = None
    hi: float | None = None
    kind = "normal"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mu) and math.isfinite(self.sigma) and self.sigma > 0):
            raise SetupError(f"normal prior mu={self.mu!r}, sigma={self.sigma!r}: expected finite values, sigma > 0")
        if self.lo is not None and self.hi is not None and self.lo >= self.hi:
            raise SetupError(f"normal prior truncation [{self.lo!r}, {self.hi!r}]: expected lo < hi")

    @property
    def bounds(self):
        return (self.lo if self.lo is not None else -math.inf, self.hi if self.hi is not None else math.inf)

    def ln_prob(self, u):
        from scipy.special import ndtr

        u = np.asarray(u, dtype=float)
        lo, hi = self.bounds
        mass = ndtr((hi - self.mu) / self.sigma) - ndtr((lo - self.mu) / self.sigma)
        z = (u - self.mu) / self.sigma
        with np.errstate(invalid="ignore"):
            lp = -0.5 * z * z - math.log(self.sigma * math.sqrt(2 * math.pi)) - math.log(mass)
        return np.where(self.in_support(u), lp, -np.inf)

    def sample(self, rng, n):
        lo, hi = self.bounds
        out = np.empty(0)
        while out.size < n:
            u = rng.normal(self.mu, self.sigma, size=2 * n)
            out = np.concatenate([out, u[(u >= lo) & (u <= hi)]])
        return out[:n]

    def to_physical(self, u):
        return u

    def to_sampling(self, x):
        return x

    def optimisation_bounds(self):
        lo, hi = self.bounds
        return (max(lo, self.mu - 5 * self.sigma), min(hi, self.mu + 5 * self.sigma))

    def describe(self):
        return {"distribution": "normal", "mu": self.mu, "sigma": self.sigma, "lo": self.lo, "hi": self.hi}


class PriorSet:
    """An ordered set of independent priors over a parameter vector.

    Parameters
    ----------
    priors : mapping of parameter name to Prior, in vector order
    """

    def __init__(self, priors: Mapping[str, Prior]):
        if not priors:
            raise SetupError("a prior set needs at least one parameter")
        self.priors = dict(priors)
        self.names = tuple(self.priors)
        # Uniform and log-uniform priors have a constant density in their sampling
        # coordinate: their sum is one bounds test plus a constant (the hot path).
        flat = [j for j, p in enumerate(self.priors.values()) if isinstance(p, (Uniform, LogUniform))]
        self._flat = np.array(flat, dtype=int)
        self._flat_lo = np.array([list(self.priors.values())[j].bounds[0] for j in flat])
        self._flat_hi = np.array([list(self.priors.values())[j].bounds[1] for j in flat])
        self._flat_const = float(sum(float(list(self.priors.values())[j].ln_prob(list(self.priors.values())[j].bounds[0]))
                                     for j in flat))
        self._other = [(j, p) for j, p in enumerate(self.priors.values()) if j not in set(flat)]

    @property
    def ndim(self) -> int:
        return len(self.names)

    def __getitem__(self, name: str) -> Prior:
        return self.priors[name]

    @property
    def bounds(self) -> np.ndarray:
        """(ndim, 2) bounds of the sampling coordinates."""
        return np.array([p.bounds for p in self.priors.values()], dtype=float)

    def optimisation_bounds(self) -> list[tuple[float, float]]:
        return [p.optimisation_bounds() for p in self.priors.values()]

    def ln_prob(self, theta: np.ndarray) -> np.ndarray:
        """Sum of the log densities.

        Parameters
        ----------
        theta : (n, ndim) sampling coordinates

        Returns
        -------
        (n,) float, ``-inf`` where any coordinate is outside its support
        """
        theta = np.atleast_2d(theta)
        if self._flat.size:
            t = theta[:, self._flat]
            inside = np.all((t >= self._flat_lo) & (t <= self._flat_hi), axis=1)
            total = np.where(inside, self._flat_const, -np.inf)
        else:
            total = np.zeros(theta.shape[0])
        for j, p in self._other:
            total = total + p.ln_prob(theta[:, j])
        return total

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, ndim) independent draws of the sampling coordinates."""
        return np.column_stack([p.sample(rng, n) for p in self.priors.values()])

    def to_physical(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        """Physical values of each parameter, ``{name: (n,)}``."""
        theta = np.atleast_2d(theta)
        return {name: np.asarray(p.to_physical(theta[:, j]), dtype=float) for j, (name, p) in enumerate(self.priors.items())}

    def to_sampling(self, values: Mapping[str, float]) -> np.ndarray:
        """Sampling coordinates (ndim,) of one physical parameter set."""
        missing = [n for n in self.names if n not in values]
        if missing:
            raise SetupError(f"parameter values missing for {missing}; expected all of {list(self.names)}")
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.array([float(self.priors[n].to_sampling(values[n])) for n in self.names])

    def check_inside(self, theta: np.ndarray, what: str = "starting point") -> None:
        """Raise :class:`SetupError` naming the first coordinate outside the support.

        Parameters
        ----------
        theta : (n, ndim) sampling coordinates
        what : str
            Used in the message (e.g. ``"walker start"``).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.shape[1] != self.ndim:
            raise SetupError(f"{what}: {theta.shape[1]} coordinates, expected {self.ndim} ({list(self.names)})")
        for j, (name, p) in enumerate(self.priors.items()):
            bad = ~p.in_support(theta[:, j])
            if np.any(bad):
                i = int(np.argmax(bad))
                x = p.to_physical(theta[i, j]) if np.isfinite(theta[i, j]) else theta[i, j]
                raise SetupError(
                    f"{what} {i}: parameter {name} = {float(x):.6g} lies outside its prior support "
                    f"{p.describe()}"
                )

    def describe(self) -> dict:
        return {n: p.describe() for n, p in self.priors.items()}


def prior_from_spec(spec, name: str, default_kind: str = "log-uniform") -> Prior:
    """Build a prior from a setup-file value.

    Parameters
    ----------
    spec : [lo, hi] pair or table
        A pair means ``default_kind`` between the bounds.  A table names
        ``distribution`` ("uniform", "log-uniform", "log-normal", "normal")
        and its parameters (``lo``, ``hi``, ``median``, ``mu``, ``sigma``).
    name : str
        Setup key, used in error messages.
    """
    if isinstance(spec, (list, tuple)):
        if len(spec) != 2:
            raise SetupError(f"{name} = {spec!r}: expected a [lo, hi] pair")
        try:
            lo, hi = (float(v) for v in spec)
        except (TypeError, ValueError):
            raise SetupError(f"{name} = {spec!r}: expected a [lo, hi] pair of numbers") from None
        try:
            return LogUniform(lo, hi) if default_kind == "log-uniform" else Uniform(lo, hi)
        except SetupError as exc:
            raise SetupError(f"{name}: {exc}") from None
    if isinstance(spec, Mapping):
        kind = str(spec.get("distribution", default_kind)).lower()
        try:
            if kind == "uniform":
                return Uniform(float(spec["lo"]), float(spec["hi"]))
            if kind in ("log-uniform", "loguniform"):
                return LogUniform(float(spec["lo"]), float(spec["hi"]))
            if kind in ("log-normal", "lognormal"):
                return LogNormal(float(spec["median"]), float(spec["sigma"]), _opt(spec, "lo"), _opt(spec, "hi"))
            if kind == "normal":
                return Normal(float(spec["mu"]), float(spec["sigma"]), _opt(spec, "lo"), _opt(spec, "hi"))
        except KeyError as exc:
            raise SetupError(f"{name}: {kind} prior needs key {exc.args[0]!r}") from None
        except SetupError as exc:  # a constructor's own check (e.g. sigma <= 0): keep its reason, name the key
            raise SetupError(f"{name}: {exc}") from None
        except (TypeError, ValueError):
            raise SetupError(f"{name} = {dict(spec)!r}: prior parameters must be numbers") from None
        raise SetupError(f"{name}: unknown distribution {kind!r}; expected uniform, log-uniform, log-normal or normal")
    raise SetupError(f"{name} = {spec!r}: expected a [lo, hi] pair or a table with 'distribution'")


def _opt(spec: Mapping, key: str) -> float | None:
    return None if spec.get(key) is None else float(spec[key])

