"""``stiffness_step``: the contact engages a further zone at some clamping length (a step in the law).

The baseline growth law is linear in the normalised clamping length
``x = (l - l_a) / (l_b - l_a)``, ``k(l) = k_a (1 + g x)``.  The contact of a
tool shank in its holder is not one uniform band: a collet has slots and a
nose, a shrink-fit bore has a relief groove, a side-lock holder a flat.
While the shank's end lies in such a gap, more length adds little contact;
once it reaches the next bearing zone the stiffness rises over the
millimetres in which that zone comes into contact (the spread of form
error and surface roughness sets how sharply).  Between the two fitted
outer lengths the law is then a smooth step, here the normalised logistic

    T(x) = (sigma(r (x - c)) - sigma(-r c)) / (sigma(r (1 - c)) - sigma(-r c)),
    k(l) = k_a (1 + g T(x)),

with ``sigma`` the logistic function.  ``T(0) = 0`` and ``T(1) = 1`` keep
the stiffness at ``l_a`` and ``l_b``; the same ``T`` applies to ``k_xf``
and ``k_thetaM`` with their own growth factors (one engagement changes
both).  ``c`` is where the new zone engages (``l_s = l_a + c (l_b - l_a)``)
and ``r`` how sharply (the step rises over about ``4 / r`` of the range).
``T -> x`` as ``r -> 0`` (the linear law, the baseline, where the term adds
exactly zero).

What it can and cannot represent:

* a jump, or a steep rise, of the stiffness *between* the outermost fitted
  lengths, at any position and sharpness, including a jump that also
  changes the slope of the law (the relative jump of ``(1 + g x)(1 + m H)``
  is matched at the measured lengths by ``c`` and ``r``);
* not a law that bends without a step (``c`` at a bound of [0, 1] is then
  the fit: at ``c = 0`` the logistic is a saturating ``tanh`` shape, at
  ``c = 1`` a progressive one).  That is ``nonlinear_stiffness_law``; a fit
  with ``c`` on its bound is rejected by the workflow as a surrogate;
* nothing with fewer than three clamping lengths: with two, the ends fix
  the law and a step between them is invisible (score 0), like every law
  shape;
* not a step outside the fitted range (an extrapolation cannot see it).

Parameters
----------
``stiffness_step_position`` (1)
    ``c``, the engagement position in normalised clamping length, uniform on
    [0, 1] (a step outside the fitted lengths is not identifiable from
    them); baseline 0.5 (irrelevant at ``r = 0``).
``stiffness_step_sharpness`` (1)
    ``r``, uniform on [0, 60]; baseline 0, the linear law.  At ``r = 60``
    the rise spans about 7 % of the range (1 mm of a 15 mm range), sharper
    than measured lengths a few millimetres apart can resolve.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import Contact, ModelTerm, bend_growth_law

__all__ = ["StiffnessStep", "step_shape"]

#: Below this sharpness the shape is the linear law to within r^2/48 (series of the logistic).
_LINEAR_BELOW = 1e-6


def step_shape(c: np.ndarray, r: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Normalised logistic step ``T(x)``, exactly ``x`` where ``r`` is (nearly) 0.

    Parameters
    ----------
    c : (n_sets, 1) engagement positions, normalised length
    r : (n_sets, 1) sharpness, dimensionless
    x : (1, n_cfg) normalised clamping lengths

    Returns
    -------
    (n_sets, n_cfg)

    Notes
    -----
    Differences of logistics are formed as differences of ``tanh`` of half
    the argument, which keeps full precision for small ``r`` (no
    cancellation of two numbers near 1/2).
    """
    c = np.asarray(c, dtype=float)
    r = np.asarray(r, dtype=float)
    x = np.asarray(x, dtype=float)
    linear = np.abs(r) < _LINEAR_BELOW
    r_safe = np.where(linear, 1.0, r)
    lo = np.tanh(-0.5 * r_safe * c)
    num = np.tanh(0.5 * r_safe * (x - c)) - lo
    den = np.tanh(0.5 * r_safe * (1.0 - c)) - lo
    return np.where(linear, x, num / den)


@register_term
class StiffnessStep(ModelTerm):
    """A smooth step of the contact-stiffness law between the fitted lengths (joint kind)."""

    name = "stiffness_step"
    kind = "joint"
    min_clamping_lengths = 3  # the law keeps its ends: invisible with two lengths
    description = ("the contact stiffness rises in a step at some clamping length, where the shank reaches a "
                   "further contact zone of the holder (past a collet slot, a relief groove)")

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter("stiffness_step_position", unit="1", role="term", prior=Uniform(0.0, 1.0),
                      label="stiffness step position c", baseline=0.5, term=self.name,
                      description="engagement at l_a + c (l_b - l_a)"),
            Parameter("stiffness_step_sharpness", unit="1", role="term", prior=Uniform(0.0, 60.0),
                      label="stiffness step sharpness r", baseline=0.0, term=self.name,
                      description="k(l) = k_a (1 + g T_{c,r}(x)), normalised logistic; r = 0 is the linear law"),
        )

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths, l_a: float, l_b: float) -> Contact:
        """Contact stiffness on the stepped law.

        Adds ``k_a g (T(x) - x)`` to the incoming (linear-law) stiffness, so
        other joint terms applied before this one are kept.

        Parameters
        ----------
        values : needs ``stiffness_step_position``, ``stiffness_step_sharpness``, ``k_xf``, ``k_thetaM``,
            ``g_xf``, ``g_thetaM``, each (n_sets,)
        contact : Contact, fields (n_sets, n_cfg)
        lengths : (n_cfg,) m
        l_a, l_b : m, the growth law's range

        Raises
        ------
        ModelError
            If the growth parameters are not in ``values``.
        """
        c = np.asarray(values["stiffness_step_position"], dtype=float)[:, None]
        r = np.asarray(values["stiffness_step_sharpness"], dtype=float)[:, None]
        return bend_growth_law(self.name, values, contact, lengths, l_a, l_b, lambda x: step_shape(c, r, x))
