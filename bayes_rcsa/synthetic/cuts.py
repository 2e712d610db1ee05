"""Cutting-test outcomes from the bench's truth: which test cuts chatter (issue #23).

A machinist's cut at spindle speed n and axial depth a is stable when a lies
below the true stability limit a_lim(n) of the *true* structure with the
*true* cutting-force coefficients.  This module computes that limit from the
noise-free tool-point FRFs of the finite-element bench
(:func:`~bayes_rcsa.synthetic.bench.true_tool_point_frf`, X and Y, at the
cut's clamping length) and labels cuts with it.  The hidden effect the hammer
test cannot see is the cutting coefficients: the user assumes ``kt_assumed``,
``kr_assumed`` while the truth is ``kt_assumed (1 + kt_error)``,
``kr_assumed (1 + kr_error)``.

Independence from the model under test
--------------------------------------
The bench never shares code with what it tests (no inverse crime), and the
package layers forbid ``synthetic`` to import ``stability``.  The truth here
is therefore its own implementation of the zero-order (ZOA) limit:

* the mean directional matrix H0 is the tooth-pass average of the
  instantaneous directional matrix by trapezoidal quadrature (4001 angles),
  not the closed form of :func:`bayes_rcsa.stability.cutting.mean_directional_matrix`;
* the limit at a speed is found by *root finding in frequency* at that fixed
  speed: with the tooth period τ = 60/(N n) and an eigenvalue μ(f) of
  H0 diag(G_x, G_y) with Re μ > 0, chatter at f needs the phase residual
  r(f) = 2π f τ − ε(f) (ε = π + 2 arctan(Im μ / Re μ)) to be a multiple of
  2π; every sign change of the wrapped residual between two lines (the two
  eigenvalues paired between the lines by distance) is a root, its depth
  1/(2 Re μ) is interpolated linearly, and the limit is the smallest root
  depth (+inf without a root: the FRF band holds no chatter frequency for
  that speed).  :func:`bayes_rcsa.stability.zoa.zoa_lobes` instead takes the
  lower envelope of lobes in speed; the two agree to the interpolation
  error of the frequency grid (tests/test_cuts_bench.py).

The lowest limit is used (stable islands above it are ignored), as in the
project's P(stable) maps.

Label noise (optional)
----------------------
With ``label_noise`` σ > 0 a cut chatters with probability
Φ(ln(a / a_lim) / σ) (a probit in the log depth ratio), so cuts within a few
σ of the boundary may be labelled either way; σ = 0 (default) labels
exactly: stable iff a < a_lim.

Files
-----
:func:`write_cuts` writes ``cuts.csv`` (the columns of
:func:`bayes_rcsa.stability.tests_io.read_cutting_tests` plus
``clamping_length_m, radial_immersion, feed_direction, tool``) and
``cuts_truth.json`` (true and assumed coefficients, the true limit on the
map's speed grid and the true stable/chatter map on a 50 x 50 grid).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SetupError
from ..io.atomic import atomic_write_text
from ..io.jsonable import to_jsonable
from ..model.assembly import Configuration
from .bench import true_tool_point_frf
from .config import BenchConfig

__all__ = [
    "CutPlan", "CutCampaign", "quadrature_directional_matrix", "root_depth_limit", "true_cut_frfs",
    "true_depth_limit", "label_cuts", "truth_map", "generate_cuts", "cuts_csv_text", "cuts_truth_document",
    "write_cuts", "CUTS_FILE", "CUTS_TRUTH_FILE",
]

CUTS_FILE = "cuts.csv"
CUTS_TRUTH_FILE = "cuts_truth.json"
_LAYOUTS = ("random", "grid")


@dataclass(frozen=True)
class CutPlan:
    """What cutting tests to simulate and under which (true and assumed) cutting conditions.

    Attributes
    ----------
    n_cuts : int >= 0
    clamping_length : float, m (must be a clamping length the bench can build)
    speed_range : (lo, hi) rpm, range of the test cuts and of the truth map
    depth_range : (lo, hi) m, range of the test cuts; the truth map's depth axis runs from
        ``depth_range[1] / map_points`` to ``depth_range[1]``
    kt_assumed, kr_assumed : Pa, what the user believes
    kt_error, kr_error : float, relative error of the belief: true = assumed (1 + error), > -1
    flutes : int; radial_immersion : (0, 1]; milling : {"down", "up"}; feed : {"x", "y"}
    label_noise : float >= 0, σ of the probit in ln(a / a_lim) (0: exact labels)
    layout : {"random", "grid"}, cuts uniform at random in the box, or a near-square grid
    map_points : int, speeds and depths of the truth map (50 x 50)
    frequency_step : float, Hz, line spacing of the true FRFs (over the bench's band)
    """

    n_cuts: int = 10
    clamping_length: float = 0.030
    speed_range: tuple[float, float] = (5000.0, 30000.0)
    depth_range: tuple[float, float] = (0.0002, 0.004)
    kt_assumed: float = 790e6
    kr_assumed: float = 230e6
    kt_error: float = 0.2
    kr_error: float = 0.2
    flutes: int = 4
    radial_immersion: float = 0.95
    milling: str = "down"
    feed: str = "y"
    label_noise: float = 0.0
    layout: str = "random"
    map_points: int = 50
    frequency_step: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "speed_range", tuple(float(v) for v in self.speed_range))
        object.__setattr__(self, "depth_range", tuple(float(v) for v in self.depth_range))
        if isinstance(self.n_cuts, bool) or not isinstance(self.n_cuts, int) or self.n_cuts < 0:
            raise SetupError(f"cuts = {self.n_cuts!r}: expected an integer >= 0")
        lo, hi = self.speed_range
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise SetupError(f"cut speed range {list(self.speed_range)!r} rpm: expected 0 < lo < hi")
        lo, hi = self.depth_range
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise SetupError(f"cut depth range {list(self.depth_range)!r} m: expected 0 < lo < hi")
        if hi > 0.05:
            raise SetupError(f"cut depth range {list(self.depth_range)!r}: depths are in m (0.004 is 4 mm); "
                             f"{hi!r} m looks like millimetres")
        for name in ("kt_assumed", "kr_assumed"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise SetupError(f"{name} = {v!r} Pa: expected a finite number > 0")
        for name in ("kt_error", "kr_error"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > -1):
                raise SetupError(f"{name} = {v!r}: expected a relative error > -1 (true = assumed (1 + error))")
        if not (math.isfinite(self.label_noise) and self.label_noise >= 0):
            raise SetupError(f"label_noise = {self.label_noise!r}: expected a number >= 0")
        if not (0 < self.radial_immersion <= 1):
            raise SetupError(f"radial_immersion = {self.radial_immersion!r}: expected a value in (0, 1]")
        if self.milling not in ("down", "up") or self.feed not in ("x", "y"):
            raise SetupError(f"milling = {self.milling!r}, feed = {self.feed!r}: expected down/up and x/y")
        if isinstance(self.flutes, bool) or not isinstance(self.flutes, int) or self.flutes < 1:
            raise SetupError(f"flutes = {self.flutes!r}: expected an integer >= 1")
        if self.layout not in _LAYOUTS:
            raise SetupError(f"cut layout = {self.layout!r}: expected one of {_LAYOUTS}")
        if self.map_points < 2 or not (self.frequency_step > 0):
            raise SetupError("map_points must be >= 2 and frequency_step > 0")

    @property
    def kt_true(self) -> float:
        """True tangential coefficient, Pa."""
        return self.kt_assumed * (1.0 + self.kt_error)

    @property
    def kr_true(self) -> float:
        """True radial coefficient, Pa."""
        return self.kr_assumed * (1.0 + self.kr_error)

    @property
    def angles(self) -> tuple[float, float]:
        """(entry, exit) immersion angles in rad (clockwise from the feed-normal axis; docs/stability.md)."""
        r = self.radial_immersion
        if self.milling == "up":
            return 0.0, math.acos(1.0 - 2.0 * r)
        return math.acos(2.0 * r - 1.0), math.pi


#: How the bench's own limit is computed (the default truth when no other method is passed).
OWN_ZOA = "zoa (own root-finding implementation on the noise-free FE FRFs, X and Y)"


@dataclass(frozen=True)
class CutCampaign:
    """Simulated cutting tests and the truth they were labelled with.

    Attributes
    ----------
    plan : CutPlan
    speed_rpm, depth_m : (n_cuts,) rpm, m
    stable : (n_cuts,) bool, the recorded outcome
    p_chatter : (n_cuts,) probability of chatter the label was drawn with (0/1 without label noise)
    true_limit_at_cuts : (n_cuts,) m, true limit at each cut's speed
    map_speed_rpm : (P,) rpm; map_depth_m : (P,) m
    map_limit_m : (P,) m, true limit at the map speeds (+inf: no chatter frequency in the band)
    map_stable : (P, P) bool, [speed, depth]: depth < limit
    """

    plan: CutPlan
    speed_rpm: np.ndarray
    depth_m: np.ndarray
    stable: np.ndarray
    p_chatter: np.ndarray
    true_limit_at_cuts: np.ndarray
    map_speed_rpm: np.ndarray
    map_depth_m: np.ndarray
    map_limit_m: np.ndarray
    map_stable: np.ndarray
    truth_method: str = OWN_ZOA


# ------------------------------------------------------------------ physics --
def quadrature_directional_matrix(kt: float, kr: float, flutes: int, entry: float, exit_: float, feed: str,
                                  n_points: int = 4001) -> np.ndarray:
    """Mean directional matrix H0 (Pa, machine frame) by quadrature over the cutting arc.

    The regenerative force of one tooth at angle φ (feed frame, chip
    h = Δq_1 sin φ + Δq_2 cos φ, F_t = K_t a h, F_r = K_r a h) is a H(φ) Δq with
    H = [[-(K_t cos φ + K_r sin φ) sin φ, -(K_t cos φ + K_r sin φ) cos φ],
    [(K_t sin φ - K_r cos φ) sin φ, (K_t sin φ - K_r cos φ) cos φ]];
    N teeth spread over 2π give H0 = N/(2π) ∫_entry^exit H dφ.

    Returns
    -------
    (2, 2) Pa
    """
    phi = np.linspace(entry, exit_, n_points)
    s, c = np.sin(phi), np.cos(phi)
    g = kt * c + kr * s
    e = kt * s - kr * c
    h = np.array([[-g * s, -g * c], [e * s, e * c]])  # (2, 2, n)
    mean = np.trapezoid(h, phi, axis=-1) * flutes / (2.0 * math.pi)
    if feed == "x":
        return mean
    rot = np.array([[0.0, 1.0], [-1.0, 0.0]])  # feed frame from the machine frame for feed +Y
    return rot.T @ mean @ rot


def _eigenvalues(h0: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """(n_freq, 2) eigenvalues of H0 diag(gx, gy), 1/m (principal square root; paired later)."""
    a = h0[0, 0] * gx
    d = h0[1, 1] * gy
    root = np.sqrt(0.25 * (a - d) ** 2 + h0[0, 1] * h0[1, 0] * gx * gy)
    return np.stack([0.5 * (a + d) + root, 0.5 * (a + d) - root], axis=-1)


def root_depth_limit(frf_x, frf_y, frequency_hz, h0: np.ndarray, flutes: int, speed_rpm) -> np.ndarray:
    """Lowest ZOA depth limit at each speed by root finding in frequency (module docstring).

    Parameters
    ----------
    frf_x, frf_y : (n_freq,) complex, m/N, direct tool-point receptances
    frequency_hz : (n_freq,) Hz, increasing
    h0 : (2, 2) Pa, mean directional matrix
    flutes : int
    speed_rpm : (n_speed,) rpm

    Returns
    -------
    (n_speed,) m, +inf where no chatter frequency in the band satisfies the phase condition.
    """
    f = np.asarray(frequency_hz, dtype=float)
    mu = _eigenvalues(h0, np.asarray(frf_x, dtype=complex), np.asarray(frf_y, dtype=complex))
    m0, m1 = mu[:-1], mu[1:]
    swap = (np.abs(m0[:, 0] - m1[:, 1]) + np.abs(m0[:, 1] - m1[:, 0])
            < np.abs(m0[:, 0] - m1[:, 0]) + np.abs(m0[:, 1] - m1[:, 1]))
    m1 = np.where(swap[:, None], m1[:, ::-1], m1)  # pair each eigenvalue with its nearest neighbour
    ok = (m0.real > 0) & (m1.real > 0)  # (n_freq - 1, 2): a real positive depth at both ends
    s0 = np.where(ok, m0.real, 1.0)
    s1 = np.where(ok, m1.real, 1.0)
    eps0 = math.pi + 2.0 * np.arctan(m0.imag / s0)
    eps1 = math.pi + 2.0 * np.arctan(m1.imag / s1)
    tau = 60.0 / (flutes * np.asarray(speed_rpm, dtype=float))  # (S,)
    r0 = 2 * math.pi * f[:-1, None, None] * tau - eps0[..., None]  # (F-1, 2, S)
    r1 = 2 * math.pi * f[1:, None, None] * tau - eps1[..., None]
    r0 = np.mod(r0 + math.pi, 2 * math.pi) - math.pi
    r1 = np.mod(r1 + math.pi, 2 * math.pi) - math.pi
    root = ok[..., None] & (np.sign(r0) != np.sign(r1)) & (np.abs(r1 - r0) < math.pi)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(root, r0 / (r0 - r1), 0.0)
    depth = np.where(root, 0.5 / s0[..., None] + t * (0.5 / s1[..., None] - 0.5 / s0[..., None]), np.inf)
    return np.min(depth, axis=(0, 1))


def true_cut_frfs(config: BenchConfig, clamping_length: float, frequency_hz) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free tool-point FRFs of the true structure in X and Y at one clamping length, (n_freq,) m/N each."""
    gx = true_tool_point_frf(config, Configuration(float(clamping_length), "x", "tool"), frequency_hz)
    gy = true_tool_point_frf(config, Configuration(float(clamping_length), "y", "tool"), frequency_hz)
    return gx, gy


def _frequency_grid(config: BenchConfig, step: float) -> np.ndarray:
    n = int(math.floor((config.frequency_stop - config.frequency_start) / step + 1e-9)) + 1
    return config.frequency_start + step * np.arange(n)


def true_depth_limit(config: BenchConfig, plan: CutPlan, speed_rpm, frfs=None) -> np.ndarray:
    """True depth limit (m) at ``speed_rpm`` for the plan's clamping length and TRUE coefficients.

    ``frfs`` = (frequency_hz, gx, gy) reuses FRFs already computed.
    """
    if frfs is None:
        f = _frequency_grid(config, plan.frequency_step)
        gx, gy = true_cut_frfs(config, plan.clamping_length, f)
    else:
        f, gx, gy = frfs
    entry, exit_ = plan.angles
    h0 = quadrature_directional_matrix(plan.kt_true, plan.kr_true, plan.flutes, entry, exit_, plan.feed)
    return root_depth_limit(gx, gy, f, h0, plan.flutes, np.atleast_1d(np.asarray(speed_rpm, dtype=float)))


def label_cuts(depth_m, limit_m, label_noise: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Outcomes of cuts at depths ``depth_m`` under true limits ``limit_m``: (stable bool, P(chatter)).

    σ = 0: stable iff depth < limit.  σ > 0: chatter with probability Φ(ln(a / a_lim) / σ).
    """
    a = np.asarray(depth_m, dtype=float)
    lim = np.asarray(limit_m, dtype=float)
    if label_noise == 0:
        p = (a >= lim).astype(float)
        return a < lim, p
    from scipy.special import ndtr

    with np.errstate(divide="ignore"):
        p = ndtr(np.log(a / lim) / label_noise)
    return rng.random(a.shape) >= p, p


def truth_map(plan: CutPlan, limit_fn) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The true stable/chatter map: speeds (P,), depths (P,), limits (P,), stable (P, P) [speed, depth]."""
    p = plan.map_points
    speeds = np.linspace(plan.speed_range[0], plan.speed_range[1], p)
    depths = np.linspace(plan.depth_range[1] / p, plan.depth_range[1], p)
    lim = limit_fn(speeds)
    return speeds, depths, lim, depths[None, :] < lim[:, None]


def _layout(plan: CutPlan, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    n = plan.n_cuts
    (s0, s1), (d0, d1) = plan.speed_range, plan.depth_range
    if plan.layout == "random":
        return rng.uniform(s0, s1, n), rng.uniform(d0, d1, n)
    cols = max(1, int(math.ceil(math.sqrt(n))))
    rows = max(1, int(math.ceil(n / cols)))
    # cell centres of a cols x rows grid, filled row by row (the last row may be partial)
    sc = s0 + (np.arange(cols) + 0.5) * (s1 - s0) / cols
    dc = d0 + (np.arange(rows) + 0.5) * (d1 - d0) / rows
    s, d = np.meshgrid(sc, dc)
    return s.ravel()[:n], d.ravel()[:n]


def generate_cuts(config: BenchConfig, plan: CutPlan, rng: np.random.Generator, true_limit=None,
                  truth_method: str | None = None) -> CutCampaign:
    """Cut locations (random or grid in the plan's box), their true outcomes and the truth map.

    Parameters
    ----------
    config : BenchConfig
    plan : CutPlan
    rng : numpy.random.Generator
    true_limit : callable, optional
        ``(frequency_hz (n_freq,), frf_x (n_freq,), frf_y (n_freq,), speed_rpm (n,)) -> (n,) m``: the true
        limit from another stability method on the true FRFs (e.g. the project's SDM, passed in from a
        higher layer: this package may not import ``stability``).  Default: the bench's own ZOA.
    truth_method : str, optional
        What ``true_limit`` computes, for the truth file.
    """
    f = _frequency_grid(config, plan.frequency_step)
    frfs = (f, *true_cut_frfs(config, plan.clamping_length, f))

    def limit(s):
        if true_limit is not None:
            return np.asarray(true_limit(frfs[0], frfs[1], frfs[2], np.atleast_1d(np.asarray(s, dtype=float))),
                              dtype=float)
        return true_depth_limit(config, plan, s, frfs)

    speeds, depths = _layout(plan, rng)
    lim = limit(speeds) if speeds.size else np.zeros(0)
    stable, p = label_cuts(depths, lim, plan.label_noise, rng)
    ms, md, ml, mstab = truth_map(plan, limit)
    return CutCampaign(plan, speeds, depths, stable, p, lim, ms, md, ml, mstab,
                       OWN_ZOA if true_limit is None else (truth_method or "a method passed by the caller"))


# ------------------------------------------------------------------- files --
def cuts_csv_text(cuts: CutCampaign, tool: str = "tool") -> str:
    """The cutting-test CSV (``read_cutting_tests`` columns plus setup columns)."""
    p = cuts.plan
    lines = [
        "# synthetic cutting tests from the bench's truth (bayes_rcsa.synthetic.cuts); see cuts_truth.json",
        "spindle_speed_rpm,depth_m,outcome,clamping_length_m,radial_immersion,feed_direction,tool",
    ]
    for s, d, ok in zip(cuts.speed_rpm, cuts.depth_m, cuts.stable):
        lines.append(f"{float(s)!r},{float(d)!r},{'stable' if ok else 'chatter'},{float(p.clamping_length)!r},"
                     f"{float(p.radial_immersion)!r},{p.feed},{tool}")
    return "\n".join(lines) + "\n"


def cuts_truth_document(cuts: CutCampaign, seed: int | None = None) -> dict:
    """JSON-able truth of the cutting tests."""
    p = cuts.plan
    return to_jsonable({
        "format": "bayes_rcsa.synthetic.cuts_truth/1",
        "method": cuts.truth_method,
        "seed": seed,
        "plan": dataclasses.asdict(p),
        "kt_true": p.kt_true, "kr_true": p.kr_true, "kt_assumed": p.kt_assumed, "kr_assumed": p.kr_assumed,
        "cutting": {"flutes": p.flutes, "radial_immersion": p.radial_immersion, "milling": p.milling,
                    "feed": p.feed, "clamping_length_m": p.clamping_length},
        "label_noise": p.label_noise,
        "cuts": [{"spindle_speed_rpm": s, "depth_m": d, "stable": bool(ok), "p_chatter": q, "true_limit_m": lim}
                 for s, d, ok, q, lim in zip(cuts.speed_rpm, cuts.depth_m, cuts.stable, cuts.p_chatter,
                                             cuts.true_limit_at_cuts)],
        "map": {"speed_rpm": cuts.map_speed_rpm, "depth_m": cuts.map_depth_m, "limit_m": cuts.map_limit_m,
                "stable": cuts.map_stable.astype(int)},
    })  # an infinite limit (no chatter frequency in the band) is written as null


def write_cuts(cuts: CutCampaign, out_dir, seed: int | None = None) -> tuple[Path, Path]:
    """Write ``cuts.csv`` and ``cuts_truth.json`` into ``out_dir`` (each atomically)."""
    out = Path(out_dir)
    csv_path, truth_path = out / CUTS_FILE, out / CUTS_TRUTH_FILE
    atomic_write_text(truth_path, json.dumps(cuts_truth_document(cuts, seed), indent=2, sort_keys=True) + "\n")
    atomic_write_text(csv_path, cuts_csv_text(cuts))
    return csv_path, truth_path
