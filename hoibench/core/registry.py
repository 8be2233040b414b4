"""Named registries (tracks, evaluator backends, scorers) and ``"module:attr"`` references.

A :class:`Registry` maps names to entries, refuses a name registered twice and answers an
unknown name with the known ones; :func:`load_object` imports what a ``"module:attr"``
reference names, on use (heavy modules load only when an entry is used)."""
from __future__ import annotations

from importlib import import_module
from typing import Any, Generic, Iterator, TypeVar

T = TypeVar("T")


class Registry(Generic[T]):
    """Entries of one kind (``what`` names the kind in errors)."""

    def __init__(self, what: str):
        self.what = what
        self._entries: dict[str, T] = {}

    def add(self, name: str, entry: T) -> T:
        if name in self._entries:
            raise ValueError(f"{self.what} {name!r} is registered twice")
        self._entries[name] = entry
        return entry

    def get(self, name: str) -> T:
        if name not in self._entries:
            raise KeyError(f"unknown {self.what} {name!r}; known: {', '.join(sorted(self._entries))}")
        return self._entries[name]

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(self._entries))

    def in_order(self) -> list[str]:
        """The names, in registration order."""
        return list(self._entries)

    def values(self) -> list[T]:
        """The entries, sorted by name."""
        return [self._entries[k] for k in sorted(self._entries)]


def load_object(reference: str, package: str | None = None) -> Any:
    """The object a ``"module:attr"`` reference names (a relative module needs ``package``)."""
    module, _, attr = reference.partition(":")
    return getattr(import_module(module, package), attr)


__all__ = ["Registry", "load_object"]
