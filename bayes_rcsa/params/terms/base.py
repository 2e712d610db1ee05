"""The model-term protocol: physical (or statistical) extensions of the RCSA model.

A model term owns a few parameters (each with a prior and a *baseline* value
at which the term vanishes) and changes one stage of the batched forward
evaluation.  Stages, in evaluation order, and the hook a term of that kind
implements:

=============  ==================  ==========================================================
kind           hook                acts on
=============  ==================  ==========================================================
spindle        :meth:`spindle`     the flange receptance, (B, n_lines, 2, 2)
substructure   :meth:`substructures`  holder / tool receptances before coupling (:class:`Substructures`)
joint          :meth:`joint`       contact parameters per configuration (:class:`Contact`)
frf            :meth:`frf`         the assembled tool-point FRF, (n_sets, n_lines)
=============  ==================  ==========================================================

Batch axes: ``values`` maps every parameter name to an ``(n_sets,)`` array of
physical values.  Receptance arrays carry a leading *batch* axis ``B`` that is
either 1 (shared by all parameter sets) or ``n_sets``; a term that makes a
substructure depend on its parameters returns ``B = n_sets``.  Hooks must be
vectorised over that axis and over lines (no Python loop per set or line)
and must not modify their inputs.

A term with all parameters at their baseline values must reproduce the
baseline model exactly (tests check this for every registered term).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, ClassVar, Mapping, NamedTuple, Sequence

import numpy as np

from ...model.timoshenko import TwoPort
from ..parameter import Parameter

if TYPE_CHECKING:  # pragma: no cover
    from ...model.assembly import Configuration, ToolPointModel

__all__ = ["KINDS", "Contact", "Substructures", "TermContext", "ModelTerm", "bend_growth_law"]

KINDS = ("spindle", "substructure", "joint", "frf")


class Contact(NamedTuple):
    """Contact parameters per parameter set and configuration, each (n_sets, n_cfg).

    ``k_xf`` N/m, ``k_thetaM`` N m/rad, ``c_xf`` N s/m, ``c_thetaM`` N m s/rad;
    ``h_xf`` N/m and ``h_thetaM`` N m/rad the hysteretic (rate-independent)
    loss stiffness, 0 unless a joint term sets it: the joint's complex
    stiffness is ``k + i (omega c + h)``.
    """

    k_xf: np.ndarray
    k_thetaM: np.ndarray
    c_xf: np.ndarray
    c_thetaM: np.ndarray
    h_xf: np.ndarray | float = 0.0
    h_thetaM: np.ndarray | float = 0.0


@dataclass(frozen=True)
class Substructures:
    """Receptances of the substructures on the stacked lines, before the joint.

    Attributes
    ----------
    spindle : (B, n_lines, 2, 2) complex
        Flange receptance of the spindle (after spindle terms).
    holder : TwoPort, blocks (B, n_lines, 2, 2)
        Free-free holder with the clamped shank; end 1 the flange, end 2 the holder tip.
    tool : TwoPort, blocks (B, n_lines, 2, 2)
        Free-free tool overhang; end 1 its base (at the holder tip), end 2 the tool tip.
    tip : (B, n_lines, 2) float or complex, or None
        Diagonal dynamic stiffness (N/m, N m/rad) attached at the tool tip's
        (u, psi), e.g. ``-omega^2 (m, m r_g^2)`` of a tip mass; ``None`` if
        nothing is attached.  Kept apart from ``tool`` so that the forward
        model can apply it after the joint with a compiled kernel (the tool
        two-port then stays shared by all parameter sets).
    """

    spindle: np.ndarray
    holder: TwoPort
    tool: TwoPort
    tip: np.ndarray | None = None

    def replace(self, **changes) -> "Substructures":
        return replace(self, **changes)

    def add_tip(self, z_u: np.ndarray, z_psi: np.ndarray) -> "Substructures":
        """A copy with ``diag(z_u, z_psi)`` (each (B, n_lines)) added to the tip's dynamic stiffness."""
        z_u, z_psi = np.asarray(z_u), np.asarray(z_psi)
        # real (undamped) attachments stay real: the compiled kernel is cheaper for them
        dtype = np.result_type(z_u, z_psi, np.float64) if self.tip is None else complex
        z = np.empty(np.broadcast_shapes(z_u.shape, z_psi.shape) + (2,), dtype=dtype)
        z[..., 0] = z_u
        z[..., 1] = z_psi
        return replace(self, tip=z if self.tip is None else self.tip + z)


@dataclass(frozen=True)
class TermContext:
    """Parameter-independent facts a term may read (never modify).

    Attributes
    ----------
    model : ToolPointModel
        Geometry, materials, tools and spindle files.
    configurations : tuple of Configuration
        One per stacked measurement / prediction.
    frequency_hz, omega : (n_lines,) Hz, rad/s
    line_config : (n_lines,) int
        Configuration index of every line.
    lengths : (n_cfg,) m
        Clamping length of every configuration.
    l_a, l_b : float
        m, the growth law's reference range (``l_a == l_b`` without growth).
    """

    model: "ToolPointModel"
    configurations: tuple
    frequency_hz: np.ndarray
    omega: np.ndarray
    line_config: np.ndarray
    lengths: np.ndarray
    l_a: float
    l_b: float


