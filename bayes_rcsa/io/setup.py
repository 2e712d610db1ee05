"""The setup file (TOML): materials, spindle files, holder, tools, contact priors, measurements.

The binding minimum of keys is the example in the project's data contract
(docs/data-formats.md).  Parsing is strict about what it understands and
names the file and key of every problem.

This module defines the parsed, immutable :class:`Setup`; the parser is
:func:`load_setup`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..model.assembly import Configuration, ToolPointModel
from ..model.geometry import Holder, Tool
from ..model.materials import Material
from ..model.receptance import FRF, PointReceptance

__all__ = ["ContactSpec", "MeasurementSpec", "Setup", "load_setup"]


@dataclass(frozen=True)
class ContactSpec:
    """Prior information on the tool-holder contact (the ``[contact]`` table).

    Attributes
    ----------
    translational_stiffness : (lo, hi) N/m
        Log-uniform bounds of k_xf at the shortest feasible clamping length.
    rotational_stiffness : (lo, hi) N m/rad
        Log-uniform bounds of k_thetaM at the shortest feasible clamping length.
    growth_bound : float
        Q >= 0: K(l2) - K(l1) <= Q K(l1) for l2 > l1 in the feasible range.
    clamping_range : (l_a, l_b) m or None
        Feasible clamping lengths; ``None`` means the range of the measurements.
    translational_damping : float or (lo, hi)
        N s/m; a number fixes c_xf, a pair samples it (log-uniform).
    rotational_damping : float or (lo, hi)
        N m s/rad; as above for c_thetaM.
    """

    translational_stiffness: tuple[float, float]
    rotational_stiffness: tuple[float, float]
    growth_bound: float = 0.5
    clamping_range: tuple[float, float] | None = None
    translational_damping: float | tuple[float, float] = 0.0
    rotational_damping: float | tuple[float, float] = 0.0


@dataclass(frozen=True)
class MeasurementSpec:
    """One ``[[measurement]]`` entry with its loaded FRF.

    Attributes
    ----------
    file : Path
        Absolute path (the setup gives it relative to the setup file).
    clamping_length : float, m
    direction : {"x", "y"}
    tool : str
    frf : FRF or None
        ``None`` when the setup was loaded with ``load_data=False``.
    """

    file: Path
    clamping_length: float
    direction: str = "x"
    tool: str = "tool"
    frf: FRF | None = None

    @property
    def configuration(self) -> Configuration:
        return Configuration(self.clamping_length, self.direction, self.tool)


@dataclass(frozen=True)
class Setup:
    """A parsed setup file.

    Attributes
    ----------
    name : str
    path : Path
        The setup file itself.
    materials : dict of str to Material
    holder : Holder
    tools : dict of str to Tool
    spindle : dict of direction to PointReceptance
    contact : ContactSpec
    measurements : tuple of MeasurementSpec
    extra : dict
        Tables later stages interpret (``[likelihood]``, ``[priors]``,
        ``[sampler]``, ``[model]``), checked for shape and types only.
    model_table : dict
        The ``[model]`` table: ``terms`` (list of term names) and per-parameter
        prior overrides (a ``[lo, hi]`` pair, a prior table as in ``[priors]``
        or a number that fixes the parameter).  Term and parameter names are
        validated against the term registry when the parameter model is
        built.  Empty when the setup has no ``[model]`` table.
    spindle_files : dict of direction to Path
        The ``[spindle]`` files (absolute), loaded or not.
    holder_type : str or None
        The optional ``[holder] type`` (a free string such as ``"ER32"``): the
        population a tool library pools this setup with (docs/library.md).
        ``None`` when the key is absent.
    """

    name: str
    path: Path
    materials: dict[str, Material]
    holder: Holder
    tools: dict[str, Tool]
    spindle: dict[str, PointReceptance]
    contact: ContactSpec
    measurements: tuple[MeasurementSpec, ...]
    extra: dict[str, Any] = field(default_factory=dict)
    model_table: dict[str, Any] = field(default_factory=dict)
    spindle_files: dict[str, Path] = field(default_factory=dict)
    holder_type: str | None = None

    def model(self) -> ToolPointModel:
        """The RCSA forward model of this setup."""
        return ToolPointModel(self.holder, self.tools, self.spindle)

    @property
    def feasible_range(self) -> tuple[float, float]:
        """(l_a, l_b) in m: the contact's clamping range or else the measured range."""
        if self.contact.clamping_range is not None:
            return self.contact.clamping_range
        lengths = [m.clamping_length for m in self.measurements]
        return (min(lengths), max(lengths))


def load_setup(path, load_data: bool = True, load_spindle: bool | None = None) -> Setup:
    """Parse a setup file.

    Parameters
    ----------
    path : str or Path
    load_data : bool
        Read the measurement files (and, by default, the spindle files).
    load_spindle : bool or None
        Read the spindle files; ``None`` follows ``load_data``.  Simulation
        needs the spindle but not the measurements.
    """
    from ._setup_parser import parse_setup

    return parse_setup(Path(path), load_data=load_data, load_spindle=load_spindle)
