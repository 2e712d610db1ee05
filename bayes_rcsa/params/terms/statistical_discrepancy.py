"""A statistical discrepancy term for what no named effect explains (Kennedy & O'Hagan, 2001).

When no candidate clears the bar, the workflow adds this term and refits,
so that the contact-stiffness and natural-frequency intervals account for
a model that is known to be imperfect.

Structure (and why)
-------------------
Kennedy & O'Hagan write the measurement as ``model(theta) + delta + noise``
with a Gaussian-process discrepancy ``delta``.  Brynjarsdóttir & O'Hagan
(2014) showed that a discrepancy *without* prior structure can mimic any
change of the physical parameters, which then become unidentifiable: the
posterior of the stiffness is as wide as its prior and not centred on
anything physical.  The structure imposed here keeps the physical
parameters in charge of what they are good at (placing resonances):

* **multiplicative** and complex: ``H = H_model (1 + delta(f))``, so the
  discrepancy scales with the response and is zero where the model is zero;
* **smooth** across the whole frequency range: ``delta`` is a combination of
  the first ``K = 3`` Chebyshev polynomials ``T_k(x)`` of the normalised
  frequency ``x in [-1, 1]`` over the spindle file's range, with complex
  coefficients ``a_k + i b_k`` (a Gaussian process with a degenerate,
  very smooth covariance, ``Cov delta(f) delta(f')^* = sigma_d^2 sum T_k(x) T_k(x')``);
* **shared** by all measurements (clamping lengths, directions): one
  smooth gain/phase error of the measurement chain or of the spindle file;
* **shrunk**: every coefficient has a Normal(0, ``sigma_d = 0.05``) prior,
  i.e. a few per cent of gain or phase error is plausible, tens of per
  cent are not.

What it can absorb: calibration and sensitivity errors, a slow phase drift
(e.g. an unmodelled time delay or an anti-aliasing filter), smooth
gain trends from out-of-band modes.  What it cannot absorb (by
construction): a resonance in the wrong place or with the wrong width --
the residual of a shifted peak changes sign across a few half-power
bandwidths, far sharper than a quadratic over the whole range -- and any
effect that differs between clamping lengths.  Those stay in the residuals,
where the likelihood's tempering by the residual correlation length
(docs/identification.md) widens the intervals; the term's own parameters,
marginalised in the Laplace/MCMC posterior, widen them further where a
smooth gain error trades off against the stiffness.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import Normal
from .base import ModelTerm
from . import register_term

__all__ = ["StatisticalDiscrepancy", "N_BASIS", "PRIOR_SD"]

N_BASIS = 3
PRIOR_SD = 0.05


def _names():
    return [f"discrepancy_{part}_{k}" for k in range(N_BASIS) for part in ("re", "im")]


@register_term
class StatisticalDiscrepancy(ModelTerm):
    """Smooth multiplicative complex discrepancy shared by all measurements (frf kind, role discrepancy)."""

    name = "statistical_discrepancy"
    kind = "frf"
    role = "discrepancy"
    description = ("an unexplained smooth gain/phase error of the whole model (statistical discrepancy, "
                   "Kennedy-O'Hagan), used when no physical effect explains the data")

    def parameters(self, model) -> tuple[Parameter, ...]:
        out = []
        for n in _names():
            k = int(n.rsplit("_", 1)[1])
            part = "real" if "_re_" in n else "imaginary"
            out.append(Parameter(n, unit="1", role="discrepancy", prior=Normal(0.0, PRIOR_SD), baseline=0.0,
                                 term=self.name, label=f"discrepancy {part} T{k}",
                                 description=f"{part} part of the Chebyshev-T{k} coefficient of the relative discrepancy"))
        return tuple(out)

    @staticmethod
    def basis(ctx) -> np.ndarray:
        """Chebyshev polynomials T_0..T_{K-1} on the stacked lines, (K, n_lines)."""
        spindles = ctx.model.spindle.values()
        lo = min(float(r.frequency_hz[0]) for r in spindles)
        hi = max(float(r.frequency_hz[-1]) for r in spindles)
        x = (2 * np.asarray(ctx.frequency_hz, dtype=float) - (lo + hi)) / (hi - lo)
        return np.polynomial.chebyshev.chebvander(x, N_BASIS - 1).T

    def frf(self, values: Mapping[str, np.ndarray], h: np.ndarray, ctx) -> np.ndarray:
        """``h (1 + delta)``, (n_sets, n_lines) complex; exactly ``h`` at zero coefficients."""
        t = self.basis(ctx)
        coef = np.stack([np.asarray(values[f"discrepancy_re_{k}"], dtype=float)
                         + 1j * np.asarray(values[f"discrepancy_im_{k}"], dtype=float) for k in range(N_BASIS)], axis=1)
        delta = coef @ t  # (n_sets, n_lines)
        return h + h * delta
