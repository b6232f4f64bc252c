"""Navigation in the loop: the autopilot and the guidance fly on an estimator's solution.

An open-loop scenario flies once and corrupts that one truth for every run. With a
``closed_loop`` block each Monte Carlo run flies its own aircraft: at every step the guidance
(position, course, ground speed) and the height, climb-rate, roll and pitch the autopilot holds
come from the navigation solution of the estimator named by ``fly_on``, so navigation errors
move the aircraft. Airspeed, body rates and sideslip stay on the truth (the air-data and gyro
signals an autopilot reads directly). ``fly_on: truth`` flies the same loop on the truth.

P1's safety strategy (Jiang & Chen) is ``return_to_land``: when the watched GNSS receiver has
had no fix for longer than ``lost_s``, the mission is abandoned and the aircraft flies, on the
navigation solution with whatever aids remain, to the recovery point; when the solution says
it is there (within ``acceptance_m`` along the leg), the parachute opens and the run's miss
distance is the true horizontal distance to the recovery point. Each run is scored up to its
own end (landing, end of the track, failure; :func:`end_records` blanks what follows), so what a
run contributes does not depend on the runs it was batched with::

    closed_loop:
      fly_on: SINS/GNSS/baro           # an estimator label, or truth
      time_limit_s: 1500               # the loop stops here at the latest
      return_to_land:
        gnss: gps                      # the receiver watched (a gnss sensor of the scenario)
        lost_s: 10                     # no fix for longer than this: abort the mission
        lat_deg: 30.5                  # the recovery point (or north_m / east_m from the start)
        lon_deg: 114.3
        alt_m: 120                     # height of the way back (default: the height commanded)
        acceptance_m: 0                # the parachute opens this far before the point (estimate)
        area_m: 150                    # a landing within this of the point reached the area

Sensors: every run's sensor errors are its own random streams, drawn as in open loop by the
same emulators (on a static record as long as ``time_limit_s``: the errors of the supported
sensors do not depend on the trajectory) and added to the run's own truth as it is flown: IMU
(scale factor, misalignment, biases, noise, vibration, quantization; the IMU rate must be the
flight rate) and every kind whose registration says how it flies in the loop
(:class:`navsim.sensors.registry.InLoop`: GNSS without latency, lever arm or interference, which
depend on the trajectory, barometer, air data, magnetometer). Other kinds are refused with a clear error.

A multirotor (a ``hover`` start) flies its cascade controller (:mod:`navsim.flight.rotorcraft`)
on the solution's position, velocity and attitude and the gyros' measured rates; its return is
a ``goto`` to the recovery point and a ``land`` there.

JSBSim holds one aircraft per instance, so the physics steps each run in turn; a fixed wing's
sensing, failure checks, segments and autopilot step every run of the batch in one compiled call
(:mod:`navsim.flight.fleet`), sensors and estimators are batched over the runs. A run that has
ended (landed, flown its track, failed) is no longer flown.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from navsim.experiment.driver import Driver, perturbed_start
from navsim.flight import properties as P
from navsim.flight.airframe import MULTIROTOR
from navsim.flight.environment import steady_wind_n_mps
from navsim.flight.multirotor import MultirotorState
from navsim.flight.rotorcraft import Rotorcraft, RotorSegments, check_row
from navsim.flight.fleet import (ABORT, FAILS, NOT_STARTED, STEPPED, FleetArrays, Watchdog, failure, finish_step,
                                 fleet_arrays, fleet_step, resume, state_of)
from navsim.flight.simulator import Aircraft, load_limits
from navsim.flight.track import LAND_RATE_MPS, Segment
from navsim.flight.truth import Pose, Truth, truth_from_rows
from navsim.foundations.config import MAX_DURATION_S, Node, close_match
from navsim.foundations.errors import FlightError, ScenarioError
from navsim.foundations.transform import quat_from_euler
from navsim.navigation.estimators import factory
from navsim.navigation.estimators.base import navigation
from navsim.records.history import EPOCH_ARRAYS
from navsim.records.truth import TruthBias
from navsim.sensors import emulate
from navsim.sensors.registry import INERTIAL, LoopSample, get as get_kind, kinds as sensor_kinds
from navsim.sensors.imu import OnlineIncrements, error_increments
from navsim.sensors.kernels import measured_increments

RETURN_LABEL = "return to land"
#: the states of a run still flown (one that has landed, flown its track or failed is not)
_FLOWN = ("flying", "aborted")
_RAW_TO_SI = np.array(P.RAW_TO_SI)


@dataclass(frozen=True)
class ReturnToLand:
    gnss: str
    lost_s: float
    point: dict                  #: lat_deg/lon_deg or north_m/east_m
    alt_m: float | None
    acceptance_m: float
    area_m: float


@dataclass(frozen=True)
class ClosedLoopConfig:
    fly_on: str                  #: estimator label, or "truth"
    time_limit_s: float
    return_to_land: ReturnToLand | None = None


def in_loop_kinds() -> list[str]:
    """The sensor kinds a closed loop flies: the IMU and every registered kind that declares how
    (:class:`navsim.sensors.registry.InLoop`)."""
    return ([k.name for k in sensor_kinds() if k.role == INERTIAL]
            + [k.name for k in sensor_kinds() if k.in_loop is not None and k.role != INERTIAL])


def _check_in_loop(c, file) -> None:
    """Sensor ``c`` (a SensorConfig) can fly in the closed loop, or a ScenarioError says why."""
    key, kind = f"sensors.{c.name}", get_kind(c.kind)
    if c.role != INERTIAL and kind.in_loop is None:
        raise ScenarioError(f"is a {c.kind}, whose errors depend on the trajectory: it cannot be "
                            "flown in the loop", file=file, key=key,
                            expected="with closed_loop, sensors of kinds " + ", ".join(in_loop_kinds()),
                            hint="remove it from this scenario or fly it open loop")
    refusal = kind.in_loop.refuse(c) if kind.in_loop is not None and kind.in_loop.refuse is not None else None
    if refusal is not None:
        raise ScenarioError(refusal.what, file=file, key=key, expected=refusal.expected, hint=refusal.hint)


def parse_closed_loop(node: Node, labels: list[str], sensors, track, duration_s: float,
                      rate_hz: float) -> ClosedLoopConfig:
    """Validate a scenario's ``closed_loop`` block (``sensors``: the scenario's SensorConfigs)."""
    fly_on = node.get("fly_on", str)
    if fly_on != "truth" and fly_on not in labels:
        raise node.error(f"'{fly_on}' is not an estimator of this scenario", "fly_on",
                         expected="an estimator label or 'truth'", hint=close_match(fly_on, labels))
    default_limit = (duration_s * 1.5 + 300.0) if math.isfinite(duration_s) else 3600.0
    limit = node.get("time_limit_s", float, default_limit, exclusive_minimum=0.0, maximum=MAX_DURATION_S)
    if track.start.type not in ("air", "hover"):
        what = "starts on a launcher" if track.start.type == "launch" else "starts on the ground"
        raise ScenarioError(what, file=node.file, key="track.start.type",
                            expected="with closed_loop, an air start (a multirotor's: hover)",
                            hint="launches, takeoffs and parked vehicles are open loop only")
    imu = [c for c in sensors if c.role == INERTIAL]
    for c in sensors:
        _check_in_loop(c, node.file)
    if imu and any(v.type == "rotor" for v in imu[0].spec.vibration):
        raise ScenarioError("a rotor vibration in a closed loop", file=node.file, key=f"sensors.{imu[0].name}.vibration",
                            expected="with closed_loop, a sine or random vibration: each run's rotor speeds are "
                                     "not known before it flies")
    if imu and abs(imu[0].spec.rate_hz - rate_hz) > 1e-9:
        raise ScenarioError(f"runs at {imu[0].spec.rate_hz:g} Hz, the flight at {rate_hz:g} Hz",
                            file=node.file, key=f"sensors.{imu[0].name}",
                            expected="with closed_loop, an IMU at the flight rate (flight.rate_hz)",
                            hint=f"flight: {{rate_hz: {imu[0].spec.rate_hz:g}}}")
    rtl = None
    sub = node.child("return_to_land", None)
    if sub is not None:
        gnss = sub.get("gnss", str)
        kinds = {c.name: c.kind for c in sensors}
        if kinds.get(gnss) != "gnss":
            raise sub.error(f"'{gnss}' is not a gnss sensor of this scenario", "gnss",
                            hint=close_match(gnss, [k for k, v in kinds.items() if v == "gnss"]))
        if "lat_deg" in sub.data or "lon_deg" in sub.data:
            point = {"lat_deg": sub.get("lat_deg", float, minimum=-90.0, maximum=90.0),
                     "lon_deg": sub.get("lon_deg", float, minimum=-180.0, maximum=180.0)}
        else:
            point = {"north_m": sub.get("north_m", float), "east_m": sub.get("east_m", float)}
        rtl = ReturnToLand(gnss=gnss, lost_s=sub.get("lost_s", float, 10.0, exclusive_minimum=0.0, maximum=MAX_DURATION_S),
                           point=point, alt_m=sub.get("alt_m", float, None),
                           acceptance_m=sub.get("acceptance_m", float, 0.0, minimum=0.0),
                           area_m=sub.get("area_m", float, 150.0, exclusive_minimum=0.0))
        sub.done()
    node.done()
    return ClosedLoopConfig(fly_on=fly_on, time_limit_s=limit, return_to_land=rtl)


class _StepTruth:
    """The true state of ``B`` runs at one step, shaped as a one-sample truth record
    (``[0]`` gives ``(B, ...)``) for :func:`navsim.experiment.driver.nav_errors`; the attitude
    quaternion is computed when read (the records of an epoch), not at every step."""

    def __init__(self, rows: np.ndarray, batched: bool = True):
        r = rows
        one = (lambda x: x[None]) if batched else (lambda x: x)   # unbatched: ``[k]`` is run k
        self._rows, self._one = rows, one
        self.lat_rad = one(r[:, P.COL_LAT])
        self.lon_rad = one(r[:, P.COL_LON])
        self.h_m = one(r[:, P.COL_H])
        self.vel_n_mps = one(r[:, P.COL_VN:P.COL_VD + 1])
        self.euler_rad = one(r[:, [P.COL_ROLL, P.COL_PITCH, P.COL_YAW]])
        self.omega_ib_b_rps = r[:, P.COL_PI:P.COL_RI + 1]
        self.f_b_mps2 = r[:, P.COL_FX:P.COL_FZ + 1] / r[:, P.COL_MASS:P.COL_MASS + 1]
        self.wind_steady_n_mps = one(r[:, P.COL_WSN:P.COL_WSD + 1])

    @functools.cached_property
    def quat_nb(self) -> np.ndarray:
        r = self._rows
        return self._one(quat_from_euler(r[:, P.COL_ROLL], r[:, P.COL_PITCH], r[:, P.COL_YAW]))


@dataclass
class LoopBatch:
    """What :func:`fly_batch` returns for its runs."""

    histories: dict              #: label -> EstimatorHistory
    outcome: list                #: per run: landed, completed (track flown), failed, time limit
    failed: dict                 #: run index -> reason
    abort_t_s: np.ndarray        #: (B,) time the mission was abandoned (NaN: never)
    land_t_s: np.ndarray         #: (B,) time the parachute opened (NaN: never)
    fail_t_s: np.ndarray         #: (B,) time the flight failed (NaN: never)
    end_t_s: np.ndarray          #: (B,) time the run ended: landed, track flown, failed (NaN: time limit)
    miss_m: np.ndarray           #: (B,) true horizontal distance of the landing to the point
    miss_est_m: np.ndarray       #: (B,) the same, of the navigation solution
    landing_n_m: np.ndarray      #: (B, 2) true north, east of the landing from the track start
    path_t_s: np.ndarray         #: (E,) times of the recorded paths (the estimators' epochs)
    path_n_m: np.ndarray         #: (B, E, 3) true north, east, height from the track start
    point_n_m: tuple | None      #: the recovery point, north/east from the track start
    truth_bias: TruthBias        #: gyro_bias/accel_bias (B, E, 3) at the epochs
    truth: Truth | None = None   #: the whole truth of the first run (``keep_truth``)


def _sensor_streams(scenario, seed, runs, dt, n):
    """IMU error increments and the other sensors' data (values to be filled in flight)."""
    imu_cfg = next(c for c in scenario.sensors if c.role == INERTIAL)
    imu = error_increments(imu_cfg.spec, seed, runs, n, dt, name=imu_cfg.name)
    start = scenario.flight.track.start
    static = Truth.static((n - 1) * dt, 1.0 / dt, Pose(start.lat_deg, start.lon_deg, start.alt_m))
    others = {c.name: emulate(static, c, seed, runs) for c in scenario.sensors if c.role != INERTIAL}
    for data in others.values():
        data.meta["step"] = int(round(1.0 / (data.meta["rate_hz"] * dt)))
        prepare = get_kind(data.kind).in_loop.prepare
        if prepare is not None:
            prepare(data, static)
    return imu_cfg, imu, others


