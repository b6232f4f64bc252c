"""The single-vehicle contract: a filter written for one vehicle, filterpy-style, run by navsim
for every Monte Carlo run and scored like any estimator.

A class with these members (subclassing :class:`VehicleFilter` is not needed; it documents
them)::

    period_s = 1.0                                  # its epochs, s (a whole number of IMU steps)
    def initialize(self, nav0, P0): ...             # NavState of one run (B = 1), P0 (9, 9)
    def predict(self, imu): ...                     # ImuBlock: dtheta_b, dv_b (K, 3), dt
    def update(self, t_s, samples): ...             # sensor name -> Sample at t_s; returns
                                                    #   a list of VehicleInnovation, or None
    def solution(self): ...                         # VehicleSolution: nav, P (9, 9), biases

``P0`` and ``VehicleSolution.P`` are over the attitude error (rad, N E D), the velocity error
(m/s) and the position error (latitude, longitude in rad, height in m), the batch contract's
``P_nav``. :class:`VehicleBatch` runs one object of the class per run, in a Python loop: a
prototype's speed (its cost per run is in ``docs/plugins.md``); the batch contract
(:mod:`.base`) is the one for speed. A run whose filter raises is flagged diverged with the
exception as its cause; the other runs go on.
"""

from __future__ import annotations

import inspect
import logging
from dataclasses import dataclass, field

import numpy as np

from navsim.foundations.transform import rotation
from navsim.navigation.estimators.base import Innovation, Solution, parse_params, sample
from navsim.navigation.strapdown import BlockStrapdown, NavState

log = logging.getLogger(__name__)
#: the members a single-vehicle filter class has (:func:`is_vehicle_filter`)
VEHICLE_METHODS = ("initialize", "predict", "update", "solution")
NAV_BLOCKS = ("att", "vel", "pos")


@dataclass
class ImuBlock:
    """The IMU intervals since the last call, for one vehicle."""

    dtheta_b: np.ndarray      #: (K, 3) angle increments, body frame, rad
    dv_b: np.ndarray          #: (K, 3) velocity increments, body frame, m/s
    dt: float                 #: each interval, s


@dataclass
class Sample:
    """One sensor's sample at the epoch, for one vehicle: ``values[key]`` in SI (a float or an
    array: the keys of :data:`navsim.sensors.OUTPUTS` for its kind)."""

    sensor: str
    kind: str
    t_s: float
    values: dict
    meta: dict = field(default_factory=dict)


@dataclass
class VehicleInnovation:
    """One correction: the innovation ``y`` ``(m,)`` and its covariance ``S`` ``(m, m)``."""

    measurement: str
    sensor: str
    y: np.ndarray
    S: np.ndarray


@dataclass
class VehicleSolution:
    """A single-vehicle filter's answer: the navigation state (one run), the covariance of its
    errors ``(9, 9)`` (None: no NEES) and the estimated biases ``(3,)`` (rad/s, m/s²; None:
    not estimated)."""

    nav: NavState
    P: np.ndarray | None = None
    gyro_bias: np.ndarray | None = None
    accel_bias: np.ndarray | None = None


class VehicleFilter:
    """The single-vehicle contract (see the module docstring); a base class to subclass or not."""

    period_s: float = 1.0

    def initialize(self, nav0: NavState, P0: np.ndarray) -> None:
        raise NotImplementedError

    def predict(self, imu: ImuBlock) -> None:
        raise NotImplementedError

    def update(self, t_s: float, samples: dict) -> list | None:
        raise NotImplementedError

    def solution(self) -> VehicleSolution:
        raise NotImplementedError


class VehicleStrapdown:
    """One vehicle's strapdown: navsim's compiled mechanization
    (:class:`~navsim.navigation.strapdown.BlockStrapdown`) on a state of one run, with the
    means a filter's time update needs over the intervals since its last epoch."""

    def __init__(self, nav0: NavState):
        self._sd = BlockStrapdown(nav0.copy())

    @property
    def nav(self) -> NavState:
        """The current state (one run); change it in place to feed back a correction
        (:func:`remove_errors`)."""
        return self._sd.state

    def step(self, imu: ImuBlock, gyro_bias=None, accel_bias=None) -> NavState:
        """Mechanize ``imu``'s intervals less the bias estimates (rad/s, m/s², ``(3,)``)."""
        one = lambda b: None if b is None else np.asarray(b, float).reshape(1, 3)
        return self._sd.block(imu.dtheta_b[None], imu.dv_b[None], imu.dt, one(gyro_bias), one(accel_bias))

    def since_epoch(self, dt: float) -> tuple[np.ndarray, np.ndarray, float]:
        """``(C_nb, f_n, elapsed_s)`` over the intervals since the last call (each ``dt`` s):
        the mean attitude, the mean specific force in NED (m/s²) and their time; then starts
        anew."""
        sd, steps = self._sd, max(self._sd.steps, 1)
        out = sd.sum_C_nb[0] / steps, sd.sum_dv_n_mps[0] / (steps * dt), sd.steps * dt
        sd.reset_sums()
        return out


