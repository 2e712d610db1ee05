"""``bayes-rcsa simulate``: predicted tool-point FRF for given contact parameters."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import SetupError
from ._common import Summary, add_force_argument, parse_float, parse_frequency_grid

ORDER = 20


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate",
        help="predict the tool-point FRF for given contact parameters",
        description="Predict the tool-point receptance h = u/F (m/N) of the set-up in SETUP at one clamping "
        "length for given tool-holder contact stiffness and damping, and write it as a tool-point FRF CSV "
        "(frequency_hz,real,imag) or universal file.  The frequency grid is the spindle file's unless --freq is given.",
    )
    p.add_argument("setup", metavar="SETUP", help="setup TOML file")
    p.add_argument("--clamping-length", required=True, metavar="L", help="clamping length, m (e.g. 0.025)")
    p.add_argument("--kx", required=True, metavar="K", help="translational contact stiffness k_xf, N/m")
    p.add_argument("--ktheta", required=True, metavar="K", help="rotational contact stiffness k_thetaM, N m/rad")
    p.add_argument("--cx", default="0", metavar="C", help="translational contact damping c_xf, N s/m (default 0)")
    p.add_argument("--ctheta", default="0", metavar="C", help="rotational contact damping c_thetaM, N m s/rad (default 0)")
    p.add_argument("--direction", default="x", choices=("x", "y"), help="spindle direction (default x)")
    p.add_argument("--tool", default=None, help="tool name (default: the setup's only tool)")
    p.add_argument("--freq", default=None, metavar="START,STOP,STEP", help="frequency grid in Hz")
    p.add_argument("--out", required=True, metavar="FILE",
                   help="output FRF file, written atomically; the suffix chooses the format (.csv, or .uff/.unv "
                        "for a universal file dataset 58)")
    add_force_argument(p)
    p.set_defaults(func=run, out_kind="file")


def run(args: argparse.Namespace) -> Summary:
    from ..io import load_setup
    from ..io.writers import frf_writer_for, write_frf
    from ..model import FRF, Configuration

    cl = parse_float(args.clamping_length, "--clamping-length", positive=True)
    kx = parse_float(args.kx, "--kx", positive=True)
    kt = parse_float(args.ktheta, "--ktheta", positive=True)
    cx = parse_float(args.cx, "--cx")
    ct = parse_float(args.ctheta, "--ctheta")
    if cx < 0 or ct < 0:
        raise SetupError("--cx/--ctheta: expected damping >= 0")
    frf_writer_for(args.out)  # refuse an unknown output type before computing anything
    if Path(args.out).exists() and not args.force:
        raise SetupError(f"--out {args.out}: exists; use --force to replace it")
    freq = parse_frequency_grid(args.freq) if args.freq is not None else None
    setup = load_setup(args.setup, load_data=False, load_spindle=True)
    tool = args.tool
    if tool is None:
        if len(setup.tools) != 1:
            raise SetupError(f"--tool: the setup defines several tools {sorted(setup.tools)}; name one")
        tool = next(iter(setup.tools))
    model = setup.model()
    if freq is None:
        freq = model.spindle_receptance(args.direction).frequency_hz
    config = Configuration(cl, args.direction, tool)
    h = model.frf(config, freq, kx, kt, cx, ct)
    comments = [
        f"bayes-rcsa simulate: {setup.name}",
        f"tool={tool} direction={args.direction} clamping_length={cl!r} m",
        f"k_xf={kx!r} N/m k_thetaM={kt!r} N*m/rad c_xf={cx!r} N*s/m c_thetaM={ct!r} N*m*s/rad",
    ]
    write_frf(args.out, FRF(freq, h, source=args.out), comments=comments)
    i_peak = int(abs(h).argmax())
    return Summary(
        f"wrote {args.out} ({freq.size} lines, {freq[0]:g}-{freq[-1]:g} Hz; largest |h| {abs(h[i_peak]):.3g} m/N "
        f"at {freq[i_peak]:g} Hz)",
        {"out": str(args.out), "n_lines": int(freq.size), "peak_hz": float(freq[i_peak]),
         "peak_abs_m_per_n": float(abs(h[i_peak]))},
    )
