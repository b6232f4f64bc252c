"""Plug-ins: the objects installed packages add through an entry-point group (``navsim.estimators``,
``navsim.sensors``), loaded for the registries.

A plug-in that cannot be loaded (its module gone, as after removing the folder of an editable
install, or failing on import) must not take navsim with it: it is named in one
:class:`PluginWarning` (its package, its entry point, the error) and left out, and every other
name is looked up as without it. What a loaded object must be is the registry's to check.
"""

from __future__ import annotations

import warnings
from collections.abc import Container, Iterator
from importlib import metadata


class PluginWarning(UserWarning):
    """An installed plug-in that cannot be loaded (left out)."""


#: the entry points ``(group, name)`` that failed to load in this process: warned about once,
#: not tried again
_FAILED: set[tuple[str, str]] = set()


def describe(ep: metadata.EntryPoint, group: str) -> str:
    """``the entry point NAME = 'module:attr' of the group 'GROUP'``, as messages name it."""
    return f"the entry point {ep.name} = {ep.value!r} of the group '{group}'"


def package_of(ep: metadata.EntryPoint) -> str:
    """The name of the distribution that declares ``ep`` (its module's where it is not known)."""
    dist = getattr(ep, "dist", None)
    return dist.name if dist is not None and dist.name else ep.module


def load_entry_points(group: str, skip: Container[str] = ()) -> Iterator[tuple[metadata.EntryPoint, object]]:
    """Each entry point of ``group`` whose name is not in ``skip`` (read at each step: a
    registry filled while iterating), with the object it names. One that cannot be loaded is
    named in a :class:`PluginWarning` the first time and left out.

    Parameters
    ----------
    group : str
        The entry-point group (``navsim.estimators``).
    skip : container of str
        Names already registered (not loaded again).

    Yields
    ------
    (EntryPoint, object)
        The entry point and what loading it gave.
    """
    for ep in metadata.entry_points(group=group):
        if ep.name in skip or (group, ep.name) in _FAILED:
            continue
        try:
            obj = ep.load()
        except Exception as exc:           # a third party's import: anything may be raised
            _FAILED.add((group, ep.name))
            warnings.warn(f"the plug-in {package_of(ep)!r} cannot be loaded and is left out: "
                          f"{describe(ep, group)}: {type(exc).__name__}: {exc}; hint: reinstall it, or "
                          f"uninstall it (pip uninstall {package_of(ep)})", PluginWarning, stacklevel=2)
            continue
        yield ep, obj
