"""One conversion of result records (numpy scalars and arrays, NaN) to strict JSON values."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

import numpy as np

from ..errors import SetupError

__all__ = ["to_jsonable", "dumps_strict"]


def to_jsonable(obj: Any, nonfinite: str = "null") -> Any:
    """Plain JSON values from numpy types, tuples, arrays and paths.

    Parameters
    ----------
    obj : any
        Nested mappings, sequences, numpy arrays and scalars.
    nonfinite : {"null", "error"}
        What NaN and infinities become: ``None`` (JSON ``null``: "no value",
        e.g. a quantile of an empty set) or a :class:`SetupError` (records
        that must not hold them, e.g. the truth of a synthetic campaign).

    Returns
    -------
    Plain dicts (string keys), lists, bools, ints, floats, strings and None.
    """
    if nonfinite not in ("null", "error"):
        raise ValueError(f"nonfinite = {nonfinite!r}: expected 'null' or 'error'")
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v, nonfinite) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, nonfinite) for v in obj]
    if isinstance(obj, np.ndarray):
        return [to_jsonable(v, nonfinite) for v in obj.tolist()]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        if math.isfinite(x):
            return x
        if nonfinite == "error":
            raise SetupError(f"non-finite number {x!r} in a record that must be finite")
        return None
    if isinstance(obj, PurePath):
        return obj.as_posix()
    return obj


def dumps_strict(obj: Any, nonfinite: str = "null", **kwargs) -> str:
    """``json.dumps(to_jsonable(obj), allow_nan=False, **kwargs)``: always valid JSON."""
    return json.dumps(to_jsonable(obj, nonfinite), allow_nan=False, **kwargs)
