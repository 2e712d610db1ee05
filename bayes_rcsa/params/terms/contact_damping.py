"""``contact_damping``: the tool-holder joint damping is a multiple of the assumed value.

Users rarely know the joint damping; the setup usually fixes ``c_xf`` and
``c_thetaM`` at a handbook value.  A joint that dissipates several times
more energy lowers and widens the tool-point peak without moving it much
(docs/synthetic.md: five times the damping lowers the peak by ~78 % and the
frequency by ~0.2 %).  This term multiplies both joint dampings by one
factor, the same at every clamping length.

Parameter
---------
``contact_damping_factor`` (1)
    True joint damping / assumed joint damping.  Prior log-uniform on
    [0.1, 100] (a decade less to two decades more than assumed: handbook
    values for bolted/shrink joints scatter that much); baseline 1 (the
    setup's damping), where the term vanishes exactly.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import LogUniform
from . import register_term
from .base import Contact, ModelTerm

__all__ = ["ContactDamping"]


@register_term
class ContactDamping(ModelTerm):
    """Joint damping c_xf, c_thetaM scaled by one factor (joint kind)."""

    name = "contact_damping"
    kind = "joint"
    description = "the tool-holder joint damps more (or less) than assumed: c_xf and c_thetaM times a factor"

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter("contact_damping_factor", unit="1", role="term", prior=LogUniform(0.1, 100.0),
                      label="joint damping factor", baseline=1.0, term=self.name,
                      description="true joint damping / assumed joint damping (c_xf and c_thetaM alike)"),
        )

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths, l_a: float, l_b: float) -> Contact:
        """Contact with both dampings multiplied by the factor; stiffnesses unchanged.

        Parameters
        ----------
        values : ``{"contact_damping_factor": (n_sets,)}`` (other names ignored)
        contact : Contact, fields (n_sets, n_cfg)

        Returns
        -------
        Contact, fields (n_sets, n_cfg); at factor 1 the dampings are the input's bit for bit.
        """
        f = np.asarray(values["contact_damping_factor"], dtype=float)[:, None]
        return contact._replace(c_xf=np.asarray(contact.c_xf) * f, c_thetaM=np.asarray(contact.c_thetaM) * f)
