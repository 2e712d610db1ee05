"""Argument parsing helpers shared by the sub-commands."""

from __future__ import annotations

import math

from ..errors import SetupError

__all__ = ["parse_float", "parse_float_list", "parse_frequency_grid"]


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
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    return start + step * np.arange(n)


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    import argparse

    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive integer")
    return v


def sampler_int(table: dict, key: str, default, path):
    """A positive integer from the setup's ``[sampler]`` table, or ``default``."""
    if key not in table:
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise SetupError(f"{path}: [sampler] {key} = {v!r}: expected a positive integer")
    return v
