"""``joint_loss_factor``: the tool-holder joint dissipates energy independently of frequency.

A clamped interface dissipates mainly by micro-slip friction.  The energy lost
per cycle then depends on the amplitude of the relative motion but hardly on
its rate, which is the structural (hysteretic) damping model of a joint: a
complex stiffness ``k (1 + i eta)`` with a loss factor ``eta`` (Gaul and Lenz,
Acta Mech. 125, 1997; Beards, *Structural Vibration*, ch. 5).  Measured loss
factors of bolted, shrink-fit and collet joints lie around 0.01-0.2.  A
viscous damper ``c`` gives the imaginary part ``omega c`` instead, which grows
with frequency and does not follow the stiffness from one clamping length to
the next.  The setup's viscous ``c_xf``, ``c_thetaM`` matches a hysteretic
joint at one frequency and one length only, so a model with the wrong form
fits each peak's width by trading it against the contact *stiffness*, and the
mode frequencies come out biased by a fraction of a line, at every length.

This term adds the rate-independent part: the joint's complex stiffness becomes
``k(l) (1 + i eta) + i omega c`` in both directions (one interface, one loss
factor), with ``k(l)`` whatever the growth law and the other joint terms give.

What it can represent: a loss that scales with the contact stiffness (so with
clamping length) and is the same at every frequency of the band; on top of it
the setup's viscous damping, or a multiple of it when ``contact_damping`` is in
the model too.  What it cannot: different loss factors in translation and
rotation, amplitude dependence (the hammer test's force level is fixed), or a
joint whose viscous damping is *smaller* than assumed without
``contact_damping`` beside it.

Parameter
---------
``joint_loss_factor`` (1)
    Loss factor ``eta`` of the joint.  Prior uniform on [0, 0.5] (the
    measured range above with a factor of 2.5 to spare); baseline 0, where the
    term vanishes exactly.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import Contact, ModelTerm

__all__ = ["JointLossFactor"]

#: Upper end of the loss-factor prior (see the module docstring).
ETA_MAX = 0.5


@register_term
class JointLossFactor(ModelTerm):
    """Hysteretic joint loss ``h = eta k`` in both directions (joint kind)."""

    name = "joint_loss_factor"
    kind = "joint"
    description = ("the tool-holder joint dissipates independently of frequency (micro-slip): "
                   "complex contact stiffness k (1 + i eta)")

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter("joint_loss_factor", unit="1", role="term", prior=Uniform(0.0, ETA_MAX),
                      label="joint loss factor", baseline=0.0, term=self.name,
                      description="hysteretic loss factor eta of the tool-holder joint, K = k (1 + i eta)"),
        )

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths, l_a: float, l_b: float) -> Contact:
        """Contact with the loss stiffness ``eta k`` added in both directions.

        Parameters
        ----------
        values : ``{"joint_loss_factor": (n_sets,)}`` (other names ignored)
        contact : Contact, fields (n_sets, n_cfg)

        Returns
        -------
        Contact, fields (n_sets, n_cfg); stiffness and viscous damping are the input's.
        """
        eta = np.asarray(values["joint_loss_factor"], dtype=float)[:, None]
        return contact._replace(h_xf=np.asarray(contact.h_xf) + eta * np.asarray(contact.k_xf),
                                h_thetaM=np.asarray(contact.h_thetaM) + eta * np.asarray(contact.k_thetaM))
