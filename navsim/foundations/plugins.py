"""Plug-ins: the objects installed packages add through an entry-point group (``navsim.estimators``,
``navsim.sensors``), loaded for the registries; and a plug-in in one file the user names on the
command line (``--plugin my_filter.py``, :func:`load_file`), never a scenario.

A plug-in that cannot be loaded (its module gone, as after removing the folder of an editable
install, or failing on import) must not take navsim with it: it is named in one
:class:`PluginWarning` (its package, its entry point, the error) and left out, and every other
name is looked up as without it. What a loaded object must be is the registry's to check.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import traceback
import warnings
from collections.abc import Container, Iterator
from importlib import metadata
from pathlib import Path

from navsim.foundations.errors import UsageError


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


def load_file(path, registries: dict) -> list[str]:
    """Import the Python file ``path`` (named by the user on the command line), whose classes
    register themselves in ``registries`` (what -> :class:`~navsim.foundations.registry.Registry`);
    returns what it registered (``"estimator 'my_ekf'"``).

    A :class:`UsageError` (exit 2) names the file and the line for a file that cannot be read or
    raises on import, one that registers nothing, and one that registers a name already taken
    (a shipped type, or another file's): that registration is undone, so nothing shipped is
    shadowed.
    """
    path = Path(path)
    if path.suffix != ".py" or not path.is_file():
        raise UsageError(f"--plugin {path}: not a Python file (expected the path of a .py file that registers "
                         "a filter with navsim.plugin.register)")
    name = name_of(path)
    if name in _FILES:                        # imported once per process, as a package is
        return _FILES[name]
    for reg in registries.values():          # the installed plug-ins' names taken too
        reg.names()
    before = {what: dict(reg.built()) for what, reg in registries.items()}
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module                # its classes pickle by reference, as a package's
    try:
        spec.loader.exec_module(module)
    except BaseException as exc:               # the user's code: anything may be raised
        _restore(registries, before)
        sys.modules.pop(name, None)
        if isinstance(exc, KeyboardInterrupt):
            raise
        raise UsageError(f"--plugin {path}{_line(exc, path)}: raised {type(exc).__name__} on import: {exc}") from None
    _FILES[name] = _registered(path, registries, before)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    for what, reg in registries.items():      # where each registered class came from
        for key, obj in reg.built().items():
            if key not in before[what] and isinstance(obj, type):
                obj.source_file, obj.source_sha256 = str(path.resolve()), digest
    return _FILES[name]


def name_of(path: Path) -> str:
    """The module name a plug-in file is imported under (one per resolved path)."""
    return "navsim_plugin_" + hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]


#: the files :func:`load_file` imported in this process (module name -> what they registered)
_FILES: dict[str, list[str]] = {}


def _registered(path: Path, registries: dict, before: dict) -> list[str]:
    added, taken = [], []
    for what, reg in registries.items():
        for key, obj in reg.built().items():
            if key not in before[what]:
                added.append(f"{what} '{key}'")
            elif before[what][key] is not obj:
                taken.append(f"{what} '{key}'")
    if taken:
        _restore(registries, before)
        sys.modules.pop(name_of(path), None)
        raise UsageError(f"--plugin {path}: registers {', '.join(taken)}, a name navsim or another plug-in has "
                         "already (nothing of the file is registered; hint: give it a name of its own)")
    if not added:
        sys.modules.pop(name_of(path), None)
        raise UsageError(f"--plugin {path}: registers nothing (expected a class decorated with "
                         "@navsim.plugin.register('my_filter'))")
    return added


def _restore(registries: dict, before: dict) -> None:
    for what, reg in registries.items():
        objects = reg.built()
        objects.clear()
        objects.update(before[what])


def _line(exc: BaseException, path: Path) -> str:
    """``:LINE``, the last line of ``path`` in ``exc``'s traceback (or its syntax error's)."""
    if isinstance(exc, SyntaxError) and exc.lineno:
        return f":{exc.lineno}"
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename).resolve() == path.resolve()]
    return f":{frames[-1].lineno}" if frames else ""
