"""A bounded first-in-first-out cache of results that depend only on their exact inputs.

Several computations are asked again with the same inputs inside one run (a spindle file's modal fit at every
model evaluation, a cut's interval matrices at every step of a depth search, the unchanged segments of a tool at
every parameter set).  Each keeps its results here, keyed by what the result depends on (the callers build the
key from the exact bytes of their arrays), and hands out read-only arrays so that no caller can change what
the next one receives.  The size bound keeps a long session's memory flat; a lock keeps the table consistent
when worker threads share it.
"""

from __future__ import annotations

import threading
from typing import Any, Hashable

__all__ = ["BoundedCache"]


class BoundedCache:
    """At most ``maxsize`` entries; the oldest is dropped first.

    Parameters
    ----------
    maxsize : int
        Largest number of entries kept.
    """

    def __init__(self, maxsize: int):
        if maxsize < 1:
            raise ValueError(f"maxsize = {maxsize}: expected a positive number of entries")
        self.maxsize = int(maxsize)
        self._entries: dict = {}
        self._lock = threading.Lock()

    def get(self, key: Hashable, default: Any = None) -> Any:
        """The value stored under ``key``, else ``default``."""
        with self._lock:
            return self._entries.get(key, default)

    def put(self, key: Hashable, value: Any) -> Any:
        """Store ``value`` under ``key`` (dropping the oldest entries beyond ``maxsize``); returns ``value``."""
        with self._lock:
            self._entries.pop(key, None)
            while len(self._entries) >= self.maxsize:
                self._entries.pop(next(iter(self._entries)))
            self._entries[key] = value
        return value

    def values(self) -> list:
        """The stored values, oldest first (a copy)."""
        with self._lock:
            return list(self._entries.values())

    def clear(self) -> None:
        """Drop every entry."""
        with self._lock:
            self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key: Hashable) -> bool:
        with self._lock:
            return key in self._entries
