"""Model term ``tip_mass``: a small rigid body (e.g. an accelerometer) at the tool tip.

Physics
-------
A rigid body of mass ``m`` fixed to the tip section, its centre of mass
an axial distance ``e`` from the tip node (``e > 0`` beyond the tip, ``e < 0``
towards the holder, e.g. a sensor glued on the flank flush with the tip)
and its own rotary inertia ``m r_g^2`` about its centre (transverse axis;
``r_g`` = half the tool's tip diameter, a body the size of the tool on its
flank), moves with the tip section as ``u_c = u + e psi``.  Its kinetic energy gives
the 2x2 mass matrix at the tip's (u, psi)::

    M = m [[1, e], [e, e^2 + r_g^2]],      Z = -w^2 M

which is positive semi-definite for every ``m >= 0`` (so passive and
reciprocal) and zero for ``m = 0`` (the baseline).  ``Z`` is added at end 2
of the tool-overhang two-port ``R`` by the Woodbury identity with
``W = Z (I + R22 Z)^-1``::

    R11' = R11 - R12 W R21      R12' = R12 - R12 W R22
    R21' = R21 - R22 W R21      R22' = R22 - R22 W R22

For ``e = 0`` ``Z`` is diagonal and is handed to the forward model as the
substructures' tip impedance (:meth:`Substructures.add_tip`; the tool
two-port then stays shared by all parameter sets, the cheap path); for
``e != 0`` the term folds the full ``Z`` into the tool two-port.

Why the offset.  The former term fixed ``e = 0``.  On the independent
rotor bench (a 3 g cylinder on the flank, flush with the tip) it left
k_thetaM 2.6 times too stiff with its growth on the prior bound
(noise-free, 25/40 mm, x/y), and the discrepancy workflow named
``fluted_section`` instead.  With the offset the rotor bench's gap closes
0.040 -> 0.0002 with the contact at its truth (fitted ``e`` = -3.5 mm,
``m`` = 3.03 g), and the workflow names ``tip_mass`` (gap 0.046 -> noise
floor).  A free ``r_g`` as a third parameter was tried: it made the bench's
body of ``r_g`` = 8 mm exact (the fixed ``r_g`` closes its gap
0.042 -> 0.0004 but biases k_thetaM by +11 %), but ``e`` and ``r_g`` are
nearly degenerate (the rotary inertia ``m (e^2 + r_g^2)`` is what the data
see) and on noisy bench campaigns the fit ran ``r_g`` onto its bound 0.

Parameters
----------
``tip_mass_kg`` (kg): prior uniform on [0, 0.02] kg, baseline 0.  20 g
    covers miniature accelerometers (0.5-10 g) with margin.
``tip_mass_offset_m`` (m): axial offset ``e`` of the body's centre of mass
    from the tip node.  Prior uniform on [-0.01, 0.01] m (a body of at most
    2 cm mounted on the flank or the end face); baseline 0.

Without a model (``parameters(None)``, e.g. a hand-made parameter model)
only ``tip_mass_kg`` is declared and the hook uses ``e = 0``, the former
term exactly; so does any caller that omits the offset.

Validation: systematic gap before -> after (workflow, 2 % noise, 4 Hz,
25/40 mm, x/y; noise-free fit, 600-2000 Hz, x):

=====================================  ======  ==============================  ===============
generator, body                        seeds   workflow: named, gap            noise-free fit
=====================================  ======  ==============================  ===============
bench, 2 g point mass, r_g 4 mm        3 / 5   yes, 0.040 -> 0.002 / 0.040 -> 0.004   0.042 -> 0.000
bench, 2 g, r_g 8 mm                   --      --                              0.042 -> 0.0003 (k_thetaM +21 %)
rotor, 3 g cylinder on the flank       3 / 5 / 6   yes, 0.046 -> 0 / 0.046 -> 0.002 / 0.048 -> 0   0.042 -> 0.0002
bench, 2 g + spindle file +15 %        5       yes (tip_mass), 0.042 -> 0.014  --
=====================================  ======  ==============================  ===============

Override in the setup::

    [model]
    terms = ["tip_mass"]
    tip_mass_kg = [0.0, 0.005]          # uniform bounds, kg
    # or: tip_mass_kg = 0.0021          # fixed, e.g. the sensor's data-sheet mass

Can represent: a rigid body fixed to the tip section, with its mass and
the axial position of its centre (rotary inertia ``m (e^2 + r_g^2)``).
Cannot represent: an own rotary inertia far from ``m (d_tip / 2)^2`` (a
large flat body: the contact's rotational stiffness absorbs the rest), a
compliant mount (the body's own resonance), a radial offset's coupling to
axial or torsional motion, and bodies whose inertia differs between x and y.
"""

