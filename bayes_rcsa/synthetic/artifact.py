"""Artifact mode of the synthetic bench: hammer tests on a standard holder + blank.

A spindle identification (paper section 2.3) clamps a *standard artifact* in
the spindle: a shrink-fit holder whose blank (a plain cylinder) is bonded
to it, so that the holder-blank joint is rigid.  Hammer tests give the
direct receptance H11 at the blank's free end, the cross receptances
H12 = u1/F2 and H21 = u2/F1 between the free end and a second point a known
distance towards the holder, and the direct receptance H22 at that point.

The true structure here is the bench's finite-element spindle (shaft,
bearings, holder taper: :mod:`bayes_rcsa.synthetic.spindle`) carrying the
artifact, modelled with the bench's Timoshenko elements
(:mod:`bayes_rcsa.synthetic.fe`) as **one** chain: the blank is merged with
the holder into a composite section over the clamping length and continues
as a plain beam beyond the holder tip (a perfectly bonded shrink fit).  No
code of the RCSA model or of :mod:`bayes_rcsa.spindle` is used, so the
spindle identification is tested against an independent truth.

The taper belongs to the spindle side of the flange (z = 0) and is made of
the bench's holder material, exactly as in
:func:`bayes_rcsa.synthetic.bench.true_spindle_receptance`; that function
therefore gives the flange receptance the identification must recover.

Point positions are distances from the blank's free end (m), as in the
artifact file read by ``bayes-rcsa spindle``.
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SetupError
from ..io.jsonable import dumps_strict
from ..model.geometry import Holder, HolderSegment
from ..model.materials import Material
from ..model.receptance import FRF
from ..model.sections import circular_section, composite_section
from .bench import true_spindle_receptance
from .campaign import _replace_dir
from .config import BenchConfig
from .fe import Chain, NodeRef, assemble, mesh, receptance
from .noise import add_measurement_noise
from .spindle import bearing_joints, spindle_breakpoints, spindle_section

__all__ = [
    "BenchArtifact",
    "default_bench_artifact",
    "ArtifactTests",
    "build_artifact_assembly",
    "true_artifact_frfs",
    "generate_artifact_tests",
    "write_artifact_tests",
    "ARTIFACT_TRUTH_FORMAT",
    "ARTIFACT_FRF_NAMES",
]

ARTIFACT_TRUTH_FORMAT = "bayes_rcsa.synthetic.artifact_truth/1"
# measured FRFs: (name, response point, excitation point)
ARTIFACT_FRF_NAMES = (("h11", 1, 1), ("h12", 1, 2), ("h21", 2, 1), ("h22", 2, 2))
_CHAIN = "outer"


@dataclass(frozen=True)
class BenchArtifact:
    """The standard artifact and its test conditions.

    Attributes
    ----------
    holder_material, blank_material : str
        Names in the bench's material table.
    holder_segments : tuple of HolderSegment
        Flange -> holder tip; the trailing hollow segments form the bore.
    blank_length : float
        m, total length of the blank.
    blank_diameter : float
        m, blank diameter (it must fit the bore).
    clamping_length : float
        m, blank length inside the holder (bonded).
    point_distances : (d1, d2)
        m, distances of measurement points 1 and 2 from the blank's free end.
    frequency_start, frequency_stop, frequency_step : float
        Hz, measurement grid ``start, start + step, ... <= stop``.
    noise_relative : float
        Standard deviation of the complex noise relative to |H|.
    noise_floor : float
        m/N, additive noise standard deviation.
    n_averages : int
        Impacts per measurement (sets the coherence column).
    """

    holder_material: str = "steel"
    holder_segments: tuple[HolderSegment, ...] = (
        HolderSegment(0.020, 0.063, 0.0),
        HolderSegment(0.0316, 0.044, 0.0),
        HolderSegment(0.050, 0.040, 0.020),
    )
    blank_material: str = "steel"
    blank_length: float = 0.125
    blank_diameter: float = 0.020
    clamping_length: float = 0.045
    point_distances: tuple[float, float] = (0.0, 0.1716)
    frequency_start: float = 200.0
    frequency_stop: float = 4000.0
    frequency_step: float = 1.0
    noise_relative: float = 0.01
    noise_floor: float = 0.0
    n_averages: int = 5

    def __post_init__(self) -> None:
        object.__setattr__(self, "holder_segments", tuple(self.holder_segments))
        object.__setattr__(self, "point_distances", tuple(float(d) for d in self.point_distances))
        for key in ("blank_length", "blank_diameter", "clamping_length", "frequency_start", "frequency_stop",
                    "frequency_step"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise SetupError(f"artifact {key} = {v!r}: expected a finite number > 0")
        for key in ("noise_relative", "noise_floor"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v >= 0):
                raise SetupError(f"artifact {key} = {v!r}: expected a finite number >= 0")
        if self.frequency_stop <= self.frequency_start:
            raise SetupError("artifact frequency_stop must exceed frequency_start")
        if len(self.point_distances) != 2:
            raise SetupError(f"artifact point_distances = {self.point_distances!r}: expected two distances (m)")
        d1, d2 = self.point_distances
        if not (0 <= d1 < self.total_length and 0 <= d2 < self.total_length):
            raise SetupError(
                f"artifact point_distances = {list(self.point_distances)!r}: expected 0 <= d < artifact length "
                f"{self.total_length!r} m"
            )
        if abs(d1 - d2) < 1e-9:
            raise SetupError(f"artifact point_distances = {list(self.point_distances)!r}: the points coincide")
        holder = Holder(Material(1.0, 1.0, 0.3), self.holder_segments)  # geometry checks only
        if not (self.clamping_length < holder.bore_depth and self.clamping_length < self.blank_length):
            raise SetupError(
                f"artifact clamping_length = {self.clamping_length!r} m: expected less than the bore depth "
                f"{holder.bore_depth!r} m and the blank length {self.blank_length!r} m"
            )
        for seg in self.holder_segments:
            if 0 < seg.inner_diameter < self.blank_diameter * (1 - 1e-9):
                raise SetupError(
                    f"artifact blank diameter {self.blank_diameter!r} m does not fit the bore {seg.inner_diameter!r} m"
                )

    @property
    def holder_length(self) -> float:
        return sum(s.length for s in self.holder_segments)

    @property
    def total_length(self) -> float:
        """m, flange face to the blank's free end."""
        return self.holder_length + self.blank_length - self.clamping_length

    @property
    def frequency_hz(self) -> np.ndarray:
        n = int(math.floor((self.frequency_stop - self.frequency_start) / self.frequency_step + 1e-9)) + 1
        return self.frequency_start + self.frequency_step * np.arange(n)

    def point_z(self) -> tuple[float, float]:
        """z positions (m, from the flange) of points 1 and 2."""
        return tuple(self.total_length - d for d in self.point_distances)


