"""The artifact file (TOML): standard holder + blank, measurement points, hammer-test files.

Layout (see docs/spindle.md)::

    name = "CAT40 shrink-fit artifact"
    [materials.steel]            # as in the setup file
    [holder]                     # as in the setup file: material, segments flange -> tip
    [blank]                      # as the setup's [tool] table, plus clamping_length
    material = "steel"
    total_length = 0.125
    clamping_length = 0.045
    segments = [{ length = 0.125, diameter = 0.020 }]
    [points]                     # distances from the blank's free end, m
    point1 = 0.0                 # optional, default 0 (H11 at the free end)
    point2 = 0.040
    [[measurement]]              # one per direction
    direction = "x"
    h11 = "h11_x.csv"            # u1/F1
    h12 = "h12_x.csv"            # u1/F2   (h12 and/or h21)
    h21 = "h21_x.csv"            # u2/F1
    h22 = "h22_x.csv"            # u2/F2
    [noise]                      # optional
    relative = 0.01              # default: estimated from the data
    floor = 0.0                  # m/N
    [fit]                        # optional
    max_modes = 8
    unreliable_threshold = 0.05
    [uncertainty]                # optional, relative standard deviations of the artifact model
    youngs_modulus = 0.0
    density = 0.0

The holder-blank joint is rigid (shrink fit): the clamped blank is merged
with the holder as in the setup's holder model, and the overhang is joined
to the holder tip without compliance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError, SetupError
from ..io.tables import (
    TableContext, check_keys, check_top_level, load_document, number, parse_holder, parse_materials, parse_tool, string,
    table,
)
from ..io.frf import FRF_SUFFIXES, read_frf
from ..model.geometry import Holder, Tool, holder_segments, tool_overhang_segments
from ..model.receptance import FRF
from ..model.timoshenko import Segment

__all__ = ["Artifact", "ArtifactMeasurement", "ArtifactSetup", "load_artifact", "FRF_KEYS", "DIRECTIONS"]

DIRECTIONS = ("x", "y")
FRF_KEYS = ("h11", "h12", "h21", "h22")
# Points closer than this (m) coincide: no finite difference or coupling can separate them.
POINT_TOL = 1e-6
# Frequency axes of the four FRFs must agree to this relative tolerance (decimal text round-off).
_AXIS_RTOL = 1e-9


@dataclass(frozen=True)
class Artifact:
    """Standard holder + blank with a rigid joint, and the two measurement points.

    Attributes
    ----------
    holder : Holder
    blank : Tool
        Segments from the free end towards the shank end.
    clamping_length : float
        m, blank length inside the holder bore.
    point_distances : (d1, d2)
        m, distances of points 1 and 2 from the blank's free end.
    """

    holder: Holder
    blank: Tool
    clamping_length: float
    point_distances: tuple[float, float]

    def __post_init__(self) -> None:
        holder_segments(self.holder, self.blank, self.clamping_length)  # validates the clamp and the bore fit
        d = tuple(float(v) for v in self.point_distances)
        object.__setattr__(self, "point_distances", d)
        if len(d) != 2 or not all(math.isfinite(v) for v in d):
            raise SetupError(f"point distances {self.point_distances!r}: expected two finite distances (m)")
        for i, v in enumerate(d):
            if not 0 <= v < self.total_length:
                raise SetupError(
                    f"point{i + 1} = {v!r} m: expected 0 <= distance from the free end < artifact length "
                    f"{self.total_length!r} m"
                )
        if abs(d[0] - d[1]) <= POINT_TOL:
            raise SetupError(
                f"point1 = {d[0]!r} m and point2 = {d[1]!r} m coincide (closer than {POINT_TOL:g} m): the cross "
                "receptance then carries no rotational information; place point 2 a known distance (e.g. "
                "20-50 mm) from point 1"
            )

    @property
    def overhang(self) -> float:
        """m, blank length outside the holder."""
        return self.blank.total_length - self.clamping_length

    @property
    def total_length(self) -> float:
        """m, flange face to the blank's free end."""
        return self.holder.length + self.overhang

    @property
    def separation(self) -> float:
        """m, distance between the two measurement points."""
        return abs(self.point_distances[1] - self.point_distances[0])

    def segments(self) -> list[Segment]:
        """Timoshenko segments from the flange (end 1) to the free end (end 2), rigid joint."""
        return holder_segments(self.holder, self.blank, self.clamping_length) + tool_overhang_segments(
            self.holder, self.blank, self.clamping_length
        )

    def point_positions(self) -> tuple[float, float]:
        """z (m) of points 1 and 2 measured from the flange."""
        return tuple(self.total_length - d for d in self.point_distances)