@dataclass(frozen=True)
class _Fleet:
    """The aircraft of a batch of runs and what stays fixed while they fly."""

    runs: list                   #: the Monte Carlo run indices
    dt: float                    #: flight step, s
    n_max: int                   #: steps up to the time limit
    craft: list                  #: one Aircraft per run
    watch: list                  #: one Watchdog per run
    imu_cfg: object              #: the IMU's SensorConfig
    imu_err: dict                #: the IMU's error increments (see error_increments)
    sensors: dict                #: name -> SensorData of the other sensors, filled in flight
    rtl: ReturnToLand | None
    point: tuple | None          #: the recovery point, north/east from the track start
    goto: Segment | None         #: the segment flown back to it
    #: a multirotor's: each run's segments (:class:`~navsim.flight.rotorcraft.RotorSegments`) and
    #: the setpoint it flies (its last one once they are flown); empty for a fixed wing
    rotor_segments: list
    setpoints: list
    #: the IMU's quanta, gyro and accelerometer, per step (0: none)
    quanta: np.ndarray = None
    #: the IMU's increments of the step (dtheta, dv), ``(B, 2, 3)``, written in place
    measured: np.ndarray = None
    #: a fixed wing's: the arrays its aircraft are stepped through (:mod:`navsim.flight.fleet`)
    arrays: FleetArrays | None = None
    #: each aircraft's JSBSim calls of a step: set_controls, run, read_raw
    steppers: list = None


