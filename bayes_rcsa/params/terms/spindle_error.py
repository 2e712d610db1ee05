"""``spindle_error``: the spindle file comes from a spindle whose bearings are stiffer or softer than the real ones.

Spindle receptances are identified once (from a model or a test on another
day, with other bearing preload or temperature) and reused.  The bench's
``spindle_error`` exports the flange receptance of a spindle whose
bearings are ``1 + e`` times stiffer than the real ones.

Physics.  With only the flange block ``S`` of the file available, a change
of the bearing stiffness is represented by what it looks like from the
flange: a change ``dK = diag(dk_u, dk_psi)`` of the (grounded) support
stiffness at the flange, translational and rotational::

    S' = (S^-1 + dK)^-1 = S - S dK (I + S dK)^-1 S

(Woodbury form: no inverse of ``S`` is needed, and ``dK = 0`` returns ``S``
exactly).  The front bearings sit a few centimetres behind the flange, so a
softer bearing is well described by a negative ``dk_u`` and a small
rotational part: on the bench (bearings 15 % stiffer in the file) the
best ``dK`` brings the file's ``h`` within 2 % of the true spindle's
(from 99 % off), ``l`` within 4 % and ``p`` within 22 %.  The term stays
reciprocal; it stays passive as long as the support stays stable (the
prior keeps ``|dK|`` well below the spindle's own dynamic stiffness).

Parameters
----------
``spindle_support_dk_u`` (N/m)
    Change of the translational support stiffness at the flange (negative:
    the real bearings are softer than in the file).  Prior uniform on
    ``[-k_u, k_u] / 2`` with ``k_u`` the median magnitude of the file's
    translational dynamic stiffness ``1 / |h|`` over its frequency range
    (per setup, from the x file if present); baseline 0.
``spindle_support_dk_psi`` (N m/rad)
    The same for rotation, scaled by ``1 / |p|``; baseline 0.  For a
    translation-only file (``p = 0``) the scale falls back to
    ``k_u * (0.05 m)^2``.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import ModelTerm

__all__ = ["SpindleError", "support_scales", "add_support_stiffness"]


def support_scales(model) -> tuple[float, float]:
    """Typical translational (N/m) and rotational (N m/rad) dynamic stiffness of the spindle files."""
    r = model.spindle.get("x") or next(iter(model.spindle.values()))
    h = np.abs(r.block[:, 0, 0])
    p = np.abs(r.block[:, 1, 1])
    k_u = float(np.median(1.0 / h[h > 0])) if np.any(h > 0) else 1e7
    k_psi = float(np.median(1.0 / p[p > 0])) if np.any(p > 0) else k_u * 0.05**2
    return k_u, k_psi


def add_support_stiffness(spindle: np.ndarray, dk_u: np.ndarray, dk_psi: np.ndarray) -> np.ndarray:
    """``(S^-1 + diag(dk_u, dk_psi))^-1`` in Woodbury form.

    Parameters
    ----------
    spindle : (B, n, 2, 2) complex
    dk_u, dk_psi : (n_sets, 1) N/m, N m/rad

    Returns
    -------
    (n_sets, n, 2, 2) complex; exactly ``spindle`` where both changes are 0.
    """
    s = np.asarray(spindle)
    # M = I + S dK (dK diagonal: column k of S scaled by dk_k)
    m00 = 1.0 + s[..., 0, 0] * dk_u
    m01 = s[..., 0, 1] * dk_psi
    m10 = s[..., 1, 0] * dk_u
    m11 = 1.0 + s[..., 1, 1] * dk_psi
    det = m00 * m11 - m01 * m10
    # W = dK M^-1 (rows of M^-1 scaled by dk)
    w00, w01 = dk_u * m11 / det, -dk_u * m01 / det
    w10, w11 = -dk_psi * m10 / det, dk_psi * m00 / det
    # S W S
    sw00 = s[..., 0, 0] * w00 + s[..., 0, 1] * w10
    sw01 = s[..., 0, 0] * w01 + s[..., 0, 1] * w11
    sw10 = s[..., 1, 0] * w00 + s[..., 1, 1] * w10
    sw11 = s[..., 1, 0] * w01 + s[..., 1, 1] * w11
    out = np.empty(np.broadcast_shapes(s.shape, det.shape + (2, 2)), dtype=complex)
    out[..., 0, 0] = s[..., 0, 0] - (sw00 * s[..., 0, 0] + sw01 * s[..., 1, 0])
    out[..., 0, 1] = s[..., 0, 1] - (sw00 * s[..., 0, 1] + sw01 * s[..., 1, 1])
    out[..., 1, 0] = s[..., 1, 0] - (sw10 * s[..., 0, 0] + sw11 * s[..., 1, 0])
    out[..., 1, 1] = s[..., 1, 1] - (sw10 * s[..., 0, 1] + sw11 * s[..., 1, 1])
    return out


@register_term
class SpindleError(ModelTerm):
    """Spindle support (bearing) stiffness changed relative to the spindle file (spindle kind)."""

    name = "spindle_error"
    kind = "spindle"
    description = ("the spindle file comes from a spindle with stiffer or softer bearings than the real one "
                   "(other day, preload, temperature, identification error)")

    def parameters(self, model) -> tuple[Parameter, ...]:
        k_u, k_psi = support_scales(model)
        return (
            Parameter("spindle_support_dk_u", unit="N/m", role="term", prior=Uniform(-0.5 * k_u, 0.5 * k_u),
                      label="spindle support change dk_u [N/m]", baseline=0.0, term=self.name,
                      description="change of the translational bearing (support) stiffness seen at the flange; "
                                  "negative: the real bearings are softer than in the spindle file"),
            Parameter("spindle_support_dk_psi", unit="N m/rad", role="term",
                      prior=Uniform(-0.5 * k_psi, 0.5 * k_psi), label="spindle support change dk_psi [N m/rad]",
                      baseline=0.0, term=self.name,
                      description="change of the rotational support stiffness seen at the flange"),
        )

    def spindle(self, values: Mapping[str, np.ndarray], spindle: np.ndarray, ctx) -> np.ndarray:
        """Flange blocks with the support change, (n_sets, n_lines, 2, 2)."""
        return add_support_stiffness(spindle, self.batch(values, "spindle_support_dk_u")[:, :, 0],
                                     self.batch(values, "spindle_support_dk_psi")[:, :, 0])