def default_bench_artifact(**overrides) -> BenchArtifact:
    """A CAT40 shrink-fit holder (20 mm bore, 101.6 mm gauge length) with a 20 mm steel blank.

    The flange (20 mm x 63 mm) is the bench's standard flange; the blank
    sticks out 80 mm.  Point 1 is the free end; point 2 lies on the flange,
    10 mm from its face (171.6 mm from the free end): a long lever between
    the points keeps the inverse coupling well conditioned (docs/spindle.md).  The grid
    (200-4000 Hz in 1 Hz steps) resolves the lightly damped artifact modes
    (damping ratio down to about 0.2 %, half-power bandwidth about 9 Hz at
    2 kHz).
    """
    return BenchArtifact(**overrides)


def _holder_piece(artifact: BenchArtifact, z: float) -> HolderSegment:
    pos = 0.0
    for seg in artifact.holder_segments:
        if z <= pos + seg.length:
            return seg
        pos += seg.length
    raise SetupError(f"z = {z!r} m lies beyond the artifact holder tip")


def build_artifact_assembly(config: BenchConfig, artifact: BenchArtifact, direction: str):
    """Finite-element model of the bench spindle carrying the artifact.

    Parameters
    ----------
    config : BenchConfig
        Supplies the spindle, the bearing anisotropy, materials and mesh size.
    artifact : BenchArtifact
    direction : {"x", "y"}

    Returns
    -------
    model : FEModel
    dofs : (2,) int
        Lateral-displacement DOFs at measurement points 1 and 2.
    """
    if direction not in ("x", "y"):
        raise SetupError(f"direction {direction!r}: expected 'x' or 'y'")
    for name in (artifact.holder_material, artifact.blank_material):
        if name not in config.materials:
            raise SetupError(f"artifact material {name!r} is not defined; materials: {sorted(config.materials)}")
    hmat = config.materials[artifact.holder_material]
    bmat = config.materials[artifact.blank_material]
    taper_mat = config.materials[config.holder_material]
    lh = artifact.holder_length
    z_clamp = lh - artifact.clamping_length
    z_end = artifact.total_length
    fwd = [0.0, lh, z_clamp, z_end, *artifact.point_z()]
    pos = 0.0
    for seg in artifact.holder_segments:
        pos += seg.length
        fwd.append(pos)
    z_fwd = mesh(fwd, config.mesh_size)
    z_sp = mesh(spindle_breakpoints(config.spindle), config.spindle.mesh_size)
    z = np.concatenate([z_sp[:-1], z_fwd])
    blank = circular_section(bmat, artifact.blank_diameter)
    sections = []
    for a, b in zip(z[:-1], z[1:]):
        m = 0.5 * (a + b)
        if m < 0:
            sections.append(spindle_section(config.spindle, config.materials, taper_mat, m))
        elif m < lh:
            hs = _holder_piece(artifact, m)
            sec = circular_section(hmat, hs.outer_diameter, hs.inner_diameter)
            # bonded shrink fit: holder and blank bend as one composite section
            sections.append(composite_section(sec, blank) if m > z_clamp else sec)
        else:
            sections.append(blank)
    chain = Chain(_CHAIN, z, tuple(sections))
    model = assemble([chain], bearing_joints(config.spindle, _CHAIN, direction))
    dofs = np.array([model.dof(NodeRef(_CHAIN, zp), "u") for zp in artifact.point_z()])
    return model, dofs


