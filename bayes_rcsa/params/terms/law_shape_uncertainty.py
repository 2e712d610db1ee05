"""``law_shape_uncertainty``: the contact law between the fitted lengths, anywhere between the two published interface laws.

The growth law of the setup is linear in the normalised clamping length
``x = (l - l_a) / (l_b - l_a)``: ``k(l) = k_a (1 + g x)``.  When the
discrepancy workflow names no effect, nothing confirms that law *between*
(or beyond) the fitted lengths, but physics still bounds it once its ends
``k_a`` and ``k_b = k_a (1 + g)`` are fixed by the data.  Two interface
models are published, and each fixes the law between the ends:

* **distributed contact in parallel** (the reference paper's assumption):
  the engaged length adds springs side by side, so the *stiffness* is an
  affine function of ``l`` -- the linear law, ``shape(x) = x``;
* **two springs in series** (the two-spring model of Matthias et al. cited
  by the reference paper): the collet-to-holder contact ``k_1``, independent
  of the clamping length, in series with the tool-to-collet contact
  ``c l``, so the *compliance* is an affine function of ``1 / l``:
  ``1/k = 1/k_1 + 1/(c l)``.  Through the same ends, with ``L = l_b / l_a``
  and ``S_L(x) = x L / (1 + x (L - 1))`` (which is ``(1/l_a - 1/l) /
  (1/l_a - 1/l_b)``),

      shape_series(x) = S_L(x) / (1 + g (1 - S_L(x))).

A real interface is a combination of both mechanisms, so its law lies
between them.  This term takes

    shape(x) = x + u (shape_series(x) - x),     k(l) = k_a (1 + g shape(x)),

with ``u`` uniform on [0, 1], per coordinate (``k_xf`` with ``g_xf``,
``k_thetaM`` with ``g_thetaM``) through the same ``u``.  At ``u = 0`` the
term adds exactly zero; the law's ends are kept for every ``u``.

How far the two laws are apart follows from the measured growth, not from
a chosen width: a contact that barely grows (``g`` near 0) is dominated by
the collet spring, and the series law is then the full saturation
``S_L``; a contact that grows in proportion to the engaged length
(``g = L - 1``, i.e. ``k_1`` infinite) makes both laws the same straight
line.  With 25 and 40 mm (``L = 1.6``) and ``g = 0.45`` they differ by
2 % of the growth at 30 mm; with ``g = 0.1``, by 9 %.  A growth faster than
proportional (``g > L - 1``) would need a negative collet stiffness in
series; the formula then bends the other way (convex), which is kept as the
same interpolation of compliance rather than refused, since the bend is
small there.  Beyond the fitted range the series law stiffens without
bound where ``g (S_L(x) - 1) >= 1`` (only for ``g > L - 1`` and far
lengths); a length there raises :class:`~bayes_rcsa.errors.ModelError`.

Role: ``discrepancy``.  It is not a named explanation (it is never a
candidate of the workflow); the unexplained remainder adds it so that a
prediction between or beyond the fitted lengths carries the law shapes the
physics allows, and no more.  An earlier form bent the law by up to the
full saturation ``S_L`` either way whatever the growth; on the rotor bench
(docs/discrepancy.md) its held-out intervals were about four times wider
than the errors and covered every held-out mode.

It cannot represent a step (a further contact zone: ``stiffness_step``) or
a saturation sharper than the series law (``nonlinear_stiffness_law``);
those are named effects and need three or more clamping lengths.

Parameter
---------
``law_shape_bend`` (1)
    ``u``, uniform on [0, 1]: 0 the parallel (linear) law, 1 the series
    law through the same ends; baseline 0.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ...errors import ModelError
from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import Contact, ModelTerm

__all__ = ["LawShapeUncertainty", "two_spring_limit", "series_law_shape", "BEND"]

#: The term's one parameter, ``u`` (pooled by a tool library, given a prior by the discrepancy workflow).
BEND = "law_shape_bend"


def two_spring_limit(x: np.ndarray, ratio: float) -> np.ndarray:
    """Normalised saturating limit of the two-spring law, ``x L / (1 + x (L - 1))``.

    Parameters
    ----------
    x : array, normalised clamping lengths ``(l - l_a) / (l_b - l_a)``
    ratio : ``L = l_b / l_a`` > 1

    Returns
    -------
    array like ``x``: 0 at ``x = 0``, 1 at ``x = 1``, concave for ``L > 1``.
    """
    x = np.asarray(x, dtype=float)
    return x * ratio / (1.0 + x * (ratio - 1.0))


def series_law_shape(x: np.ndarray, ratio: float, growth: np.ndarray) -> np.ndarray:
    """Normalised law of two springs in series through the ends ``k_a`` and ``k_a (1 + g)``: ``S_L / (1 + g (1 - S_L))``.

    Parameters
    ----------
    x : (1, n_cfg) normalised clamping lengths ``(l - l_a) / (l_b - l_a)``
    ratio : ``L = l_b / l_a`` > 1
    growth : (n_sets, 1) relative growth ``g`` of the stiffness between the ends, 1

    Returns
    -------
    (n_sets, n_cfg) array: 0 at ``x = 0``, 1 at ``x = 1``; ``x`` itself where ``g = L - 1``.

    Raises
    ------
    ModelError
        Where the series law has no finite stiffness (``1 + g (1 - S_L) <= 0``: a growth faster than
        proportional, extrapolated far beyond ``l_b``).
    """
    s = two_spring_limit(x, ratio)
    den = 1.0 + growth * (1.0 - s)
    if np.any(den <= 0.0):
        raise ModelError(f"law_shape_uncertainty: the series (two-spring) law through the fitted ends has no finite "
                         f"stiffness at normalised length {float(np.max(x)):.3g} for growth {float(np.max(growth)):.3g}; "
                         "predict closer to the fitted lengths")
    return s / den


@register_term
class LawShapeUncertainty(ModelTerm):
    """The law between the fitted lengths, anywhere between the parallel and the series interface law (joint kind, discrepancy role)."""

    name = "law_shape_uncertainty"
    kind = "joint"
    role = "discrepancy"
    min_clamping_lengths = 2  # one length has no law between lengths to bend
    description = ("the contact-stiffness law between the measured clamping lengths, anywhere between the "
                   "distributed (parallel, linear) and the two-spring (series) interface law through the same ends")

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter(BEND, unit="1", role="discrepancy", prior=Uniform(0.0, 1.0),
                      label="law bend u", baseline=0.0, term=self.name,
                      description="position of the law between the parallel (0) and the series (1) interface law"),
        )

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths, l_a: float, l_b: float) -> Contact:
        """Contact stiffness on the bent law (``k_a g u (shape_series(x) - x)`` added to the incoming one).

        Parameters
        ----------
        values : needs ``law_shape_bend``, ``k_xf``, ``k_thetaM``, ``g_xf``, ``g_thetaM``, each (n_sets,)
        contact : Contact, fields (n_sets, n_cfg)
        lengths : (n_cfg,) m
        l_a, l_b : m, the growth law's range
        """
        if not l_b > l_a:
            return contact  # one clamping length: no law between lengths to bend
        missing = [n for n in (BEND, "k_xf", "k_thetaM", "g_xf", "g_thetaM") if n not in values]
        if missing:
            raise ModelError(f"model term {self.name}: needs {missing} in its values")
        u = np.asarray(values[BEND], dtype=float)[:, None]
        x = ((np.asarray(lengths, dtype=float) - l_a) / (l_b - l_a))[None, :]
        fields = {}
        # each coordinate has its own growth and hence its own series law through its own ends
        for k_name, g_name in (("k_xf", "g_xf"), ("k_thetaM", "g_thetaM")):
            k_a = np.asarray(values[k_name], dtype=float)[:, None]
            g = np.asarray(values[g_name], dtype=float)[:, None]
            bend = u * (series_law_shape(x, l_b / l_a, g) - x)
            fields[k_name] = np.asarray(getattr(contact, k_name)) + k_a * g * bend
        return contact._replace(**fields)
