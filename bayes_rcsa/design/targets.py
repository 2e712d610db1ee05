"""Design targets and candidate tests: parsing, and the per-draw target quantity.

Target (``--target``)
---------------------
``frequency@L``
    Natural frequency (Hz) of the dominant mode at clamping length ``L`` (m)
    in the design direction, by the project's rule
    (:func:`bayes_rcsa.model.natural_frequencies.natural_frequency`) within
    the dominant mode band of the current posterior-median ``|H|``.
``stiffness@L``
    Translational contact stiffness ``k_xf`` (N/m) at ``L`` (growth law and
    joint terms applied).
``lobes@L:START:STOP[:COUNT]``
    Zero-order chatter-limit depth (m) at ``COUNT`` (default
    :data:`DEFAULT_SPEED_POINTS`) spindle speeds between ``START`` and
    ``STOP`` rpm (``,`` also separates them); the width is the mean over
    the speeds of the 90 % band.  Needs both directions in the setup and
    cutting conditions.

Candidate tests (``--candidates``)
----------------------------------
Comma-separated: ``L`` (a clamping length in m, design direction and tool),
``tool:NAME@L`` (another tool of the setup), ``dir:D@L`` (the other
direction).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import SetupError
from ..model.assembly import Configuration, ConfigurationStack
from ..model.natural_frequencies import natural_frequency
from ..params.forward import ForwardModel
from ..params.growth import GrowthLaw
from ..params.model import ParameterModel
from ..posterior.predict import find_modes

__all__ = ["TARGET_KINDS", "TARGET_UNITS", "DEFAULT_SPEED_POINTS", "Target", "Candidate", "parse_target",
           "parse_candidates", "TargetEvaluator", "design_direction", "design_tool", "frequency_lines"]

TARGET_KINDS = ("frequency", "stiffness", "lobes")
TARGET_UNITS = {"frequency": "Hz", "stiffness": "N/m", "lobes": "m"}
DEFAULT_SPEED_POINTS = 40  # speeds of a lobes target: the per-draw ZOA limit is computed once per speed
_TARGET_RE = re.compile(r"^\s*(frequency|stiffness|lobes)\s*@\s*([^:]+?)\s*(?::(.*))?$")


def _length(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise SetupError(f"{what} {text!r}: expected a clamping length in m (e.g. 0.030)") from None
    if not np.isfinite(v) or v <= 0:
        raise SetupError(f"{what} {text!r}: expected a finite clamping length > 0 in m")
    if v > 1.0:
        raise SetupError(f"{what} {text!r}: {v:g} m is not a plausible clamping length; lengths are in m (0.030 = 30 mm)")
    return v


@dataclass(frozen=True)
class Target:
    """The quantity whose 90 % credible width the design minimises.

    Attributes
    ----------
    kind : {"frequency", "stiffness", "lobes"}
    clamping_length : float, m
    speeds_rpm : (n_speed,) rpm or None (lobes only)
    text : str
        As given on the command line.
    """

    kind: str
    clamping_length: float
    speeds_rpm: np.ndarray | None = None
    text: str = ""

    @property
    def unit(self) -> str:
        return TARGET_UNITS[self.kind]


def parse_target(text: str, option: str = "--target") -> Target:
    """Parse ``frequency@L``, ``stiffness@L`` or ``lobes@L:START:STOP[:COUNT]``.

    Raises
    ------
    SetupError
        Malformed text (one line naming the option and the expected form).
    """
    m = _TARGET_RE.match(text or "")
    if m is None:
        raise SetupError(f"{option} {text!r}: expected frequency@L, stiffness@L or lobes@L:START:STOP[:COUNT] "
                         f"(L in m, speeds in rpm)")
    kind, length, rest = m.group(1), _length(m.group(2), option), m.group(3)
    if kind != "lobes":
        if rest is not None:
            raise SetupError(f"{option} {text!r}: only a lobes target takes speeds after ':'")
        return Target(kind, length, None, text)
    parts = [p for p in re.split(r"[:,]", rest or "") if p.strip()]
    if len(parts) not in (2, 3):
        raise SetupError(f"{option} {text!r}: expected lobes@L:START:STOP[:COUNT] with speeds in rpm")
    try:
        start, stop = float(parts[0]), float(parts[1])
        count = int(parts[2]) if len(parts) == 3 else DEFAULT_SPEED_POINTS
    except ValueError:
        raise SetupError(f"{option} {text!r}: START and STOP must be numbers (rpm), COUNT an integer") from None
    if not (np.isfinite(start) and np.isfinite(stop) and 0 < start < stop) or not 2 <= count <= 2000:
        raise SetupError(f"{option} {text!r}: expected 0 < START < STOP rpm and 2 <= COUNT <= 2000")
    return Target(kind, length, np.linspace(start, stop, count), text)


@dataclass(frozen=True)
class Candidate:
    """One candidate hammer test.

    Attributes
    ----------
    configuration : Configuration
    text : str
        The candidate as given.
    """

    configuration: Configuration
    text: str

    @property
    def clamping_length(self) -> float:
        return self.configuration.clamping_length

    @property
    def label(self) -> str:
        c = self.configuration
        return f"{c.direction} {c.clamping_length * 1e3:.4g} mm, tool {c.tool}"


def design_direction(setup) -> str:
    """Direction of the design: that of the setup's first measurement, else ``x`` (or the only spindle file)."""
    if getattr(setup, "measurements", None):
        return setup.measurements[0].configuration.direction
    return "x" if "x" in setup.spindle else sorted(setup.spindle)[0]


