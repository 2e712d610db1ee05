"""``bayes-rcsa lobes``: stability lobes from measured FRFs or from posterior draws.

Outputs (in ``--out``):

- ``lobes.json``: ``spindle_speed_rpm``, ``depth_limit_m`` {q05, q50, q95}
  (``null`` where no limit lies inside the analysed range: for ZOA no chatter
  frequency of the FRF band maps to the speed, for SDM the cut is stable up
  to the top of the depth grid),
  ``recommended`` {spindle_speed_rpm, depth_m, p_stable, mrr_index} or
  ``null``, the cutting conditions, the method and, with ``--tests``, the
  predicted outcome of each test and the test error (paper's Table 8).
- ``p_stable.npz``: ``spindle_speed_rpm`` (n_speed,), ``depth_m``
  (n_depth,), ``p_stable`` (n_speed, n_depth).
- ``lobes.png``: probability map, its 5/50/95 % contours, the lobe band and
  the cutting tests (circles stable, crosses chatter).

Cutting-test file (``--tests``): CSV with a header naming the columns
``spindle_speed_rpm,depth_m,outcome`` (any order, case-insensitive, ``#``
comments allowed); ``outcome`` is ``stable`` or ``chatter``.  Depths in metres.
"""

from __future__ import annotations

import argparse
import csv
import io as _io
import json
import math
from pathlib import Path

import numpy as np

from ..errors import DataError, SetupError
from ._common import parse_float, parse_float_list

__all__ = ["register", "run", "read_cutting_tests", "parse_speeds", "common_frequency_grid"]

