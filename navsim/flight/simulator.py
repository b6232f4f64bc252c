"""Fly a track in JSBSim under the autopilot and record the truth.

:func:`fly` is the entry point: it starts the aircraft (trimmed in the air, or on a launcher),
runs the segments one after the other, checks every step for stall, impact, loss of control and
NaN, and returns a :class:`~navsim.flight.truth.Truth`. A failure raises
:class:`~navsim.foundations.errors.FlightError` naming the segment and the time; the partial truth rides on
the exception as ``truth``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from navsim.flight import properties as P
from navsim.flight.airframe import (ENVELOPE_FILE, MULTIROTOR, FixedWing, Multirotor, check_controller,
                                   load_airframe, model_location)
from navsim.flight.autopilot import Autopilot, Gains, Sensed
from navsim.flight.environment import Environment, steady_wind_n_mps
from navsim.flight.fleet import (FAILS, Watchdog, failure, finish_step, fleet_arrays, fleet_step, resume,
                                 state_of)
from navsim.flight.rotorcraft import fly_rotorcraft
from navsim.flight.segments import SegmentRunner, State
from navsim.flight.track import Start, Track, check_segments, nominal_duration_s
from navsim.flight.truth import Pose, Truth, truth_from_rows
from navsim.foundations.earth import radii
from navsim.foundations.errors import FlightError

SETTLE_S = 30.0          #: air start: seconds flown before the track to settle the trim
SPINUP_S = 2.0           #: seconds the motor runs up with the airframe held
#: the aircraft flown where none is named (a shipped folder of ``aircraft/``)
DEFAULT_AIRCRAFT = "survey10"


@dataclass
class FlightConfig:
    """Everything that determines a flight (and so the key of its cache)."""

    track: Track
    environment: Environment = field(default_factory=Environment)
    aircraft: str = DEFAULT_AIRCRAFT
    rate_hz: float = 100.0
    gains: Gains = field(default_factory=Gains)
    aircraft_dir: str | None = None

    @property
    def folder(self) -> Path:
        """The aircraft's folder: ``aircraft`` in ``aircraft_dir``, or a shipped one."""
        return (Path(self.aircraft_dir) if self.aircraft_dir else P.AIRCRAFT_DIR) / self.aircraft


def load_limits(config: FlightConfig) -> FixedWing | Multirotor:
    """The envelope of ``config``'s aircraft from its ``navsim.yaml``
    (:func:`~navsim.flight.airframe.load_airframe`).

    Raises
    ------
    ScenarioError
        A ``navsim.yaml`` missing or wrong; a class navsim has no controller for; a start or a
        segment of the track that the class does not fly.
    """
    airframe = load_airframe(config.folder)
    check_controller(airframe, config.aircraft, file=str(config.folder / ENVELOPE_FILE), key="class")
    check_segments(config.track, airframe.kind, None)
    return airframe


class _Recorder:
    """Rows of SI values in preallocated chunks."""

    def __init__(self, ncols: int, chunk: int):
        self.chunk, self.ncols = chunk, ncols
        self.blocks: list[np.ndarray] = []
        self.seg: list[np.ndarray] = []
        self.i = chunk

    def add(self, row, segment: int) -> None:
        if self.i == self.chunk:
            self.blocks.append(np.empty((self.chunk, self.ncols)))
            self.seg.append(np.empty(self.chunk, np.int16))
            self.i = 0
        self.blocks[-1][self.i] = row
        self.seg[-1][self.i] = segment
        self.i += 1

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.blocks:
            return np.empty((0, self.ncols)), np.empty(0, np.int16)
        n_last = self.i
        rows = np.concatenate(self.blocks[:-1] + [self.blocks[-1][:n_last]])
        seg = np.concatenate(self.seg[:-1] + [self.seg[-1][:n_last]])
        return rows, seg