def design_tool(setup) -> str:
    """Tool of the design: that of the setup's first measurement, else the setup's only tool."""
    if getattr(setup, "measurements", None):
        return setup.measurements[0].configuration.tool
    if len(setup.tools) != 1:
        raise SetupError(f"the setup defines several tools {sorted(setup.tools)} and no measurement; "
                         f"name the tool of each candidate (tool:NAME@L)")
    return next(iter(setup.tools))


def parse_candidates(text: str, setup, feasible: GrowthLaw, option: str = "--candidates") -> list[Candidate]:
    """Parse the candidate tests and check them against the setup and the feasible range.

    Raises
    ------
    SetupError
        Malformed entry, unknown tool or direction, a length outside the
        feasible clamping range, a candidate listed twice.
    """
    items = [p.strip() for p in (text or "").split(",") if p.strip()]
    if not items:
        raise SetupError(f"{option} {text!r}: expected a comma-separated list of clamping lengths in m, "
                         f"tool:NAME@L or dir:D@L")
    d0, t0 = design_direction(setup), design_tool(setup)
    out: list[Candidate] = []
    for item in items:
        direction, tool, length_text = d0, t0, item
        if "@" in item:
            head, length_text = item.split("@", 1)
            key, _, value = head.partition(":")
            key, value = key.strip(), value.strip()
            if key == "tool" and value:
                if value not in setup.tools:
                    raise SetupError(f"{option} {item!r}: unknown tool {value!r}; the setup defines {sorted(setup.tools)}")
                tool = value
            elif key == "dir" and value:
                if value not in ("x", "y"):
                    raise SetupError(f"{option} {item!r}: direction {value!r}, expected x or y")
                if value not in setup.spindle:
                    raise SetupError(f"{option} {item!r}: the setup has spindle receptances for "
                                     f"{sorted(setup.spindle)} only")
                direction = value
            else:
                raise SetupError(f"{option} {item!r}: expected L, tool:NAME@L or dir:D@L")
        length = _length(length_text.strip(), f"{option} entry")
        feasible.check_lengths([length], f"{option} candidate")
        cand = Candidate(Configuration(length, direction, tool), item)
        if any(c.configuration == cand.configuration for c in out):
            raise SetupError(f"{option} {item!r}: candidate listed twice")
        out.append(cand)
    return out


def frequency_lines(setup, direction: str) -> np.ndarray:
    """Lines of a new measurement: those of the setup's first measurement inside the spindle data, else the spindle grid."""
    spindle_f = setup.spindle[direction].frequency_hz
    for m in getattr(setup, "measurements", ()) or ():
        if m.frf is not None:
            f = m.frf.frequency_hz
            f = f[(f >= spindle_f[0]) & (f <= spindle_f[-1])]
            if f.size >= 3:
                return f
    return np.asarray(spindle_f, dtype=float)