def true_artifact_frfs(config: BenchConfig, artifact: BenchArtifact, direction: str, frequency_hz) -> dict:
    """Noise-free artifact hammer-test receptances.

    Returns
    -------
    dict of name (``h11``, ``h12``, ``h21``, ``h22``) to (n_freq,) complex, m/N
        ``hPQ`` is the displacement at point P per force at point Q.
    """
    model, dofs = build_artifact_assembly(config, artifact, direction)
    h = receptance(model, 2 * np.pi * np.asarray(frequency_hz, dtype=float), dofs, dofs)
    return {name: h[:, p - 1, q - 1].copy() for name, p, q in ARTIFACT_FRF_NAMES}


@dataclass(frozen=True)
class ArtifactTests:
    """A simulated artifact campaign.

    Attributes
    ----------
    frfs : dict of (direction, name) to FRF
        Noisy receptances with coherence; ``source`` is the file name.
    document : dict
        The artifact file (TOML-able) that ``bayes-rcsa spindle`` reads.
    truth : dict
        JSON-able record: the true flange receptance file names and the settings.
    true_spindle : dict of direction to PointReceptance
        Flange receptance of the true spindle on the artifact grid.
    """

    frfs: dict
    document: dict
    truth: dict
    true_spindle: dict = field(default_factory=dict)


def artifact_file_name(direction: str, name: str) -> str:
    """``<name>_<direction>.csv``, e.g. ``h11_x.csv``."""
    return f"{name}_{direction}.csv"


def generate_artifact_tests(
    config: BenchConfig, artifact: BenchArtifact, rng: np.random.Generator, directions=None
) -> ArtifactTests:
    """Simulate the artifact hammer tests (noise drawn from ``rng``).

    Parameters
    ----------
    config : BenchConfig
        The bench (spindle, materials); its tool-point noise settings are not
        used, the artifact has its own.
    artifact : BenchArtifact
    rng : numpy.random.Generator
        Consumed in a fixed order: directions outer, then h11, h12, h21, h22.
    directions : sequence of {"x", "y"}, optional
        Default: ``config.directions``.

    Returns
    -------
    ArtifactTests
    """
    directions = tuple(config.directions if directions is None else directions)
    f = artifact.frequency_hz
    frfs, true_spindle = {}, {}
    for d in directions:
        clean = true_artifact_frfs(config, artifact, d, f)
        for name, _, _ in ARTIFACT_FRF_NAMES:
            noisy, coh = add_measurement_noise(clean[name], artifact.noise_relative, artifact.noise_floor,
                                               artifact.n_averages, rng)
            frfs[(d, name)] = FRF(f, noisy, coh, source=artifact_file_name(d, name))
        true_spindle[d] = true_spindle_receptance(config, d, f)
    return ArtifactTests(frfs=frfs, document=artifact_document(config, artifact, directions),
                         truth=artifact_truth(config, artifact, directions), true_spindle=true_spindle)


