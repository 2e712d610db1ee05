"""Cuts with their setups, their checks, and the draws' tool-point FRFs at every cut setup.

A cut file (:func:`bayes_rcsa.stability.tests_io.read_cut_table`) may give
each cut its own clamping length, radial immersion, feed direction and tool;
empty cells take the command's values.  Cuts that share a clamping length
and a tool share the draws' tool-point FRFs; cuts that also share the
immersion and feed share a cutting geometry (one :class:`~.likelihood.CutGroup`).

Checks (each a one-line :class:`~bayes_rcsa.errors.DataError` or
:class:`~bayes_rcsa.errors.SetupError` naming the file and line):

- a depth above :data:`MAX_PLAUSIBLE_DEPTH_M` (50 mm) or above the tool's
  flute length is named as a likely depth in mm instead of m;
- a cut whose tooth-passing frequency N n / 60 lies above the top of the FRF
  band: the band cannot hold the lowest lobe's chatter frequencies there;
- a cut at which no draw finds a limit in the band (the band says nothing
  about chatter at that speed), checked after the limits are computed
  (:func:`check_supported`);
- a clamping length the posterior cannot predict (outside the growth law's
  or the setup's feasible range) and an unknown tool.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import DataError, SetupError
from .likelihood import CutGroup

__all__ = ["MAX_PLAUSIBLE_DEPTH_M", "CutSet", "prepare_cuts", "cut_groups", "check_supported"]

#: Depths above this (m) are refused as a likely unit slip (mm given as m); no milling cut is 50 mm deep in one pass
#: on the small tools whose contact this package identifies.
MAX_PLAUSIBLE_DEPTH_M = 0.05


@dataclass(frozen=True)
class CutSet:
    """Cuts ready for the likelihood.

    Attributes
    ----------
    table : CutTable (the file)
    clamping_length_m : (n,) m, per cut
    tool : tuple of str, per cut
    cutting : tuple of CuttingConditions, per cut (geometry; coefficients are the prior's)
    """

    table: object
    clamping_length_m: np.ndarray
    tool: tuple
    cutting: tuple

    @property
    def n_cuts(self) -> int:
        return int(self.clamping_length_m.size)

    @property
    def speed_rpm(self) -> np.ndarray:
        return self.table.speed_rpm

    @property
    def depth_m(self) -> np.ndarray:
        return self.table.depth_m

    @property
    def chatter(self) -> np.ndarray:
        return ~self.table.stable

    def setups(self) -> list[tuple[float, str]]:
        """Distinct (clamping length, tool) pairs in order of first appearance."""
        out = []
        for key in zip(self.clamping_length_m.tolist(), self.tool):
            if key not in out:
                out.append(key)
        return out


def prepare_cuts(table, cutting, clamping_length: float | None, tools, default_tool: str | None = None,
                 flute_length=None, option_prefix: str = "--") -> CutSet:
    """Complete every cut with the command's values and check it.

    Parameters
    ----------
    table : CutTable
    cutting : CuttingConditions of the command (flutes, immersion or angles, milling, feed, pitch)
    clamping_length : float or None, m, for cuts without a clamping_length_m value
    tools : iterable of str, the setup's tool names
    default_tool : str or None, for cuts without a tool value (None: the setup's only tool)
    flute_length : callable(tool name) -> float or None, m (depth check), or None
    option_prefix : str
        Prefix of the command's options that the messages name (``"--cut-"`` for ``identify --cuts``,
        whose options are ``--cut-clamping-length`` and ``--cut-tool``).

    Raises
    ------
    DataError, SetupError
    """
    tools = list(tools)
    n = table.n_cuts
    for i in range(n):
        d = float(table.depth_m[i])
        if d > MAX_PLAUSIBLE_DEPTH_M:
            raise DataError(f"{table.where(i)}: depth_m {d:g} m is implausible (> {MAX_PLAUSIBLE_DEPTH_M * 1e3:g} mm); "
                            f"depths are in metres: was it {d:g} mm = {d * 1e-3:g} m?")
    length = np.array(table.clamping_length_m, dtype=float)
    if np.any(np.isnan(length)):
        if clamping_length is None:
            i = int(np.nonzero(np.isnan(length))[0][0])
            raise SetupError(f"{table.where(i)}: no clamping_length_m for this cut; give {option_prefix}clamping-length M or the "
                             "clamping_length_m column")
        length = np.where(np.isnan(length), float(clamping_length), length)
    if default_tool is None and any(t is None for t in table.tool):
        if len(tools) != 1:
            raise SetupError(f"the setup has several tools {sorted(tools)}; give {option_prefix}tool NAME or the cut file's "
                           "tool column")
        default_tool = tools[0]
    tool = tuple(t if t is not None else default_tool for t in table.tool)
    for i, t in enumerate(tool):
        if t not in tools:
            raise DataError(f"{table.where(i)}: tool {t!r} is not a tool of the setup ({', '.join(sorted(tools))})")
        fl = flute_length(t) if flute_length is not None else None
        if fl is not None and table.depth_m[i] > fl:
            raise DataError(f"{table.where(i)}: depth_m {table.depth_m[i]:g} m is deeper than the flute length "
                            f"{fl:g} m of tool {t!r}; depths are in metres (was it in mm?)")
    per_cut = []
    for i in range(n):
        c = cutting
        r = table.radial_immersion[i]
        if not math.isnan(r):
            c = replace(c, radial_immersion=float(r), entry_angle=None, exit_angle=None)
        if table.feed_direction[i] is not None:
            c = replace(c, feed=table.feed_direction[i])
        per_cut.append(c)
    return CutSet(table, length, tool, tuple(per_cut))


def cut_groups(cuts: CutSet, frfs: dict, frequency_hz) -> list[CutGroup]:
    """The likelihood's groups: cuts sharing (clamping length, tool, cutting geometry).

    Parameters
    ----------
    cuts : CutSet
    frfs : dict (clamping length, tool) -> (frf_x, frf_y), each (n_draws, n_freq) complex m/N
    frequency_hz : (n_freq,) Hz

    Raises
    ------
    DataError
        A cut whose tooth-passing frequency lies above the FRF band.
    """
    f_hi = float(np.max(frequency_hz))
    for i in range(cuts.n_cuts):
        f_tooth = cuts.cutting[i].flutes * cuts.speed_rpm[i] / 60.0
        if f_tooth > f_hi:
            lim = 60.0 * f_hi / cuts.cutting[i].flutes
            raise DataError(f"{cuts.table.where(i)}: spindle speed {cuts.speed_rpm[i]:g} rpm is outside the speed range "
                            f"the FRF band supports (tooth-passing frequency {f_tooth:.0f} Hz above the band's top "
                            f"{f_hi:.0f} Hz; at most {lim:.0f} rpm with {cuts.cutting[i].flutes} flutes)")
    keys: dict = {}
    for i in range(cuts.n_cuts):
        keys.setdefault((float(cuts.clamping_length_m[i]), cuts.tool[i], cuts.cutting[i]), []).append(i)
    out = []
    for (length, tool, cutting), idx in keys.items():
        gx, gy = frfs[(length, tool)]
        idx = np.array(idx)
        out.append(CutGroup(gx, gy, np.asarray(frequency_hz, dtype=float), cutting, idx, cuts.speed_rpm[idx]))
    return out


def check_supported(cuts: CutSet, inverse_limits) -> None:
    """Refuse cuts at which no draw finds a limit inside the FRF band (all inverse limits 0).

    Parameters
    ----------
    inverse_limits : (n_nodes, n_draws, n_cuts) 1/m
    """
    none = ~np.any(np.asarray(inverse_limits) > 0, axis=(0, 1))
    if np.any(none):
        i = int(np.nonzero(none)[0][0])
        raise DataError(f"{cuts.table.where(i)}: spindle speed {cuts.speed_rpm[i]:g} rpm is outside the speed range "
                        "the FRF band supports: no draw has a chatter frequency inside the band that maps to it, so "
                        "the band says nothing about this cut")
