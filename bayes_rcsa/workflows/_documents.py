"""Reading back the JSON document a result wrote (its ``load``)."""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import DataError

__all__ = ["read_document"]


def read_document(folder, name: str, command: str) -> dict:
    """The JSON file ``name`` in ``folder``; :class:`DataError` naming the folder and the command if absent or broken."""
    path = Path(folder) / name
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DataError(f"{folder}: not an output directory of 'bayes-rcsa {command}' ({exc})") from None
