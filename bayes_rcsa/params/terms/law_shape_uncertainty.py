"""``law_shape_uncertainty``: the contact law's bend between the fitted lengths, bounded by the two-spring model.

The growth law of the setup is linear in the normalised clamping length
``x = (l - l_a) / (l_b - l_a)``: ``k(l) = k_a (1 + g x)``.  When the
discrepancy workflow names no effect, nothing confirms that law *between*
the fitted lengths either, but physics still bounds how far it can bend.
The tool–holder interface is two springs in series (the two-spring model of
Matthias et al. cited by the reference paper): the collet-to-holder contact
``k_1``, independent of the clamping length, and the tool-to-collet contact
``k_2 = c l``, proportional to the engaged length.  Their series stiffness

    k(l) = k_1 c l / (k_1 + c l)

runs, for a given ratio ``l_b / l_a = L``, from the linear law (``c l <<
k_1``: the tool contact dominates the compliance) to the saturating limit
(``c l >> k_1``), whose normalised shape is

    S_L(x) = x L / (1 + x (L - 1)),      S_L(0) = 0,  S_L(1) = 1.

This term bends the law by a fraction ``u`` of that limit,

    shape(x) = x + u (S_L(x) - x),       k(l) = k_a (1 + g shape(x)),

``u`` uniform on [-1, 1]: up to the full saturation the two-spring model
allows and, as a conservative mirror, as much the other way (a contact
that gains stiffness late, e.g. a collet nose that grips last).  The same
``u`` applies to ``k_xf`` and ``k_thetaM`` with their own growth factors.
At ``u = 0`` the term adds exactly zero; the law's ends are kept.

Role: ``discrepancy``.  It is not a named explanation (it is never a
candidate of the workflow); the unexplained remainder adds it so that a
prediction between or beyond the fitted lengths carries the law shapes the
physics allows, and no more.  With ``L = 1.6`` (25 and 40 mm) the
saturating limit is ``S(0.5) = 0.615`` against the linear 0.5, i.e. at most
about 12 % of the growth between the ends at mid-range.

It cannot represent a step (a further contact zone: ``stiffness_step``) or
a saturation sharper than the two-spring limit (``nonlinear_stiffness_law``);
those are named effects and need three or more clamping lengths.

Parameter
---------
``law_shape_bend`` (1)
    ``u``, uniform on [-1, 1]; baseline 0 (the linear law).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import Contact, ModelTerm, bend_growth_law

__all__ = ["LawShapeUncertainty", "two_spring_limit"]


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


@register_term
class LawShapeUncertainty(ModelTerm):
    """The law's bend between the fitted lengths within the two-spring model's range (joint kind, discrepancy role)."""

    name = "law_shape_uncertainty"
    kind = "joint"
    role = "discrepancy"
    min_clamping_lengths = 2  # one length has no law between lengths to bend
    description = ("the contact-stiffness law between the measured clamping lengths, bent as far as a "
                   "two-spring (collet and tool contact in series) interface allows, either way")

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter("law_shape_bend", unit="1", role="discrepancy", prior=Uniform(-1.0, 1.0),
                      label="law bend u", baseline=0.0, term=self.name,
                      description="fraction of the two-spring saturating limit by which the law bends"),
        )

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths, l_a: float, l_b: float) -> Contact:
        """Contact stiffness on the bent law (``k_a g u (S_L(x) - x)`` added to the incoming one).

        Parameters
        ----------
        values : needs ``law_shape_bend``, ``k_xf``, ``k_thetaM``, ``g_xf``, ``g_thetaM``, each (n_sets,)
        contact : Contact, fields (n_sets, n_cfg)
        lengths : (n_cfg,) m
        l_a, l_b : m, the growth law's range
        """
        u = np.asarray(values["law_shape_bend"], dtype=float)[:, None]
        ratio = l_b / l_a if l_a > 0 else 1.0
        return bend_growth_law(self.name, values, contact, lengths, l_a, l_b,
                               lambda x: x + u * (two_spring_limit(x, ratio) - x))