@dataclass(frozen=True)
class ArtifactMeasurement:
    """The hammer tests of one direction.

    Attributes
    ----------
    direction : {"x", "y"}
    h11, h22 : FRF
        Direct receptances at points 1 and 2, m/N.
    h12, h21 : FRF or None
        Cross receptances u1/F2 and u2/F1; at least one is present.
    """

    direction: str
    h11: FRF
    h12: FRF | None
    h21: FRF | None
    h22: FRF

    def __post_init__(self) -> None:
        if self.h12 is None and self.h21 is None:
            raise DataError(
                f"direction {self.direction!r}: the cross receptance is missing; give h12 (u1/F2) and/or "
                "h21 (u2/F1)"
            )
        ref = self.h11
        for frf in self.frfs().values():
            f = frf.frequency_hz
            if f.size != ref.frequency_hz.size or not np.allclose(f, ref.frequency_hz, rtol=_AXIS_RTOL, atol=0):
                raise DataError(
                    f"direction {self.direction!r}: frequency axes differ: {frf.source} has {f.size} lines "
                    f"{f[0]:g}-{f[-1]:g} Hz, {ref.source} has {ref.frequency_hz.size} lines "
                    f"{ref.frequency_hz[0]:g}-{ref.frequency_hz[-1]:g} Hz; the inverse coupling needs all "
                    "FRFs on the same lines"
                )

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.h11.frequency_hz

    def frfs(self) -> dict[str, FRF]:
        """The FRFs present, by key (``h11``, ``h12``, ``h21``, ``h22``)."""
        return {k: v for k, v in (("h11", self.h11), ("h12", self.h12), ("h21", self.h21), ("h22", self.h22))
                if v is not None}


@dataclass(frozen=True)
class ArtifactSetup:
    """A parsed artifact file.

    Attributes
    ----------
    name : str
    path : Path
    artifact : Artifact
    measurements : dict of direction to ArtifactMeasurement
    noise_relative : float or None
        Relative noise standard deviation of the FRFs; ``None``: estimate from the data.
    noise_floor : float
        m/N, additive noise standard deviation.
    max_modes : int
        Largest mode count tried by the modal smoothing.
    unreliable_threshold : float
        Lines whose predicted relative standard deviation of h exceeds this are flagged.
    youngs_modulus_rsd, density_rsd : float
        Relative standard deviations of the artifact's material properties
        used by the bootstrap (0: the artifact model is exact).
    """

    name: str
    path: Path
    artifact: Artifact
    measurements: dict
    noise_relative: float | None = None
    noise_floor: float = 0.0
    max_modes: int = 8
    unreliable_threshold: float = 0.05
    youngs_modulus_rsd: float = 0.0
    density_rsd: float = 0.0


def _points(ctx: TableContext, doc: dict) -> tuple[float, float]:
    where = "[points]"
    tbl = table(ctx, doc, "points", where)
    check_keys(ctx, tbl, where, ("point1", "point2"))
    expected = "a finite distance >= 0 from the blank's free end (m)"
    d1 = number(ctx, tbl, where, "point1", lambda x: x >= 0, expected, default=0.0)
    d2 = number(ctx, tbl, where, "point2", lambda x: x >= 0, expected)
    return d1, d2


