"""``fluted_section``: the fluted part of the tool is thinner (or thicker) in bending than declared.

The setup describes a fluted length by its effective bending diameter,
``diameter * diameter_ratio`` (typically 0.75-0.85 of the shank diameter for
end mills, from a handbook rule).  The true value depends on the flute
count, core diameter and helix and is easily off by 10 %.  This term
scales the effective diameter of every fluted tool segment (those with
``diameter_ratio < 1``) by one factor.

Physics.  A solid circular section of diameter ``d`` has EI, kappa G A,
rho A, rho I proportional to ``d^4, d^2, d^2, d^4`` (Cowper's kappa of a solid
circle does not depend on ``d``), so scaling ``d`` by ``s`` scales the
four section properties by ``s^4, s^2, s^2, s^4``.  The tool-overhang
two-port is then recomputed with exact Timoshenko segment dynamic
stiffnesses, vectorised over parameter sets and lines (one small linear
solve per set and line, no loop over either).  A thinner fluted section
loses mass at the tip and bending stiffness; with a compliant joint the
lighter tip usually wins and the tool mode moves *up*
(docs/synthetic.md).

Parameter
---------
``flute_diameter_scale`` (1)
    True / declared effective diameter of the fluted segments.  Prior
    uniform on [0.6, 1.15] (the ratio 0.8 of the setup may be anywhere
    from about 0.5 to a solid section); baseline 1, where the declared
    tool two-port is returned unchanged (bit for bit).

Limits: fluted segments clamped inside the holder are refused (the holder
two-port would change too); flutes are assumed to stay circular-equivalent.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ...errors import ModelError
from ...model.geometry import tool_overhang_segments
from ...model.timoshenko import TwoPort
from ..parameter import Parameter
from ..priors import Uniform
from . import register_term
from .base import ModelTerm, Substructures

__all__ = ["FlutedSection", "batched_segment_stiffness", "batched_free_free"]


def batched_segment_stiffness(length: float, EI, kGA, rhoA, rhoI, omega) -> np.ndarray:
    """Exact dynamic stiffness of a uniform Timoshenko segment for batches of sections.

    Parameters
    ----------
    length : float, m
    EI : (B, 1) complex N m^2;  kGA : (B, 1) complex N;  rhoA : (B, 1) kg/m;  rhoI : (B, 1) kg m
    omega : (n,) rad/s, > 0

    Returns
    -------
    (B, n, 4, 4) complex: end displacements (u0, psi0, uL, psiL) -> end forces (F0, M0, FL, ML).

    Notes
    -----
    Solutions ``u = e^{lam z}`` with ``psi = (kGA lam^2 + rhoA w^2) / (kGA lam) u``
    and ``kGA EI lam^4 + w^2 (kGA rhoI + rhoA EI) lam^2 + rhoA w^2 (rhoI w^2 - kGA) = 0``.
    Growing exponentials are referred to the far end (``e^{lam (z - L)}``) so
    no term exceeds one in modulus.
    """
    w2 = (np.asarray(omega, dtype=float) ** 2)[None, :].astype(complex)
    EI, kGA = np.asarray(EI, dtype=complex), np.asarray(kGA, dtype=complex)
    rhoA, rhoI = np.asarray(rhoA, dtype=float), np.asarray(rhoI, dtype=float)
    a = kGA * EI
    b = w2 * (kGA * rhoI + rhoA * EI)
    c = rhoA * w2 * (rhoI * w2 - kGA)
    disc = np.sqrt(b * b - 4 * a * c)
    sign = np.where((np.conj(b) * disc).real >= 0, 1.0, -1.0)
    q = -0.5 * (b + sign * disc)  # larger root without cancellation, smaller one from the product c / a
    r1, r2 = np.sqrt(q / a), np.sqrt(c / q)
    lam = np.stack([r1, -r1, r2, -r2], axis=-1)  # (B, n, 4)
    kGA_, EI_, rhoA_ = kGA[..., None], EI[..., None], rhoA[..., None]
    psi = (kGA_ * lam**2 + rhoA_ * w2[..., None]) / (kGA_ * lam)
    grows = lam.real >= 0
    decay = np.exp(np.where(grows, -lam, lam) * length)
    phi0 = np.where(grows, decay, 1.0)
    phiL = np.where(grows, 1.0, decay)
    shear = kGA_ * (lam - psi)
    moment = EI_ * lam * psi
    d = np.stack([phi0, psi * phi0, phiL, psi * phiL], axis=-2)
    f = np.stack([-shear * phi0, -moment * phi0, shear * phiL, moment * phiL], axis=-2)
    # K D = F  <=>  D^T K^T = F^T
    return np.swapaxes(np.linalg.solve(np.swapaxes(d, -1, -2), np.swapaxes(f, -1, -2)), -1, -2)


def batched_free_free(pieces: Sequence[tuple[float, tuple]], omega) -> TwoPort:
    """End receptances of a free-free stepped beam whose sections vary over a batch.

    Parameters
    ----------
    pieces : sequence of (length, (EI, kGA, rhoA, rhoI)), end 1 to end 2;
        each property a (B, 1) array (or broadcastable).
    omega : (n,) rad/s

    Returns
    -------
    TwoPort with blocks (B, n, 2, 2)
    """
    blocks = [batched_segment_stiffness(length, *props, omega) for length, props in pieces]
    shape = np.broadcast_shapes(*(k.shape[:-2] for k in blocks))
    n_dof = 2 * (len(pieces) + 1)
    k = np.zeros(shape + (n_dof, n_dof), dtype=complex)
    for i, blk in enumerate(blocks):
        k[..., 2 * i : 2 * i + 4, 2 * i : 2 * i + 4] += blk
    ends = [0, 1, n_dof - 2, n_dof - 1]
    rhs = np.zeros((n_dof, 4), dtype=complex)
    rhs[ends, np.arange(4)] = 1.0
    cols = np.linalg.solve(k, np.broadcast_to(rhs, shape + rhs.shape))
    return TwoPort.from_matrix(cols[..., ends, :])


def _fluted_flags(tool, clamping_length: float) -> list[bool]:
    """Whether each overhang piece (base -> tip, as :func:`tool_overhang_segments`) is fluted."""
    overhang = tool.total_length - clamping_length
    flags, pos = [], 0.0
    for seg in tool.segments:  # from the tip
        piece = min(pos + seg.length, overhang) - pos
        if piece > 1e-9 * overhang:
            flags.append(seg.diameter_ratio < 1.0)
        if seg.diameter_ratio < 1.0 and pos + seg.length > overhang * (1 + 1e-9):
            raise ModelError(
                f"fluted_section: tool {tool.name!r} has a fluted segment reaching into the holder at clamping "
                f"length {clamping_length * 1e3:g} mm; this term handles fluted overhangs only")
        pos += seg.length
    return flags[::-1]


@register_term
class FlutedSection(ModelTerm):
    """Effective diameter of the fluted tool segments scaled by one factor (substructure kind)."""

    name = "fluted_section"
    kind = "substructure"
    description = "the fluted part of the tool is thinner (or thicker) in bending than its declared diameter ratio"

    def parameters(self, model) -> tuple[Parameter, ...]:
        if not any(s.diameter_ratio < 1 for t in model.tools.values() for s in t.segments):
            raise ModelError("fluted_section: no tool of the setup has a fluted segment (diameter_ratio < 1)")
        return (
            Parameter("flute_diameter_scale", unit="1", role="term", prior=Uniform(0.6, 1.15),
                      label="fluted diameter scale", baseline=1.0, term=self.name,
                      description="true / declared effective bending diameter of the fluted segments"),
        )

    def substructures(self, values: Mapping[str, np.ndarray], subs: Substructures, ctx) -> Substructures:
        """Tool two-ports recomputed with the scaled fluted sections, blocks (n_sets, n_lines, 2, 2)."""
        s = np.asarray(values["flute_diameter_scale"], dtype=float)
        at_base = s == 1.0
        if np.all(at_base):
            return subs
        s2, s4 = (s * s)[:, None], (s**4)[:, None]
        n_sets = s.size
        tool = subs.tool
        out = {k: np.array(np.broadcast_to(getattr(tool, k), (n_sets,) + getattr(tool, k).shape[1:]))
               for k in ("r11", "r12", "r21", "r22")}
        for j, cfg in enumerate(ctx.configurations):  # a few configurations, each batched over sets and lines
            lines = np.flatnonzero(ctx.line_config == j)
            if lines.size == 0:
                continue
            t = ctx.model.tool(cfg.tool)
            segs = tool_overhang_segments(ctx.model.holder, t, cfg.clamping_length)
            flags = _fluted_flags(t, cfg.clamping_length)
            if len(flags) != len(segs):
                raise ModelError(f"fluted_section: could not match the overhang segments of tool {t.name!r}")
            pieces = []
            for seg, fluted in zip(segs, flags):
                p = seg.section
                if fluted:
                    pieces.append((seg.length, (p.EI * s4, p.kGA * s2, p.rhoA * s2, p.rhoI * s4)))
                else:
                    one = np.ones((1, 1))
                    pieces.append((seg.length, (p.EI * one, p.kGA * one, p.rhoA * one, p.rhoI * one)))
            tp = batched_free_free(pieces, ctx.omega[lines])
            for k in out:
                new = np.broadcast_to(getattr(tp, k), (n_sets, lines.size, 2, 2))
                out[k][:, lines] = np.where(at_base[:, None, None, None], out[k][:, lines], new)
        return subs.replace(tool=TwoPort(**out))
