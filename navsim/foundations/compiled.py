"""The numba compiler as navsim's kernels use it (:mod:`navsim.sensors.kernels`,
:mod:`navsim.navigation.kernels`): compiled code cached in navsim's cache folder
(``$NAVSIM_CACHE/numba``), or in ``NUMBA_CACHE_DIR`` where that is set, never in the installed
package.

Where that folder cannot be created or written (a read-only home, ``NAVSIM_CACHE`` through a
file), the kernels are compiled without a cache, with a warning: numba would otherwise fall back to
writing ``__pycache__`` beside navsim's sources, or fail at import. ``NAVSIM_CACHE`` set but
empty leaves the kernels uncached here; the commands that need the cache refuse it (exit 2).
"""

from __future__ import annotations

import os
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


#: the folder numba caches the kernels in, or None: compiled anew in each process
CACHE_FOLDER = _cache_folder()
if CACHE_FOLDER is not None:
    numba.config.CACHE_DIR = str(CACHE_FOLDER)


def njit(*args, **options):
    """``numba.njit``, with ``cache=True`` honoured only where :data:`CACHE_FOLDER` is usable."""
    if CACHE_FOLDER is None:
        options["cache"] = False
    return numba.njit(*args, **options)


__all__ = ["njit", "CACHE_FOLDER"]
