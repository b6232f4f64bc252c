"""A multirotor flown in JSBSim: its segments as setpoints, its motors commanded by the cascade
controller of :mod:`navsim.flight.multirotor`, its mixer derived from the rotor table of its
``navsim.yaml`` (:class:`~navsim.flight.airframe.Multirotor`).

:func:`fly_rotorcraft` is what :func:`navsim.flight.simulator.fly` runs for an aircraft of class
``multirotor``: started hovering at the track's start (``start: {type: hover}``) or standing on
the surface on its wheels or skids (``start: {type: ground}`` and a ``takeoff`` first), the
motors' thrust map calibrated first with the airframe held (JSBSim's thrust at the declared hover
throttle, per command squared), then the segments flown on the true state (``takeoff``: a point
rising from where it stands; ``hover``: hold the point; ``goto``: a point moving along the line
at the segment's speed; ``circle``: a point moving round the circle; ``land``: a point sinking
into the surface, the motors stopped when a wheel or skid first carries weight), each step
checked for NaN, impact (but in a takeoff or a landing) and loss of control.

Segments chain on the commanded point, not on where the vehicle happens to be: a segment starts
where the one before left its setpoint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.flight import properties as P
from navsim.flight.airframe import ENVELOPE_FILE, Multirotor, Rotor, model_location
from navsim.flight.environment import Environment, steady_wind_n_mps
from navsim.flight.multirotor import (GRAVITY_MPS2, Mixer, MultirotorController, MultirotorGains, MultirotorState,
                                      Setpoint, YawMode)
from navsim.flight.multirotor import Rotor as MixerRotor
from navsim.flight.track import MULTIROTOR_SPEED_MPS, Segment, Track
from navsim.foundations.earth import radii
from navsim.foundations.errors import FlightError, ScenarioError
from navsim.foundations.transform import dcm_from_euler_one

CALIBRATION_S = 1.0          #: seconds the motors run at the hover throttle, airframe held
MAX_TILT_FAIL_RAD = math.radians(70.0)   #: roll or pitch beyond this is a loss of control
MIN_AGL_M = 0.3              #: lower than this above the surface is an impact (the skids' height)
#: a goto's moving point and a circle's reach their speed, and stop at a leg's end, at this
#: acceleration, m/s^2
SETPOINT_ACCEL_MPS2 = 1.0
ZERO3 = (0.0, 0.0, 0.0)
#: a landing's point sinks at its rate until a wheel or skid carries weight, as an autopilot
#: descends at its landing speed until its land detector trips (not to a height, which a
#: navigation solution off by a few metres would put above or below the ground); it fails when
#: its point is this far below where the vehicle would stand on the surface, m
LAND_BELOW_M = 20.0
#: the motors stop at touchdown; a landing ends this long after it, s
SETTLE_S = 1.0
#: the least steady wind a multirotor flies JSBSim's turbulence in, m/s (:func:`check_environment`)
MIN_TURBULENCE_WIND_MPS = 3.0


def mixer_rotor(rotor: Rotor, thrust_per_cmd2_n: float) -> MixerRotor:
    """The mixer's view of an airframe rotor: its thrust axis (tilted ``tilt_deg`` about its arm,
    the horizontal line from the centre of gravity out to the rotor), its spin about that axis
    (an airframe's +1, clockwise seen from above, turns left-handed about the upward thrust),
    the drag torque per thrust ``torque_coefficient / thrust_coefficient`` and the command map."""
    x, y, _ = rotor.position_m
    az, tilt = math.atan2(y, x), math.radians(rotor.tilt_deg)
    axis = (-math.sin(tilt) * math.sin(az), math.sin(tilt) * math.cos(az), -math.cos(tilt))
    return MixerRotor(pos_b_m=tuple(rotor.position_m), spin=-rotor.spin, thrust_per_cmd2_n=thrust_per_cmd2_n,
                      torque_per_thrust_m=rotor.torque_coefficient / rotor.thrust_coefficient, axis_b=axis)


def check_environment(env: Environment, file: str | None = None, track: Track | None = None) -> None:
    """Refuse JSBSim's turbulence on a multirotor in a steady wind (at the start, or one of its
    ``wind_changes``) below :data:`MIN_TURBULENCE_WIND_MPS`: its models carry a frozen gust field
    past the vehicle at its airspeed, which a hover has only from the wind (in calm air a hover
    would see none). A ``track`` starting on the ground must stand on the surface.

    Raises
    ------
    ScenarioError
        Naming ``file`` and ``environment.turbulence``.
    """
    # the calmest steady wind of the flight: its start's, or one it changes to
    if track is not None and takes_off(track) and abs(track.start.alt_m - env.surface_m) > 0.01:
        raise ScenarioError(f"a multirotor standing at {track.start.alt_m:g} m on a surface at {env.surface_m:g} m",
                            file=file, key="track.start.alt_m",
                            expected="the surface's height (environment.surface_m): it stands on it to take off")
    wind = min(math.hypot(w[0], w[1]) for w in (env.wind_n_mps, *(w for _, w in env.wind_changes)))
    if env.turbulence != "none" and wind < MIN_TURBULENCE_WIND_MPS:
        raise ScenarioError(f"'{env.turbulence}' turbulence in a {wind:g} m/s wind on a multirotor", file=file,
                            key="environment.turbulence",
                            expected=f"a steady wind of at least {MIN_TURBULENCE_WIND_MPS:g} m/s with it: JSBSim's "
                                     "turbulence is a gust field carried past the vehicle at its airspeed, which a "
                                     "hovering multirotor has only from the wind")


def takes_off(track: Track) -> bool:
    """Whether ``track`` starts standing on the ground and takes off (a ``ground`` start whose
    first segment is a ``takeoff``; one of ``hold`` segments is parked, with no dynamics)."""
    return track.start.type == "ground" and track.segments[0].type == "takeoff"


def circle_tilt_rad(speed_mps: float, radius_m: float) -> float:
    """The tilt a circle at ``speed_mps`` of ``radius_m`` needs in calm air (its centripetal
    acceleration over gravity)."""
    return math.atan(speed_mps ** 2 / (radius_m * GRAVITY_MPS2))


def check_envelope(track: Track, airframe: Multirotor, file: str | None = None) -> None:
    """Refuse a multirotor track that asks its airframe for more than its envelope: a speed above
    ``max_speed_mps``, a circle needing more tilt than ``max_tilt_deg`` (in calm air: a wind asks
    more, and fails the flight, exit 3).

    Raises
    ------
    ScenarioError
        Naming ``file``, the segment's key and the limit.
    """
    speed = track.start.speed_mps or MULTIROTOR_SPEED_MPS
    for i, seg in enumerate(track.segments):
        speed = seg.speed_mps or speed
        key = f"track.segments[{i}]"
        if seg.type == "hover":                  # it does not move: its speed is the next ones'
            continue
        if speed > airframe.max_speed_mps:
            raise ScenarioError(f"flies at {speed:g} m/s", file=file, key=f"{key}.speed_mps",
                                expected=f"at most the aircraft's max_speed_mps ({airframe.max_speed_mps:g} m/s)")
        if seg.type == "circle" and circle_tilt_rad(speed, seg["radius_m"]) > math.radians(airframe.max_tilt_deg):
            raise ScenarioError(
                f"a {seg['radius_m']:g} m circle at {speed:g} m/s needs a "
                f"{math.degrees(circle_tilt_rad(speed, seg['radius_m'])):.0f} deg tilt", file=file, key=f"{key}.radius_m",
                expected=f"at most the aircraft's max_tilt_deg ({airframe.max_tilt_deg:g} deg): a wider circle or a lower speed")


class Rotorcraft:
    """One JSBSim multirotor hovering at its track's start or standing there, its controller
    built: ready to step."""

    def __init__(self, config, airframe: Multirotor):
        track, env = config.track, config.environment
        check_environment(env, track=track)
        self.config, self.airframe, self.dt = config, airframe, 1.0 / config.rate_hz
        model, model_dir = model_location(config.folder, airframe)
        self.io = io = P.JSBSimIO(model, self.dt, model_dir)
        start = track.start
        self.lat0, self.lon0 = math.radians(start.lat_deg), math.radians(start.lon_deg)
        r_m, r_n = radii(self.lat0)
        self.k_north, self.k_east = float(r_m), float(r_n) * math.cos(self.lat0)
        self.h0 = start.alt_m
        file = str(config.folder / ENVELOPE_FILE)
        self._place(start, env, file)
        self.n = len(airframe.rotors)
        if io.engine_count() != self.n:
            raise ScenarioError(f"the model has {io.engine_count()} engines, the rotor table {self.n} rotors", file=file,
                                key="rotors", expected="one rotor per JSBSim engine, in the model's engine order")
        self.set_commands = self._properties(io.rotor_commands, "command", file)
        self.read_rpm = self._properties(io.rotor_rpm, "rpm", file)
        k = self._calibrate(airframe.hover_throttle)
        if not k > 0.0:
            raise ScenarioError(f"the model's {self.n} engines give no thrust at hover_throttle {airframe.hover_throttle:g}",
                                file=file, key="rotors", expected="one JSBSim engine (a thruster) per rotor of the table")
        mass_kg, inertia = io.mass_properties()
        try:
            mixer = Mixer.from_rotors([mixer_rotor(r, k) for r in airframe.rotors])
        except ValueError as exc:            # fewer than 4 rotors, or a wrench they cannot make
            raise ScenarioError(str(exc), file=file, key="rotors",
                                expected="rotors whose thrusts and torques make any thrust, roll, pitch and yaw") from None
        gains = MultirotorGains(max_tilt_rad=math.radians(airframe.max_tilt_deg), max_climb_mps=airframe.max_climb_mps,
                                max_sink_mps=airframe.max_descent_mps)
        self.controller = MultirotorController(mixer, mass_kg, inertia, gains)
        io.use_accurate_integrators()
        if env.turbulence != "none":          # after the calibration, which it would disturb
            io.set_turbulence(env.turbulence, env.turbulence_wind20_mps, env.turbulence_severity,
                              env.turbulence_seed)
        io.run_ic()

    def _place(self, start, env: Environment, file: str) -> None:
        """Start still: hovering at the start's height, or (a ``ground`` start) standing on the
        surface on the model's lowest contacts. Sets :attr:`ground_down_m`, the down coordinate
        (from the start's height) of the centre of gravity standing on the surface."""
        io = self.io
        self.rest_m = rest_m = io.rest_height_m()
        standing = takes_off(self.config.track)
        grounded = [seg.type for seg in self.config.track.segments if seg.type in ("takeoff", "land")]
        if grounded and rest_m is None:
            raise ScenarioError(f"the model has no wheel or skid (JSBSim BOGEY contact): it cannot {grounded[0]}",
                                file=file, expected="a model with landing gear, or a track without takeoff or land")
        self.ground_down_m = self.h0 - env.surface_m - (rest_m or 0.0)
        io.set_terrain(env.surface_m)
        io.set_wind_ned(env.wind_n_mps)
        io.set_initial(P.InitialCondition(lat_rad=self.lat0, lon_rad=self.lon0,
                                          h_m=env.surface_m + rest_m if standing else start.alt_m, tas_mps=0.0,
                                          yaw_rad=math.radians(start.heading_deg), pitch_rad=0.0,
                                          terrain_m=env.surface_m), still=True)

    def _properties(self, bind, key: str, file: str):
        """``bind`` (a :class:`~navsim.flight.properties.JSBSimIO` method) over the rotors'
        property ``key``; a property the model lacks refused naming the rotor's key."""
        names = [getattr(r, key) for r in self.airframe.rotors]
        try:
            return bind(names)
        except KeyError as exc:
            i = names.index(exc.args[0])
            raise ScenarioError(f"the model has no property '{names[i]}'", file=file, key=f"rotors[{i}].{key}",
                                expected="a property of the JSBSim model (its flight control system's input, "
                                         "or the default of aircraft/README.md)") from None

    def _calibrate(self, u: float) -> float:
        """Thrust per command squared of one rotor (N): the motors held at ``u`` for
        :data:`CALIBRATION_S`, the airframe re-placed at its start every step."""
        self.set_commands([u] * self.n)
        for _ in range(int(round(CALIBRATION_S / self.dt))):
            self.io.run()
            self.io.run_ic()
        return self.io.rotor_thrust_n() / (self.n * u * u)

    def state(self, row) -> MultirotorState:
        """The controller's state of a JSBSim row (:data:`~navsim.flight.properties.RAW_PROPERTIES`)."""
        return MultirotorState(
            np.array([(row[P.COL_LAT] - self.lat0) * self.k_north, (row[P.COL_LON] - self.lon0) * self.k_east,
                      self.h0 - row[P.COL_H]]),
            np.array([row[P.COL_VN], row[P.COL_VE], row[P.COL_VD]]),
            dcm_from_euler_one(row[P.COL_ROLL], row[P.COL_PITCH], row[P.COL_YAW]),
            np.array([row[P.COL_P], row[P.COL_Q], row[P.COL_R]]))

    def local_of_latlon(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """North and east (m) of a latitude and longitude (deg) from the start."""
        return ((math.radians(lat_deg) - self.lat0) * self.k_north, (math.radians(lon_deg) - self.lon0) * self.k_east)


@dataclass
class _Leg:
    """The moving point of a segment: from ``origin`` (NED, m) along a line or round a circle."""

    origin: np.ndarray
    end: np.ndarray | None = None          #: a line's end
    center: np.ndarray | None = None       #: a circle's centre
    sense: float = 1.0                     #: +1 clockwise seen from above (right), -1 left
    length_m: float = 0.0                  #: the way to go (a line's length, a circle's arc)
    speed_cap_mps: float = math.inf        #: a line's speed at the climb or descent limit
    travelled_m: float = 0.0
    speed_mps: float = 0.0                 #: the moving point's speed now
    vertical: bool = False                 #: a takeoff's or a landing's: at ``speed_cap_mps``, not the segments' speed


class RotorSegments:
    """The setpoints of a multirotor's segments, one per step, and when each ends."""

    def __init__(self, track: Track, craft: Rotorcraft):
        self.segments, self.craft = list(track.segments), craft
        self.speed_mps = track.start.speed_mps or MULTIROTOR_SPEED_MPS
        self.heading_rad = math.radians(track.start.heading_deg)   # the nose's, a `yaw: hold` keeps
        self.course_rad = self.heading_rad     # the way flown last: a circle is centred to its side
        self.point = np.array([0.0, 0.0, craft.ground_down_m if takes_off(track) else 0.0])
        self.index, self.finished, self.t0 = -1, False, 0.0
        self.leg: _Leg | None = None
        self.yaw = YawMode("heading", heading_rad=self.heading_rad)   # the segment's (set by next)
        #: the time a landing touched down (its motors stopped since), None in the air
        self.landed_s: float | None = None

    def fail(self, reason: str, t: float) -> FlightError:
        seg = self.segments[self.index] if 0 <= self.index < len(self.segments) else None
        return FlightError(reason, segment=self.index if seg else None, segment_label=seg.label if seg else None,
                           time_s=t)

    def next(self, t: float) -> None:
        """Begin the next segment at time ``t`` (or finish)."""
        self.index += 1
        self.finished = self.index >= len(self.segments)
        if self.finished:
            return
        seg, self.t0 = self.segments[self.index], t
        if self.craft.controller.heading_rad is not None:
            self.heading_rad = self.craft.controller.heading_rad
        speed = seg.speed_mps or self.speed_mps
        if speed > self.craft.airframe.max_speed_mps and seg.type != "hover":
            raise self.fail(f"speed {speed:g} m/s above the aircraft's max_speed_mps "
                            f"({self.craft.airframe.max_speed_mps:g} m/s)", t)
        self.speed_mps = speed
        if seg.type in ("takeoff", "land"):
            self.leg = self._vertical(seg)
        else:
            self.leg = None if seg.type == "hover" else (self._line(seg) if seg.type == "goto" else self._circle(seg, t))
        self.yaw = self._yaw(seg)          # the nose's mode: fixed over the segment

    def _vertical(self, seg: Segment) -> _Leg:
        """A takeoff's climb from the ground to ``agl_m``, or a landing's descent to (and
        on through, :data:`LAND_BELOW_M`) the surface, at the segment's rate within the airframe's."""
        af, craft = self.craft.airframe, self.craft
        if seg.type == "takeoff":
            if seg["agl_m"] < craft.rest_m + MIN_AGL_M:
                raise self.fail(f"a takeoff to {seg['agl_m']:g} m, where the aircraft stands at {craft.rest_m:.2f} m "
                                f"(at least {craft.rest_m + MIN_AGL_M:.2f} m over the surface)", self.t0)
            self.landed_s = None
            craft.controller.reset()                    # nothing learned on the ground
            down, rate = craft.h0 - craft.config.environment.surface_m - seg["agl_m"], min(seg["rate_mps"], af.max_climb_mps)
        else:
            down, rate = craft.ground_down_m + LAND_BELOW_M, min(seg["rate_mps"], af.max_descent_mps)
        if seg.type == "takeoff":                       # from where it stands, not where a landing pressed
            self.point[2] = min(self.point[2], craft.ground_down_m)
        end = np.array([self.point[0], self.point[1], down])
        return _Leg(origin=self.point.copy(), end=end, length_m=abs(down - self.point[2]), speed_cap_mps=rate,
                    vertical=True)

    def touchdown(self, t: float, on_ground: bool) -> None:
        """During a landing: the time a ground contact first carries weight, from which its
        motors stop (as an autopilot's land detector disarms: flying on, the attitude loop
        would fight the contacts' forces and rock it)."""
        if self.landed_s is None and on_ground:
            self.landed_s = t

    def _line(self, seg: Segment) -> _Leg:
        if "north_m" in seg.params:
            north, east = seg["north_m"], seg["east_m"]
        else:
            north, east = self.craft.local_of_latlon(seg["lat_deg"], seg["lon_deg"])
        down = self.craft.h0 - seg["alt_m"] if "alt_m" in seg.params else self.point[2]
        end = np.array([north, east, down])
        way = end - self.point
        length = float(np.linalg.norm(way))
        if math.hypot(way[0], way[1]) > 0.1:
            self.course_rad = math.atan2(way[1], way[0])
        # the climb or descent along the line held to the airframe's limits
        af, sine = self.craft.airframe, abs(way[2]) / max(length, 1e-9)
        cap = (af.max_descent_mps if way[2] > 0 else af.max_climb_mps) / sine if sine > 0 else math.inf
        return _Leg(origin=self.point.copy(), end=end, length_m=length, speed_cap_mps=cap)

    def _circle(self, seg: Segment, t: float) -> _Leg:
        """Centred ``radius_m`` to the side of the way flown last (right for ``direction: right``):
        the last goto's direction, the start's heading before any."""
        sense = 1.0 if seg["direction"] == "right" else -1.0
        side = self.course_rad + sense * math.pi / 2.0
        r = seg["radius_m"]
        tilt = circle_tilt_rad(self.speed_mps, r)
        if tilt > math.radians(self.craft.airframe.max_tilt_deg):
            raise self.fail(f"a {r:g} m circle at {self.speed_mps:g} m/s needs a {math.degrees(tilt):.0f} deg tilt "
                            f"beyond the aircraft's max_tilt_deg ({self.craft.airframe.max_tilt_deg:g} deg)", t)
        center = self.point + r * np.array([math.cos(side), math.sin(side), 0.0])
        arc = 2.0 * math.pi * r * seg["laps"] if "laps" in seg.params else math.inf
        return _Leg(origin=self.point.copy(), center=center, sense=sense, length_m=arc)

    def setpoint(self, t: float, dt: float) -> Setpoint:
        """The setpoint at time ``t``; moves to the next segment when this one is done."""
        seg = self.segments[self.index]
        leg = self.leg
        vel = acc = ZERO3
        if leg is not None:
            left = leg.length_m - leg.travelled_m          # slowing to stop at a leg's end
            leg.speed_mps = min(leg.speed_cap_mps if leg.vertical else min(self.speed_mps, leg.speed_cap_mps),
                                leg.speed_mps + SETPOINT_ACCEL_MPS2 * dt,
                                math.sqrt(2.0 * SETPOINT_ACCEL_MPS2 * left) if left < math.inf else math.inf)
            leg.travelled_m = min(leg.travelled_m + leg.speed_mps * dt, leg.length_m)
            self.point, vel, acc = self._along(leg)
            vel, acc = vel.tolist(), acc.tolist()
        if seg.type == "land":
            done = self.landed_s is not None and t - self.landed_s >= SETTLE_S
            if self.landed_s is None and leg.travelled_m >= leg.length_m:
                raise self.fail(f"no touchdown: the landing's point is {LAND_BELOW_M:g} m below the surface", t)
        else:
            done = (t - self.t0 >= seg["time_s"] - 1e-9) if "time_s" in seg.params else leg.travelled_m >= leg.length_m
        yaw = self.yaw
        turning = leg is not None and leg.center is not None and yaw.kind != "heading"
        sp = Setpoint(pos_n_m=tuple(self.point.tolist()), vel_n_mps=tuple(vel), acc_n_mps2=tuple(acc),
                      speed_max_mps=self.speed_mps + 1.0, yaw=yaw,
                      # round a circle the course and the bearing of its centre turn at v / r
                      yaw_rate_rps=leg.sense * leg.speed_mps / self._radius(leg) if turning else 0.0)
        if done:
            self.next(t)
        return sp

    def _along(self, leg: _Leg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The moving point, its velocity and (round a circle) its centripetal acceleration."""
        if leg.end is not None:
            u = (leg.end - leg.origin) / max(leg.length_m, 1e-9)
            return leg.origin + leg.travelled_m * u, leg.speed_mps * u * (leg.travelled_m < leg.length_m), np.zeros(3)
        r_vec = leg.origin - leg.center
        r = self._radius(leg)
        a = math.atan2(r_vec[1], r_vec[0]) + leg.sense * leg.travelled_m / r
        radial = np.array([math.cos(a), math.sin(a), 0.0])
        tangent = leg.sense * np.array([-math.sin(a), math.cos(a), 0.0])
        return leg.center + r * radial, leg.speed_mps * tangent, -(leg.speed_mps ** 2 / r) * radial

    @staticmethod
    def _radius(leg: _Leg) -> float:
        """A circle's radius (its start's distance from the centre), m."""
        return math.hypot(leg.origin[0] - leg.center[0], leg.origin[1] - leg.center[1])

    @property
    def near_ground(self) -> bool:
        """Whether the segment flown (or the last one, the track flown) is a takeoff or a
        landing, which touch the ground."""
        i = min(self.index, len(self.segments) - 1)
        return i >= 0 and self.segments[i].type in ("takeoff", "land")

    def _yaw(self, seg: Segment) -> YawMode:
        mode = seg.get("yaw") or ("course" if seg.type in ("goto", "circle") else "hold")
        if "heading_deg" in seg.params:
            return YawMode("heading", heading_rad=math.radians(seg["heading_deg"]))
        if mode == "center":
            return YawMode("point", target_n_m=tuple(self.leg.center))
        return YawMode("course") if mode == "course" else YawMode("heading", heading_rad=self.heading_rad)


def check_row(row, t: float, segments: RotorSegments) -> None:
    """The failure checks of a step on the true state: NaN, impact (but in a takeoff or a
    landing, which touch the ground), loss of control."""
    if not (math.isfinite(row[P.COL_H]) and math.isfinite(row[P.COL_ROLL])):
        raise segments.fail("the state became NaN (numerical failure)", t)
    if row[P.COL_HAGL] < MIN_AGL_M and not segments.near_ground:
        raise segments.fail(f"ground impact (height above surface {row[P.COL_HAGL]:.1f} m)", t)
    if abs(row[P.COL_ROLL]) > MAX_TILT_FAIL_RAD or abs(row[P.COL_PITCH]) > MAX_TILT_FAIL_RAD:
        raise segments.fail(f"loss of control (roll {math.degrees(row[P.COL_ROLL]):.0f} deg, "
                            f"pitch {math.degrees(row[P.COL_PITCH]):.0f} deg)", t)


def fly_rotorcraft(config, airframe: Multirotor, record, progress=None, nominal_s: float = 0.0) -> Rotorcraft:
    """Fly ``config``'s track with the multirotor ``airframe``, each step's row (its properties,
    then its rotors' speeds in r/min) given to ``record(row, segment)``; ``progress(t_s,
    nominal_s)`` about once per simulated second. Returns the craft. Raises FlightError."""
    craft = Rotorcraft(config, airframe)
    segments = RotorSegments(config.track, craft)
    io, dt, ctrl = craft.io, craft.dt, craft.controller
    read_rpm = craft.read_rpm
    env = config.environment
    wind_changes = bool(env.wind_changes)
    segments.next(0.0)
    stopped = [0.0] * craft.n
    k, next_progress = 0, 0.0
    while True:
        t = k * dt
        row = io.read_row()
        check_row(row, t, segments)
        index = segments.index
        if segments.finished:
            return craft
        setpoint = segments.setpoint(t, dt)
        record(row + read_rpm(), index)
        if progress is not None and t >= next_progress:
            progress(t, nominal_s)
            next_progress += 1.0
        if not segments.finished and segments.segments[segments.index].type == "land":
            segments.touchdown(t, io.on_ground())
        if segments.landed_s is None:
            craft.set_commands(ctrl.command(craft.state(row), setpoint, dt))
        else:                                       # landed: the motors stopped
            craft.set_commands(stopped)
        if wind_changes:
            io.set_wind_ned(steady_wind_n_mps(env, t + dt))
        io.run()
        k += 1