def _measurements(ctx: TableContext, doc: dict, load_data: bool) -> dict:
    raw = doc.get("measurement")
    expected = "one [[measurement]] table per direction with direction, h11, h12 and/or h21, h22"
    if not isinstance(raw, list) or not raw or not all(isinstance(m, dict) for m in raw):
        raise ctx.error("[[measurement]]", f"missing or malformed; expected {expected}")
    out = {}
    for i, m in enumerate(raw):
        where = f"[[measurement]] {i}"
        check_keys(ctx, m, where, ("direction",) + FRF_KEYS)
        direction = string(ctx, m, where, "direction", "\"x\" or \"y\"", default="x")
        if direction not in DIRECTIONS:
            raise ctx.bad(where, "direction", direction, "\"x\" or \"y\"")
        if direction in out:
            raise ctx.error(where, f"direction {direction!r} is measured twice")
        for key in ("h11", "h22"):
            if key not in m:
                raise ctx.missing(where, key, f"the {key} FRF file ({'u1/F1' if key == 'h11' else 'u2/F2'})")
        if "h12" not in m and "h21" not in m:
            raise ctx.error(where, "missing cross FRF: give h12 (u1/F2) and/or h21 (u2/F1)")
        files = {}
        for key in FRF_KEYS:
            if key in m:
                name = string(ctx, m, where, key, "an FRF file name relative to the artifact file")
                if Path(name).suffix.lower() not in FRF_SUFFIXES:
                    raise ctx.bad(where, key, name, f"a file ending in one of {', '.join(FRF_SUFFIXES)}")
                files[key] = ctx.resolve(name)
        if not load_data:
            out[direction] = files
            continue
        frfs = {}
        for key, path in files.items():
            try:
                # h11 and h22 are point receptances (checked for passivity); h12/h21 are transfers.
                frfs[key] = read_frf(path, point=key in ("h11", "h22"))
            except DataError as exc:
                raise DataError(f"{ctx.file}: {where} {key} = {m[key]!r}: {exc}") from exc
        try:
            out[direction] = ArtifactMeasurement(direction, frfs["h11"], frfs.get("h12"), frfs.get("h21"), frfs["h22"])
        except DataError as exc:
            raise DataError(f"{ctx.file}: {where}: {exc}") from exc
    return out


def load_artifact(path, load_data: bool = True) -> ArtifactSetup:
    """Parse and validate an artifact file.

    Parameters
    ----------
    path : path-like
    load_data : bool
        Read the FRF files.  With ``False``, ``measurements`` maps each
        direction to a dict of resolved file paths instead.

    Returns
    -------
    ArtifactSetup

    Raises
    ------
    SetupError
        Missing/unknown keys, invalid geometry, coinciding points.
    DataError
        Missing or malformed FRF files, a missing cross FRF, frequency axes
        that differ between the FRFs of one direction.
    """
    path = Path(path)
    ctx = TableContext(path)
    doc = load_document(path, "artifact file")
    known = ("name", "materials", "holder", "blank", "points", "measurement", "noise", "fit", "uncertainty")
    check_top_level(ctx, doc, known)
    name = string(ctx, doc, "(top level)", "name", "a non-empty string", default=path.stem)
    materials = parse_materials(ctx, doc)
    holder = parse_holder(ctx, doc, materials)
    blank_tbl = dict(table(ctx, doc, "blank", "[blank]"))
    cl = number(ctx, blank_tbl, "[blank]", "clamping_length", lambda x: x > 0, "a finite number > 0 (m)")
    del blank_tbl["clamping_length"]
    blank = parse_tool(ctx, blank_tbl, "[blank]", "blank", materials, allow_name=False)
    d1, d2 = _points(ctx, doc)
    try:
        artifact = Artifact(holder, blank, cl, (d1, d2))
    except SetupError as exc:
        raise SetupError(f"{ctx.file}: [blank]/[points]: {exc}") from exc

    noise = table(ctx, doc, "noise", "[noise]", required=False) or {}
    check_keys(ctx, noise, "[noise]", ("relative", "floor"))
    rel = number(ctx, noise, "[noise]", "relative", lambda x: x > 0, "a finite number > 0", default=None)
    floor = number(ctx, noise, "[noise]", "floor", lambda x: x >= 0, "a finite number >= 0 (m/N)", default=0.0)
    fit = table(ctx, doc, "fit", "[fit]", required=False) or {}
    check_keys(ctx, fit, "[fit]", ("max_modes", "unreliable_threshold"))
    max_modes = fit.get("max_modes", 8)
    if isinstance(max_modes, bool) or not isinstance(max_modes, int) or not 1 <= max_modes <= 20:
        raise ctx.bad("[fit]", "max_modes", max_modes, "an integer in [1, 20]")
    thr = number(ctx, fit, "[fit]", "unreliable_threshold", lambda x: x > 0, "a finite number > 0", default=0.05)
    unc = table(ctx, doc, "uncertainty", "[uncertainty]", required=False) or {}
    check_keys(ctx, unc, "[uncertainty]", ("youngs_modulus", "density"))
    rsd = {k: number(ctx, unc, "[uncertainty]", k, lambda x: 0 <= x < 0.5, "a relative standard deviation in [0, 0.5)",
                   default=0.0) for k in ("youngs_modulus", "density")}
    return ArtifactSetup(
        name=name, path=path, artifact=artifact, measurements=_measurements(ctx, doc, load_data),
        noise_relative=rel, noise_floor=floor, max_modes=max_modes, unreliable_threshold=thr,
        youngs_modulus_rsd=rsd["youngs_modulus"], density_rsd=rsd["density"],
    )
