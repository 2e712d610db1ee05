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
JointMember      log10 x or x           one coordinate of a JointNormal
===============  =====================  ===========================

A :class:`JointNormal` is a multivariate normal over the sampling
coordinates of several parameters (e.g. the contact law's population
predictive from a tool library, :mod:`bayes_rcsa.library`).  Each of those
parameters carries a :class:`JointMember` prior (its marginal, its
coordinate, its bounds and a reference to the group); a :class:`PriorSet`
that holds every member of a group evaluates and samples the group's joint
density instead of the product of the marginals.

A log-uniform stiffness is therefore sampled as a uniform ``log10 k``, which
is what makes ensemble moves efficient over several decades.  ``ln_prob`` is
the log density *of u* (the Jacobian of the physical-to-sampling map is part
of the prior's definition, so nothing else has to add it).

:class:`PriorSet` is an ordered collection that sums the log densities of a
whole parameter vector, draws from it and checks that user-supplied starting
points lie in its support.
"""

from __future__ import annotations

import functools
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
    "JointNormal",
    "JointMember",
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


_SCALES = ("log10", "linear")


@dataclass(frozen=True)
class JointNormal:
    """Multivariate normal over the sampling coordinates of several parameters, truncated to a box.

    Parameters
    ----------
    names : tuple of str, (d,)
        Parameter names, in the order of ``mean`` and ``cov``.
    mean : tuple of float, (d,)
        Mean in the sampling coordinates.
    cov : tuple of tuples, (d, d)
        Covariance in the sampling coordinates (symmetric positive definite).
    scales : tuple of str, (d,)
        ``"log10"`` (sampling coordinate log10 x, x > 0) or ``"linear"``
        (the value itself) per parameter.
    lo, hi : tuple of float or None, (d,)
        Box of the sampling coordinates (``None``: unbounded); e.g. a growth
        factor's [0, Q].

    Notes
    -----
    The truncation's normalising mass is a Monte Carlo estimate (20 000
    draws, a fixed private generator): it is a constant, so it does not
    affect the sampled posterior, only the absolute value of ``ln_prob``.
    """

    names: tuple
    mean: tuple
    cov: tuple
    scales: tuple
    lo: tuple
    hi: tuple

    def __post_init__(self) -> None:
        d = len(self.names)
        m = np.asarray(self.mean, dtype=float)
        c = np.asarray(self.cov, dtype=float)
        if d == 0 or len(set(self.names)) != d:
            raise SetupError(f"joint-normal prior names {list(self.names)}: expected distinct names")
        if m.shape != (d,) or c.shape != (d, d) or len(self.scales) != d or len(self.lo) != d or len(self.hi) != d:
            raise SetupError(f"joint-normal prior over {list(self.names)}: mean, cov, scales, lo, hi must have "
                             f"{d} entries (cov {d}x{d})")
        if not (np.all(np.isfinite(m)) and np.all(np.isfinite(c)) and np.allclose(c, c.T, rtol=1e-9, atol=0)):
            raise SetupError(f"joint-normal prior over {list(self.names)}: expected a finite mean and a finite "
                             "symmetric covariance")
        try:
            np.linalg.cholesky(c)
        except np.linalg.LinAlgError:
            raise SetupError(f"joint-normal prior over {list(self.names)}: the covariance is not positive "
                             "definite") from None
        bad = [s for s in self.scales if s not in _SCALES]
        if bad:
            raise SetupError(f"joint-normal prior scales {bad}: expected {_SCALES}")
        for j in range(d):
            lo, hi = self.box[j]
            if not lo < hi:
                raise SetupError(f"joint-normal prior {self.names[j]}: bounds [{lo!r}, {hi!r}], expected lo < hi")

    @property
    def ndim(self) -> int:
        return len(self.names)

    @property
    def box(self) -> np.ndarray:
        """(d, 2) bounds of the sampling coordinates (``-inf``/``inf`` where open)."""
        return np.array([[-math.inf if a is None else float(a), math.inf if b is None else float(b)]
                         for a, b in zip(self.lo, self.hi)])

    @functools.cached_property
    def _chol(self) -> np.ndarray:
        return np.linalg.cholesky(np.asarray(self.cov, dtype=float))

    @functools.cached_property
    def _ln_norm(self) -> float:
        # log of (2 pi)^(d/2) |C|^(1/2) times the mass inside the box
        L = self._chol
        base = 0.5 * self.ndim * math.log(2 * math.pi) + float(np.sum(np.log(np.diag(L))))
        box = self.box
        if np.all(np.isinf(box)):
            return base
        z = np.random.default_rng(20260).standard_normal((20000, self.ndim))  # private, fixed: a constant
        u = np.asarray(self.mean, dtype=float) + z @ L.T
        mass = float(np.mean(np.all((u >= box[:, 0]) & (u <= box[:, 1]), axis=1)))
        if mass <= 0:
            raise SetupError(f"joint-normal prior over {list(self.names)}: the box keeps no mass of the normal")
        return base + math.log(mass)

    def ln_prob(self, u: np.ndarray) -> np.ndarray:
        """Joint log density of the sampling coordinates.

        Parameters
        ----------
        u : (n, d) sampling coordinates, columns in the order of ``names``

        Returns
        -------
        (n,) float, ``-inf`` outside the box
        """
        u = np.atleast_2d(np.asarray(u, dtype=float))
        box = self.box
        inside = np.all(np.isfinite(u) & (u >= box[:, 0]) & (u <= box[:, 1]), axis=1)
        r = np.where(np.isfinite(u), u, 0.0) - np.asarray(self.mean, dtype=float)
        from scipy.linalg import solve_triangular

        w = solve_triangular(self._chol, r.T, lower=True)
        lp = -0.5 * np.sum(w * w, axis=0) - self._ln_norm
        return np.where(inside, lp, -np.inf)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, d) independent draws inside the box (rejection)."""
        box = self.box
        out = np.empty((0, self.ndim))
        mean = np.asarray(self.mean, dtype=float)
        for _ in range(1000):
            if out.shape[0] >= n:
                break
            u = mean + rng.standard_normal((2 * n + 16, self.ndim)) @ self._chol.T
            out = np.concatenate([out, u[np.all((u >= box[:, 0]) & (u <= box[:, 1]), axis=1)]])
        if out.shape[0] < n:
            raise SetupError(f"joint-normal prior over {list(self.names)}: the box keeps too little mass to sample")
        return out[:n]

    def member(self, name: str) -> "JointMember":
        """The one-parameter prior of ``name`` that belongs to this group."""
        j = self.names.index(name)
        lo, hi = self.box[j]
        return JointMember(float(self.mean[j]), math.sqrt(float(self.cov[j][j])),
                           None if math.isinf(lo) else float(lo), None if math.isinf(hi) else float(hi),
                           joint=self, index=j)

    def describe(self) -> dict:
        return {"names": list(self.names), "mean": [float(v) for v in self.mean],
                "cov": [[float(v) for v in row] for row in self.cov], "scales": list(self.scales),
                "lo": [None if v is None else float(v) for v in self.lo],
                "hi": [None if v is None else float(v) for v in self.hi]}

    @classmethod
    def from_arrays(cls, names, mean, cov, scales, lo=None, hi=None) -> "JointNormal":
        """A group from arrays (``lo``/``hi`` entries that are not finite mean open)."""
        d = len(names)
        lo = [None] * d if lo is None else [None if v is None or not math.isfinite(v) else float(v) for v in lo]
        hi = [None] * d if hi is None else [None if v is None or not math.isfinite(v) else float(v) for v in hi]
        cov = np.asarray(cov, dtype=float)
        cov = 0.5 * (cov + cov.T)
        return cls(tuple(str(n) for n in names), tuple(float(v) for v in np.asarray(mean, dtype=float)),
                   tuple(tuple(float(v) for v in row) for row in cov), tuple(scales), tuple(lo), tuple(hi))