class TargetEvaluator:
    """The target quantity of a batch of parameter sets, ``(n_sets, n_components)``.

    Parameters
    ----------
    target : Target
    parameters : ParameterModel
        The draws' parameter model.
    model : ToolPointModel
    setup : Setup
    direction, tool : str
        Of the frequency target.
    cutting : CuttingConditions or None
        Needed by a lobes target.
    reference_values : mapping name -> (n,), optional
        Draws whose median ``|H|`` fixes the dominant-mode band of a
        frequency target (without them: the whole grid).

    Notes
    -----
    Built once; :meth:`__call__` is vectorised over parameter sets (one
    forward-model call per configuration).
    """

    def __init__(self, target: Target, parameters: ParameterModel, model, setup, direction: str, tool: str,
                 cutting=None, reference_values: Mapping[str, np.ndarray] | None = None):
        self.target = target
        self.parameters = parameters
        length = target.clamping_length
        self.band = None
        self._forward: dict[str, ForwardModel] = {}
        if target.kind == "frequency":
            f = frequency_lines(setup, direction)
            self.frequency_hz = f
            self._forward["f"] = ForwardModel(parameters, ConfigurationStack(
                [model.precompute(Configuration(length, direction, tool), f)]), model)
            if reference_values is not None:
                h = self._forward["f"].frf(reference_values)
                median = np.median(np.abs(h), axis=0)
                modes = find_modes(f, median)
                if modes:
                    peaks = [float(np.max(median[(f >= lo) & (f <= hi)])) for lo, hi, _ in modes]
                    lo, hi, _ = modes[int(np.argmax(peaks))]
                    self.band = (lo, hi)
                    # only the band's lines are needed from now on (same rule, same lines, less work)
                    keep = (f >= lo) & (f <= hi)
                    self.frequency_hz = f[keep]
                    self._forward["f"] = ForwardModel(parameters, ConfigurationStack(
                        [model.precompute(Configuration(length, direction, tool), f[keep])]), model)
        elif target.kind == "lobes":
            if cutting is None:
                raise SetupError(f"--target {target.text!r}: a lobes target needs the cutting conditions "
                                 f"(--kt, --kr, --flutes, --immersion)")
            missing = [d for d in ("x", "y") if d not in setup.spindle]
            if missing:
                raise SetupError(f"--target {target.text!r}: chatter limits need spindle receptances in x and y; "
                                 f"the setup lacks {missing}")
            fx, fy = setup.spindle["x"].frequency_hz, setup.spindle["y"].frequency_hz
            if fx.shape != fy.shape or not np.allclose(fx, fy):
                raise SetupError(f"--target {target.text!r}: the x and y spindle files must share their frequency lines")
            self.frequency_hz = np.asarray(fx, dtype=float)
            self.cutting = cutting
            for d in ("x", "y"):
                self._forward[d] = ForwardModel(parameters, ConfigurationStack(
                    [model.precompute(Configuration(length, d, tool), self.frequency_hz)]), model)
        elif target.kind != "stiffness":
            raise SetupError(f"--target {target.text!r}: unknown kind {target.kind!r}")

    @property
    def n_components(self) -> int:
        return 1 if self.target.kind != "lobes" else int(self.target.speeds_rpm.size)

    def __call__(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Target of each parameter set, (n_sets, n_components); NaN where undefined (no resonance in the band)."""
        kind = self.target.kind
        if kind == "stiffness":
            return self.parameters.contact(values, [self.target.clamping_length]).k_xf[:, :1].astype(float)
        if kind == "frequency":
            return natural_frequency(self.frequency_hz, self._forward["f"].frf(values))[:, None]
        from ..stability import zoa_lobes

        hx = self._forward["x"].frf(values)
        hy = self._forward["y"].frf(values)
        depth = zoa_lobes(hx, hy, self.frequency_hz, self.cutting, self.target.speeds_rpm).depth_limit_m
        return np.where(np.isfinite(depth), depth, np.nan)
