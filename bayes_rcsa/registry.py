"""A tiny name -> object registry shared by the extension points.

Model terms (:mod:`bayes_rcsa.params.terms`), stability methods
(:mod:`bayes_rcsa.stability`) and output writers (:mod:`bayes_rcsa.io`) each
keep one :class:`Registry`; adding one of them is one file plus one
registration.
"""

from __future__ import annotations

from typing import Callable, Generic, Iterator, TypeVar

from .errors import SetupError

__all__ = ["Registry"]

T = TypeVar("T")


class Registry(Generic[T]):
    """Named entries of one kind.

    Parameters
    ----------
    kind : str
        What the entries are, for messages (e.g. ``"model term"``).
    """

    def __init__(self, kind: str):
        self.kind = kind
        self._entries: dict[str, T] = {}

    def register(self, name: str, entry: T, replace: bool = False) -> T:
        """Add ``entry`` under ``name``; refuses a second entry of the same name unless ``replace``."""
        if not isinstance(name, str) or not name:
            raise SetupError(f"{self.kind} name {name!r}: expected a non-empty string")
        if name in self._entries and not replace and self._entries[name] is not entry:
            raise SetupError(f"{self.kind} {name!r} is registered already")
        self._entries[name] = entry
        return entry

    def decorator(self, name_attr: str = "name") -> Callable[[T], T]:
        """Class decorator registering a class under its ``name_attr`` attribute."""

        def deco(cls: T) -> T:
            return self.register(getattr(cls, name_attr), cls)

        return deco

    def unregister(self, name: str) -> None:
        """Remove ``name`` (tests register temporary entries)."""
        self._entries.pop(name, None)

    def get(self, name: str, where: str = "") -> T:
        """The entry called ``name``; :class:`SetupError` listing the known names otherwise."""
        try:
            return self._entries[name]
        except (KeyError, TypeError):
            prefix = f"{where}: " if where else ""
            raise SetupError(f"{prefix}unknown {self.kind} {name!r}; known: {', '.join(self.names()) or 'none'}") from None

    def names(self) -> tuple[str, ...]:
        return tuple(sorted(self._entries))

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self._entries)
