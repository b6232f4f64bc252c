"""The numba compiler as navsim's kernels use it (:mod:`navsim.sensors.kernels`,
:mod:`navsim.navigation.kernels`): compiled code cached in navsim's cache folder
(``$NAVSIM_CACHE/numba``), or in ``NUMBA_CACHE_DIR`` where that is set, never in the installed
package.

Where that folder cannot be created or written (a read-only home, ``NAVSIM_CACHE`` through a
file), the kernels are compiled without a cache, with a warning: numba would otherwise fall back to
writing ``__pycache__`` beside navsim's sources, or fail at import. ``NAVSIM_CACHE`` set but
empty leaves the kernels uncached here; the commands that need the cache refuse it (exit 2).

numba keys a cached kernel on its own source file only: a kernel that calls one of another module,
or freezes another module's constants (``COL_*``, a field's index), would load stale from the cache
after that module changed, and compute with the old code. So the kernels are cached in a subfolder
named for a digest of the sources of every navsim module that compiles kernels and of the navsim
modules they import (:func:`kernel_digest`): any change there compiles them anew.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

import numba

from navsim.foundations.config import cache_dir, usable_folder
from navsim.foundations.errors import UsageError


def _cache_folder() -> Path | None:
    """Where the kernels are cached: ``NUMBA_CACHE_DIR`` where set, else ``$NAVSIM_CACHE/numba``;
    ``None`` (no caching) where that folder is unusable."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return usable_folder(Path(os.environ["NUMBA_CACHE_DIR"]), "cache of compiled kernels (NUMBA_CACHE_DIR)")
    try:
        return cache_dir("numba")
    except UsageError:           # NAVSIM_CACHE="": refused by the commands that use the cache
        return None


#: ``from navsim.x import a, b`` (a and b may be modules) and ``import navsim.x``
_IMPORT = re.compile(rb"^[ \t]*(?:from[ \t]+(navsim[\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)|import[ \t]+(navsim[\w.]*))",
                     re.M)


def _module_file(package: Path, name: str) -> Path | None:
    """The source file of the navsim module ``name`` (dotted), or None."""
    parts = name.split(".")[1:]
    for path in (package.joinpath(*parts).with_suffix(".py"), package.joinpath(*parts, "__init__.py")):
        if path.is_file():
            return path
    return None


def kernel_digest(package: Path | None = None) -> str:
    """A digest of the sources numba's cached kernels depend on: each module of the navsim
    ``package`` folder (this one by default) that compiles kernels (its text names ``njit``) and,
    transitively, the navsim modules it imports."""
    package = Path(__file__).resolve().parents[1] if package is None else Path(package)
    todo = [p for p in package.rglob("*.py") if b"njit" in p.read_bytes()]
    seen: set[Path] = set()
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for m in _IMPORT.finditer(path.read_bytes()):
            base = (m.group(1) or m.group(3)).decode()
            names = [n.split()[0] for n in (m.group(2) or b"").decode().strip("()").split(",") if n.strip()]
            for name in [base] + [f"{base}.{n}" for n in names]:
                found = _module_file(package, name)
                if found is not None:
                    todo.append(found)
    digest = hashlib.sha1()
    for path in sorted(seen):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


#: the folder numba caches the kernels in (a subfolder per :func:`kernel_digest`), or None:
#: compiled anew in each process
CACHE_FOLDER = _cache_folder()
if CACHE_FOLDER is not None:
    CACHE_FOLDER = CACHE_FOLDER / f"kernels-{kernel_digest()}"
    numba.config.CACHE_DIR = str(CACHE_FOLDER)


def njit(*args, **options):
    """``numba.njit``, with ``cache=True`` honoured only where :data:`CACHE_FOLDER` is usable."""
    if CACHE_FOLDER is None:
        options["cache"] = False
    return numba.njit(*args, **options)


__all__ = ["njit", "CACHE_FOLDER"]