@dataclass(frozen=True)
class JointMember(Normal):
    """One parameter of a :class:`JointNormal`: its marginal, coordinate and bounds.

    A :class:`Normal` (its truncated normal marginal, ``mu``, ``sigma``,
    ``lo``, ``hi`` in the sampling coordinate) that also knows its group:
    alone it is that marginal (so every consumer of a normal prior reads
    it), and in a :class:`PriorSet` holding all members of the group the
    group's joint density is used.  Made by :meth:`JointNormal.member`.
    """

    joint: JointNormal | None = None
    index: int = 0
    kind = "joint-normal"

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.joint, JointNormal) or not 0 <= self.index < self.joint.ndim:
            raise SetupError("a joint-normal member needs its JointNormal group and an index into it")

    @property
    def name(self) -> str:
        return self.joint.names[self.index]

    def to_physical(self, u):
        u = np.asarray(u, dtype=float)
        return 10.0 ** u if self.joint.scales[self.index] == "log10" else u

    def to_sampling(self, x):
        x = np.asarray(x, dtype=float)
        return np.log10(x) if self.joint.scales[self.index] == "log10" else x

    def describe(self):
        return {"distribution": "joint-normal", "member": self.name, "joint": self.joint.describe()}


class PriorSet:
    """An ordered set of priors over a parameter vector, independent except for joint groups.

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
        self._groups: list[tuple[JointNormal, np.ndarray]] = []
        members = {j: p for j, p in enumerate(self.priors.values()) if isinstance(p, JointMember)}
        for group in dict.fromkeys(p.joint for p in members.values()):
            cols = []
            for gname in group.names:
                if gname not in self.priors or not (isinstance(self.priors[gname], JointMember)
                                                    and self.priors[gname].joint == group):
                    raise SetupError(f"joint-normal prior over {list(group.names)}: parameter {gname} is not sampled "
                                     "with it; a joint prior needs all its parameters")
                cols.append(self.names.index(gname))
            self._groups.append((group, np.array(cols, dtype=int)))
        for j, p in members.items():
            if p.name != self.names[j]:
                raise SetupError(f"parameter {self.names[j]}: its joint-normal prior is that of {p.name}")
        self._other = [(j, p) for j, p in enumerate(self.priors.values()) if j not in set(flat) and j not in members]

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
        for group, cols in self._groups:
            total = total + group.ln_prob(theta[:, cols])
        return total

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, ndim) draws of the sampling coordinates (a joint group's columns jointly)."""
        out = np.column_stack([p.sample(rng, n) for p in self.priors.values()])
        for group, cols in self._groups:
            out[:, cols] = group.sample(rng, n)
        return out

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
            if kind == "joint-normal":
                j = spec["joint"]
                group = JointNormal.from_arrays(j["names"], j["mean"], j["cov"], j["scales"],
                                                [math.nan if v is None else v for v in j["lo"]],
                                                [math.nan if v is None else v for v in j["hi"]])
                return group.member(str(spec["member"]))
        except KeyError as exc:
            raise SetupError(f"{name}: {kind} prior needs key {exc.args[0]!r}") from None
        except SetupError as exc:  # a constructor's own check (e.g. sigma <= 0): keep its reason, name the key
            raise SetupError(f"{name}: {exc}") from None
        except (TypeError, ValueError):
            raise SetupError(f"{name} = {dict(spec)!r}: prior parameters must be numbers") from None
        raise SetupError(f"{name}: unknown distribution {kind!r}; expected uniform, log-uniform, log-normal, normal "
                         "or joint-normal")
    raise SetupError(f"{name} = {spec!r}: expected a [lo, hi] pair or a table with 'distribution'")


def _opt(spec: Mapping, key: str) -> float | None:
    return None if spec.get(key) is None else float(spec[key])