@dataclass(frozen=True)
class _Tally:
    """What the runs record as they fly (filled in place, one entry per run)."""

    status: list                 #: flying, aborted (returning), landed, completed, failed
    failed: dict                 #: run index -> reason
    abort_t: np.ndarray
    land_t: np.ndarray
    fail_t: np.ndarray
    end_t: np.ndarray
    landing: np.ndarray          #: (B, 2) true north, east of the landing
    landing_est: np.ndarray      #: (B, 2) the same, of the navigation solution
    last_fix: np.ndarray         #: (B,) time of the watched receiver's last fix
    paths: list
    path_t: list
    kept: list | None            #: the first run's truth rows (``keep_truth``)
    seg_kept: list               #: their segment indices

    @classmethod
    def empty(cls, B: int, keep_truth: bool) -> _Tally:
        nan = lambda *shape: np.full(shape, np.nan)
        return cls(status=["flying"] * B, failed={}, abort_t=nan(B), land_t=nan(B), fail_t=nan(B),
                   end_t=nan(B), landing=nan(B, 2), landing_est=nan(B, 2), last_fix=np.zeros(B),
                   paths=[], path_t=[], kept=[] if keep_truth else None, seg_kept=[])


def _recovery(rtl: ReturnToLand | None, c0) -> tuple:
    """The recovery point (north/east from the track start) and the segment back to it."""
    if rtl is None:
        return None, None
    if "north_m" in rtl.point:
        point = (rtl.point["north_m"], rtl.point["east_m"])
    elif isinstance(c0, Rotorcraft):
        point = c0.local_of_latlon(rtl.point["lat_deg"], rtl.point["lon_deg"])
    else:
        point = c0.local_of_latlon(math.radians(rtl.point["lat_deg"]), math.radians(rtl.point["lon_deg"]))
    goto = Segment("goto", RETURN_LABEL, {"north_m": point[0], "east_m": point[1],
                                          "acceptance_m": rtl.acceptance_m,
                                          **({"alt_m": rtl.alt_m} if rtl.alt_m is not None else {})})
    return point, goto


