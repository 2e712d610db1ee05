"""Parameter vector layout, the growth law k(l), and the map to contact parameters.

The sampled vector ``theta`` (shape ``(n, ndim)``) holds the *sampling
coordinates* of the priors (see :mod:`.priors`: log10 for log-uniform
stiffness, the value itself for the growth factors).  :class:`ParameterLayout`
knows which entries are sampled and which are fixed, turns ``theta`` into
physical values, and from those into the per-configuration contact
parameters that :meth:`bayes_rcsa.model.ConfigurationStack.frf` takes.

Parameter names (physical units)
--------------------------------
``k_xf``, ``k_thetaM``
    Contact stiffness at the reference clamping length ``l_ref`` (N/m,
    N m/rad).  For Method II ``l_ref = l_a``, the short end of the feasible
    range; for a single clamping length (Method I, literature method) it is
    that length.
``g_xf``, ``g_thetaM``
    Growth factors of the linear, bounded growth law (Method II only)::

        k(l) = k(l_a) * (1 + g * (l - l_a) / (l_b - l_a)),   0 <= g <= Q

    This set of functions is exactly the set of *linear* k(l) that are
    non-decreasing and satisfy ``k(l2) - k(l1) <= Q k(l1)`` for all
    ``l_a <= l1 < l2 <= l_b`` (the worst pair is ``(l_a, l_b)``).
``c_xf``, ``c_thetaM``
    Contact damping (N s/m, N m s/rad), same at every clamping length; fixed
    or sampled as the setup says.
``sigma_<j>``
    Relative noise scale of measurement ``j`` (dimensionless), see
    :mod:`.likelihood`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence  # noqa: F401

import numpy as np

from ..errors import SetupError
from .priors import PriorSet

__all__ = ["GrowthLaw", "ParameterLayout", "PARAMETER_UNITS"]

PARAMETER_UNITS = {
    "k_xf": "N/m",
    "k_thetaM": "N m/rad",
    "g_xf": "1",
    "g_thetaM": "1",
    "c_xf": "N s/m",
    "c_thetaM": "N m s/rad",
}

@dataclass(frozen=True)
class GrowthLaw:
    """Linear bounded growth of the contact stiffness with clamping length.

    Parameters
    ----------
    l_a, l_b : float
        m, feasible clamping range (``l_a < l_b``), or ``l_a == l_b`` for a
        single clamping length (no growth).
    growth_bound : float
        Q >= 0, the largest allowed relative increase over the range.
    """

    l_a: float
    l_b: float
    growth_bound: float = 0.5

    def __post_init__(self) -> None:
        if not (np.isfinite(self.l_a) and np.isfinite(self.l_b) and 0 < self.l_a <= self.l_b):
            raise SetupError(f"feasible clamping range [{self.l_a!r}, {self.l_b!r}] m: expected 0 < l_a <= l_b")
        if not (np.isfinite(self.growth_bound) and self.growth_bound >= 0):
            raise SetupError(f"growth_bound = {self.growth_bound!r}: expected a finite number >= 0")

    @property
    def has_growth(self) -> bool:
        return self.l_b > self.l_a

    def check_lengths(self, lengths: Sequence[float], what: str = "clamping length") -> None:
        """Raise :class:`SetupError` for lengths outside ``[l_a, l_b]``."""
        # 1 nm of slack absorbs decimal round-off of lengths written in files.
        tol = 1e-9
        for length in lengths:
            if not (self.l_a - tol <= length <= self.l_b + tol):
                raise SetupError(
                    f"{what} {length * 1e3:.4g} mm lies outside the feasible clamping range "
                    f"[{self.l_a * 1e3:.4g}, {self.l_b * 1e3:.4g}] mm (contact.clamping_range)"
                )

    def stiffness(self, k_ref, g, lengths) -> np.ndarray:
        """Stiffness at ``lengths`` for a batch of (k(l_a), g).

        Parameters
        ----------
        k_ref : (n,) stiffness at ``l_a``
        g : (n,) growth factors (ignored without growth)
        lengths : (n_len,) m

        Returns
        -------
        (n, n_len)
        """
        k_ref = np.asarray(k_ref, dtype=float)[:, None]
        lengths = np.asarray(lengths, dtype=float)[None, :]
        if not self.has_growth:
            return np.broadcast_to(k_ref, (k_ref.shape[0], lengths.shape[1])).copy()
        x = (lengths - self.l_a) / (self.l_b - self.l_a)
        return k_ref * (1.0 + np.asarray(g, dtype=float)[:, None] * x)


@dataclass(frozen=True)
class ParameterLayout:
    """Which parameters are sampled, which are fixed, and how they map to the model.

    Parameters
    ----------
    priors : PriorSet
        Sampled parameters in vector order.
    fixed : mapping of name to float
        Parameters held fixed (physical units), e.g. damping or, without
        growth, ``g_xf = g_thetaM = 0``.
    growth : GrowthLaw
    n_measurements : int
        Number of noise scales ``sigma_0 ... sigma_{n-1}`` (each must be in
        ``priors`` or ``fixed``).
    """

    priors: PriorSet
    fixed: Mapping[str, float] = field(default_factory=dict)
    growth: GrowthLaw = None  # type: ignore[assignment]
    n_measurements: int = 1

    def __post_init__(self) -> None:
        required = ["k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "c_thetaM"]
        required += [self.noise_name(j) for j in range(self.n_measurements)]
        for name in required:
            if (name in self.priors.names) == (name in self.fixed):
                raise SetupError(f"parameter {name!r} must be either sampled or fixed (exactly one)")
        if self.growth is None:
            raise SetupError("a parameter layout needs a growth law")

    @staticmethod
    def noise_name(j: int) -> str:
        return f"sigma_{j}"

    @property
    def names(self) -> tuple[str, ...]:
        return self.priors.names

    @property
    def ndim(self) -> int:
        return self.priors.ndim

    def values(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        """Physical values of all parameters, sampled and fixed, ``{name: (n,)}``."""
        theta = np.atleast_2d(theta)
        out = self.priors.to_physical(theta)
        n = theta.shape[0]
        for name, v in self.fixed.items():
            out[name] = np.full(n, float(v))
        return out

    def contact(self, theta: np.ndarray, lengths) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Contact parameters at ``lengths`` for a batch of parameter vectors.

        Parameters
        ----------
        theta : (n, ndim) sampling coordinates
        lengths : (n_cfg,) m, clamping length of every configuration

        Returns
        -------
        k_xf, k_thetaM, c_xf, c_thetaM : each (n, n_cfg)
        """
        v = self.values(theta)
        return self.contact_from_values(v, lengths)

    def contact_from_values(self, v: Mapping[str, np.ndarray], lengths):
        kx = self.growth.stiffness(v["k_xf"], v["g_xf"], lengths)
        kt = self.growth.stiffness(v["k_thetaM"], v["g_thetaM"], lengths)
        shape = kx.shape
        cx = np.broadcast_to(np.asarray(v["c_xf"], dtype=float)[:, None], shape)
        ct = np.broadcast_to(np.asarray(v["c_thetaM"], dtype=float)[:, None], shape)
        return kx, kt, cx, ct

    def noise(self, theta: np.ndarray) -> np.ndarray:
        """Relative noise scales, (n, n_measurements)."""
        v = self.values(theta)
        return np.column_stack([v[self.noise_name(j)] for j in range(self.n_measurements)])

    def sampled_units(self) -> dict[str, str]:
        return {n: PARAMETER_UNITS.get(n, "1") for n in self.names}