class Aircraft:
    """One JSBSim aircraft under the autopilot, started (trimmed in the air or on its launcher)
    and ready to be stepped: :func:`fly` steps one on the truth; the closed loop
    (:mod:`navsim.experiment.closed_loop`) steps one per Monte Carlo run on a navigation solution."""

    def __init__(self, config: FlightConfig):
        track, env = config.track, config.environment
        self.config, self.dt = config, 1.0 / config.rate_hz
        self.limits = load_limits(config)
        model, model_dir = model_location(config.folder, self.limits)
        self.io = io = P.JSBSimIO(model, self.dt, model_dir)
        self.ap = ap = Autopilot(config.gains)
        start = track.start
        self.lat0, self.lon0 = lat0, lon0 = math.radians(start.lat_deg), math.radians(start.lon_deg)
        r_m, r_n = radii(lat0)
        self.k_north, self.k_east = float(r_m), float(r_n) * math.cos(lat0)
        io.set_terrain(env.surface_m)
        io.set_wind_ned(env.wind_n_mps)
        self.turbulence_pending = env.turbulence != "none"
        if self.turbulence_pending and start.type == "air":
            self.start_turbulence()   # JSBSim's turbulence models need airspeed: launch turns it on later
        heading = math.radians(start.heading_deg)
        ap.course_cmd = heading
        ap.speed_cmd = start.speed_mps
        departure = Departure(start, lat0, lon0, heading, env.surface_m)
        if start.type == "air":
            _air_start(io, ap, self.limits, departure, self.dt)
        else:
            _launch_prepare(io, ap, departure, self.dt)
        self.runner = SegmentRunner(track.segments, ap, self.limits, self.local_of_latlon)
        self.runner.course_ref = heading
        self.runner.speed_target = start.speed_mps

    def local_of_latlon(self, lat, lon):
        """North and east (m) of a latitude and longitude (rad) from the track's start."""
        return (lat - self.lat0) * self.k_north, (lon - self.lon0) * self.k_east

    def set_wind_at(self, t_s: float) -> None:
        """The steady wind of the time ``t_s`` (:func:`steady_wind_n_mps`), where it changes."""
        env = self.config.environment
        if env.wind_changes:
            self.io.set_wind_ned(steady_wind_n_mps(env, t_s))

    def start_turbulence(self) -> None:
        env = self.config.environment
        self.io.set_turbulence(env.turbulence, env.turbulence_wind20_mps, env.turbulence_severity,
                               env.turbulence_seed)
        self.turbulence_pending = False


def fly(config: FlightConfig | Track, progress=None) -> Truth:
    """Fly ``config`` and return its truth, sampled at ``config.rate_hz``.

    ``progress``, if given, is called as ``progress(t_s, nominal_duration_s)`` about once per
    simulated second.
    """
    if isinstance(config, Track):
        config = FlightConfig(track=config)
    if config.track.start.type == "ground" and config.track.segments[0].type == "hold":
        return _parked(config)
    airframe = load_limits(config)
    # a multirotor's rows carry its rotors' speeds after the properties (truth_from_rows)
    extra = len(airframe.rotors) if airframe.kind == MULTIROTOR else 0
    rec, dt = _Recorder(len(P.RAW_PROPERTIES) + extra, 1 << 14), 1.0 / config.rate_hz
    try:
        if airframe.kind == MULTIROTOR:
            fly_rotorcraft(config, airframe, rec.add, progress,
                           nominal_duration_s(config.track, config.environment.surface_m))
        else:
            _fly_track(Aircraft(config), rec, progress)
    except FlightError as exc:
        rows, seg = rec.arrays()
        exc.truth = _make_truth(rows, seg, dt, config.track, config) if len(rows) > 1 else None
        raise
    rows, seg = rec.arrays()
    return _make_truth(rows, seg, dt, config.track, config)


def _fly_track(craft: Aircraft, rec: _Recorder, progress) -> None:
    """Step ``craft`` on the truth through the launch (if any) and its segments, recording every
    row in ``rec``, until the track is flown. Raises FlightError."""
    io, runner, dt = craft.io, craft.runner, craft.dt
    watch = Watchdog(craft.limits, dt)
    nominal = nominal_duration_s(craft.config.track)
    k = _launch(craft, watch, rec, progress, nominal)
    fleet = fleet_arrays([craft], [watch])
    rows, code, controls = fleet.rows, fleet.code, fleet.controls
    next_progress = math.ceil(round(k * dt, 9))             # the launch called it every second
    read_row, set_controls, run = io.read_row, io.set_controls, io.run
    while True:
        t = k * dt
        rows[0] = row = read_row()
        if fleet_step(fleet, t, dt) and _stopped(craft, fleet, int(code[0]), t):
            rec.add(row, runner.index - 1)
            return
        rec.add(row, runner.index)
        if progress is not None and t >= next_progress:
            progress(t, nominal)
            next_progress += 1.0
        elev, ail, rud, thr = controls[0].tolist()
        set_controls(elev, ail, rud, thr)
        craft.set_wind_at(t + dt)
        run()
        k += 1


