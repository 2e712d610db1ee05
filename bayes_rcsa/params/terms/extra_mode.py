"""``extra_mode``: a resonance on the spindle/holder side that the spindle file does not contain.

A drawbar, a loose holder flange, a coolant unit or a housing mode can
add a resonance that was not present (or not excited) when the spindle
receptance was measured or modelled.  This term hangs a single-degree-of-
freedom resonator (mass ``m`` on a spring-damper, tuned to ``f_r`` with
damping ratio ``zeta``) on the translational DOF of the flange.

Physics.  Seen from its attachment point, the resonator is a dynamic
stiffness (force per displacement, convention x(t) = Re{X e^{+i w t}})::

    z(w) = -w^2 m (k + i w c) / (k + i w c - w^2 m),   k = m w_r^2,  c = 2 zeta m w_r

Attaching it to the flange block ``S`` (2x2, DOFs u, psi) at ``u`` gives,
by the Sherman-Morrison formula on ``(S^-1 + z e e^T)^-1``::

    S' = S - z S e e^T S / (1 + z S_00),   e = (1, 0)

which is reciprocal (``S'`` symmetric when ``S`` is) and passive (a
damped resonator only dissipates).  With ``m = 0``, ``z = 0`` and ``S' = S``
exactly.

Parameters
----------
``extra_mode_mass_kg`` (kg)
    Modal mass of the resonance.  Prior uniform on [0, 1] kg (a holder or
    drawbar mode of up to a kilogram; the bench default is 0.2 kg); baseline 0.
``extra_mode_frequency_hz`` (Hz)
    Its natural frequency.  Prior uniform over the spindle file's frequency
    range (a resonance outside it cannot be located from the data).
``extra_mode_damping_ratio`` (1)
    Prior log-uniform on [0.005, 0.2].

Limits: the resonator acts on the flange translation only; a resonance
that rocks the holder (rotational coupling) or sits at the holder tip is
approximated by an equivalent flange resonator.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import LogUniform, Uniform
from . import register_term
from .base import ModelTerm

__all__ = ["ExtraMode", "resonator_dynamic_stiffness", "attach_translational"]


def resonator_dynamic_stiffness(omega: np.ndarray, mass: np.ndarray, frequency_hz: np.ndarray,
                                damping_ratio: np.ndarray) -> np.ndarray:
    """Dynamic stiffness of a base-excited SDOF resonator seen from its base.

    Parameters
    ----------
    omega : (n_lines,) rad/s
    mass : (n_sets, 1) kg;  frequency_hz : (n_sets, 1) Hz;  damping_ratio : (n_sets, 1)

    Returns
    -------
    (n_sets, n_lines) complex, N/m; exactly 0 where ``mass == 0``.
    """
    w_r = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    m = np.asarray(mass, dtype=float)
    w = np.asarray(omega, dtype=float)[None, :]
    # per unit mass, so that m = 0 gives an exact zero and no 0/0
    spring = w_r**2 + 2j * np.asarray(damping_ratio, dtype=float) * w_r * w
    return -(w**2) * m * spring / (spring - w**2)


def attach_translational(spindle: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Add a dynamic stiffness ``z`` on the u DOF of point blocks ``spindle``.

    Parameters
    ----------
    spindle : (B, n_lines, 2, 2) complex, B = 1 or n_sets
    z : (n_sets, n_lines) complex, N/m

    Returns
    -------
    (n_sets, n_lines, 2, 2) complex
    """
    s = np.asarray(spindle)
    col = s[..., :, 0]  # S e, (B, n, 2)
    row = s[..., 0, :]  # e^T S
    factor = z / (1.0 + z * s[..., 0, 0])  # (n_sets, n)
    return s - factor[..., None, None] * col[..., :, None] * row[..., None, :]


@register_term
class ExtraMode(ModelTerm):
    """A resonator on the flange that the spindle receptance lacks (spindle kind)."""

    name = "extra_mode"
    kind = "spindle"
    description = ("a resonance on the spindle/holder side (drawbar, holder flange, housing) that the spindle "
                   "file does not contain")

    def parameters(self, model) -> tuple[Parameter, ...]:
        lo = min(float(r.frequency_hz[0]) for r in model.spindle.values())
        hi = max(float(r.frequency_hz[-1]) for r in model.spindle.values())
        return (
            Parameter("extra_mode_mass_kg", unit="kg", role="term", prior=Uniform(0.0, 1.0),
                      label="extra mode mass [kg]", baseline=0.0, term=self.name,
                      description="modal mass of the missing resonance on the flange"),
            Parameter("extra_mode_frequency_hz", unit="Hz", role="term", prior=Uniform(lo, hi),
                      label="extra mode frequency [Hz]", baseline=0.5 * (lo + hi), term=self.name,
                      description="natural frequency of the missing resonance"),
            Parameter("extra_mode_damping_ratio", unit="1", role="term", prior=LogUniform(0.005, 0.2),
                      label="extra mode damping ratio", baseline=0.02, term=self.name,
                      description="damping ratio of the missing resonance"),
        )

    def spindle(self, values: Mapping[str, np.ndarray], spindle: np.ndarray, ctx) -> np.ndarray:
        """Flange blocks with the resonator attached, (n_sets, n_lines, 2, 2)."""
        z = resonator_dynamic_stiffness(
            ctx.omega, self.batch(values, "extra_mode_mass_kg")[:, :, 0],
            self.batch(values, "extra_mode_frequency_hz")[:, :, 0],
            self.batch(values, "extra_mode_damping_ratio")[:, :, 0])
        return attach_translational(spindle, z)
