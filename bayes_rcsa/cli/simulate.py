"""``bayes-rcsa simulate``: predicted tool-point FRF for given contact parameters."""

from __future__ import annotations

import argparse
from ._common import Summary, add_force_argument, parse_float, parse_frequency_grid

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
    from ..workflows.simulation import SimulatedFRF, simulate

    numbers = dict(clamping_length=parse_float(args.clamping_length, "--clamping-length", positive=True),
                   kx=parse_float(args.kx, "--kx", positive=True), ktheta=parse_float(args.ktheta, "--ktheta", positive=True),
                   cx=parse_float(args.cx, "--cx"), ctheta=parse_float(args.ctheta, "--ctheta"))
    SimulatedFRF.check_output(args.out, args.force)  # an unknown output type or an existing file: before any work
    freq = parse_frequency_grid(args.freq) if args.freq is not None else None
    result = simulate(args.setup, direction=args.direction, tool=args.tool, frequency_hz=freq, **numbers)
    result.save(args.out, force=args.force)
    return Summary(result.summary_line(), {"out": str(args.out), **result.summary_data()}, warnings=result.warnings)
