"""Foundations every other layer stands on: the WGS-84 Earth (:mod:`~navsim.foundations.earth`),
rotations (:mod:`~navsim.foundations.transform`), the ISA (:mod:`~navsim.foundations.atmosphere`),
YAML read safely with key paths (:mod:`~navsim.foundations.config`), the errors that reach the
user (:mod:`~navsim.foundations.errors`), output folders (:mod:`~navsim.foundations.outputs`),
provenance (:mod:`~navsim.foundations.provenance`), plug-ins' entry points
(:mod:`~navsim.foundations.plugins`) and numba's settings (:mod:`~navsim.foundations.compiled`).

The notation (frames, names, units) is fixed in :mod:`navsim`'s docstring.
"""
