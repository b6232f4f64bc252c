"""The estimator contract (:class:`Estimator`) and the registry.

An estimator works on a batch of ``B`` Monte Carlo runs at once and is driven by
:class:`navsim.experiment.driver.Driver` (the same in Monte Carlo, in the closed loop and in log
replay):

1. ``initialize(nav0, sigma0)``: the initial navigation state :class:`NavState` (``B`` runs,
   already carrying the drawn initial errors) and its 1-sigma uncertainty per error-state
   block, ``(3,)`` arrays: ``sigma0["att"]`` rad about N, E, D, ``["vel"]`` m/s NED, ``["pos"]``
   latitude and longitude in rad and height in m; plus what the optional ``noise_sigma0()``
   returned;
2. ``propagate(dtheta_b, dv_b, dt)``: the IMU increments (rad, m/s) of the ``K`` intervals of
   ``dt`` seconds since the last call, ``(B, K, 3)``. Open-loop Monte Carlo hands the whole
   block between two of the estimator's epochs (or less: a block never crosses an epoch of any
   estimator of the scenario), the closed loop one interval at a time; the result must not
   depend on how the intervals are cut into blocks;
3. ``epoch(t, sensors)`` every ``period_s`` (rounded to a whole number of IMU intervals, at least
   one): ``sensors`` maps each sensor name to its :class:`~navsim.sensors.base.Measurements`
   (``t_s``, ``values``, ``valid``, ``meta``: the measurements only, never the true errors);
   returns the :class:`Innovation` of each correction (innovations and NIS, for the consistency
   scores);
4. ``solution()``: the current :class:`Solution` (navigation state, covariance of the attitude,
   velocity and position errors, bias estimates; ``extra["diverged"]`` ``(B,)`` bool flags runs
   the estimator knows to be lost, ``extra["resets"]`` lists per run its reset events
   ``(t_s, cause)``).

Optional hooks: ``noise_sigma0() -> dict``, initial 1-sigma of the estimator's own states (merged
into ``sigma0``); the classmethods ``parse(node, sensors) -> dict`` (its scenario entry checked,
plain values: :class:`~navsim.foundations.config.Node`, ``sensors`` the scenario's sensor name ->
kind) and ``from_params(params)`` (the object); without them the entry's keys are the
constructor's keyword arguments; ``navigation() -> NavState``, the current navigation state
alone (:func:`navigation`: what a closed loop reads at every step, where ``solution()`` would
build the whole :class:`Solution` a hundred times a second; it must be ``solution().nav``).

Estimators are registered by name with :func:`register`; third-party packages add theirs
through the ``navsim.estimators`` entry-point group (``name = "package.module:Class"``), loaded
by :func:`get`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from navsim.foundations.registry import Registry
from navsim.navigation.strapdown import NavState

ENTRY_POINT_GROUP = "navsim.estimators"


@dataclass
class Innovation:
    """One measurement's innovations at one epoch, over the runs: what ``epoch`` returns for each
    sensor sample it used (the driver records the NIS against its chi-square band)."""

    measurement: str           #: name of the measurement model
    sensor: str                #: name of the sensor in the scenario
    t_s: float                 #: the epoch, s
    y: np.ndarray              #: (B, m) innovation, in the measurement's units
    S: np.ndarray              #: (B, m, m) its covariance, in the measurement's units squared
    nis: np.ndarray            #: (B,) normalised innovation squared, dimensionless (NaN where no sample)


@dataclass
class Solution:
    """An estimator's answer at an epoch, over the runs: the navigation state, its covariance
    and the estimated sensor errors (None where the estimator has none); ``extra`` holds what
    only this estimator reports (``diverged`` (B,) bool, the full ``P``, resets, ...)."""

    nav: NavState                            #: the estimated navigation state, (B,) runs
    P_nav: np.ndarray | None = None          #: (B, 9, 9): att (rad), vel (m/s), pos (rad, rad, m)
    gyro_bias: np.ndarray | None = None      #: (B, 3) estimated, rad/s
    accel_bias: np.ndarray | None = None     #: (B, 3) estimated, m/s^2
    gyro_bias_sigma: np.ndarray | None = None    #: (B, 3) 1-sigma of ``gyro_bias``, rad/s (NaN: not a state)
    accel_bias_sigma: np.ndarray | None = None   #: (B, 3) 1-sigma of ``accel_bias``, m/s^2 (NaN: not a state)
    wind_n_mps: np.ndarray | None = None     #: (B, 3) estimated wind NED, m/s (NaN: an axis not estimated)
    wind_sigma_mps: np.ndarray | None = None     #: (B, 3) its 1-sigma, m/s
    extra: dict = field(default_factory=dict)    #: estimator-specific outputs, each (B, ...)


@runtime_checkable
class Estimator(Protocol):
    """What the driver calls (see the module's docstring for the contract and the hooks)."""

    period_s: float

    def initialize(self, nav0: NavState, sigma0: dict) -> None:
        """Start from ``nav0`` (the perturbed initial state, ``B`` runs) with the initial
        1-sigma ``sigma0``: ``att`` (rad), ``vel`` (m/s), ``pos`` (rad, rad, m), each ``(3,)``
        and the same for every run, plus the keys of the estimator's own ``noise_sigma0()``
        where it has one."""

    def propagate(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float) -> None:
        """Take ``K`` IMU intervals: the increments ``dtheta_b`` (rad) and ``dv_b`` (m/s), each
        (B, K, 3) in the body frame, ``dt`` (s) each."""

    def epoch(self, t: float, sensors: dict) -> list:
        """The filter epoch at ``t`` (s): predict, take the sensors' samples (``sensors``: name
        -> :class:`~navsim.sensors.base.Measurements`) and return their
        :class:`Innovation` objects."""

    def solution(self) -> Solution:
        """The current :class:`Solution` (the driver records it at every epoch)."""


#: the methods an :class:`Estimator` class must have
METHODS = ("initialize", "propagate", "epoch", "solution")


def navigation(estimator) -> "NavState":
    """``estimator``'s current navigation state: its optional ``navigation()`` hook, else its
    ``solution().nav``."""
    hook = getattr(estimator, "navigation", None)
    return hook() if hook is not None else estimator.solution().nav


def sample(sensors: dict, name: str | None, t: float, t_prev: float | None = None, tol: float = 1e-6):
    """``(data, j)``: sensor ``name``'s sample ``j`` at the epoch ``t`` (within ``tol``) or, with
    ``t_prev``, its latest sample in ``(t_prev, t]``; ``(None, None)`` without one (or without
    that sensor). The window lets a filter whose epochs do not fall on the sensor's sample times
    (a replayed log) still see every sensor period; the exact time is what the ES-KF family uses."""
    data = sensors.get(name) if name else None
    if data is None:
        return None, None
    j = int(data.t_s.searchsorted(t + tol, side="right")) - 1
    lo = t - tol if t_prev is None else t_prev + tol
    if j >= 0 and data.t_s[j] >= lo:
        return data, j
    return None, None


def _checked(name: str, cls: type) -> type:
    """``cls`` registered as ``name``: checked for the :class:`Estimator` methods, its
    ``type_name`` set."""
    missing = [m for m in METHODS if not callable(getattr(cls, m, None))]
    if missing:
        raise TypeError(f"estimator '{name}': {cls.__name__} has no {', '.join(m + '()' for m in missing)}")
    cls.type_name = name
    return cls


#: the estimator classes by name: the built-in ones and the ``navsim.estimators`` entry points'
ESTIMATORS: Registry[type] = Registry("estimator", ENTRY_POINT_GROUP, _checked)
#: what is registered now (a test's monkeypatch adds to it)
_REGISTRY = ESTIMATORS.built()


def register(name: str):
    """Class decorator: make an estimator available by ``name`` (its class checked for the
    :class:`Estimator` methods)."""
    return ESTIMATORS.decorator(name)


def parse_params(cls: type, node, sensors: dict) -> dict:
    """An estimator's parameters from its scenario entry (``node``, the ``label`` and ``type``
    read): its ``parse``, or the entry's other keys as keyword arguments."""
    if hasattr(cls, "parse"):
        return cls.parse(node, sensors)
    params = {k: v for k, v in node.data.items() if k not in ("label", "type")}
    node._seen.update(params)
    return params


def build(cls: type, params: dict):
    """An estimator object from what :func:`parse_params` returned."""
    return cls.from_params(params) if hasattr(cls, "from_params") else cls(**params)


def plugin_sources(types) -> list[dict]:
    """The ``--plugin`` files (``{"type", "file", "sha256"}``) the estimator types ``types``
    come from (none for a shipped or packaged type): what a run records and its identity
    hashes, so that ``--resume`` never mixes runs of an edited file."""
    out = []
    for name in dict.fromkeys(types):
        cls = ESTIMATORS.built().get(name)
        if getattr(cls, "source_sha256", None):
            out.append({"type": name, "file": cls.source_file, "sha256": cls.source_sha256})
    return out


def available() -> list[str]:
    """The registered estimators' names, sorted (the plug-ins' included)."""
    return ESTIMATORS.names()


#: whether ``name`` is registered (the entry points read only for a name not registered yet)
known = ESTIMATORS.known
#: the estimator class registered as ``name`` (built-in or from an entry point); a
#: :class:`KeyError` naming the closest one
get = ESTIMATORS.get
