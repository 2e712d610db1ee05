"""Model terms: the registry and the built-in terms.

Adding a term is one file in this folder that defines a
:class:`~.base.ModelTerm` subclass decorated with :func:`register_term`,
plus its module name in :data:`_BUILTIN` below (a user or a test can also
register one from its own code).  See docs/architecture.md.
"""

from __future__ import annotations

import importlib

from ...registry import Registry
from .base import KINDS, Contact, ModelTerm, Substructures, TermContext

__all__ = ["TERMS", "register_term", "get_term", "known_terms", "make_term",
           "KINDS", "Contact", "ModelTerm", "Substructures", "TermContext"]

#: Registry of model-term classes by canonical name.
TERMS: Registry[type[ModelTerm]] = Registry("model term")


def register_term(cls: type[ModelTerm]) -> type[ModelTerm]:
    """Class decorator: register a :class:`ModelTerm` subclass under ``cls.name``."""
    from ...errors import SetupError

    if not (isinstance(cls, type) and issubclass(cls, ModelTerm)):
        raise SetupError(f"register_term: {cls!r} is not a ModelTerm subclass")
    if cls.kind not in KINDS:
        raise SetupError(f"model term {cls.name!r}: kind {cls.kind!r}, expected one of {KINDS}")
    return TERMS.register(cls.name, cls)


def get_term(name: str, where: str = "[model] terms") -> type[ModelTerm]:
    return TERMS.get(name, where)


def make_term(name: str, where: str = "[model] terms") -> ModelTerm:
    """An instance of the registered term ``name``."""
    return get_term(name, where)()


def known_terms() -> tuple[str, ...]:
    return TERMS.names()


# Built-in terms, one module each (each registers itself on import).
_BUILTIN: tuple[str, ...] = ("tip_mass", "contact_damping", "joint_loss_factor", "extra_mode", "fluted_section",
                              "nonlinear_stiffness_law", "stiffness_step",
                              "spindle_error", "spindle_rotation_omitted", "statistical_discrepancy",
                              "law_shape_uncertainty")

for _mod in _BUILTIN:
    importlib.import_module(f"{__name__}.{_mod}")
