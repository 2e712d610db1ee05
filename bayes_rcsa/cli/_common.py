"""Argument parsing helpers shared by the sub-commands.

Every numeric option is parsed by a helper here (or, for argparse types,
checked centrally by :func:`check_arguments`, which :func:`bayes_rcsa.cli.main.main`
runs before any command), so that NaN, infinities, negative seeds and
output paths that cannot be written are refused the same way everywhere:
one line naming the option, exit status 2, before anything is created.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

from ..errors import SetupError
from ..messages import current_warnings, merge_warnings
from ..workflows.result import check_output_directory

__all__ = [
    "parse_float", "parse_float_list", "parse_frequency_grid", "positive_int", "nonnegative_int", "finite_float",
    "sampler_int", "check_output_path", "check_arguments", "MAX_FREQUENCY_LINES", "Summary", "add_force_argument",
    "check_output_directory", "command_warnings", "merge_warnings",
]

def command_warnings() -> list[str]:
    """The warnings issued so far by the running command (data plausibility, numerics), one line each."""
    return current_warnings()


@dataclasses.dataclass(frozen=True)
class Summary:
    """What a command reports when it has finished (printed by :func:`bayes_rcsa.cli.main.main`).

    Attributes
    ----------
    human : str
        One line for a person, printed on stderr as ``bayes-rcsa CMD: <human>``.
    data : dict
        JSON-serialisable facts (output paths, status, headline numbers), printed
        on stdout as ONE JSON object when ``--json`` is given, and only then.
        ``main`` adds ``"command"``.
    warnings : tuple of str
        Printed before ``human`` as ``bayes-rcsa CMD: warning: ...`` lines
        (e.g. a posterior that did not converge) and added to ``data`` as
        ``"warnings"``.
    status : int
        Exit status (0 = success).
    """

    human: str
    data: dict
    warnings: tuple[str, ...] = ()
    status: int = 0


def add_force_argument(parser, resumable: bool = False) -> None:
    """``--force``: the one way every command is allowed to write into a non-empty output directory."""
    parser.add_argument("--force", action="store_true",
                        help="write into an existing non-empty output directory, replacing the files of an earlier "
                             "run (default: refuse" + (", unless --resume" if resumable else "") + ")")


#: Upper bound on the lines of a --freq grid: 1e6 complex lines are already 16 MB per FRF.
MAX_FREQUENCY_LINES = 1_000_000


def parse_float(text: str, option: str, positive: bool = False) -> float:
    """Parse a finite float given on the command line for ``option``."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise SetupError(f"{option} {text!r}: expected a number") from None
    if not math.isfinite(value) or (positive and value <= 0):
        raise SetupError(f"{option} {text!r}: expected a finite number{' > 0' if positive else ''}")
    return value


def parse_float_list(text: str, option: str, positive: bool = False) -> list[float]:
    """Parse ``'0.025,0.040'`` into floats."""
    parts = [p for p in text.split(",") if p.strip()]
    if not parts:
        raise SetupError(f"{option} {text!r}: expected a comma-separated list of numbers")
    return [parse_float(p.strip(), option, positive) for p in parts]


def parse_frequency_grid(text: str, option: str = "--freq"):
    """Parse ``START,STOP,STEP`` (Hz) into an increasing grid including STOP when it falls on the grid."""
    import numpy as np

    values = parse_float_list(text, option, positive=True)
    if len(values) != 3:
        raise SetupError(f"{option} {text!r}: expected START,STOP,STEP in Hz")
    start, stop, step = values
    if stop <= start:
        raise SetupError(f"{option} {text!r}: expected STOP > START")
    n_float = (stop - start) / step + 1e-9
    if n_float + 1 > MAX_FREQUENCY_LINES:
        raise SetupError(f"{option} {text!r}: {n_float + 1:.3g} frequency lines; at most {MAX_FREQUENCY_LINES} "
                         "are allowed (choose a larger STEP)")
    n = int(math.floor(n_float)) + 1
    return start + step * np.arange(n)


def _int_at_least(text: str, minimum: int, expected: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = None
    if v is None or v < minimum:
        raise argparse.ArgumentTypeError(f"{text!r}: expected {expected}")
    return v


def nonnegative_int(text: str) -> int:
    """argparse type: an integer >= 0 (seeds, counts where 0 means "all")."""
    return _int_at_least(text, 0, "an integer >= 0")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    return _int_at_least(text, 1, "a positive integer")


def finite_float(text: str) -> float:
    """argparse type: a finite float (NaN and infinities refused)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number")
    return v


def sampler_int(table: dict, key: str, default, path):
    """A positive integer from the setup's ``[sampler]`` table, or ``default``
    (:func:`bayes_rcsa.workflows.identification.sampler_setting`)."""
    from ..workflows.identification import sampler_setting

    return sampler_setting(table, key, default, path)


def check_output_path(path, option: str = "--out", kind: str = "dir") -> Path:
    """Refuse an output path that cannot be written, before anything is created.

    Parameters
    ----------
    path : path-like
    option : str
        Option named in the message.
    kind : {"dir", "file"}
        An output directory must not be an existing file; an output file
        must not be an existing directory.  For both, no existing parent
        may be a file.

    Returns
    -------
    Path
    """
    path = Path(path)
    if kind == "dir" and path.exists() and not path.is_dir():
        raise SetupError(f"{option} {path}: exists and is not a directory")
    if kind == "file" and path.is_dir():
        raise SetupError(f"{option} {path}: is a directory; expected an output file name")
    for parent in path.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise SetupError(f"{option} {path}: {parent} is a file, not a directory")
            break
    from ..io.atomic import check_writable

    check_writable(path, option)  # a read-only or forbidden folder is refused before any work
    return path


def check_arguments(args: argparse.Namespace) -> None:
    """Checks every command shares, run before the command itself.

    - every float option is finite (argparse's ``type=float`` accepts
      ``nan`` and ``inf``);
    - ``--seed`` is >= 0 (:func:`numpy.random.default_rng` refuses negative seeds) and below 2**63;
    - counts (``--walkers``, ``--draws``, ...) are within :data:`bayes_rcsa.io.limits.COUNT_LIMITS`;
    - ``--out`` can be written: a directory, or a file for commands that set
      ``out_kind="file"`` in their defaults.
    """
    for name, value in vars(args).items():
        if isinstance(value, float) and not math.isfinite(value):
            raise SetupError(f"--{name.replace('_', '-')} {value!r}: expected a finite number")
    from ..io.limits import MAX_SEED, check_count

    seed = getattr(args, "seed", None)
    if isinstance(seed, int) and not isinstance(seed, bool) and seed < 0:
        raise SetupError(f"--seed {seed}: expected an integer >= 0")
    if isinstance(seed, int) and not isinstance(seed, bool) and seed > MAX_SEED:
        raise SetupError(f"--seed {seed}: at most 2**63 - 1 = {MAX_SEED} is allowed (seeds are stored as 64-bit "
                         "integers; every smaller seed gives its own random stream)")
    for name, value in vars(args).items():
        check_count(name, value)  # documented limits on counts (docs/cli-reference.md, "Limits")
    out = getattr(args, "out", None)
    if out is not None:
        check_output_path(out, "--out", getattr(args, "out_kind", "dir"))
