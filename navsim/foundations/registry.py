"""One registry, name -> object, for everything navsim looks up by name: estimators, sensor
kinds, measurement types, commands (the report's pages are an ordered list, not looked up by
name: :data:`navsim.report.pages.PAGE_SOURCES`).

A :class:`Registry` holds the built-in objects (registered when their module is imported) and,
where it has an entry-point group, those of installed plug-ins, read only when a name is not
registered yet (reading them takes about 9 ms) and loaded through
:func:`navsim.foundations.plugins.load_entry_points` (a plug-in that cannot be loaded is named
in one warning and left out). Each registry checks what is registered with its own ``check``; an
unknown name is a :class:`KeyError` naming the closest registered name; a test's toy object is
registered and then unregistered.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from navsim.foundations.config import close_match
from navsim.foundations.errors import UsageError
from navsim.foundations.plugins import describe, load_entry_points

T = TypeVar("T")


class Registry(Generic[T]):
    """Objects by name.

    Parameters
    ----------
    what : str
        What an object is, as messages name it (``estimator``, ``sensor kind``).
    group : str, optional
        The entry-point group of plug-ins (``navsim.estimators``); None: built-in objects only.
    check : callable, optional
        ``check(name, obj)``: raises :class:`TypeError` saying what is wrong with ``obj`` (its
        declaration), or returns the object to register (the object itself, or one it completed).
    """

    def __init__(self, what: str, group: str | None = None, check: Callable[[str, T], T] | None = None):
        self.what = what
        self.group = group
        self._check = check
        self._objects: dict[str, T] = {}

    def register(self, name: str, obj: T, replace: bool = True) -> T:
        """Make ``obj`` known as ``name`` (checked first); returns what was registered.
        ``replace=False``: another object of that name already registered is a
        :class:`TypeError`."""
        if not replace and name in self._objects and self._objects[name] is not obj:
            raise TypeError(f"{self.what} '{name}' is registered already")
        if self._check is not None:
            obj = self._check(name, obj)
        self._objects[name] = obj
        return obj

    def decorator(self, name: str) -> Callable[[T], T]:
        """``@registry.decorator(name)``: register the decorated class as ``name``."""
        def deco(obj: T) -> T:
            return self.register(name, obj)
        return deco

    def unregister(self, name: str) -> None:
        """Forget ``name`` (a test's toy object); nothing happens for an unknown name."""
        self._objects.pop(name, None)

    def known(self, name: str) -> bool:
        """Whether ``name`` is registered; the entry points are read only for a name not
        registered yet."""
        if name not in self._objects:
            self._read_entry_points()
        return name in self._objects

    def get(self, name: str) -> T:
        """The object registered as ``name``; :class:`KeyError` naming the closest one."""
        if not self.known(name):
            raise KeyError(f"no {self.what} '{name}' ({close_match(name, self._objects) or 'none registered'})")
        return self._objects[name]

    def names(self) -> list[str]:
        """The registered names, sorted (the plug-ins' included)."""
        self._read_entry_points()
        return sorted(self._objects)

    def values(self) -> list[T]:
        """The registered objects, in the order of :meth:`names`."""
        return [self._objects[n] for n in self.names()]

    def built(self) -> dict[str, T]:
        """What is registered now, without reading the entry points (a live view's source)."""
        return self._objects

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self.known(name)

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())

    def _read_entry_points(self) -> None:
        """Register each entry point of the group not registered yet (a wrong object is a
        :class:`UsageError` naming the entry point)."""
        if self.group is None:
            return
        for ep, obj in load_entry_points(self.group, skip=self._objects):
            try:
                self.register(ep.name, obj)
            except TypeError as exc:
                raise UsageError(f"{describe(ep, self.group)}: {exc}") from exc