def _fleet(scenario, seed: int, runs: list) -> _Fleet:
    """Sensor streams, aircraft and watchdogs of the runs ``runs``."""
    cl, fc = scenario.closed_loop, scenario.flight
    dt = 1.0 / fc.rate_hz
    n_max = int(round(cl.time_limit_s / dt)) + 1
    imu_cfg, imu_err, sensors = _sensor_streams(scenario, seed, runs, dt, n_max)
    airframe = load_limits(fc)
    if airframe.kind == MULTIROTOR:
        craft = [Rotorcraft(fc, airframe) for _ in runs]
        watch, segments = [], [RotorSegments(fc.track, c) for c in craft]
        for segs in segments:
            segs.next(0.0)
    else:
        craft = [Aircraft(fc) for _ in runs]
        watch, segments = [Watchdog(c.limits, dt) for c in craft], []
    point, goto = _recovery(cl.return_to_land, craft[0])
    arrays = None
    if airframe.kind != MULTIROTOR:
        rtl = cl.return_to_land
        arrays = fleet_arrays(craft, watch, rtl.lost_s if rtl is not None else math.inf)
        arrays.flying[:] = rtl is not None
    return _Fleet(runs=runs, dt=dt, n_max=n_max, craft=craft, watch=watch, imu_cfg=imu_cfg,
                  imu_err=imu_err, sensors=sensors, rtl=cl.return_to_land, point=point, goto=goto,
                  rotor_segments=segments, setpoints=[None] * len(craft), arrays=arrays,
                  quanta=np.array([(e.quantization or 0.0) * dt for e in (imu_cfg.spec.gyro, imu_cfg.spec.accel)]),
                  measured=np.zeros((len(runs), 2, 3)),
                  steppers=[(c.io.set_controls, c.io.run, c.io.read_raw) for c in craft])


