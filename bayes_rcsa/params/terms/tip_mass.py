"""Model term ``tip_mass``: a small mass (e.g. an accelerometer) at the tool tip.

Physics
-------
A rigid body of mass ``m`` at the tip node adds the dynamic stiffness
``Z = -omega^2 diag(m, J)`` to the tip's (u, psi) degrees of freedom, with
the rotary inertia ``J = m r_g^2``.  The radius of gyration ``r_g`` is half
the tool's tip diameter (the last tool segment's ``diameter``), i.e. a mass
whose inertia about the tool's transverse axis is that of a point mass on
the tool's circumference (the synthetic bench's default, 4 mm for the
7.94 mm end mill).  Adding ``Z`` at end 2 of the tool-overhang two-port
``R`` gives, by the Woodbury identity with ``W = Z (I + R22 Z)^-1``::

    R11' = R11 - R12 W R21      R12' = R12 - R12 W R22
    R21' = R21 - R22 W R21      R22' = R22 - R22 W R22

which stays reciprocal and passive for ``m >= 0`` and is exactly ``R``
for ``m = 0`` (the baseline).  The term hands ``Z`` to the forward model as
the substructures' tip impedance (:meth:`Substructures.add_tip`): the
forward model applies it to the assembled tool-point block,
``H' = H (I + Z H)^-1`` (the same physics, the tool two-port staying shared
by all parameter sets), or folds it into the tool two-port with
:func:`bayes_rcsa.model.coupling.add_end_impedance` when another term has changed a substructure.

Parameter
---------
``tip_mass_kg`` (kg): default prior uniform on [0, 0.02] kg, baseline 0.
The lower bound is the baseline so the term can vanish; 20 g covers
miniature accelerometers (0.5-10 g) with margin.  Override in the setup::

    [model]
    terms = ["tip_mass"]
    tip_mass_kg = [0.0, 0.005]          # uniform bounds, kg
    # or: tip_mass_kg = 0.0021          # fixed, e.g. the sensor's data-sheet mass
"""

from __future__ import annotations

import numpy as np

from ...model.coupling import add_end_impedance
from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import ModelTerm

__all__ = ["TipMass", "tip_radius_of_gyration", "add_end_impedance"]


def tip_radius_of_gyration(model, configurations) -> np.ndarray:
    """Radius of gyration (m) per configuration: half the tip diameter of its tool, (n_cfg,)."""
    return np.array([0.5 * model.tool(c.tool).segments[-1].diameter for c in configurations], dtype=float)


@register_term
class TipMass(ModelTerm):
    """Point mass and rotary inertia at the tool tip (see the module docstring)."""

    name = "tip_mass"
    kind = "substructure"
    description = "a small mass such as an accelerometer at the tool tip (mass m, rotary inertia m r_g^2)"
    parameter_name = "tip_mass_kg"

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (Parameter(self.parameter_name, "kg", "term", prior=Uniform(0.0, 0.02), label="tip mass (kg)",
                          baseline=0.0, term=self.name,
                          description="mass at the tool tip; rotary inertia m (d_tip / 2)^2"),)

    def substructures(self, values, subs, ctx):
        m = np.asarray(values[self.parameter_name], dtype=float)
        if not np.any(m):
            return subs  # the baseline: nothing to add (and nothing recomputed)
        rg = tip_radius_of_gyration(ctx.model, ctx.configurations)[ctx.line_config]  # (n_lines,)
        z_u = -m[:, None] * (ctx.omega**2)[None, :]  # (n_sets, n_lines) N/m
        z_psi = z_u * (rg**2)[None, :]
        return subs.add_tip(z_u, z_psi)
