"""The numba compiler as navsim's kernels use it (:mod:`navsim.sensors.kernels`,
:mod:`navsim.navigation.kernels`): compiled code cached in navsim's cache folder
(``$NAVSIM_CACHE/numba``) rather than in the installed package, unless ``NUMBA_CACHE_DIR`` says
otherwise."""

from __future__ import annotations

import os

import numba
from numba import njit

from navsim.foundations.config import cache_dir

if "NUMBA_CACHE_DIR" not in os.environ:
    numba.config.CACHE_DIR = str(cache_dir() / "numba")

__all__ = ["njit"]
