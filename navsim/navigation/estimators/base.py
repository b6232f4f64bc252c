"""The estimator plug-in contract and the registry.

An estimator works on a batch of ``B`` Monte Carlo runs at once and is driven by the runner:

1. ``initialize(nav0, P0_sigma)``: the initial navigation state ``NavState`` (``B`` runs,
   already carrying the drawn initial errors) and its 1-sigma uncertainty per error-state
   block;
2. ``propagate(dtheta_b, dv_b, dt)``: the IMU increments (rad, m/s) of the ``K`` intervals of
   ``dt`` seconds since the last call, ``(B, K, 3)``. Open-loop Monte Carlo hands the whole
   block between two of the estimator's epochs (or less: a block never crosses an epoch of any
   estimator of the scenario), the closed loop one interval at a time; the result must not
   depend on how the intervals are cut into blocks;
3. ``epoch(t, sensors)`` at every filter epoch (``period_s``): predict the covariance and
   ``correct`` with each measurement model whose sensor has a sample at ``t``; returns the
   :class:`Innovation` of each correction (innovations and NIS, for consistency scoring);
4. ``solution()``: the current :class:`Solution` (navigation state, covariance of the
   position, velocity and attitude errors, bias estimates).

Estimators are registered by name with :func:`register`; third-party packages add theirs
through the ``navsim.estimators`` entry-point group (``name = "package.module:Class"``), loaded
by :func:`get`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import metadata

import numpy as np

from navsim.foundations.config import close_match
from navsim.navigation.strapdown import NavState

_REGISTRY: dict[str, type] = {}
ENTRY_POINT_GROUP = "navsim.estimators"


@dataclass
class Innovation:
    measurement: str           #: name of the measurement model
    sensor: str
    t_s: float
    y: np.ndarray              #: (B, m) innovation
    S: np.ndarray              #: (B, m, m) its covariance
    nis: np.ndarray            #: (B,) normalised innovation squared (NaN where no sample)


@dataclass
class Solution:
    nav: NavState
    P_nav: np.ndarray | None = None          #: (B, 9, 9): att (rad), vel (m/s), pos (rad, rad, m)
    gyro_bias: np.ndarray | None = None      #: (B, 3) estimated, rad/s
    accel_bias: np.ndarray | None = None     #: (B, 3) estimated, m/s^2
    extra: dict = field(default_factory=dict)


def register(name: str):
    """Class decorator: make an estimator available by ``name``."""
    def deco(cls):
        _REGISTRY[name] = cls
        cls.type_name = name
        return cls
    return deco


def available() -> list[str]:
    _load_entry_points()
    return sorted(_REGISTRY)


def get(name: str) -> type:
    """The estimator class registered as ``name`` (built-in or from an entry point)."""
    if name not in _REGISTRY:
        _load_entry_points()
    if name not in _REGISTRY:
        raise KeyError(f"no estimator '{name}' ({close_match(name, _REGISTRY) or 'none registered'})")
    return _REGISTRY[name]


def _load_entry_points() -> None:
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        if ep.name not in _REGISTRY:
            cls = ep.load()
            _REGISTRY[ep.name] = cls
