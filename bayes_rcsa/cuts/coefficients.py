"""Prior of the cutting coefficients of an update: a force level and a ratio.

``--kt 560e6±30%`` has the meaning it has in ``bayes-rcsa lobes``: the
tolerance is on the *cutting-force level*, which scales K_t and K_r together.
``--kr 170e6±20%`` adds an independent spread of the *ratio* K_r/K_t.  With
``u`` the log level and ``δ`` the log ratio offset,

    K_t = K_t0 e^u,    K_r = K_r0 e^(u + δ),
    u ~ Normal(0, ln(1 + tol_t)),    δ ~ the ratio prior (below).

The stability limits are exactly inversely proportional to the level at a
fixed ratio (:mod:`bayes_rcsa.stability.coefficients`), so ``u`` costs
nothing to vary; every ratio value costs one evaluation of the stability
method on all draws.  The ratio prior is therefore a discrete distribution on
``nodes`` equally probable values, the midpoint quantiles
``δ_j = σ_r Φ^-1((j + 1/2)/n)`` of Normal(0, σ_r = ln(1 + tol_r)).  Linear
interpolation of the limits between ratio nodes was measured and rejected:
near lobe crossings it misses the limit by up to 9 % (immersion 0.5) and
100 % (immersion 0.2) for a ±30 % ratio.

Small object in the style of the identification's priors: :meth:`sample`,
:meth:`ln_prob`, :meth:`bounds`, :meth:`describe`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError

__all__ = ["CoefficientPrior", "DEFAULT_RATIO_NODES"]

#: Ratio nodes when --kr carries a tolerance (5 equally probable values of K_r/K_t; each costs one method call).
DEFAULT_RATIO_NODES = 5


@dataclass(frozen=True)
class CoefficientPrior:
    """Prior of (K_t, K_r).

    Attributes
    ----------
    kt, kr : float, Pa, the assumed (median) coefficients
    level_sd : float >= 0, standard deviation of ln(level) (0: the level is fixed)
    ratio_sd : float >= 0, standard deviation of ln(K_r/K_t) (0: the ratio is fixed)
    nodes : int >= 1, number of ratio values when ``ratio_sd > 0``
    """

    kt: float
    kr: float
    level_sd: float = 0.0
    ratio_sd: float = 0.0
    nodes: int = DEFAULT_RATIO_NODES

    def __post_init__(self) -> None:
        if not (math.isfinite(self.kt) and self.kt > 0 and math.isfinite(self.kr) and self.kr > 0):
            raise SetupError(f"cutting coefficients kt={self.kt!r}, kr={self.kr!r} Pa: expected finite values > 0")
        for name in ("level_sd", "ratio_sd"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 <= v < 1.0):
                raise SetupError(f"{name}={v!r}: expected a log standard deviation in [0, 1)")
        if int(self.nodes) != self.nodes or self.nodes < 1:
            raise SetupError(f"nodes={self.nodes!r}: expected an integer >= 1")

    @classmethod
    def from_tolerances(cls, kt: float, kt_tol: float, kr: float, kr_tol: float,
                        nodes: int = DEFAULT_RATIO_NODES) -> "CoefficientPrior":
        """From ``--kt V±tol_t --kr V±tol_r`` (relative tolerances): sd = ln(1 + tol)."""
        return cls(float(kt), float(kr), math.log1p(kt_tol), math.log1p(kr_tol), int(nodes))

    @property
    def ratio_offsets(self) -> np.ndarray:
        """(n_nodes,) δ_j, log offsets of K_r/K_t from K_r0/K_t0 (one node, 0, when the ratio is fixed)."""
        if self.ratio_sd == 0 or self.nodes == 1:
            return np.zeros(1)
        from scipy.special import ndtri

        return self.ratio_sd * ndtri((np.arange(self.nodes) + 0.5) / self.nodes)

    @property
    def ratios(self) -> np.ndarray:
        """(n_nodes,) K_r/K_t at the nodes."""
        return self.kr / self.kt * np.exp(self.ratio_offsets)

    @property
    def sampled(self) -> bool:
        return self.level_sd > 0 or self.ratio_offsets.size > 1

    def sample(self, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` draws: log level ``u`` (n,) and ratio node index (n,) int."""
        u = rng.normal(0.0, self.level_sd, n) if self.level_sd > 0 else np.zeros(n)
        node = rng.integers(0, self.ratio_offsets.size, n)
        return u, node

    def ln_prob(self, u, node) -> np.ndarray:
        """Log density of ``u`` (times the node probability 1/n_nodes); -inf outside the support."""
        u = np.asarray(u, dtype=float)
        node = np.asarray(node)
        m = self.ratio_offsets.size
        ok = (node >= 0) & (node < m)
        if self.level_sd > 0:
            lp = -0.5 * (u / self.level_sd) ** 2 - math.log(self.level_sd * math.sqrt(2 * math.pi))
        else:
            lp = np.where(u == 0, 0.0, -np.inf)
        return np.where(ok, lp - math.log(m), -np.inf)

    def coefficients(self, u, node) -> tuple[np.ndarray, np.ndarray]:
        """(K_t, K_r) in Pa of draws (u, node)."""
        u = np.asarray(u, dtype=float)
        return self.kt * np.exp(u), self.kr * np.exp(u + self.ratio_offsets[np.asarray(node)])

    def bounds(self) -> tuple[float, float]:
        """Support of the log level ``u``."""
        return (-math.inf, math.inf) if self.level_sd > 0 else (0.0, 0.0)

    def describe(self) -> dict:
        return {"kt_pa": self.kt, "kr_pa": self.kr, "level_log_sd": self.level_sd, "ratio_log_sd": self.ratio_sd,
                "ratio_nodes": [float(r) for r in self.ratios],
                "meaning": "K_t = kt e^u, K_r = kr e^(u + delta); u ~ Normal(0, level_log_sd), delta on equally "
                           "probable ratio nodes (midpoint quantiles of Normal(0, ratio_log_sd))"}