DEFAULT_SPEED_POINTS = 400


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "lobes",
        help="milling stability lobes (ZOA or SDM), deterministic or probabilistic",
        description="Compute milling stability lobes from measured tool-point FRFs in X and Y "
        "(--measured-x/--measured-y, deterministic) or from posterior draws of the contact parameters "
        "(SETUP --posterior, probabilistic).  Writes OUT/lobes.json, OUT/p_stable.npz and OUT/lobes.png.  "
        "Axis convention: X right, Y up seen from the spindle towards the tool tip, cutter turning clockwise "
        "in that view; --feed names the machine axis along which the tool advances.",
    )
    src = p.add_argument_group("dynamics (one of the two modes)")
    src.add_argument("setup", nargs="?", metavar="SETUP", help="setup TOML (posterior mode)")
    src.add_argument("--posterior", metavar="FILE", help="posterior.nc of 'bayes-rcsa identify' (posterior mode)")
    src.add_argument("--clamping-length", metavar="M", help="clamping length in m (posterior mode)")
    src.add_argument("--draws", type=int, default=500, metavar="N", help="posterior draws used (default 500)")
    src.add_argument("--seed", type=int, default=0, help="seed for choosing posterior draws (default 0)")
    src.add_argument("--measured-x", metavar="FX", help="measured tool-point FRF in X (CSV frequency_hz,real,imag)")
    src.add_argument("--measured-y", metavar="FY", help="measured tool-point FRF in Y (CSV frequency_hz,real,imag)")
    cut = p.add_argument_group("cutting conditions")
    cut.add_argument("--flutes", type=int, required=True, metavar="N", help="number of teeth")
    cut.add_argument("--kt", required=True, metavar="PA", help="tangential cutting-force coefficient in Pa (e.g. 790e6)")
    cut.add_argument("--kr", required=True, metavar="PA", help="radial cutting-force coefficient in Pa (e.g. 230e6)")
    cut.add_argument("--immersion", metavar="R", help="radial depth / tool diameter in (0, 1], 1 = slotting")
    cut.add_argument("--angles", metavar="ENTRY,EXIT", help="entry and exit angles in degrees instead of --immersion")
    cut.add_argument("--milling", choices=("down", "up"), default="down", help="down (climb) or up milling (default down)")
    cut.add_argument("--feed", choices=("x", "y"), default="x", help="feed direction (default x; the paper feeds in y)")
    cut.add_argument("--pitch", metavar="DEG,...", help="variable pitch: angle (deg) from each tooth to the one ahead")
    grid = p.add_argument_group("grid and method")
    grid.add_argument("--speeds", required=True, metavar="START:STOP[:COUNT]", help=f"spindle speeds in rpm (default COUNT {DEFAULT_SPEED_POINTS})")
    grid.add_argument("--max-depth", metavar="M", help="largest axial depth in m (map and recommendation limit; default from the lobes)")
    grid.add_argument("--depth-points", type=int, default=200, metavar="N", help="depth levels of the map (default 200)")
    grid.add_argument("--method", choices=("zoa", "sdm"), default="zoa", help="zero-order approximation or semi-discretisation (default zoa)")
    grid.add_argument("--intervals", type=int, metavar="M", help="SDM intervals per tooth period (default: 20 per cycle of the highest mode, >= 30)")
    grid.add_argument("--max-modes", type=int, default=4, metavar="N", help="largest mode count of the SDM modal fit (default 4)")
    grid.add_argument("--level", default="0.95", metavar="P", help="P(stable) required for the recommended point (default 0.95)")
    p.add_argument("--tests", metavar="CSV", help="cutting tests: spindle_speed_rpm,depth_m,outcome (stable|chatter)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.set_defaults(func=run)


# ------------------------------------------------------------------------------------------
# argument helpers
def parse_speeds(text: str, option: str = "--speeds") -> np.ndarray:
    """``START:STOP[:COUNT]`` rpm -> increasing grid of COUNT speeds (default 400)."""
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise SetupError(f"{option} {text!r}: expected START:STOP[:COUNT] in rpm")
    start = parse_float(parts[0], option, positive=True)
    stop = parse_float(parts[1], option, positive=True)
    count = DEFAULT_SPEED_POINTS
    if len(parts) == 3:
        try:
            count = int(parts[2])
        except ValueError:
            raise SetupError(f"{option} {text!r}: COUNT must be an integer") from None
    if stop <= start or count < 2:
        raise SetupError(f"{option} {text!r}: expected STOP > START and COUNT >= 2")
    return np.linspace(start, stop, count)


def _cutting(args):
    from ..stability import CuttingConditions

    kt = parse_float(args.kt, "--kt", positive=True)
    kr = parse_float(args.kr, "--kr")
    if (args.immersion is None) == (args.angles is None):
        raise SetupError("give exactly one of --immersion (radial depth / diameter) and --angles ENTRY,EXIT (deg)")
    kw = {}
    if args.immersion is not None:
        kw["radial_immersion"] = parse_float(args.immersion, "--immersion", positive=True)
    else:
        ang = parse_float_list(args.angles, "--angles")
        if len(ang) != 2:
            raise SetupError(f"--angles {args.angles!r}: expected ENTRY,EXIT in degrees")
        kw["entry_angle"], kw["exit_angle"] = (math.radians(a) for a in ang)
    if args.pitch is not None:
        kw["pitch_angles"] = tuple(math.radians(a) for a in parse_float_list(args.pitch, "--pitch", positive=True))
    return CuttingConditions(kt=kt, kr=kr, flutes=args.flutes, milling=args.milling, feed=args.feed, **kw)


def common_frequency_grid(frf_x, frf_y):
    """Both FRFs on one grid: X's lines inside the overlap, Y interpolated (complex, linear) when grids differ.

    Returns
    -------
    frequency_hz (n,), gx (n,), gy (n,)
    """
    fx, fy = frf_x.frequency_hz, frf_y.frequency_hz
    if fx.shape == fy.shape and np.allclose(fx, fy, rtol=1e-12, atol=0):
        return fx, frf_x.values, frf_y.values
    lo, hi = max(fx[0], fy[0]), min(fx[-1], fy[-1])
    keep = (fx >= lo) & (fx <= hi)
    if keep.sum() < 2:
        raise DataError(
            f"{frf_x.source} ({fx[0]:g}-{fx[-1]:g} Hz) and {frf_y.source} ({fy[0]:g}-{fy[-1]:g} Hz) do not share a frequency band"
        )
    f = fx[keep]
    gy = np.interp(f, fy, frf_y.values.real) + 1j * np.interp(f, fy, frf_y.values.imag)
    return f, frf_x.values[keep], gy


def read_cutting_tests(path):
    """Read a cutting-test CSV.

    Returns
    -------
    speed_rpm (n,), depth_m (n,), stable (n,) bool
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a UTF-8 text file") from None
    rows = [(i + 1, line) for i, line in enumerate(text.splitlines()) if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        raise DataError(f"{path}: no header row (expected spindle_speed_rpm,depth_m,outcome)")
    header = [h.strip().lower() for h in next(csv.reader(_io.StringIO(rows[0][1])))]
    need = ("spindle_speed_rpm", "depth_m", "outcome")
    missing = [c for c in need if c not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {','.join(header)})")
    col = {c: header.index(c) for c in need}
    speed, depth, stable = [], [], []
    for lineno, line in rows[1:]:
        cells = next(csv.reader(_io.StringIO(line)))
        if len(cells) != len(header):
            raise DataError(f"{path}:{lineno}: {len(cells)} fields, expected {len(header)}")
        try:
            s = float(cells[col["spindle_speed_rpm"]])
            d = float(cells[col["depth_m"]])
        except ValueError:
            raise DataError(f"{path}:{lineno}: spindle_speed_rpm and depth_m must be numbers") from None
        if not (math.isfinite(s) and s > 0 and math.isfinite(d) and d > 0):
            raise DataError(f"{path}:{lineno}: expected speed > 0 rpm and depth > 0 m, got {s!r}, {d!r}")
        o = cells[col["outcome"]].strip().lower()
        if o not in ("stable", "chatter"):
            raise DataError(f"{path}:{lineno}: outcome {cells[col['outcome']]!r}, expected 'stable' or 'chatter'")
        speed.append(s)
        depth.append(d)
        stable.append(o == "stable")
    if not speed:
        raise DataError(f"{path}: no cutting tests after the header")
    return np.array(speed), np.array(depth), np.array(stable, dtype=bool)


def _finite_list(a):
    return [float(v) if np.isfinite(v) else None for v in np.asarray(a, dtype=float)]


# ------------------------------------------------------------------------------------------
def _dynamics(args):
    """FRF draws (n_draws, n_freq) in X and Y, frequency grid, description."""
    measured = args.measured_x is not None or args.measured_y is not None
    posterior = args.setup is not None or args.posterior is not None or args.clamping_length is not None
    if measured and posterior:
        raise SetupError("give either --measured-x/--measured-y or SETUP --posterior --clamping-length, not both")
    if measured:
        if args.measured_x is None or args.measured_y is None:
            raise SetupError("measured mode needs both --measured-x and --measured-y")
        from ..io.frf import read_frf

        fx = read_frf(args.measured_x)
        fy = read_frf(args.measured_y)
        f, gx, gy = common_frequency_grid(fx, fy)
        return f, gx[None], gy[None], {"mode": "measured", "measured_x": str(args.measured_x), "measured_y": str(args.measured_y)}
    if args.setup is None or args.posterior is None or args.clamping_length is None:
        raise SetupError(
            "give --measured-x FX --measured-y FY, or SETUP --posterior FILE --clamping-length M for posterior draws"
        )
    clamping = parse_float(args.clamping_length, "--clamping-length", positive=True)
    if args.draws < 1:
        raise SetupError(f"--draws {args.draws}: expected >= 1")
    return posterior_frf_draws(args.setup, args.posterior, clamping, args.draws, np.random.default_rng(args.seed),
                               tool=getattr(args, "tool", None))


def posterior_frf_draws(setup_path, posterior_path, clamping_length: float, n_draws: int, rng, tool=None):
    """Posterior-predictive tool-point FRFs in X and Y at one clamping length.

    The contact parameters are shared by both directions; the spindle
    receptance is per direction.  The frequency lines are those of the X
    spindle file inside the range both spindle files cover.

    Returns
    -------
    frequency_hz : (n_freq,) Hz
    hx, hy : (n_draws, n_freq) complex m/N
    source : dict
    """
    from ..io import load_setup
    from ..model import Configuration
    from ..posterior.draws import load_posterior
    from ..posterior.predict import predictive_frf
    from ..posterior.prediction_outputs import check_prediction_lengths

    setup = load_setup(setup_path, load_data=False, load_spindle=True)
    for d in ("x", "y"):
        if d not in setup.spindle:
            raise SetupError(f"{setup_path}: [spindle] {d} is needed for lobes (both directions are coupled)")
    if tool is None:
        if len(setup.tools) != 1:
            raise SetupError(f"{setup_path}: several tools {sorted(setup.tools)}; the posterior mode needs one")
        tool = next(iter(setup.tools))
    draws = load_posterior(posterior_path, setup).subset(n_draws, rng)
    check_prediction_lengths(draws, setup, [clamping_length])
    sx, sy = setup.spindle["x"].frequency_hz, setup.spindle["y"].frequency_hz
    lo, hi = max(sx[0], sy[0]), min(sx[-1], sy[-1])
    f = sx[(sx >= lo) & (sx <= hi)]
    model = setup.model()
    hx = predictive_frf(draws, model, Configuration(clamping_length, "x", tool), f)
    hy = predictive_frf(draws, model, Configuration(clamping_length, "y", tool), f)
    source = {
        "mode": "posterior",
        "setup": str(setup_path),
        "posterior": str(posterior_path),
        "clamping_length_m": clamping_length,
        "n_draws": int(draws.n_draws),
        "method": draws.method,
    }
    return f, hx, hy, source


def _plot(path, res, q, tests, deterministic: bool, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io.atomic import atomic_path

    n = res.speed_rpm
    a_mm = res.depth_m * 1e3
    fig, ax = plt.subplots(figsize=(9, 5.5))
    mesh = ax.pcolormesh(n, a_mm, res.p_stable.T, shading="nearest", cmap="RdYlGn", vmin=0, vmax=1, alpha=0.75)
    fig.colorbar(mesh, ax=ax, label="P(stable)")
    top = a_mm[-1]
    levels = [v for v in (0.05, 0.5, 0.95) if res.p_stable.min() < v < res.p_stable.max()]
    if not deterministic and levels:
        cs = ax.contour(n, a_mm, res.p_stable.T, levels=levels, colors="k", linewidths=0.8)
        ax.clabel(cs, fmt={v: f"P={v:g}" for v in levels}, fontsize=7)
    for key, style in ((0.5, "-"), (0.05, "--"), (0.95, ":")):
        y = np.where(np.isfinite(q[key]), q[key] * 1e3, np.nan)
        ax.plot(n, np.minimum(y, top * 1.05), style, color="navy", lw=1.2, label=("lobe" if deterministic else f"a_lim q{int(key * 100):02d}"))
        if deterministic:
            break
    if not deterministic:
        lo = np.where(np.isfinite(q[0.05]), q[0.05] * 1e3, np.nan)
        hi = np.where(np.isfinite(q[0.95]), q[0.95] * 1e3, np.nan)
        ax.fill_between(n, np.minimum(lo, top), np.minimum(hi, top), color="navy", alpha=0.15, label="5-95 % band")
    if res.recommended is not None:
        ax.plot(res.recommended.spindle_speed_rpm, res.recommended.depth_m * 1e3, "*", ms=14, color="gold", mec="k", label="recommended")
    if tests is not None:
        s, d, st = tests
        ax.plot(s[st], d[st] * 1e3, "o", mfc="none", mec="darkgreen", ms=7, label="test: stable")
        ax.plot(s[~st], d[~st] * 1e3, "x", color="darkred", ms=7, label="test: chatter")
    ax.set_xlim(n[0], n[-1])
    ax.set_ylim(0, top)
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth of cut (mm)")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    from ..io.atomic import atomic_path, atomic_write_text
    from ..stability import lobes_from_frf_draws
    from ..stability.compare import stable_at, test_error

    cutting = _cutting(args)
    speeds = parse_speeds(args.speeds)
    level = parse_float(args.level, "--level", positive=True)
    if level > 1:
        raise SetupError(f"--level {args.level}: expected a probability in (0, 1]")
    max_depth = parse_float(args.max_depth, "--max-depth", positive=True) if args.max_depth is not None else None
    if args.depth_points < 2:
        raise SetupError(f"--depth-points {args.depth_points}: expected >= 2")
    if args.intervals is not None and args.intervals < 2:
        raise SetupError(f"--intervals {args.intervals}: expected >= 2")
    tests = read_cutting_tests(args.tests) if args.tests is not None else None
    f, gx, gy, source = _dynamics(args)  # validates before any output is written

    res = lobes_from_frf_draws(
        gx,
        gy,
        f,
        cutting,
        speeds,
        method=args.method,
        level=level,
        max_depth=max_depth,
        depth_points=args.depth_points,
        intervals=args.intervals,
        max_modes=args.max_modes,
    )
    q = res.quantiles
    deterministic = res.depth_limit_m.shape[0] == 1
    phi_in, phi_out = cutting.angles
    out = {
        "spindle_speed_rpm": [float(v) for v in res.speed_rpm],
        "depth_limit_m": {"q05": _finite_list(q[0.05]), "q50": _finite_list(q[0.5]), "q95": _finite_list(q[0.95])},
        "recommended": None
        if res.recommended is None
        else {
            "spindle_speed_rpm": res.recommended.spindle_speed_rpm,
            "depth_m": res.recommended.depth_m,
            "p_stable": res.recommended.p_stable,
            "mrr_index": res.recommended.mrr_index,
        },
        "level": level,
        "method": res.method,
        "n_draws": int(res.depth_limit_m.shape[0]),
        "deterministic": deterministic,
        "depth_grid_m": {"min": float(res.depth_m[0]), "max": float(res.depth_m[-1]), "count": int(res.depth_m.size)},
        "cutting": {
            "kt_pa": cutting.kt,
            "kr_pa": cutting.kr,
            "flutes": cutting.flutes,
            "radial_immersion": cutting.radial_immersion,
            "milling": cutting.milling,
            "entry_angle_deg": math.degrees(phi_in),
            "exit_angle_deg": math.degrees(phi_out),
            "feed": cutting.feed,
            "pitch_deg": [math.degrees(v) for v in cutting.pitches],
        },
        "source": source,
        "notes": "depth_limit_m quantiles are over draws: q05 is the depth 95 % of the draws consider stable; "
        "null = no limit inside the analysed range (zoa: no chatter frequency of the FRF band maps to that speed; "
        "sdm: stable up to the top of the depth grid). mrr_index = depth_m * spindle_speed_rpm.",
    }
    if res.recommended is None:
        out["recommended_note"] = f"no grid point reaches P(stable) >= {level}"
    if res.modal_fits:
        fx, fy = res.modal_fits[0]
        out["modal_fit"] = {
            d: {
                "natural_frequency_hz": fit.model.natural_frequency_hz.tolist(),
                "damping_ratio": fit.model.damping_ratio.tolist(),
                "stiffness_n_per_m": fit.model.stiffness.tolist(),
                "rms_relative": fit.rms_relative,
            }
            for d, fit in (("x", fx), ("y", fy))
        }
    if tests is not None:
        ts, td, tst = tests
        per_draw = np.array([stable_at(res.speed_rpm, lim, ts, td) for lim in res.depth_limit_m])
        p_test = per_draw.mean(axis=0)
        predicted = p_test >= 0.5
        out["tests"] = [
            {"spindle_speed_rpm": float(s), "depth_m": float(d), "outcome": "stable" if o else "chatter", "p_stable": float(p), "predicted": "stable" if pr else "chatter"}
            for s, d, o, p, pr in zip(ts, td, tst, p_test, predicted)
        ]
        out["test_error"] = test_error(predicted, tst)

    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    title = f"{cutting.flutes} flutes, {res.method.upper()}, " + (
        "measured FRFs" if source["mode"] == "measured" else f"{res.depth_limit_m.shape[0]} draws"
    )
    # each file is written atomically; the figure first, as the step most likely to fail
    _plot(outdir / "lobes.png", res, q, tests, deterministic, title)
    with atomic_path(outdir / "p_stable.npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, spindle_speed_rpm=res.speed_rpm, depth_m=res.depth_m, p_stable=res.p_stable)
    atomic_write_text(outdir / "lobes.json", json.dumps(out, indent=1) + "\n")
    rec = res.recommended
    msg = f"wrote {outdir / 'lobes.json'}, p_stable.npz, lobes.png"
    if rec is not None:
        msg += f"; recommended {rec.spindle_speed_rpm:.0f} rpm, {rec.depth_m * 1e3:.3f} mm (P(stable) = {rec.p_stable:.2f})"
    print(msg)
    return 0
