"""One model parameter: name, unit, role, prior or fixed value, plot label.

After lmfit's ``Parameter`` and bilby's priors: a :class:`Parameter` is a
small immutable record.  It is *sampled* when it has a prior and *fixed*
when it has a value; never both.  Terms (:mod:`bayes_rcsa.params.terms`)
declare their parameters with the ``baseline`` value at which the term
vanishes (the model reduces exactly to the baseline RCSA model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from ..errors import SetupError

__all__ = ["Parameter", "ROLES"]

#: What a parameter is for.  ``contact``: joint stiffness/damping at the
#: reference clamping length; ``growth``: the growth law's factors;
#: ``noise``: relative noise scale of one measurement; ``term``: a physical
#: model term; ``discrepancy``: a statistical discrepancy term.
ROLES = ("contact", "growth", "noise", "term", "discrepancy")


@dataclass(frozen=True)
class Parameter:
    """A named model parameter.

    Parameters
    ----------
    name : str
        Unique name, e.g. ``"k_xf"`` or ``"tip_mass_kg"``.
    unit : str
        SI unit of the physical value (``"1"`` if dimensionless).
    role : str
        One of :data:`ROLES`.
    prior : Prior or None
        Prior (an object with ``ln_prob``, ``sample``, ``to_physical``,
        ``to_sampling``, ``bounds``, ``describe``); ``None`` when fixed.
    value : float or None
        Fixed physical value; ``None`` when sampled.
    label : str
        Axis label for plots (defaults to the name).
    baseline : float or None
        Physical value at which the owning term vanishes (terms only).
    term : str or None
        Name of the model term that owns the parameter.
    description : str
        One line a user can read.
    """

    name: str
    unit: str = "1"
    role: str = "contact"
    prior: Any = None
    value: float | None = None
    label: str = ""
    baseline: float | None = None
    term: str | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if not self.name or not self.name.replace("_", "").isalnum():
            raise SetupError(f"parameter name {self.name!r}: expected letters, digits and underscores")
        if self.role not in ROLES:
            raise SetupError(f"parameter {self.name}: role {self.role!r}, expected one of {ROLES}")
        if (self.prior is None) == (self.value is None):
            raise SetupError(f"parameter {self.name}: give either a prior (sampled) or a value (fixed), not both or neither")
        if self.value is not None and not math.isfinite(float(self.value)):
            raise SetupError(f"parameter {self.name} = {self.value!r}: expected a finite number")
        if not self.label:
            object.__setattr__(self, "label", self.name)

    @property
    def sampled(self) -> bool:
        return self.prior is not None

    def fixed_at(self, value: float) -> "Parameter":
        """The same parameter held fixed at ``value`` (physical units)."""
        return replace(self, prior=None, value=float(value))

    def with_prior(self, prior) -> "Parameter":
        """The same parameter sampled with ``prior``."""
        return replace(self, prior=prior, value=None)
