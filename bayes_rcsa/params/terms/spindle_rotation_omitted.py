"""``spindle_rotation_omitted``: the spindle file lacks (part of) its rotational flange receptances.

A spindle receptance measured with a hammer and one accelerometer gives
only the translational ``h = u/F`` at the flange; ``l = u/M``,
``n = psi/F`` and ``p = psi/M`` need a moment excitation or a finite-
difference rig, and are often left at zero or taken from a crude model.
Without them RCSA treats the flange as rotationally rigid, which stiffens
the assembly.

What can be reconstructed from a translational-only file.  Nothing
exactly: the rotational receptances carry their own mode shapes.  The
term assumes that the missing flange rotation comes from a rocking of the
spindle nose about a pivot a distance ``a`` behind the flange (the front
bearing region), i.e. that every mode has ``psi = u / a`` at the flange.
Then ``l = n = h / a`` and ``p = h / a^2``, and a fraction ``rho`` of that
rocking contribution is added to the file's block::

    S' = S + rho * h * [[0, 1/a], [1/a, 1/a^2]]

For ``0 <= rho <= 1`` and a passive ``h`` (Im h <= 0) the added block is
negative semi-definite in its imaginary part, so ``S'`` stays passive and
it is symmetric (reciprocal).  ``rho = 0`` gives ``S`` exactly.

Limits (documented in docs/discrepancy.md): the reconstruction has the
frequency dependence of ``h``; the true ``p`` has its own anti-resonances
(bending of the spindle nose) that a translational file cannot reveal.  It
captures the first-order effect -- a softer flange in rotation, which
lowers and raises the tool-point peak -- and the identified ``a`` is an
effective lever, not a measured pivot.

Parameters
----------
``rotation_restored`` (1)
    Fraction of the rocking contribution restored; prior uniform on
    [0, 1]; baseline 0 (the file as given).
``rotation_lever_m`` (m)
    Effective lever ``a``; prior log-uniform on [0.02, 0.5] m (front
    bearing 2-50 cm behind the flange).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import LogUniform, Uniform
from . import register_term
from .base import ModelTerm

__all__ = ["SpindleRotationOmitted"]


@register_term
class SpindleRotationOmitted(ModelTerm):
    """Restores rotational flange receptances from the translational one (spindle kind)."""

    name = "spindle_rotation_omitted"
    kind = "spindle"
    #: Prior bounds that are physical limits (all of the rocking restored), not a chosen range: the
    #: discrepancy workflow accepts a fit there (bench magnitude 1 = translation-only file).
    physical_bounds = {"rotation_restored": (0.0, 1.0)}
    description = ("the spindle file lacks its rotational receptances (only translation was measured): the flange "
                   "is softer in rotation than the file says")

    def parameters(self, model) -> tuple[Parameter, ...]:
        return (
            Parameter("rotation_restored", unit="1", role="term", prior=Uniform(0.0, 1.0),
                      label="restored flange rotation (fraction)", baseline=0.0, term=self.name,
                      description="fraction of the reconstructed rocking receptance added to the spindle file"),
            Parameter("rotation_lever_m", unit="m", role="term", prior=LogUniform(0.02, 0.5),
                      label="rocking lever [m]", baseline=0.1, term=self.name,
                      description="effective distance from the flange to the spindle nose's rocking pivot"),
        )

    def spindle(self, values: Mapping[str, np.ndarray], spindle: np.ndarray, ctx) -> np.ndarray:
        """Flange blocks with the rocking contribution added, (n_sets, n_lines, 2, 2)."""
        rho = np.asarray(values["rotation_restored"], dtype=float)[:, None]  # (n_sets, 1)
        inv_a = 1.0 / np.asarray(values["rotation_lever_m"], dtype=float)[:, None]
        s = np.asarray(spindle)
        h = s[..., 0, 0]  # (B, n)
        add_l = rho * inv_a * h
        out = np.broadcast_to(s, np.broadcast_shapes(s.shape, add_l.shape + (2, 2))).copy()
        out[..., 0, 1] += add_l
        out[..., 1, 0] += add_l
        out[..., 1, 1] += add_l * inv_a
        return out
