"""Second synthetic bench: a spindle rotor on three bearing sets with a flexible housing (independent of the first).

Built from physics and published descriptions only; it shares no beam,
coupling or solver code with :mod:`bayes_rcsa.model` or the first bench.
Timoshenko finite elements (Friedman–Kosmatka interdependent interpolation,
consistent mass), dense assembly, and receptances by modal superposition:
undamped modes (``scipy.linalg.eigh``), complex modes of the reduced damped
system (hysteretic loss factors per component, viscous joint dampers) and a
static residual.  See docs/synthetic.md, "Second generator".

Main entry points
-----------------
:class:`RotorBenchConfig`, :func:`rotor_bench_config`
:func:`generate_rotor_campaign`, :func:`write_rotor_campaign`
:func:`true_tool_point_frf`, :func:`true_modes`, :func:`exported_spindle_receptance`
"""

from .build import build_structure, true_contact
from .campaign import (
    exported_spindle_receptance,
    generate_rotor_campaign,
    tool_point_solution,
    true_modes,
    true_spindle_receptance,
    true_tool_point_frf,
    write_rotor_campaign,
)
from .config import (
    CANONICAL_EFFECTS,
    OUT_OF_LIBRARY_EFFECTS,
    ROTOR_EFFECTS,
    BearingSet,
    HolderSegment,
    HolderTaper,
    Housing,
    RotorBenchConfig,
    ShaftSegment,
    rotor_bench_config,
)
from .sections import FluteProfile, RotorMaterial
from .solver import ModalSolution, direct_receptance, modal_solution

__all__ = [
    "RotorBenchConfig", "rotor_bench_config", "ROTOR_EFFECTS", "CANONICAL_EFFECTS", "OUT_OF_LIBRARY_EFFECTS",
    "generate_rotor_campaign", "write_rotor_campaign", "true_tool_point_frf", "true_modes",
    "exported_spindle_receptance", "true_spindle_receptance", "true_contact", "tool_point_solution",
    "build_structure", "modal_solution", "direct_receptance", "ModalSolution",
    "HolderSegment", "ShaftSegment", "BearingSet", "Housing", "HolderTaper", "FluteProfile", "RotorMaterial",
]
