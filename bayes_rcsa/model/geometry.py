"""Holder and tool geometry, and their split into Timoshenko segments.

Conventions (shared data contract): the beam axis z runs from the spindle
towards the tool tip.  Holder segments are listed from the flange to the
holder tip; tool segments from the tool tip towards the shank end.  The
clamped part of the tool is taken from the shank end and lies in the last
``clamping_length`` metres of the holder bore, where it is merged with the
holder into a composite section.  The tool overhang (tool total length minus
clamping length) is a separate beam from the holder tip (its end 1, the tool
base) to the tool tip (its end 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SetupError
from .materials import Material
from .sections import circular_section, composite_section
from .timoshenko import Segment

__all__ = ["HolderSegment", "ToolSegment", "Holder", "Tool", "holder_segments", "tool_overhang_segments"]

# Relative tolerance for "lengths add up": 1 nm in 1 m is far below any
# manufacturing tolerance yet above round-off of decimal inputs.
_LENGTH_RTOL = 1e-9


def _positive(value, what: str) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value) or value <= 0:
        raise SetupError(f"{what} = {value!r}: expected a finite number > 0 (metres)")
    return float(value)


@dataclass(frozen=True)
class HolderSegment:
    """A holder segment: ``length``, ``outer_diameter``, ``inner_diameter`` in m."""

    length: float
    outer_diameter: float
    inner_diameter: float = 0.0

    def __post_init__(self) -> None:
        _positive(self.length, "holder segment length")
        _positive(self.outer_diameter, "holder segment outer_diameter")
        if not (math.isfinite(self.inner_diameter) and 0 <= self.inner_diameter < self.outer_diameter):
            raise SetupError(
                f"holder segment inner_diameter = {self.inner_diameter!r}: expected 0 <= inner < "
                f"outer_diameter ({self.outer_diameter!r} m)"
            )


@dataclass(frozen=True)
class ToolSegment:
    """A tool segment: ``length`` and ``diameter`` in m; ``diameter_ratio`` scales the
    diameter to the effective bending diameter of a fluted section (1 for a shank)."""

    length: float
    diameter: float
    diameter_ratio: float = 1.0

    def __post_init__(self) -> None:
        _positive(self.length, "tool segment length")
        _positive(self.diameter, "tool segment diameter")
        if not (math.isfinite(self.diameter_ratio) and 0 < self.diameter_ratio <= 1):
            raise SetupError(f"tool segment diameter_ratio = {self.diameter_ratio!r}: expected 0 < ratio <= 1")

    @property
    def effective_diameter(self) -> float:
        return self.diameter * self.diameter_ratio


@dataclass(frozen=True)
class Holder:
    """A tool holder, segments from the flange (spindle side) to the holder tip."""

    material: Material
    segments: tuple[HolderSegment, ...]

    def __post_init__(self) -> None:
        if len(self.segments) == 0:
            raise SetupError("holder.segments: expected at least one segment")

    @property
    def length(self) -> float:
        return sum(s.length for s in self.segments)

    @property
    def bore_depth(self) -> float:
        """Depth of the bore measured from the holder tip, m (trailing hollow segments)."""
        depth = 0.0
        for seg in reversed(self.segments):
            if seg.inner_diameter <= 0:
                break
            depth += seg.length
        return depth


@dataclass(frozen=True)
class Tool:
    """A tool, segments from the tip towards the shank end; the last one is the shank."""

    material: Material
    total_length: float
    segments: tuple[ToolSegment, ...]
    name: str = "tool"

    def __post_init__(self) -> None:
        _positive(self.total_length, f"tool {self.name!r} total_length")
        if len(self.segments) == 0:
            raise SetupError(f"tool {self.name!r} segments: expected at least one segment")
        total = sum(s.length for s in self.segments)
        if abs(total - self.total_length) > _LENGTH_RTOL * self.total_length:
            raise SetupError(
                f"tool {self.name!r}: segment lengths add up to {total!r} m, expected total_length "
                f"{self.total_length!r} m"
            )


def _cut(segments, start: float, stop: float):
    """Pieces of consecutive ``segments`` between distances ``start`` and ``stop``
    from the first segment's start, as ``(segment, piece_length)``."""
    pieces, pos = [], 0.0
    for seg in segments:
        lo, hi = max(pos, start), min(pos + seg.length, stop)
        if hi - lo > _LENGTH_RTOL * max(stop, 1e-12):
            pieces.append((seg, hi - lo))
        pos += seg.length
    return pieces


def check_clamping(holder: Holder, tool: Tool, clamping_length: float) -> float:
    """Validate a clamping length against holder bore and tool, return it as float."""
    cl = _positive(clamping_length, "clamping_length")
    if cl >= tool.total_length:
        raise SetupError(
            f"clamping_length = {cl!r} m: expected less than tool {tool.name!r} total_length {tool.total_length!r} m"
        )
    if cl >= holder.bore_depth:
        raise SetupError(f"clamping_length = {cl!r} m: expected less than the holder bore depth {holder.bore_depth!r} m")
    return cl


def holder_segments(holder: Holder, tool: Tool, clamping_length: float) -> list[Segment]:
    """Timoshenko segments of the holder with the clamped shank merged, flange -> holder tip."""
    cl = check_clamping(holder, tool, clamping_length)
    start_clamp = holder.length - cl
    out: list[Segment] = []
    for seg, piece in _cut(holder.segments, 0.0, start_clamp):
        out.append(Segment(piece, circular_section(holder.material, seg.outer_diameter, seg.inner_diameter)))
    # The clamped tool part, from the shank end towards the tip, faces the
    # holder from ``start_clamp`` to the holder tip.
    tool_from_shank = tuple(reversed(tool.segments))
    pos = start_clamp
    for tseg, tpiece in _cut(tool_from_shank, 0.0, cl):
        for hseg, piece in _cut(holder.segments, pos, pos + tpiece):
            d_tool = tseg.effective_diameter
            if d_tool > hseg.inner_diameter * (1 + 1e-6):
                raise SetupError(
                    f"tool {tool.name!r} diameter {d_tool!r} m does not fit the holder bore "
                    f"(inner_diameter {hseg.inner_diameter!r} m)"
                )
            section = composite_section(
                circular_section(holder.material, hseg.outer_diameter, hseg.inner_diameter),
                circular_section(tool.material, d_tool),
            )
            out.append(Segment(piece, section))
        pos += tpiece
    return out


def tool_overhang_segments(holder: Holder, tool: Tool, clamping_length: float) -> list[Segment]:
    """Timoshenko segments of the tool overhang, holder tip (tool base) -> tool tip."""
    cl = check_clamping(holder, tool, clamping_length)
    overhang = tool.total_length - cl
    pieces = _cut(tool.segments, 0.0, overhang)  # from the tip
    return [Segment(piece, circular_section(tool.material, seg.effective_diameter)) for seg, piece in reversed(pieces)]