def remove_errors(nav: NavState, att_rad, vel_mps, pos) -> None:
    """Feed an estimated error back into ``nav`` (one run), in place: the errors as navsim's
    error states define them (estimate minus truth; the attitude error ``phi`` with
    ``C_nb_est = (I - [phi x]) C_nb``; the position error latitude, longitude in rad and height
    in m)."""
    nav.C_nb[0] = rotation(np.asarray(att_rad, float)) @ nav.C_nb[0]
    nav.vel_n_mps[0] -= np.asarray(vel_mps, float)
    nav.lat_rad[0] -= pos[0]
    nav.lon_rad[0] -= pos[1]
    nav.h_m[0] -= pos[2]


def is_vehicle_filter(cls: type) -> bool:
    """Whether ``cls`` follows the single-vehicle contract (and not the batch one)."""
    return all(callable(getattr(cls, m, None)) for m in VEHICLE_METHODS) and not callable(
        getattr(cls, "propagate", None))


def one_run(nav: NavState, b: int) -> NavState:
    """Run ``b`` of ``nav`` as a navigation state of one run (copies)."""
    return NavState(nav.lat_rad[b:b + 1].copy(), nav.lon_rad[b:b + 1].copy(), nav.h_m[b:b + 1].copy(),
                    nav.vel_n_mps[b:b + 1].copy(), nav.C_nb[b:b + 1].copy())


class VehicleBatch:
    """The batch contract over one single-vehicle filter per run (:func:`batch_class` makes the
    registered class of a single-vehicle one)."""

    vehicle_class: type = VehicleFilter

    def __init__(self, params: dict):
        self.params = params
        v = self.vehicle_class
        given = inspect.signature(v).parameters.get("period_s") if not hasattr(v, "from_params") else None
        default = given.default if given is not None and given.default is not given.empty else None
        self.period_s = float(params.get("period_s", default if default is not None else getattr(v, "period_s", 1.0)))
        self._t_prev = None

    @classmethod
    def parse(cls, node, sensors: dict) -> dict:
        """The single-vehicle class's ``parse``, or its entry's keys as keyword arguments, checked
        against its constructor's (an unknown or missing key is an error naming the entry)."""
        params = parse_params(cls.vehicle_class, node, sensors)
        if not hasattr(cls.vehicle_class, "parse") and not hasattr(cls.vehicle_class, "from_params"):
            try:
                inspect.signature(cls.vehicle_class).bind(**params)
            except TypeError as exc:
                raise node.error(f"does not fit {cls.vehicle_class.__name__}: {exc}",
                                 expected="the keyword arguments of its constructor: "
                                 + ", ".join(inspect.signature(cls.vehicle_class).parameters)) from None
        return params

    @classmethod
    def from_params(cls, params: dict) -> "VehicleBatch":
        return cls(params)

    def _build(self):
        v = self.vehicle_class
        return v.from_params(self.params) if hasattr(v, "from_params") else v(**self.params)

    def initialize(self, nav0: NavState, sigma0: dict) -> None:
        B = nav0.lat_rad.shape[0]
        P0 = np.diag(np.concatenate([np.asarray(sigma0[k], float) for k in NAV_BLOCKS]) ** 2)
        self.filters, self.causes = [self._build() for _ in range(B)], [None] * B
        self._solution = None
        self._each(lambda b, f: f.initialize(one_run(nav0, b), P0.copy()))

    def _each(self, call) -> list:
        """``call(b, filter)`` for each run not failed; a run whose filter raises is flagged
        with its exception (its solution NaN from then on). When every run has failed, the last
        exception is raised: the driver then flags them all with it (and a replay, a closed
        loop of one run, stop on it)."""
        out, last = [], None
        for b, f in enumerate(self.filters):
            if self.causes[b] is None:
                try:
                    out.append((b, call(b, f)))
                except Exception as exc:         # the user's code: anything may be raised
                    self.causes[b], last = f"{type(exc).__name__}: {exc}", exc
                    log.warning("%s raised in run %d of its batch, flagged diverged (the other runs go on)",
                                self.vehicle_class.__name__, b, exc_info=exc)
        if last is not None and all(c is not None for c in self.causes):
            raise last
        return out

    def propagate(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float) -> None:
        self._solution = None
        self._each(lambda b, f: f.predict(ImuBlock(dtheta_b[b].copy(), dv_b[b].copy(), dt)))

    def epoch(self, t: float, sensors: dict) -> list[Innovation]:
        """Each run's ``update`` with the sensors' latest samples since the last epoch (at ``t``
        exactly at the first)."""
        at = {name: sample(sensors, name, t, self._t_prev) for name in sensors}
        at = {name: (data, j) for name, (data, j) in at.items() if data is not None}
        self._t_prev, self._solution = t, None
        B, out = len(self.filters), {}
        self._each(lambda b, f: _innovations(out, b, B, t, f.update(t, _samples(at, b))))
        return list(out.values())

    def solution(self) -> Solution:
        """The runs' solutions stacked (asked again before the next ``propagate`` or ``epoch``,
        as the closed loop does every IMU step: the same object)."""
        if self._solution is None:
            self._solution = self._stacked_solution()
        return self._solution

    def _stacked_solution(self) -> Solution:
        B = len(self.filters)
        sols = [None] * B
        for b, s in self._each(lambda b, f: _checked_solution(f.solution())):
            sols[b] = s
        nav = _stacked([s.nav if s is not None else None for s in sols])
        pick = lambda name, shape: (None if all(s is None or getattr(s, name) is None for s in sols) else np.stack(
            [np.full(shape, np.nan) if s is None or getattr(s, name) is None else np.asarray(getattr(s, name), float)
             for s in sols]))
        biases = {name: pick(name, (3,)) for name in ("gyro_bias", "accel_bias")}
        if any(v is not None for v in biases.values()):      # the driver reads both or none
            biases = {k: np.full((B, 3), np.nan) if v is None else v for k, v in biases.items()}
        diverged = np.array([c is not None for c in self.causes])
        return Solution(nav=nav, P_nav=pick("P", (9, 9)), **biases,
                        extra={"diverged": diverged, "causes": list(self.causes)})