from __future__ import annotations

import numpy as np

from ...model.coupling import add_end_impedance, inv2, matmul2
from ...model.timoshenko import TwoPort
from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import ModelTerm

__all__ = ["TipMass", "tip_radius_of_gyration", "add_end_impedance", "add_end_dynamic_stiffness"]

#: Bound of the offset prior, m (a body of at most 2 cm on the flank or the end face).
OFFSET_MAX = 0.01


def tip_radius_of_gyration(model, configurations) -> np.ndarray:
    """Radius of gyration (m) per configuration: half the tip diameter of its tool, (n_cfg,)."""
    return np.array([0.5 * model.tool(c.tool).segments[-1].diameter for c in configurations], dtype=float)


def add_end_dynamic_stiffness(tool: TwoPort, z00, z01, z11) -> TwoPort:
    """Tool two-port with a symmetric dynamic stiffness ``[[z00, z01], [z01, z11]]`` added at end 2 (Woodbury).

    Parameters
    ----------
    tool : TwoPort, blocks (B0, n_lines, 2, 2)
    z00 : (B, n_lines) N/m;  z01 : (B, n_lines) N;  z11 : (B, n_lines) N m/rad

    Returns
    -------
    TwoPort with blocks (max(B, B0), n_lines, 2, 2)
    """
    r22 = tool.r22
    z = np.empty(np.broadcast_shapes(np.shape(z00), np.shape(z01), np.shape(z11)) + (2, 2), dtype=complex)
    z[..., 0, 0], z[..., 0, 1], z[..., 1, 0], z[..., 1, 1] = z00, z01, z01, z11
    # W = Z (I + R22 Z)^-1, written out per 2x2 block (numpy's batched inv/matmul cost far more on tiny matrices)
    m = matmul2(r22, z)
    m[..., 0, 0] += 1.0
    m[..., 1, 1] += 1.0
    w = matmul2(z, inv2(m))
    w_r21, w_r22 = matmul2(w, tool.r21), matmul2(w, r22)
    return TwoPort(r11=tool.r11 - matmul2(tool.r12, w_r21), r12=tool.r12 - matmul2(tool.r12, w_r22),
                   r21=tool.r21 - matmul2(r22, w_r21), r22=r22 - matmul2(r22, w_r22))


@register_term
class TipMass(ModelTerm):
    """A rigid body (mass, axial offset, rotary inertia) at the tool tip (see the module docstring)."""

    name = "tip_mass"
    kind = "substructure"
    description = ("a small mass such as an accelerometer at the tool tip (mass m, centre e beyond the tip, rotary "
                   "inertia m (e^2 + r_g^2))")
    parameter_name = "tip_mass_kg"
    switch = "tip_mass_kg"  # a body of no mass has no offset that matters

    def parameters(self, model) -> tuple[Parameter, ...]:
        mass = (Parameter(self.parameter_name, "kg", "term", prior=Uniform(0.0, 0.02), label="tip mass (kg)",
                          baseline=0.0, term=self.name, description="mass of the body at the tool tip"),)
        if model is None:
            return mass
        return mass + (
            Parameter("tip_mass_offset_m", "m", "term", prior=Uniform(-OFFSET_MAX, OFFSET_MAX),
                      label="tip mass offset (m)", baseline=0.0, term=self.name,
                      description="axial distance of the body's centre of mass beyond the tip node (negative: "
                                  "towards the holder)"),
        )

    def substructures(self, values, subs, ctx):
        m = np.asarray(values[self.parameter_name], dtype=float)
        if not np.any(m):
            return subs  # the baseline: nothing to add (and nothing recomputed)
        w2 = (ctx.omega**2)[None, :]
        rg2 = (tip_radius_of_gyration(ctx.model, ctx.configurations)[ctx.line_config] ** 2)[None, :]
        z_u = -m[:, None] * w2  # (n_sets, n_lines) N/m
        e = np.asarray(values.get("tip_mass_offset_m", np.zeros_like(m)), dtype=float)[:, None]
        if not np.any(e):
            return subs.add_tip(z_u, z_u * rg2)
        return subs.replace(tool=add_end_dynamic_stiffness(subs.tool, z_u, z_u * e, z_u * (e * e + rg2)))
