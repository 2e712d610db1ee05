"""The batched forward model of a parameter model on a stack of cached configurations.

:class:`ForwardModel` turns the physical values of a batch of parameter
sets into tool-point FRFs on every line of a
:class:`~bayes_rcsa.model.ConfigurationStack`:

1. contact parameters per configuration: :meth:`ParameterModel.contact`
   (growth law, then the *joint* terms);
2. without *spindle* or *substructure* terms: the compiled fast path
   :meth:`ConfigurationStack.frf` on the cached coefficients (the
   identification's hot path, unchanged by the term machinery);
   with them: the cached substructures (flange receptance, holder and tool
   two-ports, batch axis 1) go through the spindle hooks, then the
   substructure hooks (which may give them a batch axis of ``n_sets``).
   If only a tip attachment was added (:meth:`Substructures.add_tip`, e.g.
   the tip mass), a compiled kernel applies it to the assembled tool-point
   block (:meth:`ConfigurationStack.frf_tip`).  Otherwise the holder is
   re-coupled to the spindle only if one of the two changed, a tip
   attachment is folded into the tool two-port, the fast-path coefficients
   are recomputed per set
   (:func:`bayes_rcsa.model.assembly.tool_point_coefficients`) and the
   compiled batched kernel evaluates them;
3. the *frf* terms act on the assembled FRFs.

Everything is vectorised over parameter sets and lines; no Python loop runs
per set or per line.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..model.assembly import ConfigurationStack, ToolPointModel, tool_point_coefficients
from ..model.coupling import add_end_impedance, attach
from .model import ParameterModel
from .terms import Contact, Substructures, TermContext

__all__ = ["ForwardModel"]


class ForwardModel:
    """Tool-point FRFs of a :class:`ParameterModel` on a :class:`ConfigurationStack`.

    Parameters
    ----------
    parameters : ParameterModel
    stack : ConfigurationStack
        Caches made by :meth:`ToolPointModel.precompute` (they hold the
        substructures the terms need).
    model : ToolPointModel
        The model the stack was built from (terms may read its geometry).

    Notes
    -----
    Stable API: :meth:`frf` (physical values), :meth:`frf_theta` (sampling
    coordinates), :meth:`contact`, :attr:`context`.  Fixed contact damping
    is passed to the kernel as a scalar when no joint term can change it.
    """

    def __init__(self, parameters: ParameterModel, stack: ConfigurationStack, model: ToolPointModel):
        self.parameters = parameters
        self.stack = stack
        self.model = model
        self.lengths = np.array([c.configuration.clamping_length for c in stack.caches], dtype=float)
        g = parameters.growth
        self.context = TermContext(
            model=model, configurations=tuple(stack.configurations), frequency_hz=stack.frequency_hz,
            omega=stack.omega, line_config=stack.index, lengths=self.lengths, l_a=g.l_a, l_b=g.l_b,
        )
        no_joint = not parameters.terms_of_kind("joint")
        self._scalar_damping = {n: parameters.fixed[n] for n in ("c_xf", "c_thetaM")
                                if no_joint and n in parameters.fixed}
        self._spindle_terms = parameters.terms_of_kind("spindle")
        self._substructure_terms = parameters.terms_of_kind("substructure")
        self._frf_terms = parameters.terms_of_kind("frf")
        self._holder_tip = None  # (1, n_lines, 2, 2), built on first use

    @property
    def n_lines(self) -> int:
        return self.stack.n_lines

    def contact(self, values: Mapping[str, np.ndarray]) -> Contact:
        """Contact parameters of every set and configuration, each (n_sets, n_cfg)."""
        return self.parameters.contact(values, self.lengths)

    def frf(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Tool-point FRF on all lines, (n_sets, n_lines) complex m/N.

        Parameters
        ----------
        values : mapping name -> (n_sets,) physical values of every parameter
            (:meth:`ParameterModel.values`).
        """
        contact = self.contact(values)
        kx, kt = contact.k_xf, contact.k_thetaM
        cx = self._scalar_damping.get("c_xf", contact.c_xf)
        ct = self._scalar_damping.get("c_thetaM", contact.c_thetaM)
        loss = (contact.h_xf, contact.h_thetaM)
        if self._spindle_terms or self._substructure_terms:
            h = self._general(values, kx, kt, cx, ct, loss)
        else:
            h = self.stack.frf(kx, kt, cx, ct, *loss)
        for t in self._frf_terms:
            h = t.frf(values, h, self.context)
        return h

    def frf_theta(self, theta: np.ndarray) -> np.ndarray:
        """:meth:`frf` for sampling coordinates ``theta`` (n, ndim)."""
        return self.frf(self.parameters.values(np.atleast_2d(theta)))

    def substructures(self, values: Mapping[str, np.ndarray]) -> Substructures:
        """The substructures after the spindle and substructure terms (batch axis 1 or n_sets)."""
        spindle, holder, tool = self.stack.substructures()
        for t in self._spindle_terms:
            spindle = t.spindle(values, spindle, self.context)
        subs = Substructures(spindle, holder, tool)
        for t in self._substructure_terms:
            subs = t.substructures(values, subs, self.context)
        return subs

    def _general(self, values, kx, kt, cx, ct, loss=(0.0, 0.0)) -> np.ndarray:
        base_spindle, base_holder, base_tool = self.stack.substructures()
        subs = self.substructures(values)
        shape = kx.shape
        cx = np.broadcast_to(np.asarray(cx, dtype=float), shape)
        ct = np.broadcast_to(np.asarray(ct, dtype=float), shape)
        same = subs.spindle is base_spindle and subs.holder is base_holder and subs.tool is base_tool
        if same and subs.tip is None:
            return self.stack.frf(kx, kt, cx, ct, *loss)  # every term at its baseline
        if same:
            # only something attached at the tip: the cached blocks stay shared by all sets
            return self.stack.frf_tip(subs.tip, kx, kt, cx, ct, *loss)
        tool = subs.tool
        if subs.tip is not None:
            tool = add_end_impedance(tool, subs.tip[..., 0], subs.tip[..., 1])
        if subs.spindle is base_spindle and subs.holder is base_holder:
            # the cached spindle + holder coupling still holds
            if self._holder_tip is None:
                self._holder_tip = np.concatenate([c.holder_tip for c in self.stack.caches])[None]
            holder_tip = self._holder_tip
        else:
            holder_tip = attach(subs.spindle, subs.holder)
        return self.stack.frf_with(tool_point_coefficients(holder_tip, tool), kx, kt, cx, ct, *loss)