def _stopped(craft: Aircraft, fleet, code: int, t: float) -> bool:
    """Act on the code :func:`~navsim.flight.fleet.fleet_step` left for a fleet of one: a failure
    raised, the segments started or gone on to the next, the step finished; returns whether the
    track is flown."""
    s = state_of(fleet, 0)
    if code in FAILS:
        raise craft.runner.fail(failure(code, fleet.rows[0]), s)
    resume(craft.runner, s, code, craft.dt)
    if craft.runner.finished:
        return True
    finish_step(fleet, 0, craft.dt)
    return False


def _launch(craft: Aircraft, watch: Watchdog, rec: _Recorder, progress, nominal: float) -> int:
    """Step ``craft`` on its launcher up to the step that hands it over to its track, that step
    included (nothing where it starts in the air); returns the steps taken. Raises FlightError."""
    if craft.config.track.start.type != "launch":
        return 0
    io, ap, runner, dt = craft.io, craft.ap, craft.runner, craft.dt
    booster_steps = int(round(craft.config.track.start.booster_time_s / dt))
    state = State()
    k, launching = 0, True
    while launching:
        t = k * dt
        row = io.read_row()
        _sense(state, row, craft, t)
        reason = watch.check(row, ground_ok=t < 5.0, stall_ok=k <= booster_steps)
        if reason is not None:
            raise runner.fail(reason, state)
        launching = _launch_step(craft, state, row, k, booster_steps)
        rec.add(row, runner.index)
        if progress is not None and k % max(int(round(1.0 / dt)), 1) == 0:
            progress(t, nominal)
        io.set_controls(*ap.step(dt, Sensed(state.tas, state.h, -row[P.COL_VD], row[P.COL_ROLL], row[P.COL_PITCH],
                                            row[P.COL_P], row[P.COL_Q], row[P.COL_BETA], state.course)))
        craft.set_wind_at(t + dt)
        io.run()
        k += 1
    return k


def _sense(state: State, row, craft: Aircraft, t: float) -> None:
    """Fill the segments' State from the true ``row`` at time ``t`` (on the launcher)."""
    state.t = t
    state.north = (row[P.COL_LAT] - craft.lat0) * craft.k_north
    state.east = (row[P.COL_LON] - craft.lon0) * craft.k_east
    state.h = row[P.COL_H]
    vn, ve = row[P.COL_VN], row[P.COL_VE]
    state.ground_speed = math.hypot(vn, ve)
    state.course = math.atan2(ve, vn)
    state.tas = row[P.COL_TAS]


def _launch_step(craft: Aircraft, state: State, row, k: int, booster_steps: int) -> bool:
    """One step on the launch: wings level, booster cut, turbulence turned on at speed; at
    flying speed hand over to the track. Returns whether still launching."""
    io, ap, runner, start = craft.io, craft.ap, craft.runner, craft.config.track.start
    tas = state.tas
    ap.course_cmd = state.course if state.ground_speed > 1.0 else ap.course_cmd  # wings level
    if k == booster_steps:
        io.set_booster_n(0.0)
    if craft.turbulence_pending and tas > 8.0:
        craft.start_turbulence()
    if k >= booster_steps and tas >= 0.9 * start.speed_mps and row[P.COL_HAGL] > 10.0:
        ap.pitch_hold = None
        ap.throttle_hold = None
        ap.i_climb = row[P.COL_PITCH] - math.asin(min(max(-row[P.COL_VD] / tas, -0.5), 0.5))
        ap.i_speed = 0.6
        ap.alt_cmd, ap.climb_rate = state.h, 0.0
        runner.next(state)
        return False
    if state.t > 30.0:
        raise runner.fail("the launch did not reach flying speed within 30 s", state)
    return True


def _parked(config: FlightConfig) -> Truth:
    """The truth of a vehicle parked for the track's ``hold`` segments (no flight dynamics)."""
    track, start = config.track, config.track.start
    duration = sum(s["time_s"] for s in track.segments)
    pose = Pose(start.lat_deg, start.lon_deg, start.alt_m, start.heading_deg, start.roll_deg, start.pitch_deg)
    truth = Truth.static(duration, config.rate_hz, pose, h_agl_m=0.0)
    ends = np.cumsum([s["time_s"] for s in track.segments])
    truth.segment = np.minimum(np.searchsorted(ends, truth.t_s - 1e-9), len(ends) - 1).astype(np.int16)
    truth.segment_labels = [s.label for s in track.segments]
    truth.meta.update({"aircraft": config.aircraft, "track": track.name, "start": "ground"})
    return truth


