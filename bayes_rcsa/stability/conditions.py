"""Cutting conditions from plain numbers, with the checks every workflow applies before any work.

The workflows (:mod:`bayes_rcsa.workflows`) receive the cutting case as numbers
(Pa, fractions, radians) and build the :class:`~.cutting.CuttingConditions`
here, so that ``lobes``, ``update``, ``design --next-cut`` and ``identify
--cuts`` refuse the same things with the same one-line messages (they name the
command-line options, the place most values come from).
"""

from __future__ import annotations

from typing import Sequence

from ..errors import SetupError
from .cutting import CuttingConditions
from .plausibility import check_cutting_coefficients

__all__ = ["cutting_conditions"]


def cutting_conditions(*, kt: float, kr: float, flutes: int, radial_immersion: float | None = None,
                       entry_angle: float | None = None, exit_angle: float | None = None, milling: str = "down",
                       feed: str = "x", pitch_angles: Sequence[float] | None = None,
                       allow_unusual: bool = False) -> tuple[CuttingConditions, list[str]]:
    """The :class:`CuttingConditions` of a cutting case and the plausibility warnings of its coefficients.

    Parameters
    ----------
    kt, kr : float, Pa
        Tangential and radial cutting-force coefficients.
    flutes : int, number of teeth
    radial_immersion : float or None
        Radial depth / tool diameter in (0, 1]; give exactly one of it and (``entry_angle``, ``exit_angle``).
    entry_angle, exit_angle : float or None, rad
    milling : {"down", "up"}
    feed : {"x", "y"}
    pitch_angles : (flutes,) rad or None
        Variable pitch: angle from each tooth to the one ahead.
    allow_unusual : bool
        Coefficients outside the ranges for metals are returned as warnings instead of refused
        (:func:`~.plausibility.check_cutting_coefficients`).

    Returns
    -------
    cutting : CuttingConditions
    warnings : list of str

    Raises
    ------
    SetupError
        Implausible coefficients (a likely unit slip), neither or both of the immersion and the angles, or
        conditions :class:`CuttingConditions` refuses.
    """
    warnings = check_cutting_coefficients(kt, kr, allow_unusual=allow_unusual)
    if (radial_immersion is None) == (entry_angle is None or exit_angle is None):
        raise SetupError("give exactly one of --immersion (radial depth / diameter) and --angles ENTRY,EXIT (deg)")
    kw = {}
    if radial_immersion is not None:
        kw["radial_immersion"] = radial_immersion
    else:
        kw["entry_angle"], kw["exit_angle"] = entry_angle, exit_angle
    if pitch_angles is not None:
        kw["pitch_angles"] = tuple(float(a) for a in pitch_angles)
    return CuttingConditions(kt=kt, kr=kr, flutes=flutes, milling=milling, feed=feed, **kw), warnings