def _samples(at: dict, b: int) -> dict:
    """Sensor name -> :class:`Sample` of run ``b`` (only the sensors with a valid sample; the
    values copied, so that no filter changes what the others read)."""
    return {name: Sample(name, data.kind, float(data.t_s[j]),
                         {k: np.array(v[b, j]) if np.ndim(v[b, j]) else float(v[b, j]) for k, v in data.values.items()},
                         data.meta)
            for name, (data, j) in at.items() if data.valid[b, j]}


def _innovations(out: dict, b: int, B: int, t: float, items) -> None:
    """Run ``b``'s :class:`VehicleInnovation` list into ``out``, one :class:`Innovation` per
    measurement and sensor (NaN for the runs without it); a malformed one raises (the run is
    flagged, not the batch)."""
    for v in items or []:
        y, S = np.atleast_1d(np.asarray(v.y, float)), np.atleast_2d(np.asarray(v.S, float))
        if y.ndim != 1 or S.shape != (y.shape[0], y.shape[0]):
            raise ValueError(f"innovation {v.measurement}:{v.sensor}: y {y.shape} and S {S.shape} (expected (m,) "
                             "and (m, m))")
        key = (v.measurement, v.sensor)
        if key not in out:
            out[key] = Innovation(v.measurement, v.sensor, t, np.full((B, y.shape[0]), np.nan),
                                  np.full((B, y.shape[0], y.shape[0]), np.nan), np.full(B, np.nan))
        inn = out[key]
        if inn.y.shape[1] != y.shape[0]:
            raise ValueError(f"innovation {v.measurement}:{v.sensor}: {y.shape[0]} values, "
                             f"{inn.y.shape[1]} in another run")
        inn.y[b], inn.S[b] = y, S
        inn.nis[b] = float(y @ np.linalg.solve(S, y))


def _checked_solution(s) -> VehicleSolution:
    """``s`` if it is a :class:`VehicleSolution` of the contract's shapes; raises otherwise."""
    if not isinstance(s, VehicleSolution):
        raise TypeError(f"solution() returned {type(s).__name__}, not a VehicleSolution")
    for name, shape in (("P", (9, 9)), ("gyro_bias", (3,)), ("accel_bias", (3,))):
        value = getattr(s, name)
        if value is not None and np.shape(value) != shape:
            raise ValueError(f"solution().{name} has shape {np.shape(value)}, expected {shape}")
    return s


def _stacked(navs: list) -> NavState:
    """One :class:`NavState` of the runs' states (NaN for a run without one)."""
    nan = NavState(np.full(1, np.nan), np.full(1, np.nan), np.full(1, np.nan), np.full((1, 3), np.nan),
                   np.full((1, 3, 3), np.nan))
    navs = [n if n is not None else nan for n in navs]
    return NavState(*(np.concatenate([np.asarray(getattr(n, f), float).reshape((1,) + np.shape(getattr(nan, f))[1:])
                                      for n in navs]) for f in ("lat_rad", "lon_rad", "h_m", "vel_n_mps", "C_nb")))


def batch_class(cls: type) -> type:
    """The batch-contract class that runs the single-vehicle class ``cls`` for every run (what
    is registered under its name); its ``SCHEMA`` is ``cls``'s."""
    return type(f"{cls.__name__}Batch", (VehicleBatch,), {
        "vehicle_class": cls, "SCHEMA": getattr(cls, "SCHEMA", {}), "__doc__": cls.__doc__,
        "__module__": cls.__module__})
