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

Spindle samples.  Built with ``spindle_samples`` (bootstrap samples of the
flange receptance, :class:`bayes_rcsa.spindle.SpindleSamples`), the model
evaluates every parameter set with its own sample (``frf(values,
spindle_sample=index)``): the flange receptance ``S`` and the spindle +
holder coupling are the only parts that depend on the spindle, so each
sample gets a copy of the stack with them recomputed
(:meth:`CachedConfiguration.with_spindle`, built on first use and kept) while
the holder and tool two-ports stay shared.  The sets are grouped by sample
and each group runs steps 1-2 above on its sample's stack, so every model
term acts exactly as without samples (a spindle term on the sample's
flange); the *frf* terms then act once on all sets.  Directions the samples
do not cover keep the model's own spindle.

Everything is vectorised over parameter sets and lines; no Python loop runs
per set or per line (only one per spindle sample present in a batch).
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Mapping

import numpy as np

from ..errors import SetupError
from ..model.assembly import ConfigurationStack, ToolPointModel, tool_point_coefficients
from ..model.coupling import add_end_impedance, attach
from .model import ParameterModel
from .terms import Contact, Substructures, TermContext

if TYPE_CHECKING:  # pragma: no cover
    from ..spindle.uncertainty import SpindleSamples

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
    spindle_samples : SpindleSamples, optional
        Bootstrap samples of the flange receptance; then :meth:`frf` can
        evaluate each parameter set with its own sample (``spindle_sample``).
        Their frequency range must cover the stack's lines in every direction
        they hold.

    Notes
    -----
    Stable API: :meth:`frf` (physical values), :meth:`frf_theta` (sampling
    coordinates), :meth:`contact`, :attr:`context`, :attr:`spindle_samples`.
    Fixed contact damping is passed to the kernel as a scalar when no joint
    term can change it.
    """

    def __init__(self, parameters: ParameterModel, stack: ConfigurationStack, model: ToolPointModel,
                 spindle_samples: "SpindleSamples | None" = None):
        self.parameters = parameters
        self.stack = stack
        self.model = model
        self.spindle_samples = spindle_samples
        self._sample_models: dict[int, ForwardModel] = {}  # per spindle sample, built on first use
        if spindle_samples is not None:
            _check_sample_range(spindle_samples, stack)
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
        structural = {t.name for t in self._spindle_terms + self._substructure_terms}
        # sampled parameters that no spindle or substructure term reads (contact, growth, noise, FRF terms): sets
        # that differ only in them share their substructures (see _unique_sets)
        self._not_structural = {n for n in parameters.names if parameters[n].term not in structural}

    @property
    def n_lines(self) -> int:
        return self.stack.n_lines

    def contact(self, values: Mapping[str, np.ndarray]) -> Contact:
        """Contact parameters of every set and configuration, each (n_sets, n_cfg)."""
        return self.parameters.contact(values, self.lengths)

    def frf(self, values: Mapping[str, np.ndarray], spindle_sample: np.ndarray | None = None) -> np.ndarray:
        """Tool-point FRF on all lines, (n_sets, n_lines) complex m/N.

        Parameters
        ----------
        values : mapping name -> (n_sets,) physical values of every parameter
            (:meth:`ParameterModel.values`).
        spindle_sample : (n_sets,) int, optional
            Index into :attr:`spindle_samples` of every set's flange
            receptance (e.g. :func:`bayes_rcsa.spindle.assign_samples`);
            default: the model's own spindle for all sets.

        Raises
        ------
        SetupError
            ``spindle_sample`` without spindle samples, of the wrong length or
            out of range.
        """
        if spindle_sample is None:
            h = self._assembled(values)
        else:
            h = self._assembled_by_sample(values, self._check_assignment(spindle_sample, values))
        for t in self._frf_terms:
            h = t.frf(values, h, self.context)
        return h

    def grid_sums(self, values: Mapping[str, np.ndarray], n_x: int, n_t: int, data: np.ndarray,
                  weight: np.ndarray) -> np.ndarray | None:
        """``sum_lines weight |H - data|^2`` per configuration on a contact grid, or None where that is not separable.

        Equal to :meth:`frf` followed by the sums (to rounding) without
        forming the FRFs (:meth:`ConfigurationStack.grid_sums`): the grid
        search's evaluation.

        Parameters
        ----------
        values : mapping name -> (n_x * n_t,) physical values
            Grid point ``(a, b)`` at index ``a * n_t + b``; the translational
            joint must vary only with ``a`` and the rotational one only with ``b``.
        n_x, n_t : int
        data : (n_lines,) complex, m/N
        weight : (n_lines,) float

        Returns
        -------
        (n_x, n_t, n_configs) float, or None
            None when a spindle, substructure or FRF term is active (the FRF
            is then not the plain joint formula) or the joint terms make the
            translational joint depend on the column or the rotational joint
            on the row; then evaluate with :meth:`frf`.
        """
        grid = self._separable_grid(values, n_x, n_t)
        return None if grid is None else self.stack.grid_sums(*grid, data, weight)

    def grid_profile_sums(self, values: Mapping[str, np.ndarray], n_x: int, n_t: int, data: np.ndarray,
                          coherence: np.ndarray, eps2: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The likelihood's ``sum |H - data|^2 / v`` and ``sum ln v`` per configuration on a contact grid, or None.

        :meth:`grid_sums` with the noise model's variance ``v`` of the *model* FRF in place of fixed weights
        (:meth:`ConfigurationStack.grid_profile_sums`): the exact grid search's evaluation.  None under the
        same conditions as :meth:`grid_sums`.

        Parameters
        ----------
        values, n_x, n_t, data : as :meth:`grid_sums`
        coherence : (n_lines,) float in (0, 1]
        eps2 : float, squared relative noise floor

        Returns
        -------
        (Q, L), each (n_x, n_t, n_configs) float, or None
        """
        grid = self._separable_grid(values, n_x, n_t)
        return None if grid is None else self.stack.grid_profile_sums(*grid, data, coherence, eps2)

    def _separable_grid(self, values: Mapping[str, np.ndarray], n_x: int, n_t: int):
        """(rows, columns) of a contact grid for the stack's grid kernels, or None where the FRF is not the plain
        joint formula or the joints are not separable (see :meth:`grid_sums`)."""
        if self._spindle_terms or self._substructure_terms or self._frf_terms:
            return None
        contact = self.contact(values)
        n_cfg = self.lengths.size
        shape = (n_x, n_t, n_cfg)
        parts = [contact.k_xf, self._scalar_damping.get("c_xf", contact.c_xf), contact.h_xf,
                 contact.k_thetaM, self._scalar_damping.get("c_thetaM", contact.c_thetaM), contact.h_thetaM]
        grids = [np.broadcast_to(np.asarray(v, dtype=float), (n_x * n_t, n_cfg)).reshape(shape) for v in parts]
        rows = [g[:, 0, :] for g in grids[:3]]
        columns = [g[0, :, :] for g in grids[3:]]
        if not (all(np.all(g == r[:, None, :]) for g, r in zip(grids[:3], rows))
                and all(np.all(g == c[None, :, :]) for g, c in zip(grids[3:], columns))):
            return None
        return rows, columns

    def frf_theta(self, theta: np.ndarray, spindle_sample: np.ndarray | None = None) -> np.ndarray:
        """:meth:`frf` for sampling coordinates ``theta`` (n, ndim)."""
        return self.frf(self.parameters.values(np.atleast_2d(theta)), spindle_sample)

    def _assembled(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Steps 1-2 of the module notes on this model's stack: the FRFs before the *frf* terms."""
        contact = self.contact(values)
        kx, kt = contact.k_xf, contact.k_thetaM
        cx = self._scalar_damping.get("c_xf", contact.c_xf)
        ct = self._scalar_damping.get("c_thetaM", contact.c_thetaM)
        loss = (contact.h_xf, contact.h_thetaM)
        if self._spindle_terms or self._substructure_terms:
            h = self._general(values, kx, kt, cx, ct, loss)
        else:
            h = self.stack.frf(kx, kt, cx, ct, *loss)
        return h

    def _check_assignment(self, spindle_sample, values: Mapping[str, np.ndarray]) -> np.ndarray:
        samples = self.spindle_samples
        if samples is None:
            raise SetupError("spindle_sample given, but the forward model was built without spindle_samples")
        index = np.asarray(spindle_sample)
        n_sets = next((np.shape(v)[0] for v in values.values() if np.ndim(v) >= 1), 1)
        if index.shape != (n_sets,) or not np.issubdtype(index.dtype, np.integer) or \
                np.any(index < 0) or np.any(index >= samples.n_samples):
            raise SetupError(f"{samples.source}: spindle_sample must hold {n_sets} integer sample indices in "
                             f"[0, {samples.n_samples}), got shape {index.shape} of {index.dtype}")
        return index

    def _assembled_by_sample(self, values: Mapping[str, np.ndarray], index: np.ndarray) -> np.ndarray:
        """Steps 1-2 with every set on its own spindle sample's stack, grouped by sample."""
        n_sets = index.size
        out = np.empty((n_sets, self.n_lines), dtype=complex)
        for j in np.unique(index):
            rows = np.flatnonzero(index == j)
            part = {k: (np.asarray(v)[rows] if np.ndim(v) >= 1 and np.shape(v)[0] == n_sets else v)
                    for k, v in values.items()}
            out[rows] = self._sample_model(int(j))._assembled(part)
        return out

    def _sample_model(self, j: int) -> "ForwardModel":
        """This model on spindle sample ``j``'s stack (same parameters, terms and context), cached."""
        fm = self._sample_models.get(j)
        if fm is None:
            samples = self.spindle_samples
            caches = [c.with_spindle(samples.receptance(c.configuration.direction, j).interpolate(c.frequency_hz))
                      if c.configuration.direction in samples.nominal else c for c in self.stack.caches]
            # a shallow copy shares the term context, so terms that cache per context (the spindle terms' modal
            # data) compute it once for all samples
            fm = copy.copy(self)
            fm.stack = ConfigurationStack(caches)
            fm.spindle_samples = None
            fm._sample_models = {}
            fm._holder_tip = None
            self._sample_models[j] = fm
        return fm

    def substructures(self, values: Mapping[str, np.ndarray]) -> Substructures:
        """The substructures after the spindle and substructure terms (batch axis 1 or n_sets)."""
        spindle, holder, tool = self.stack.substructures()
        for t in self._spindle_terms:
            spindle = t.spindle(values, spindle, self.context)
        subs = Substructures(spindle, holder, tool)
        for t in self._substructure_terms:
            subs = t.substructures(values, subs, self.context)
        return subs

    def _unique_sets(self, values, n_sets: int):
        """Sets with distinct structural-term values: (first index of each, inverse map), or None if all differ.

        A grid over the contact (the optimiser's start search, a leave-one-length-out refit) varies only the
        contact, so the spindle and holder coupling of one set serves them all: it is computed once per distinct
        term value instead of once per set (the 2x2 inversions per line are most of the cost).
        """
        if n_sets <= 1:
            return None
        cols = [np.broadcast_to(np.asarray(v, dtype=float), (n_sets,)) for k, v in values.items()
                if k not in self._not_structural and np.ndim(v) <= 1 and np.size(v) in (1, n_sets)]
        if not cols:
            return None
        _, first, inverse = np.unique(np.column_stack(cols), axis=0, return_index=True, return_inverse=True)
        if first.size == n_sets:
            return None
        return first, inverse.ravel()

    def _general(self, values, kx, kt, cx, ct, loss=(0.0, 0.0)) -> np.ndarray:
        base_spindle, base_holder, base_tool = self.stack.substructures()
        shape = kx.shape
        unique = self._unique_sets(values, shape[0])
        if unique is not None:
            first, inverse = unique
            values = {k: (np.asarray(v)[first] if np.ndim(v) == 1 and np.size(v) == shape[0] else v)
                      for k, v in values.items()}
        subs = self.substructures(values)
        cx = np.broadcast_to(np.asarray(cx, dtype=float), shape)
        ct = np.broadcast_to(np.asarray(ct, dtype=float), shape)
        same = subs.spindle is base_spindle and subs.holder is base_holder and subs.tool is base_tool
        if same and subs.tip is None:
            return self.stack.frf(kx, kt, cx, ct, *loss)  # every term at its baseline
        if same:
            # only something attached at the tip: the cached blocks stay shared by all sets
            tip = subs.tip if unique is None else self._per_set(subs.tip, unique)
            return self.stack.frf_tip(tip, kx, kt, cx, ct, *loss)
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
        coef = tool_point_coefficients(holder_tip, tool)
        if unique is not None:
            coef = {k: self._per_set(v, unique) for k, v in coef.items()}
        return self.stack.frf_with(coef, kx, kt, cx, ct, *loss)

    @staticmethod
    def _per_set(a: np.ndarray, unique) -> np.ndarray:
        """Rows of the distinct sets back to one row per set; a batch axis of 1 is shared by all sets as it is."""
        first, inverse = unique
        return a[inverse] if first.size > 1 and np.shape(a)[0] == first.size else a


def _check_sample_range(samples: "SpindleSamples", stack: ConfigurationStack) -> None:
    """Refuse spindle samples that do not cover the lines of a configuration in one of their directions."""
    f = samples.frequency_hz
    tol = 1e-12 * f[-1]  # as PointReceptance.interpolate: decimal text grids match the ends
    for c in stack.caches:
        cf = c.frequency_hz
        if c.configuration.direction in samples.nominal and (cf[0] < f[0] - tol or cf[-1] > f[-1] + tol):
            raise SetupError(f"{samples.source}: the spindle samples cover {f[0]:g}-{f[-1]:g} Hz; "
                             f"{c.configuration.label()} needs {cf[0]:g}-{cf[-1]:g} Hz")