def _start_navigation(scenario, seed: int, fleet: _Fleet, estimators: dict, rows: np.ndarray) -> tuple:
    """The estimators' Driver started on the runs' perturbed initial state, and the IMU's
    online increments primed with the first step."""
    view = _StepTruth(rows)
    errors = scenario.initial.draw(seed, fleet.runs)
    nav0 = perturbed_start(_StepTruth(rows[:1], batched=False), errors, 0)
    sigma0 = scenario.initial.sigma_blocks(rows[0, P.COL_LAT], rows[0, P.COL_H])
    loop = Driver(estimators, fleet.dt, len(fleet.runs), isolate=False)   # the guidance needs every step
    loop.start(nav0, sigma0, view, 0)
    inc = OnlineIncrements(len(fleet.runs), fleet.dt)
    inc.update(view.omega_ib_b_rps, view.f_b_mps2)
    return loop, inc


def _advance(fleet: _Fleet, loop, inc, rows: np.ndarray, k: int) -> np.ndarray:
    """Step ``k`` of the sensors (the runs' truth ``rows`` plus their errors) and the estimators;
    returns the gyros' measured rates over the step, ``(B, 3)`` rad/s (what a multirotor's rate
    loop reads)."""
    dt, err = fleet.dt, fleet.imu_err
    view = _StepTruth(rows)
    inc.update(view.omega_ib_b_rps, view.f_b_mps2)
    measured_increments(inc.out, err["gyro_matrix"], err["accel_matrix"], err["gyro"][:, k], err["accel"][:, k],
                        fleet.quanta, fleet.measured)
    dth, dv = fleet.measured[:, 0].copy(), fleet.measured[:, 1].copy()   # the filters may keep them
    sample = LoopSample(rows[:, P.COL_LAT], rows[:, P.COL_LON], rows[:, P.COL_H], rows[:, P.COL_VN:P.COL_VD + 1],
                        rows[:, P.COL_ROLL:P.COL_YAW + 1], rows[:, P.COL_PS], rows[:, P.COL_PT],
                        rows[:, P.COL_TEMP], rows[:, P.COL_ALPHA], rows[:, P.COL_BETA])
    for data in fleet.sensors.values():
        if k % data.meta["step"] == 0:
            get_kind(data.kind).in_loop.fill(data, k // data.meta["step"], sample)
    loop.advance(dth[:, None], dv[:, None], k * dt, fleet.sensors, view, 0)
    return dth / dt


def _record(fleet: _Fleet, tally: _Tally, rows: np.ndarray, k: int, t: float, path_every: int) -> None:
    """The true paths every ``path_every`` steps and the time of the watched receiver's last fix."""
    c0 = fleet.craft[0]
    if k % path_every == 0:
        tally.path_t.append(t)
        tally.paths.append(np.stack([(rows[:, P.COL_LAT] - c0.lat0) * c0.k_north,
                                     (rows[:, P.COL_LON] - c0.lon0) * c0.k_east, rows[:, P.COL_H]], -1))
    if fleet.rtl is not None:
        g = fleet.sensors[fleet.rtl.gnss]
        if k % g.meta["step"] == 0:
            tally.last_fix[g.valid[:, k // g.meta["step"]]] = t


def _ended(tally: _Tally, b: int, row: np.ndarray, c0, est_ne: tuple, t: float) -> None:
    """Run ``b`` has flown its segments at ``t``: landed where its truth ``row`` is (the
    navigation putting it at ``est_ne``, north and east) if it was returning, else its track
    completed."""
    tally.end_t[b] = t
    if tally.status[b] == "aborted":
        tally.status[b], tally.land_t[b] = "landed", t
        tally.landing[b] = ((row[P.COL_LAT] - c0.lat0) * c0.k_north, (row[P.COL_LON] - c0.lon0) * c0.k_east)
        tally.landing_est[b] = est_ne
    else:
        tally.status[b] = "completed"


def _step_fleet(fleet: _Fleet, tally: _Tally, nav, t: float) -> None:
    """One step of the fixed-wing runs still flying (on the truth, or ``nav``, the navigation
    solution): failure checks, segments and autopilot in one compiled call
    (:func:`~navsim.flight.fleet.fleet_step`), what is rare in :func:`_resolve`; then each
    aircraft's physics."""
    f, dt = fleet.arrays, fleet.dt
    if nav is not None:
        f.nav_llh[:, 0], f.nav_llh[:, 1], f.nav_llh[:, 2] = nav.lat_rad, nav.lon_rad, nav.h_m
        f.nav_vel[:], f.nav_C[:] = nav.vel_n_mps, nav.C_nb
    f.on_nav[0] = nav is not None
    if fleet_step(f, t, dt):
        for b in np.flatnonzero(f.live & (f.code != STEPPED)).tolist():
            _resolve(fleet, tally, b, t)
    if tally.kept is not None and tally.status[0] != "failed" and (f.live[0] or tally.end_t[0] == t):
        runner = fleet.craft[0].runner
        tally.kept.append(f.rows[0].copy())
        tally.seg_kept.append(len(fleet.craft[0].config.track.segments) if tally.status[0] in ("aborted", "landed")
                              else runner.index - 1 if runner.finished else runner.index)
    controls, rows, winds = f.controls.tolist(), f.rows, fleet.craft[0].config.environment.wind_changes
    live = np.flatnonzero(f.live)
    for b in live.tolist():                         # each aircraft's physics, and its next row
        set_controls, run, read_raw = fleet.steppers[b]
        set_controls(*controls[b])
        if winds:
            fleet.craft[b].set_wind_at(t + dt)
        run()
        rows[b] = read_raw()
    rows[live] *= _RAW_TO_SI


def _resolve(fleet: _Fleet, tally: _Tally, b: int, t: float) -> None:
    """Act on what :func:`~navsim.flight.fleet.fleet_step` stopped run ``b`` for: a failure, the
    mission abandoned on a lost fix (the segments replaced by the way back), the segments started
    or gone on to the next, the run's end; then finish its step."""
    f, c0, runner, st = fleet.arrays, fleet.craft[0], fleet.craft[b].runner, tally.status
    code, s = int(f.code[b]), state_of(f, b)
    try:
        if code in FAILS:
            raise runner.fail(failure(code, f.rows[b]), s)
        if code == ABORT:
            st[b], tally.abort_t[b], f.flying[b] = "aborted", t, False
            runner.segments, runner.index, runner.finished = [fleet.goto], -1, False
            code = NOT_STARTED
        resume(runner, s, code, fleet.dt)
    except FlightError as exc:
        st[b], tally.fail_t[b], tally.end_t[b] = "failed", t, t
        tally.failed[fleet.runs[b]] = str(exc)
        f.live[b] = f.flying[b] = False
        return
    if runner.finished:
        _ended(tally, b, f.rows[b], c0, (s.north, s.east), t)
        f.live[b] = f.flying[b] = False
    else:
        finish_step(f, b, fleet.dt)


#: the landing that ends a multirotor's return home, at a track's default rate
_LAND = Segment("land", "land", {"rate_mps": LAND_RATE_MPS})


def _rotor_state(craft: Rotorcraft, row: np.ndarray, nav, b: int, omega_b: np.ndarray) -> MultirotorState:
    """Run ``b``'s state for its multirotor controller: its truth ``row``'s, or (``nav``) the
    navigation solution's position, velocity and attitude with the gyros' measured rates
    ``omega_b`` (rad/s)."""
    if nav is None:
        return craft.state(row)
    pos = np.array([(float(nav.lat_rad[b]) - craft.lat0) * craft.k_north,
                    (float(nav.lon_rad[b]) - craft.lon0) * craft.k_east, craft.h0 - float(nav.h_m[b])])
    return MultirotorState(pos, np.array(nav.vel_n_mps[b], float), np.array(nav.C_nb[b], float),
                           np.asarray(omega_b, float))


def _follow_rotor(fleet: _Fleet, tally: _Tally, b: int, row: np.ndarray, est_ne: tuple, t: float) -> None:
    """Run ``b``'s multirotor segments for one step: the failure checks, home and a landing on a
    lost fix, the end of the track or the landing (``est_ne``: where the navigation puts it).
    Raises FlightError."""
    segs, st, c0 = fleet.rotor_segments[b], tally.status, fleet.craft[0]
    check_row(row, t, segs)
    if st[b] == "flying" and fleet.rtl is not None and t - tally.last_fix[b] > fleet.rtl.lost_s:
        st[b], tally.abort_t[b] = "aborted", t
        segs.segments, segs.index = [fleet.goto, _LAND], -1
        segs.next(t)
    if segs.finished:
        return
    fleet.setpoints[b] = segs.setpoint(t, fleet.dt)
    if not segs.finished and segs.segments[segs.index].type == "land":
        segs.touchdown(t, fleet.craft[b].io.on_ground())
    if not segs.finished:
        return
    _ended(tally, b, row, c0, est_ne, t)


def _step_rotor(fleet: _Fleet, tally: _Tally, b: int, row: np.ndarray, nav, omega_b, t: float) -> None:
    """One step of the multirotor run ``b``: segments, failure checks, controller (on the truth
    or, ``nav``, the navigation) and physics, as :func:`~navsim.flight.rotorcraft.fly_rotorcraft`
    steps one on the truth."""
    c, segs = fleet.craft[b], fleet.rotor_segments[b]
    state = _rotor_state(c, row, nav, b, omega_b)
    index = segs.index
    try:
        _follow_rotor(fleet, tally, b, row, (float(state.pos_n_m[0]), float(state.pos_n_m[1])), t)
    except FlightError as exc:
        tally.status[b], tally.fail_t[b], tally.end_t[b] = "failed", t, t
        tally.failed[fleet.runs[b]] = str(exc)
        return
    if tally.kept is not None and b == 0:
        tally.kept.append(np.concatenate([row, c.read_rpm()]))
        tally.seg_kept.append(len(c.config.track.segments) if tally.status[0] in ("aborted", "landed") else index)
    if segs.landed_s is None:
        c.set_commands(c.controller.command(state, fleet.setpoints[b], fleet.dt))
    else:                                            # landed: the motors stopped
        c.set_commands([0.0] * c.n)
    env = c.config.environment
    if env.wind_changes:
        c.io.set_wind_ned(steady_wind_n_mps(env, t + fleet.dt))
    c.io.run()


def fly_batch(scenario, seed: int, runs, on_truth: bool = False, keep_truth: bool = False,
              progress=None) -> LoopBatch:
    """Fly the runs ``runs`` of ``scenario`` with navigation in the loop (see the module
    docstring); ``on_truth`` flies them on the truth whatever ``fly_on`` says; ``keep_truth``
    keeps the first run's whole truth record (for the flight pages of the report)."""
    cl = scenario.closed_loop
    fleet = _fleet(scenario, seed, list(runs))
    estimators = {e.label: factory.build(e) for e in scenario.estimators}   # looked up at the call
    driver = None if (on_truth or cl.fly_on == "truth") else estimators[cl.fly_on]
    craft = fleet.craft
    rows = fleet.arrays.rows if fleet.arrays is not None else np.zeros((len(craft), len(P.RAW_PROPERTIES)))
    rows[:] = [c.io.read_row() for c in craft]
    loop, inc = _start_navigation(scenario, seed, fleet, estimators, rows)
    path_every = min(loop.every.values())
    tally = _Tally.empty(len(craft), keep_truth)
    if fleet.arrays is not None:                 # the fleet's kernel reads the last fixes there
        tally = replace(tally, last_fix=fleet.arrays.last_fix)
    status = tally.status
    for k in range(fleet.n_max):
        t = k * fleet.dt
        omega = _advance(fleet, loop, inc, rows, k) if k > 0 else rows[:, P.COL_P:P.COL_R + 1]
        _record(fleet, tally, rows, k, t, path_every)
        nav = navigation(driver) if driver is not None else None
        if fleet.rotor_segments:
            for b in range(len(craft)):
                if status[b] in _FLOWN:
                    _step_rotor(fleet, tally, b, rows[b], nav, omega[b], t)
        else:
            _step_fleet(fleet, tally, nav, t)
        if not (fleet.arrays.live.any() if fleet.arrays is not None else any(st in _FLOWN for st in status)):
            break
        if progress is not None and k % 1000 == 0:
            progress(t, cl.time_limit_s)
        if fleet.arrays is None:                  # a fixed wing's rows are read as it steps
            for b in [b for b, st in enumerate(status) if st in _FLOWN]:
                rows[b] = craft[b].io.read_row()
    return _batch(scenario.flight, fleet, tally, loop.histories())


def _truth_bias(imu_err: dict, histories: dict, dt: float, B: int) -> TruthBias:
    """The IMU's true gyro and accelerometer biases ``(B, E, 3)`` at the estimators' epochs."""
    ks = np.round(next(iter(histories.values())).t_s / dt).astype(int)
    bias = {}
    for key in ("gyro_bias", "accel_bias"):
        v = np.broadcast_to(imu_err[key], (B, imu_err[key].shape[1], 3))
        bias[key] = v[:, ks] if v.shape[1] > 1 else np.repeat(v, len(ks), axis=1)
    return TruthBias(**bias)


def _batch(fc, fleet: _Fleet, tally: _Tally, histories: dict) -> LoopBatch:
    """The LoopBatch of the flown runs (``fc``: the scenario's FlightConfig)."""
    B, dt, point = len(fleet.runs), fleet.dt, fleet.point
    outcome = ["time limit" if st in ("flying", "aborted") else st for st in tally.status]
    miss = np.hypot(*(tally.landing - np.asarray(point)).T) if point is not None else np.full(B, np.nan)
    miss_est = np.hypot(*(tally.landing_est - np.asarray(point)).T) if point is not None else np.full(B, np.nan)
    truth = None
    if tally.kept:
        labels = [s.label for s in fc.track.segments] + [RETURN_LABEL]
        truth = truth_from_rows(np.array(tally.kept), np.arange(len(tally.kept)) * dt, np.array(tally.seg_kept),
                                labels, {"aircraft": fc.aircraft, "rate_hz": fc.rate_hz, "track": fc.track.name,
                                         "start": "air", "closed_loop": True})
    return LoopBatch(histories=histories, outcome=outcome, failed=tally.failed, abort_t_s=tally.abort_t,
                     land_t_s=tally.land_t, fail_t_s=tally.fail_t, end_t_s=tally.end_t, miss_m=miss,
                     miss_est_m=miss_est, landing_n_m=tally.landing, path_t_s=np.array(tally.path_t),
                     path_n_m=np.stack(tally.paths, axis=1), point_n_m=point,
                     truth_bias=_truth_bias(fleet.imu_err, histories, dt, B), truth=truth)


def end_records(batch: LoopBatch, dt: float) -> None:
    """Blank (NaN) every run's records after its own end (landing, end of the track, failure), so
    that what a run contributes does not depend on the runs it was batched with."""
    end = np.where(np.isfinite(batch.end_t_s), batch.end_t_s, np.inf)
    for h in batch.histories.values():
        after = h.t_s[None, :] > end[:, None] + 0.5 * dt            # (B, E)
        for name in EPOCH_ARRAYS:
            a = getattr(h, name)
            if a is not None:
                a[after] = np.nan
        for v in h.nis.values():
            v[after] = np.nan
    after = batch.path_t_s[None, :] > end[:, None] + 0.5 * dt
    batch.path_n_m[after] = np.nan
