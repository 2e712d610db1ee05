"""The bounded linear growth law of the contact stiffness with clamping length.

For Method II (several clamping lengths) the sampled stiffness is the one at
``l_a``, the short end of the feasible range, and::

    k(l) = k(l_a) * (1 + g * (l - l_a) / (l_b - l_a)),   0 <= g <= Q

This set of functions is exactly the set of *linear* k(l) that are
non-decreasing and satisfy ``k(l2) - k(l1) <= Q k(l1)`` for all
``l_a <= l1 < l2 <= l_b`` (the worst pair is ``(l_a, l_b)``).  With a single
clamping length (``l_a == l_b``) the stiffness is the same at every length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import SetupError

__all__ = ["GrowthLaw"]


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
