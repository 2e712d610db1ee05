"""``nonlinear_stiffness_law``: the contact stiffness saturates with clamping length.

The baseline growth law is linear in the normalised clamping length
``x = (l - l_a) / (l_b - l_a)``::

    k(l) = k_a (1 + g x)

A real collet or shrink fit often gains most of its stiffness in the first
millimetres of engagement and little after that.  This term replaces ``x``
by the saturating shape

    S_s(x) = (1 - exp(-s x)) / (1 - exp(-s)),    k(l) = k_a (1 + g S_s(x))

which keeps the stiffness at ``l_a`` and ``l_b`` (``S_s(0) = 0``,
``S_s(1) = 1``) and bends the law in between: ``s > 0`` saturating (stiffer
at intermediate lengths), ``s < 0`` progressive (softer in between).  The
same ``s`` applies to ``k_xf`` and ``k_thetaM`` with their own growth
factors ``g_xf``, ``g_thetaM``.  ``S_s(x) -> x`` as ``s -> 0``; it is
evaluated with ``expm1`` so that small ``s`` keeps full precision, and at
``s = 0`` exactly the term adds exactly zero.

The term only has an effect with two or more clamping lengths
(``l_b > l_a``) and a non-zero growth factor; it needs the growth factors
``g_xf``, ``g_thetaM`` and the reference stiffnesses ``k_xf``, ``k_thetaM``
in ``values`` (the parameter model passes every parameter's values).

Parameter
---------
``stiffness_saturation`` (1)
    Saturation rate s.  Prior uniform on [-8, 8] (at |s| = 8 the law is
    within 0.03 % of a step at one end of the range, so wider is
    meaningless); baseline 0 (the linear law).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import Contact, ModelTerm, bend_growth_law

__all__ = ["NonlinearStiffnessLaw", "saturating_shape"]


def saturating_shape(s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``(1 - exp(-s x)) / (1 - exp(-s))``, and ``x`` where ``s == 0``.

    Parameters
    ----------
    s : (n_sets, 1) saturation rates, dimensionless
    x : (1, n_cfg) normalised clamping lengths

    Returns
    -------
    (n_sets, n_cfg)
    """
    s = np.asarray(s, dtype=float)
    x = np.asarray(x, dtype=float)
    zero = s == 0.0
    s_safe = np.where(zero, 1.0, s)
    with np.errstate(over="ignore", invalid="ignore"):
        shape = np.expm1(-s_safe * x) / np.expm1(-s_safe)
    return np.where(zero, x, shape)


@register_term
class NonlinearStiffnessLaw(ModelTerm):
    """Saturating (or progressive) contact-stiffness law over the clamping range (joint kind)."""

    name = "nonlinear_stiffness_law"
    kind = "joint"
    min_clamping_lengths = 3  # the law keeps its ends: invisible with two lengths
    description = ("the contact stiffness does not grow linearly with clamping length: it gains most of its "
                   "stiffness early (saturating) or late (progressive)")

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter("stiffness_saturation", unit="1", role="term", prior=Uniform(-8.0, 8.0),
                      label="stiffness-law saturation s", baseline=0.0, term=self.name,
                      description="k(l) = k_a (1 + g (1 - exp(-s x)) / (1 - exp(-s))); s = 0 is the linear law"),
        )

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths, l_a: float, l_b: float) -> Contact:
        """Contact stiffness on the saturating law.

        Adds ``k_a g (S_s(x) - x)`` to the incoming (linear-law) stiffness,
        so other joint terms applied before this one are kept.

        Parameters
        ----------
        values : needs ``stiffness_saturation``, ``k_xf``, ``k_thetaM``, ``g_xf``, ``g_thetaM``, each (n_sets,)
        contact : Contact, fields (n_sets, n_cfg)
        lengths : (n_cfg,) m
        l_a, l_b : m, the growth law's range

        Raises
        ------
        ModelError
            If the growth parameters are not in ``values``.
        """
        s = np.asarray(values["stiffness_saturation"], dtype=float)[:, None]
        return bend_growth_law(self.name, values, contact, lengths, l_a, l_b, lambda x: saturating_shape(s, x))
