"""Documented limits on sizes and counts, checked before anything is allocated (docs/cli-reference.md, "Limits").

A count far beyond any useful value (``--speeds 0:1:10**11``, ``--seed 2**70``)
used to reach numpy and end in a ``MemoryError`` or ``TypeError`` traceback.
Every limit here is refused with one line that names the limit and how to
go past it; the estimated memory of the big arrays is compared with the
memory available.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import DataError, SetupError

__all__ = [
    "MAX_SEED", "COUNT_LIMITS", "MAX_INPUT_BYTES", "INPUT_LIMIT_ENV", "MEMORY_FRACTION", "check_count",
    "check_input_size", "max_input_bytes", "format_count", "available_memory", "check_memory", "format_bytes",
]

#: Seeds are stored as signed 64-bit integers (HDF5 attributes, netCDF); every seed below gives its own stream.
MAX_SEED = 2**63 - 1

#: option dest -> (largest value, how to go past it).  Far above any useful value: they only stop typos and
#: absurd numbers before they become allocations.
COUNT_LIMITS: dict[str, tuple[int, str]] = {
    "walkers": (10_000, "a few times the number of parameters is enough"),
    "max_steps": (10_000_000, "a chain that has not converged by then will not; check the model and the priors"),
    "check_every": (10_000_000, "a check every few hundred steps is enough"),
    "draws": (100_000, "run the command several times with different --seed and pool the results"),
    "depth_points": (100_000, "zoom in with --max-depth instead"),
    "intervals": (10_000, "SDM converges with a few hundred intervals per tooth period"),
    "max_modes": (100, "a modal fit needs the few modes inside the band"),
    "samples": (100_000, "run the command several times with different --seed and pool the results"),
    "truths": (100_000, "run the command several times with different --seed"),
    "workers": (1024, "use a scheduler (batch --scheduler) to spread over more machines"),
    "refit": (100, "a handful of refits is enough"),
    "flutes": (100, "no milling tool has more"),
    "speed_points": (100_000, "split the speed range into several runs"),
}

#: Largest input file (CSV, UFF, TOML) read by default; raise it with the environment variable below.
MAX_INPUT_BYTES = 256 * 2**20
INPUT_LIMIT_ENV = "BAYES_RCSA_MAX_INPUT_MB"

#: Share of the available memory one command's largest arrays may take.
MEMORY_FRACTION = 0.5


def check_count(name: str, value: int, option: str | None = None) -> None:
    """Refuse ``value`` above ``COUNT_LIMITS[name]`` (one line naming the limit and the way past it)."""
    if name not in COUNT_LIMITS or isinstance(value, bool) or not isinstance(value, int):
        return
    limit, how = COUNT_LIMITS[name]
    if value > limit:
        option = option or "--" + name.replace("_", "-")
        raise SetupError(f"{option} {value}: at most {format_count(limit)} is allowed ({how})")


def format_count(n: int) -> str:
    """``10 000 000``: thousands separated by spaces (the SI way, unambiguous in every locale)."""
    return f"{n:,}".replace(",", " ")


def max_input_bytes() -> int:
    """:data:`MAX_INPUT_BYTES`, or the limit in MB set by the environment variable :data:`INPUT_LIMIT_ENV`."""
    text = os.environ.get(INPUT_LIMIT_ENV)
    if not text:
        return MAX_INPUT_BYTES
    try:
        mb = float(text)
    except ValueError:
        mb = -1.0
    if not mb > 0:
        raise SetupError(f"{INPUT_LIMIT_ENV}={text!r}: expected a size in MB > 0")
    return int(mb * 2**20)


def format_bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1024 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} TB"  # pragma: no cover


def check_input_size(path, what: str, error: type[Exception] = DataError) -> None:
    """Refuse an input file larger than :func:`max_input_bytes` before it is read into memory."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError:
        return  # the reader names a missing or unreadable file itself
    limit = max_input_bytes()
    if size > limit:
        raise error(f"{path}: {what} is {format_bytes(size)}, above the limit of {format_bytes(limit)} for an input "
                    f"file (decimate or split it, or raise the limit with {INPUT_LIMIT_ENV}=<MB>)")


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), or ``None`` if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(nbytes: float, what: str, how: str) -> None:
    """Refuse a job whose largest arrays (``nbytes``, estimated) exceed :data:`MEMORY_FRACTION` of the free memory.

    Parameters
    ----------
    nbytes : estimated bytes
    what : the sizes that make it, e.g. ``"--draws 500 x --speeds 400"``
    how : the way to make it smaller (a flag, or batching)
    """
    avail = available_memory()
    if avail is None or nbytes <= MEMORY_FRACTION * avail:
        return
    raise SetupError(f"{what} needs about {format_bytes(nbytes)} of memory, more than half of the "
                     f"{format_bytes(avail)} available; {how}")
