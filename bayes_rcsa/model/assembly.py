"""The RCSA assembly: spindle -> holder (with clamped shank) -> elastic contact -> tool.

Everything that does not depend on the contact parameters (beam receptances,
the spindle-holder coupling) is computed once per configuration by
:meth:`ToolPointModel.precompute`.  The result, a :class:`CachedConfiguration`,
evaluates the tool-point FRF for a whole batch of contact parameter sets with
a handful of elementwise complex operations.  :class:`ConfigurationStack`
concatenates several configurations (clamping lengths, tools, directions) on
one flat axis of frequency lines so that a batch of walkers is evaluated on
all measurements at once.

Derivation of the fast path.  With ``S`` the holder-tip point receptance of
spindle + holder, ``T`` the tool-overhang two-port (end 1 base, end 2 tip)
and ``K`` the contact stiffness, the tool-point block is
``T22 - T21 (S + T11 + K^-1)^-1 T12``.  Only its ``h`` entry is measured, so
with ``E = S + T11``, ``a = T21[0, :]``, ``b = T12[:, 0]``, ``A = E00 + 1/kx``
and ``B = E11 + 1/ktheta``::

    h = T22[0,0] - (p B + q A - r) / (A B - g)
    p = a0 b0,  q = a1 b1,  r = a0 E01 b1 + a1 E10 b0,  g = E01 E10
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from ..errors import SetupError
from ._kernels import (grid_profile_kernel, grid_sums_kernel, pack_coefficients, tip_coefficients, tool_point_kernel,
                       tool_point_kernel_batched, tool_point_kernel_tip)
from .coupling import attach, contact_compliance
from .geometry import Holder, Tool, holder_segments, tool_overhang_segments
from .receptance import PointReceptance
from .timoshenko import TwoPort, free_free_receptances

__all__ = ["Configuration", "ToolPointModel", "CachedConfiguration", "ConfigurationStack", "tool_point_coefficients",
           "COEFFICIENT_NAMES"]

#: The parameter-independent coefficients of the fast path, in the order the kernels pack them.
COEFFICIENT_NAMES = ("t22", "e00", "e11", "g", "p", "q", "r")


def tool_point_coefficients(holder_tip: np.ndarray, tool: TwoPort) -> dict[str, np.ndarray]:
    """Coefficients of the fast tool-point formula (module docstring) from the substructures.

    The one implementation of the formula, used by :meth:`ToolPointModel.precompute`
    and by the general path of the parameter model when a term changes a
    substructure.

    Parameters
    ----------
    holder_tip : (..., n_freq, 2, 2) complex
        Spindle + holder point receptance at the holder tip.
    tool : TwoPort with (..., n_freq, 2, 2) blocks
        Tool overhang, end 1 base, end 2 tip.

    Returns
    -------
    dict of name (:data:`COEFFICIENT_NAMES`) -> (..., n_freq) complex
    """
    e = holder_tip + tool.r11
    a0, a1 = tool.r21[..., 0, 0], tool.r21[..., 0, 1]
    b0, b1 = tool.r12[..., 0, 0], tool.r12[..., 1, 0]
    return {
        "t22": tool.r22[..., 0, 0].copy(),
        "e00": e[..., 0, 0].copy(),
        "e11": e[..., 1, 1].copy(),
        "g": e[..., 0, 1] * e[..., 1, 0],
        "p": a0 * b0,
        "q": a1 * b1,
        "r": a0 * e[..., 0, 1] * b1 + a1 * e[..., 1, 0] * b0,
    }

DIRECTIONS = ("x", "y")


@dataclass(frozen=True)
class Configuration:
    """One measured or predicted set-up.

    Parameters
    ----------
    clamping_length : float
        m, length of the tool shank inside the holder.
    direction : {"x", "y"}
    tool : str
        Name of the tool in the model's tool table.
    """

    clamping_length: float
    direction: str = "x"
    tool: str = "tool"

    def label(self) -> str:
        return f"{self.tool} {self.direction} l={self.clamping_length * 1e3:.1f} mm"


@dataclass(frozen=True)
class CachedConfiguration:
    """Parameter-independent parts of the tool-point FRF for one configuration.

    All arrays have shape (n_freq,).  Create with :meth:`ToolPointModel.precompute`.
    """

    configuration: Configuration
    frequency_hz: np.ndarray
    omega: np.ndarray
    t22: np.ndarray
    e00: np.ndarray
    e11: np.ndarray
    g: np.ndarray
    p: np.ndarray
    q: np.ndarray
    r: np.ndarray
    holder_tip: np.ndarray  # (n_freq, 2, 2) spindle+holder point receptance at the holder tip
    tool: TwoPort  # tool overhang two-port, end 1 base, end 2 tip
    # Substructures before coupling, for model terms that change one of them (kept: ~5 blocks of
    # (n_freq, 2, 2) complex, 320 bytes per line).
    spindle: np.ndarray | None = None  # (n_freq, 2, 2) flange receptance of the spindle
    holder: TwoPort | None = None  # free-free holder with the clamped shank, end 1 flange, end 2 holder tip

    def frf(self, k_xf, k_thetaM, c_xf=0.0, c_thetaM=0.0, h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Tool-point receptance h = u/F for a batch of contact parameters.

        Parameters
        ----------
        k_xf : (...) N/m
        k_thetaM : (...) N m/rad
        c_xf : (...) N s/m
        c_thetaM : (...) N m s/rad
        h_xf : (...) N/m
        h_thetaM : (...) N m/rad
            Broadcastable arrays, one value per parameter set.  ``h`` is the
            hysteretic loss stiffness: the joint is ``k + i (omega c + h)``.

        Returns
        -------
        (..., n_freq) complex, m/N
        """
        return _fast_h(
            self.omega, self.t22, self.e00, self.e11, self.g, self.p, self.q, self.r,
            *(np.asarray(v, dtype=float)[..., None] for v in (k_xf, k_thetaM, c_xf, c_thetaM, h_xf, h_thetaM)),
        )

    def block(self, k_xf, k_thetaM, c_xf=0.0, c_thetaM=0.0, h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Full 2x2 tool-point receptance block, shape (..., n_freq, 2, 2).

        Slower general path (used for rotations at the tip and for checks);
        ``numpy.inf`` stiffness gives a rigid joint.
        """
        comp = contact_compliance(self.omega, k_xf, k_thetaM, c_xf, c_thetaM, h_xf, h_thetaM)
        return attach(self.holder_tip, self.tool, comp)

    def with_spindle(self, spindle: np.ndarray) -> "CachedConfiguration":
        """The same configuration with another flange receptance (e.g. a bootstrap sample of the spindle).

        Only the spindle + holder coupling and the fast-path coefficients are
        recomputed; the holder and tool two-ports (the beam receptances, most
        of :meth:`ToolPointModel.precompute`'s cost) are shared.  Gives what
        ``precompute`` of a model with that spindle gives, bit for bit.

        Parameters
        ----------
        spindle : (n_freq, 2, 2) complex
            Flange block ``[[h, l], [n, p]]`` on this cache's lines (m/N, 1/N, rad/N, rad/(N m)).
        """
        if self.holder is None:
            raise SetupError(f"{self.configuration.label()}: the cache was built without its substructures "
                             "(use ToolPointModel.precompute)")
        spindle = np.asarray(spindle, dtype=complex)
        if spindle.shape != (self.frequency_hz.size, 2, 2):
            raise SetupError(f"{self.configuration.label()}: spindle block of shape {spindle.shape}; expected "
                             f"({self.frequency_hz.size}, 2, 2)")
        holder_tip = attach(spindle, self.holder)
        return replace(self, **tool_point_coefficients(holder_tip, self.tool), holder_tip=holder_tip, spindle=spindle)


def _fast_h(omega, t22, e00, e11, g, p, q, r, kx, kt, cx, ct, hx=0.0, ht=0.0):
    a = e00 + 1.0 / (kx + 1j * (omega * cx + hx))
    b = e11 + 1.0 / (kt + 1j * (omega * ct + ht))
    return t22 - (p * b + q * a - r) / (a * b - g)


def _loss_like(kx: np.ndarray, h_xf, h_thetaM) -> tuple[np.ndarray, np.ndarray]:
    """The hysteretic loss stiffnesses as contiguous arrays of ``kx``'s shape (scalars broadcast)."""
    return tuple(np.ascontiguousarray(np.broadcast_to(np.asarray(h, dtype=float), kx.shape)) for h in (h_xf, h_thetaM))


class ToolPointModel:
    """RCSA model of spindle, holder, elastic tool-holder contact and tool.

    Parameters
    ----------
    holder : Holder
    tools : mapping of str to Tool
    spindle : mapping of direction ("x"/"y") to PointReceptance
        Measured or identified 2x2 receptance at the holder flange.

    Notes
    -----
    The model holds no mutable state: :meth:`precompute` returns a new
    immutable cache that the caller keeps.
    """

    def __init__(self, holder: Holder, tools: Mapping[str, Tool], spindle: Mapping[str, PointReceptance]):
        if not tools:
            raise SetupError("the model needs at least one tool")
        if not spindle:
            raise SetupError("the model needs the spindle receptance in at least one direction")
        for d in spindle:
            if d not in DIRECTIONS:
                raise SetupError(f"spindle direction {d!r}: expected one of {DIRECTIONS}")
        self.holder = holder
        self.tools = dict(tools)
        self.spindle = dict(spindle)

    def tool(self, name: str) -> Tool:
        try:
            return self.tools[name]
        except KeyError:
            raise SetupError(f"unknown tool {name!r}; known tools: {sorted(self.tools)}") from None

    def spindle_receptance(self, direction: str) -> PointReceptance:
        try:
            return self.spindle[direction]
        except KeyError:
            raise SetupError(
                f"no spindle receptance for direction {direction!r}; available: {sorted(self.spindle)}"
            ) from None

    def substructures(self, configuration: Configuration, frequency_hz) -> tuple[np.ndarray, TwoPort]:
        """Holder-tip point receptance of spindle + holder, and the tool two-port.

        Returns
        -------
        holder_tip : (n_freq, 2, 2) complex
        tool : TwoPort with (n_freq, 2, 2) blocks
        """
        spindle, holder, overhang = self._parts(configuration, frequency_hz)
        return attach(spindle, holder), overhang

    def _parts(self, configuration: Configuration, frequency_hz) -> tuple[np.ndarray, TwoPort, TwoPort]:
        """Flange receptance, holder two-port and tool-overhang two-port on ``frequency_hz``."""
        f = np.asarray(frequency_hz, dtype=float)
        omega = 2 * np.pi * f
        tool = self.tool(configuration.tool)
        spindle = self.spindle_receptance(configuration.direction).interpolate(f)
        holder = free_free_receptances(holder_segments(self.holder, tool, configuration.clamping_length), omega)
        overhang = free_free_receptances(tool_overhang_segments(self.holder, tool, configuration.clamping_length), omega)
        return spindle, holder, overhang

    def precompute(self, configuration: Configuration, frequency_hz) -> CachedConfiguration:
        """Cache everything independent of the contact parameters.

        Parameters
        ----------
        configuration : Configuration
        frequency_hz : (n_freq,) Hz, inside the spindle file's range
        """
        f = np.asarray(frequency_hz, dtype=float)
        spindle, holder, t = self._parts(configuration, f)
        holder_tip = attach(spindle, holder)
        return CachedConfiguration(
            configuration=configuration,
            frequency_hz=f,
            omega=2 * np.pi * f,
            **tool_point_coefficients(holder_tip, t),
            holder_tip=holder_tip,
            tool=t,
            spindle=spindle,
            holder=holder,
        )

    def frf(self, configuration: Configuration, frequency_hz, k_xf, k_thetaM, c_xf=0.0, c_thetaM=0.0,
            h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Convenience: precompute and evaluate once. Shape (..., n_freq), m/N."""
        return self.precompute(configuration, frequency_hz).frf(k_xf, k_thetaM, c_xf, c_thetaM, h_xf, h_thetaM)


class ConfigurationStack:
    """Several cached configurations on one flat axis of frequency lines.

    Parameters
    ----------
    caches : sequence of CachedConfiguration

    Attributes
    ----------
    index : (n_lines,) int
        Configuration index of every line.
    slices : list of slice
        Lines of each configuration in the flat axis.
    """

    def __init__(self, caches: Sequence[CachedConfiguration]):
        if len(caches) == 0:
            raise SetupError("a configuration stack needs at least one configuration")
        self.caches = tuple(caches)
        sizes = [c.frequency_hz.size for c in caches]
        edges = np.concatenate([[0], np.cumsum(sizes)])
        self.slices = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
        self.index = np.repeat(np.arange(len(caches)), sizes)
        cat = lambda name: np.concatenate([getattr(c, name) for c in caches])  # noqa: E731
        self._arrays = tuple(cat(n) for n in ("omega", "t22", "e00", "e11", "g", "p", "q", "r"))
        self._starts = edges.astype(np.int64)
        self._packed = pack_coefficients(dict(zip(COEFFICIENT_NAMES, self._arrays[1:])))
        self.frequency_hz = cat("frequency_hz")
        self.omega = self._arrays[0]
        self._parts = None  # substructures of all lines, built on first use by a model term
        self._tip_blocks = None  # per-line constants of frf_tip (tip_coefficients), built on first use

    @property
    def configurations(self) -> list[Configuration]:
        return [c.configuration for c in self.caches]

    @property
    def n_lines(self) -> int:
        return self.index.size

    def frf(self, k_xf, k_thetaM, c_xf=0.0, c_thetaM=0.0, h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Tool-point FRFs of all configurations for a batch of parameter sets.

        Parameters
        ----------
        k_xf, k_thetaM, c_xf, c_thetaM, h_xf, h_thetaM : (n_sets, n_configs) or broadcastable
            Contact parameters per set and per configuration (SI units as
            :meth:`CachedConfiguration.frf`).  A 1-D array is read as one
            value per set, shared by all configurations.

        Returns
        -------
        (n_sets, n_lines) complex, m/N
        """
        n_cfg = len(self.caches)
        params = []
        for v in (k_xf, k_thetaM, c_xf, c_thetaM, h_xf, h_thetaM):
            v = np.asarray(v, dtype=float)
            if v.ndim == 1:
                v = v[:, None]
            params.append(v)
        lead = {v.shape[:-1] for v in params if v.ndim > 1}
        if len(lead) == 1 and len(shape := next(iter(lead))) == 1:
            n_sets = shape[0]  # the sampler's case, one batch shape: without broadcast_shapes' Python-level set-up
        else:
            n_sets = int(np.prod(np.broadcast_shapes(*(v.shape[:-1] if v.ndim else () for v in params)) or (1,)))
        shape = (n_sets, n_cfg)
        # filled blocks, not np.broadcast_to views: this runs once per sampler step, and broadcast_to's
        # Python-level set-up cost more than the kernel itself on the calibration test's two-length problems
        blocks = []
        for v in params:
            b = np.empty(shape)
            b[...] = v
            blocks.append(b)
        kx, kt, cx, ct, hx, ht = blocks
        out = np.empty((n_sets, self.n_lines), dtype=complex)
        tool_point_kernel(kx, kt, cx, ct, hx, ht, self._starts, self.omega, self._packed, out)
        return out

    def grid_sums(self, rows: Sequence[np.ndarray], columns: Sequence[np.ndarray], data: np.ndarray,
                  weight: np.ndarray) -> np.ndarray:
        """``sum_lines weight |H - data|^2`` per configuration on a grid of contacts, without forming ``H``.

        Grid point ``(a, b)`` has the translational joint of row ``a`` and the
        rotational joint of column ``b``.  Same arithmetic as :meth:`frf`
        rearranged (the FRF is a Moebius map of the rotational stiffness for a
        fixed translational one), so the sums agree with :meth:`frf` to
        rounding; about four times faster than :meth:`frf` plus the sums.

        Parameters
        ----------
        rows : (k_xf, c_xf, h_xf), each (n_x, n_configs)
            N/m, N s/m, N/m.
        columns : (k_thetaM, c_thetaM, h_thetaM), each (n_t, n_configs)
            N m/rad, N m s/rad, N m/rad.
        data : (n_lines,) complex, m/N
        weight : (n_lines,) float

        Returns
        -------
        (n_x, n_t, n_configs) float
        """
        rows, columns, d = self._grid_inputs(rows, columns, data)
        q = np.empty((rows[0].shape[0], columns[0].shape[0], len(self.caches)))
        grid_sums_kernel(*rows, *columns, self._starts, self.omega, self._packed, d,
                         np.ascontiguousarray(weight, dtype=float), q)
        return q

    def grid_profile_sums(self, rows: Sequence[np.ndarray], columns: Sequence[np.ndarray], data: np.ndarray,
                          coherence: np.ndarray, eps2: float) -> tuple[np.ndarray, np.ndarray]:
        """The likelihood's own sums per configuration on a grid of contacts, without forming ``H``.

        With the noise model's variance ``v_n = (|H_n|^2 + eps2 max_config |H|^2) / coherence_n``
        (:func:`bayes_rcsa.inference.likelihood.noise_variance`, each configuration one measurement):
        ``Q = sum_lines |H - data|^2 / v`` and ``L = sum_lines ln v``, the two sums of the log-likelihood
        with its noise scale profiled out.  Same arithmetic as :meth:`grid_sums`; the band maximum
        needs a second pass over each configuration's lines.

        Parameters
        ----------
        rows, columns, data : as :meth:`grid_sums`
        coherence : (n_lines,) float in (0, 1]
        eps2 : float, squared relative noise floor

        Returns
        -------
        Q, L : (n_x, n_t, n_configs) float
            ``Q`` dimensionless, ``L`` the sum of ``ln v`` with ``v`` in (m/N)^2.
        """
        rows, columns, d = self._grid_inputs(rows, columns, data)
        shape = (rows[0].shape[0], columns[0].shape[0], len(self.caches))
        q, lv = np.empty(shape), np.empty(shape)
        grid_profile_kernel(*rows, *columns, self._starts, self.omega, self._packed, d,
                            np.ascontiguousarray(coherence, dtype=float), float(eps2), q, lv)
        return q, lv

    def _grid_inputs(self, rows, columns, data):
        """Contiguous (n, n_configs) rows and columns and the data's (2, n_lines) real/imaginary parts."""
        n_cfg = len(self.caches)
        rows = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), np.shape(rows[0]))) for v in rows]
        columns = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), np.shape(columns[0])))
                   for v in columns]
        if rows[0].ndim != 2 or rows[0].shape[1] != n_cfg or columns[0].ndim != 2 or columns[0].shape[1] != n_cfg:
            raise ValueError(f"grid rows and columns must be (n, {n_cfg}), got {rows[0].shape} and {columns[0].shape}")
        d = np.ascontiguousarray(np.stack([np.real(data), np.imag(data)]), dtype=float)
        return rows, columns, d

    def frf_numpy(self, k_xf, k_thetaM, c_xf=0.0, c_thetaM=0.0, h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Same as :meth:`frf` with plain numpy array operations (reference path)."""
        n_cfg = len(self.caches)
        per_line = []
        for v in (k_xf, k_thetaM, c_xf, c_thetaM, h_xf, h_thetaM):
            v = np.asarray(v, dtype=float)
            if v.ndim == 0:
                per_line.append(v)
            else:
                if v.ndim == 1:
                    v = v[:, None]
                v = np.broadcast_to(v, v.shape[:-1] + (n_cfg,))
                per_line.append(v[..., self.index])
        return _fast_h(*self._arrays, *per_line)

    def substructures(self) -> tuple[np.ndarray, TwoPort, TwoPort]:
        """Flange receptance, holder and tool two-ports of all lines, each with a leading batch axis of 1.

        Returns
        -------
        spindle : (1, n_lines, 2, 2) complex
        holder, tool : TwoPort with (1, n_lines, 2, 2) blocks
        """
        if self._parts is None:
            if any(c.spindle is None or c.holder is None for c in self.caches):
                raise SetupError("a model term needs the substructures, but a cache was built without them "
                                 "(use ToolPointModel.precompute)")
            cat = lambda arrays: np.concatenate(arrays)[None]  # noqa: E731
            two = lambda name: TwoPort(*(cat([getattr(getattr(c, name), r) for c in self.caches])  # noqa: E731
                                         for r in ("r11", "r12", "r21", "r22")))
            self._parts = (cat([c.spindle for c in self.caches]), two("holder"), two("tool"))
        return self._parts

    def frf_with(self, coefficients: Mapping[str, np.ndarray], k_xf, k_thetaM, c_xf, c_thetaM,
                 h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Tool-point FRFs from batched coefficients (a term changed a substructure).

        Parameters
        ----------
        coefficients : mapping name -> (B, n_lines) complex
            :func:`tool_point_coefficients` of the changed substructures on
            this stack's lines; ``B`` is 1 or ``n_sets``.
        k_xf, k_thetaM, c_xf, c_thetaM : (n_sets, n_configs)
        h_xf, h_thetaM : (n_sets, n_configs) or scalar, hysteretic loss stiffness

        Returns
        -------
        (n_sets, n_lines) complex, m/N
        """
        kx, kt, cx, ct = (np.ascontiguousarray(v, dtype=float) for v in (k_xf, k_thetaM, c_xf, c_thetaM))
        hx, ht = _loss_like(kx, h_xf, h_thetaM)
        n_sets = kx.shape[0]
        b = max(np.shape(coefficients[name])[0] for name in COEFFICIENT_NAMES)
        if b not in (1, n_sets):
            raise SetupError(f"substructure batch of {b} for {n_sets} parameter sets: expected 1 or {n_sets}")
        packed = np.empty((b, 14, self.n_lines))
        for i, name in enumerate(COEFFICIENT_NAMES):
            c = np.broadcast_to(coefficients[name], (b, self.n_lines))
            packed[:, 2 * i] = c.real
            packed[:, 2 * i + 1] = c.imag
        out = np.empty((n_sets, self.n_lines), dtype=complex)
        tool_point_kernel_batched(kx, kt, cx, ct, hx, ht, self._starts, self.omega, packed, out)
        return out

    def frf_tip(self, tip: np.ndarray, k_xf, k_thetaM, c_xf, c_thetaM, h_xf=0.0, h_thetaM=0.0) -> np.ndarray:
        """Tool-point FRFs with a diagonal dynamic stiffness attached at the tool tip.

        Parameters
        ----------
        tip : (B, n_lines, 2) float or complex
            ``(z_u, z_psi)`` per line (N/m, N m/rad), ``B`` 1 or ``n_sets``
            (real for an undamped attachment such as a mass).
        k_xf, k_thetaM, c_xf, c_thetaM : (n_sets, n_configs)
        h_xf, h_thetaM : (n_sets, n_configs) or scalar, hysteretic loss stiffness

        Returns
        -------
        (n_sets, n_lines) complex, m/N
        """
        if self._tip_blocks is None:
            cat = lambda get: np.ascontiguousarray(np.concatenate([get(c) for c in self.caches]))  # noqa: E731
            self._tip_blocks = tip_coefficients(cat(lambda c: c.holder_tip + c.tool.r11), cat(lambda c: c.tool.r12),
                                                cat(lambda c: c.tool.r21), cat(lambda c: c.tool.r22))
        kx, kt, cx, ct = (np.ascontiguousarray(v, dtype=float) for v in (k_xf, k_thetaM, c_xf, c_thetaM))
        hx, ht = _loss_like(kx, h_xf, h_thetaM)
        z = np.ascontiguousarray(tip)
        if z.dtype not in (np.float64, np.complex128):
            z = z.astype(complex)
        if z.shape[0] not in (1, kx.shape[0]) or z.shape[1:] != (self.n_lines, 2):
            raise SetupError(f"tip impedance of shape {z.shape}: expected (1 or {kx.shape[0]}, {self.n_lines}, 2)")
        out = np.empty((kx.shape[0], self.n_lines), dtype=complex)
        tool_point_kernel_tip(kx, kt, cx, ct, hx, ht, self._starts, self.omega, self._tip_blocks, z, out)
        return out

    def cache_digest(self) -> str:
        """SHA-256 of the cached lines and coefficients (changes with any geometry, material or spindle change)."""
        import hashlib

        h = hashlib.sha256()
        for a in (self.omega, self._packed, self._starts):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()

    def split(self, values: np.ndarray) -> list[np.ndarray]:
        """Split ``(..., n_lines)`` into one array per configuration."""
        return [values[..., s] for s in self.slices]
