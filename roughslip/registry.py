"""Registries: the single source of the names of methods, laws and histories.

Each family (squeeze methods, pull methods, slip laws, coupled solvers, squeeze histories)
keeps one :class:`Registry`; an entry registers itself once, next to its code, with a
one-line summary. The configuration, the command line and the error messages read names and
summaries from the registry, live, so an entry cannot exist in one place and be missing in
another, and one registered later (a test-only method) is a valid choice at once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from roughslip.errors import InputError

T = TypeVar("T")


#: the choice that asks a family to choose by itself (by size, memory and capabilities)
AUTO = "auto"


class Registry(Generic[T]):
    """Named strategies of one family.

    Parameters
    ----------
    family : str
        What the entries are, for messages (e.g. ``"squeeze method"``).
    """

    def __init__(self, family: str) -> None:
        self.family = family
        self._items: dict[str, T] = {}
        self._summary: dict[str, str] = {}

    def register(self, name: str, summary: str) -> Callable[[T], T]:
        """Decorator registering a strategy under ``name``."""

        def deco(obj: T) -> T:
            if name in self._items:
                raise ValueError(f"{self.family} {name!r} is registered twice")
            self._items[name] = obj
            self._summary[name] = summary
            return obj

        return deco

    def remove(self, name: str) -> None:
        """Take ``name`` out of the registry (a strategy registered for a test)."""
        self._items.pop(name)
        self._summary.pop(name)

    def names(self) -> tuple[str, ...]:
        """Registered names, in registration order."""
        return tuple(self._items)

    def summary(self, name: str) -> str:
        """The one-line summary of a method."""
        return self._summary[name]

    def describe(self) -> str:
        """``"name: summary; ..."`` for help texts."""
        return "; ".join(f"{n}: {s}" for n, s in self._summary.items())

    def get(self, name: str, key: str = "method") -> T:
        """The strategy called ``name``; :class:`InputError` naming ``key`` otherwise."""
        try:
            return self._items[name]
        except (KeyError, TypeError):
            raise InputError(f"{key} = {name!r}: unknown {self.family}; choose one of "
                             f"{', '.join(self._items)}") from None

    def __repr__(self) -> str:
        return f"Registry({self.family!r}: {', '.join(self._items) or 'empty'})"

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)
