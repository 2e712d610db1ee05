"""The parameter model and model terms: what is sampled, what is fixed, and how it enters the RCSA model.

* :mod:`.parameter` -- :class:`Parameter` (name, unit, role, prior or value, label, baseline);
* :mod:`.priors` -- prior distributions in their sampling coordinates, :class:`PriorSet`;
* :mod:`.growth` -- the bounded linear growth law k(l);
* :mod:`.model` -- :class:`ParameterModel`: all parameters of a fit, theta -> values -> contact, files;
* :mod:`.forward` -- :class:`ForwardModel`: batched FRFs of a parameter model on cached configurations;
* :mod:`.terms` -- the model-term protocol, registry and built-in terms.

See docs/architecture.md.
"""

from .forward import ForwardModel
from .growth import GrowthLaw
from .model import CONTACT_NAMES, CONTACT_UNITS, ParameterModel, contact_parameter, noise_name, term_parameters
from .parameter import ROLES, Parameter
from .priors import LogNormal, LogUniform, Normal, Prior, PriorSet, Uniform, prior_from_spec
from .terms import TERMS, Contact, ModelTerm, Substructures, TermContext, known_terms, make_term, register_term

__all__ = [
    "ForwardModel", "GrowthLaw", "ParameterModel", "CONTACT_NAMES", "CONTACT_UNITS", "contact_parameter",
    "noise_name", "term_parameters", "Parameter", "ROLES",
    "LogNormal", "LogUniform", "Normal", "Prior", "PriorSet", "Uniform", "prior_from_spec",
    "TERMS", "Contact", "ModelTerm", "Substructures", "TermContext", "known_terms", "make_term", "register_term",
]