def _make_truth(rows, seg, dt, track, config) -> Truth:
    t = np.arange(len(rows)) * dt
    meta = {"aircraft": config.aircraft, "rate_hz": config.rate_hz, "track": track.name,
            "start": track.start.type, "environment": {
                "wind_n_mps": list(config.environment.wind_n_mps),
                "turbulence": config.environment.turbulence,
                "surface_m": config.environment.surface_m}}
    return truth_from_rows(rows, t, seg, [s.label for s in track.segments], meta)


class Departure(NamedTuple):
    """Where the aircraft is started: the track's start, its point and the heading it flies
    there, over the environment's surface."""

    start: Start                #: the track's start (its type, height, speed, launcher)
    lat_rad: float              #: geodetic latitude of the start point
    lon_rad: float              #: its longitude
    heading_rad: float          #: the heading flown from it, true
    surface_m: float            #: the terrain or sea-surface height under it, m

    def condition(self, h_m: float, tas_mps: float, pitch_rad: float,
                  gamma_rad: float = 0.0) -> P.InitialCondition:
        """JSBSim's initial condition at the start point on :attr:`heading_rad`, wings level."""
        return P.InitialCondition(lat_rad=self.lat_rad, lon_rad=self.lon_rad, h_m=h_m, tas_mps=tas_mps,
                                  yaw_rad=self.heading_rad, pitch_rad=pitch_rad, gamma_rad=gamma_rad,
                                  terrain_m=self.surface_m)


def _air_start(io, ap, limits, departure: Departure, dt) -> None:
    """Trimmed level flight: spin the motor up held, fly ``SETTLE_S`` under the autopilot to
    settle the trim, then re-initialise at the start point keeping motor, servos and loops."""
    alpha = math.radians(limits.trim_alpha_deg)
    start, heading = departure.start, departure.heading_rad
    h = start.alt_m

    def init(pitch):
        io.set_initial(departure.condition(h, start.speed_mps, pitch))

    init(alpha)
    io.set_hold_down(True)
    for _ in range(int(SPINUP_S / dt)):
        io.set_controls(0.0, 0.0, 0.0, limits.trim_throttle)
        io.run()
    io.set_hold_down(False)
    init(alpha)
    ap.alt_cmd, ap.climb_rate = h, 0.0
    ap.i_speed = limits.trim_throttle
    ap.i_climb = alpha
    for _ in range(int(SETTLE_S / dt)):
        r = io.read_row()
        ap.course_cmd = heading
        course = math.atan2(r[P.COL_VE], r[P.COL_VN])
        io.set_controls(*ap.step(dt, Sensed(r[P.COL_TAS], r[P.COL_H], -r[P.COL_VD], r[P.COL_ROLL],
                                            r[P.COL_PITCH], r[P.COL_P], r[P.COL_Q], r[P.COL_BETA], course)))
        io.run()
    r = io.read_row()
    if not math.isfinite(r[P.COL_ALPHA]) or abs(r[P.COL_H] - h) > 20.0:
        raise FlightError(f"could not trim at {h:g} m and {start.speed_mps:g} m/s", time_s=0.0)
    # start on the wanted course: keep the crab angle the settled flight needed in the wind
    crab = r[P.COL_YAW] - math.atan2(r[P.COL_VE], r[P.COL_VN])
    heading = heading + (crab + math.pi) % (2.0 * math.pi) - math.pi
    io.use_accurate_integrators()
    io.set_initial(departure._replace(heading_rad=heading).condition(
        h, start.speed_mps, r[P.COL_PITCH], gamma_rad=r[P.COL_PITCH] - r[P.COL_ALPHA]))


def _launch_prepare(io, ap, departure: Departure, dt) -> None:
    """On the launcher: motor at full power while held, then booster fired at t = 0."""
    start, heading = departure.start, departure.heading_rad
    pitch = math.radians(start.pitch_deg)
    io.set_initial(departure.condition(start.alt_m + start.launcher_height_m, 1.0, pitch, gamma_rad=pitch))
    io.set_hold_down(True)
    for _ in range(int(SPINUP_S / dt)):
        io.set_controls(0.0, 0.0, 0.0, 1.0)
        io.run()
    io.set_hold_down(False)
    io.use_accurate_integrators()
    io.run_ic()
    io.set_booster_n(start.booster_thrust_n)
    ap.pitch_hold = pitch
    ap.throttle_hold = 1.0
    ap.alt_cmd = start.alt_m + start.launcher_height_m
    ap.course_cmd = heading