def artifact_document(config: BenchConfig, artifact: BenchArtifact, directions) -> dict:
    """The artifact file as a user would write it (see docs/spindle.md)."""

    def material(name):
        m = config.materials[name]
        return {"youngs_modulus": m.youngs_modulus, "density": m.density, "poisson_ratio": m.poisson_ratio,
                "loss_factor": m.loss_factor}

    return {
        "name": "synthetic CAT40 shrink-fit artifact",
        "materials": {n: material(n) for n in dict.fromkeys((artifact.holder_material, artifact.blank_material))},
        "holder": {
            "material": artifact.holder_material,
            "segments": [{"length": s.length, "outer_diameter": s.outer_diameter, "inner_diameter": s.inner_diameter}
                         for s in artifact.holder_segments],
        },
        "blank": {
            "material": artifact.blank_material,
            "total_length": artifact.blank_length,
            "clamping_length": artifact.clamping_length,
            "segments": [{"length": artifact.blank_length, "diameter": artifact.blank_diameter}],
        },
        "points": {"point1": artifact.point_distances[0], "point2": artifact.point_distances[1]},
        "measurement": [
            {"direction": d, **{name: artifact_file_name(d, name) for name, _, _ in ARTIFACT_FRF_NAMES}}
            for d in directions
        ],
    }


def artifact_truth(config: BenchConfig, artifact: BenchArtifact, directions) -> dict:
    """JSON-able record of what generated the artifact tests."""
    return {
        "format": ARTIFACT_TRUTH_FORMAT,
        "true_spindle_files": {d: f"spindle_true_{d}.csv" for d in directions},
        "noise": {"relative": artifact.noise_relative, "floor": artifact.noise_floor,
                  "n_averages": artifact.n_averages},
        "frequency": {"start": artifact.frequency_start, "stop": artifact.frequency_stop,
                      "step": artifact.frequency_step, "n_lines": int(artifact.frequency_hz.size)},
        "joint": "bonded (rigid) shrink fit: one finite-element chain",
        "spindle": {
            "bearings": [{"position": b.position, "stiffness": b.stiffness, "damping": b.damping}
                         for b in config.spindle.bearings],
            "y_stiffness_factor": config.spindle.y_stiffness_factor,
        },
    }


def write_artifact_tests(tests: ArtifactTests, out_dir, overwrite: bool = False, seed: int | None = None) -> Path:
    """Write the artifact campaign as one directory, atomically.

    Files: ``artifact.toml``, ``h11_<dir>.csv`` ... ``h22_<dir>.csv``, the
    true flange receptances ``spindle_true_<dir>.csv`` (for checking only)
    and ``truth.json``.

    Returns
    -------
    Path
        ``artifact.toml`` inside ``out_dir``.
    """
    from ..io.frf_csv import write_frf_csv
    from ..io.receptance_csv import write_spindle_csv
    from ..io.atomic import begin_directory
    from ..io.toml_writer import dump_toml

    out_dir, tmp = begin_directory(out_dir, overwrite)
    try:
        for (d, name), frf in tests.frfs.items():
            write_frf_csv(tmp / frf.source, frf, comments=[
                "synthetic artifact hammer test (bayes_rcsa.synthetic.artifact)",
                f"{name}: displacement at point {name[1]} per force at point {name[2]} (m/N), direction {d}",
            ])
        for d, rec in tests.true_spindle.items():
            write_spindle_csv(tmp / tests.truth["true_spindle_files"][d], rec, comments=[
                "TRUE flange receptance of the synthetic spindle (for checking the identification only)",
            ])
        (tmp / "artifact.toml").write_text(
            "# Standard artifact (shrink-fit holder + bonded blank) for `bayes-rcsa spindle`.\n"
            "# Generated by bayes_rcsa.synthetic.artifact.\n" + dump_toml(tests.document), encoding="utf-8")
        truth = dict(tests.truth)
        if seed is not None:
            truth["seed"] = int(seed)
        (tmp / "truth.json").write_text(
            dumps_strict(truth, nonfinite="error", indent=2, sort_keys=True) + "\n", encoding="utf-8")
        _replace_dir(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out_dir / "artifact.toml"
