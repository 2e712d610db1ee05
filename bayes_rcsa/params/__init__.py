"""The parameter model and model terms: what is sampled, what is fixed, and how it enters the RCSA model."""

from .parameter import ROLES, Parameter

__all__ = ["Parameter", "ROLES"]