class ModelTerm:
    """Base class of model terms; subclasses are registered by name.

    Class attributes
    ----------------
    name : str
        Canonical name used in the setup's ``[model] terms`` list.
    kind : str
        One of :data:`KINDS`.
    description : str
        One line in a machinist's vocabulary ("a mass such as an
        accelerometer at the tool tip").
    role : str
        ``"term"`` for physical effects, ``"discrepancy"`` for statistical ones.
    """

    name: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    description: ClassVar[str] = ""
    role: ClassVar[str] = "term"
    #: Distinct fitted clamping lengths the term needs to have any effect on them (a law-shape term keeps the
    #: law's ends, so with two lengths it changes nothing the fit sees); the discrepancy workflow does not
    #: offer a term as a default candidate below this.
    min_clamping_lengths: ClassVar[int] = 1
    #: The parameter whose baseline switches the term off whatever its other parameters (a resonator's or a
    #: body's mass of 0); ``None`` when there is none.  The discrepancy screen's score test then differentiates
    #: only in it over the grid of the others (their derivatives are exactly 0 there); a test checks the claim
    #: for every term that makes it (tests/test_discrepancy_screen_switch.py).
    switch: ClassVar[str | None] = None

    def parameters(self, model: "ToolPointModel") -> tuple[Parameter, ...]:
        """The term's parameters with default priors and baselines for this model."""
        raise NotImplementedError

    def implausible(self, values: Mapping[str, float]) -> list[str]:
        """Why a fitted set of this term's parameters is physically impossible (empty: it is possible).

        For constraints between parameters that a box prior cannot express (e.g. a flute's second moment
        can never fall below that of the circle of the same area).  The discrepancy workflow does not name
        a candidate whose best fit is implausible: the term is then a stand-in for another effect.

        Parameters
        ----------
        values : mapping name -> float, physical values of (at least) the term's parameters
        """
        return []

    # -- hooks: implement the one of the term's kind -------------------------

    def spindle(self, values: Mapping[str, np.ndarray], spindle: np.ndarray, ctx: TermContext) -> np.ndarray:
        """New flange receptance (B, n_lines, 2, 2)."""
        raise NotImplementedError

    def substructures(self, values: Mapping[str, np.ndarray], subs: Substructures, ctx: TermContext) -> Substructures:
        """New holder / tool receptances."""
        raise NotImplementedError

    def joint(self, values: Mapping[str, np.ndarray], contact: Contact, lengths: np.ndarray,
              l_a: float, l_b: float) -> Contact:
        """New contact parameters (n_sets, n_cfg) at ``lengths`` (m).

        Called wherever contact parameters are needed (forward model,
        stiffness reports), so it gets the lengths and the growth range
        rather than a line context.
        """
        raise NotImplementedError

    def frf(self, values: Mapping[str, np.ndarray], h: np.ndarray, ctx: TermContext) -> np.ndarray:
        """New tool-point FRF (n_sets, n_lines) complex, m/N."""
        raise NotImplementedError

    # -- bookkeeping -----------------------------------------------------------

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "role": self.role, "description": self.description}

    @staticmethod
    def batch(values: Mapping[str, np.ndarray], name: str) -> np.ndarray:
        """``values[name]`` as an (n_sets, 1, 1) array for broadcasting against (B, n_lines, ...) arrays."""
        return np.asarray(values[name], dtype=float)[:, None, None]


def parameter_names(params: Sequence[Parameter]) -> tuple[str, ...]:
    return tuple(p.name for p in params)


def bend_growth_law(term: str, values, contact: Contact, lengths, l_a: float, l_b: float, shape) -> Contact:
    """Replace the linear growth law's ``x`` by ``shape(x)`` between the fitted lengths.

    Adds ``k_a g (shape(x) - x)`` to the incoming stiffnesses (so joint
    terms applied before are kept); ``shape(0) = 0`` and ``shape(1) = 1``
    keep the law's ends.  Shared by the law-shape terms
    (``nonlinear_stiffness_law``, ``stiffness_step``).

    Parameters
    ----------
    term : str, the calling term's name (for the error message)
    values : mapping with ``k_xf``, ``k_thetaM``, ``g_xf``, ``g_thetaM``, each (n_sets,)
    contact : Contact, fields (n_sets, n_cfg)
    lengths : (n_cfg,) m
    l_a, l_b : m, the growth law's range
    shape : callable, (1, n_cfg) normalised lengths -> (n_sets, n_cfg)

    Raises
    ------
    ModelError
        If the growth parameters are not in ``values``.
    """
    from ...errors import ModelError

    if not l_b > l_a:
        return contact  # one clamping length: no law between lengths to bend
    missing = [n for n in ("k_xf", "k_thetaM", "g_xf", "g_thetaM") if n not in values]
    if missing:
        raise ModelError(f"model term {term}: needs the growth-law parameters {missing} in its values")
    x = ((np.asarray(lengths, dtype=float) - l_a) / (l_b - l_a))[None, :]
    delta = shape(x) - x
    kx = np.asarray(contact.k_xf) + (np.asarray(values["k_xf"]) * np.asarray(values["g_xf"]))[:, None] * delta
    kt = np.asarray(contact.k_thetaM) + (np.asarray(values["k_thetaM"]) * np.asarray(values["g_thetaM"]))[:, None] * delta
    return contact._replace(k_xf=kx, k_thetaM=kt)
