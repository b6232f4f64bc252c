"""Segment behaviour: what each track segment commands the autopilot and when it ends.

A segment's start (its line, centre, targets, time-out; the checks that refuse what the
aircraft cannot fly) is Python, once per segment; its every step is compiled
(:func:`segment_update`), so that a fleet of aircraft steps in one call. The runner's state is
the float array ``x`` (:data:`SEGMENT_FIELDS`), read and written as attributes in Python.
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass, fields

import numpy as np

from navsim.flight.autopilot import (BANK_FF, CLIMB_RATE, COURSE_CMD, SPEED_CMD, SQUARE, ArrayField, Autopilot, G,
                                     line_course, orbit_course)
from navsim.flight.airframe import FixedWing
from navsim.flight.track import Segment
from navsim.foundations.compiled import njit
from navsim.foundations.errors import FlightError
from navsim.foundations.pymath import py_pow

TWO_PI = 2.0 * math.pi
_TURN_DONE_RAD = math.radians(2.0)     #: a turn ends within this of its final course


@dataclass
class State:
    """What the segments look at, SI: local north/east from the track origin, height, speeds.
    The kernels read it as an array of these fields in this order (:data:`STATE_FIELDS`)."""

    t: float = 0.0              #: time since the start of the track, s
    north: float = 0.0          #: m north of the track's origin
    east: float = 0.0           #: m east of it
    h: float = 0.0              #: geodetic height, m
    tas: float = 0.0            #: true airspeed, m/s
    ground_speed: float = 0.0   #: horizontal speed over the ground, m/s
    course: float = 0.0         #: course over the ground, rad from true north

    def array(self) -> np.ndarray:
        return np.array(astuple(self))


STATE_FIELDS = tuple(f.name for f in fields(State))
T, NORTH, EAST, H, TAS, GROUND_SPEED, COURSE = range(len(STATE_FIELDS))

#: the runner's state, one float each in this order: the segment's kind and end (codes below),
#: its start time and time-out, the line held, the speed ramp, and each kind's own figures
SEGMENT_FIELDS = ("kind", "end", "end_value", "t0", "timeout", "line_n0", "line_e0", "line_chi", "course_ref",
                  "speed_target", "speed_rate", "to_m", "sign", "angle", "rate", "bank", "chi0", "center_n",
                  "center_e", "radius", "lam", "phase", "swept", "length", "acceptance", "keeps_climb")
(KIND, END, END_VALUE, T0, TIMEOUT, LINE_N0, LINE_E0, LINE_CHI, COURSE_REF, SPEED_TARGET, SPEED_RATE, TO_M,
 SIGN, ANGLE, RATE, BANK, CHI0, CENTER_N, CENTER_E, RADIUS, LAM, PHASE, SWEPT, LENGTH, ACCEPTANCE,
 KEEPS_CLIMB) = range(len(SEGMENT_FIELDS))
#: the kinds' codes (climb and descend step alike)
KINDS = {"straight": 0, "speed": 1, "climb": 2, "descend": 2, "turn": 3, "circle": 4, "goto": 5}
STRAIGHT, SPEED, CLIMB, TURN, CIRCLE, GOTO = range(6)
#: how a straight or a circle ends, the first of its keys in this order: after laps (a circle),
#: after a time, at a time, after a distance (a straight)
ENDS = ("laps", "time_s", "until_s", "distance_m")
END_LAPS, END_TIME, END_UNTIL, END_DISTANCE = range(len(ENDS))
#: what :func:`segment_update` returns: go on, the segment is flown, its time-out passed
GOING, FLOWN, TIMED_OUT = range(3)
UNSTARTED = -1.0     #: a runner's ``kind`` before its first segment


@njit(cache=True)
def _start_line(x, s, chi: float) -> None:
    x[LINE_N0], x[LINE_E0], x[LINE_CHI] = s[NORTH], s[EAST], chi
    x[COURSE_REF] = chi


@njit(cache=True)
def _hold_line(g, ap, x, s) -> None:
    ap[COURSE_CMD] = line_course(g, s[NORTH], s[EAST], x[LINE_N0], x[LINE_E0], x[LINE_CHI])[0]
    ap[BANK_FF] = 0.0


@njit(cache=True)
def _along(x, s) -> float:
    chi = x[LINE_CHI]
    return math.cos(chi) * (s[NORTH] - x[LINE_N0]) + math.sin(chi) * (s[EAST] - x[LINE_E0])


@njit(cache=True)
def _straight_flown(g, ap, x, s) -> bool:
    _hold_line(g, ap, x, s)
    end = int(x[END])
    if end == END_TIME:
        return s[T] - x[T0] >= x[END_VALUE] - 1e-9
    if end == END_UNTIL:
        return s[T] >= x[END_VALUE] - 1e-9
    return _along(x, s) >= x[END_VALUE]


@njit(cache=True)
def _climb_flown(g, ap, x, s) -> bool:
    _hold_line(g, ap, x, s)
    if abs(s[H] - x[TO_M]) < 1.0:
        ap[CLIMB_RATE] = 0.0
        return True
    return False


@njit(cache=True)
def _turn_flown(ap, x, s) -> bool:
    turned = min(x[RATE] * (s[T] - x[T0]), x[ANGLE])
    ap[COURSE_CMD] = x[CHI0] + x[SIGN] * turned
    # feed-forward bank, faded out over the last ~2 s of the turn to roll out on course
    remaining = x[ANGLE] - turned
    ap[BANK_FF] = x[SIGN] * x[BANK] * min(1.0, remaining / (2.0 * x[RATE]))
    target = x[CHI0] + x[SIGN] * x[ANGLE]
    err = (target - s[COURSE] + math.pi) % TWO_PI - math.pi
    if turned >= x[ANGLE] and abs(err) < _TURN_DONE_RAD:
        _start_line(x, s, target)
        return True
    return False


@njit(cache=True)
def _circle_flown(g, ap, x, s) -> bool:
    cn, ce = x[CENTER_N], x[CENTER_E]
    ap[COURSE_CMD] = orbit_course(g, s[NORTH], s[EAST], cn, ce, x[RADIUS], x[LAM])[0]
    ap[BANK_FF] = x[LAM] * math.atan(py_pow(s[GROUND_SPEED], g[SQUARE:]) / (G * x[RADIUS]))
    phase = math.atan2(s[EAST] - ce, s[NORTH] - cn)
    x[SWEPT] += x[LAM] * ((phase - x[PHASE] + math.pi) % TWO_PI - math.pi)
    x[PHASE] = phase
    if int(x[END]) == END_LAPS:
        done = x[SWEPT] >= x[END_VALUE] * TWO_PI
    else:
        done = s[T] - x[T0] >= x[END_VALUE] - 1e-9
    if done:
        _start_line(x, s, s[COURSE])
    return done


@njit(cache=True)
def _goto_flown(g, ap, x, s) -> bool:
    _hold_line(g, ap, x, s)
    if _along(x, s) >= x[LENGTH] - x[ACCEPTANCE]:
        ap[CLIMB_RATE] = 0.0 if x[KEEPS_CLIMB] == 0.0 else ap[CLIMB_RATE]
        return True
    return False


@njit(cache=True)
def segment_update(g: np.ndarray, ap: np.ndarray, x: np.ndarray, s: np.ndarray, dt: float) -> int:
    """One step of the segment ``x`` (:data:`SEGMENT_FIELDS`) on the state ``s``
    (:data:`STATE_FIELDS`): the autopilot's commands ``ap`` refreshed in place (gains ``g``);
    returns :data:`FLOWN` when the segment is flown, :data:`TIMED_OUT` past its time-out, else
    :data:`GOING`."""
    if ap[SPEED_CMD] != x[SPEED_TARGET]:
        step = x[SPEED_RATE] * dt
        diff = x[SPEED_TARGET] - ap[SPEED_CMD]
        ap[SPEED_CMD] = x[SPEED_TARGET] if abs(diff) <= step else ap[SPEED_CMD] + math.copysign(step, diff)
    kind = int(x[KIND])
    if kind == STRAIGHT:
        done = _straight_flown(g, ap, x, s)
    elif kind == SPEED:
        _hold_line(g, ap, x, s)
        done = ap[SPEED_CMD] == x[SPEED_TARGET] and abs(s[TAS] - x[SPEED_TARGET]) < 0.3
    elif kind == CLIMB:
        done = _climb_flown(g, ap, x, s)
    elif kind == TURN:
        done = _turn_flown(ap, x, s)
    elif kind == CIRCLE:
        done = _circle_flown(g, ap, x, s)
    else:
        done = _goto_flown(g, ap, x, s)
    if done:
        return FLOWN
    return TIMED_OUT if s[T] - x[T0] > x[TIMEOUT] else GOING


class SegmentRunner:
    """Drives the autopilot through the segments of a track."""

    def __init__(self, segments, ap: Autopilot, limits: FixedWing, local_of_latlon):
        self.segments = list(segments)
        self.ap = ap
        self.limits = limits
        self.local_of_latlon = local_of_latlon
        self.x = np.zeros(len(SEGMENT_FIELDS))
        self.kind = UNSTARTED
        self.index = -1
        self.course_ref = ap.course_cmd
        self.line = (0.0, 0.0, ap.course_cmd)
        self.speed_target = ap.speed_cmd
        self.speed_rate = 0.5
        self.finished = False

    @property
    def line(self) -> tuple:
        """The line held: north and east of a point of it, its course."""
        return float(self.x[LINE_N0]), float(self.x[LINE_E0]), float(self.x[LINE_CHI])

    @line.setter
    def line(self, value) -> None:
        self.x[LINE_N0], self.x[LINE_E0], self.x[LINE_CHI] = value

    @property
    def center(self) -> tuple:
        """A circle's centre, north and east."""
        return float(self.x[CENTER_N]), float(self.x[CENTER_E])

    @center.setter
    def center(self, value) -> None:
        self.x[CENTER_N], self.x[CENTER_E] = value

    # --- life cycle ---------------------------------------------------------------------------
    def fail(self, reason: str, s: State) -> FlightError:
        seg = self.segments[self.index] if 0 <= self.index < len(self.segments) else None
        return FlightError(reason, segment=self.index if seg else None,
                           segment_label=seg.label if seg else None, time_s=s.t)

    def next(self, s: State) -> None:
        self.index += 1
        if self.index >= len(self.segments):
            self.finished = True
            return
        seg = self.segments[self.index]
        self.t0 = s.t
        if seg.speed_mps is not None:
            self._set_speed(seg.speed_mps, 0.5, s)
        getattr(self, "_begin_" + seg.type)(seg, s)
        self.kind = KINDS[seg.type]
        end = next((k for k in ENDS if k in seg.params), None)
        if end is not None:
            self.end, self.end_value = ENDS.index(end), seg[end]

    def update(self, s: State, dt: float) -> None:
        """Called every step: refresh the autopilot commands, end the segment when done."""
        self.step(s, segment_update(self.ap.gains, self.ap.x, self.x, s.array(), dt))

    def step(self, s: State, code: int) -> None:
        """Act on what :func:`segment_update` returned for this step: the next segment when this
        one is flown; FlightError past its time-out."""
        if code == FLOWN:
            self.next(s)
        elif code == TIMED_OUT:
            raise self.fail(f"segment not completed within its {self.timeout:.0f} s time-out "
                            "(the aircraft cannot fly it)", s)

    # --- helpers ------------------------------------------------------------------------------
    def _set_speed(self, speed: float, rate: float, s: State) -> None:
        lim = self.limits
        if not lim.min_speed_mps <= speed <= lim.max_speed_mps:
            raise self.fail(f"airspeed {speed:g} m/s outside the aircraft's range "
                            f"{lim.min_speed_mps:g}..{lim.max_speed_mps:g} m/s", s)
        self.speed_target, self.speed_rate = speed, rate

    def _start_line(self, s: State, chi: float) -> None:
        self.line = (s.north, s.east, chi)
        self.course_ref = chi

    # --- the segments' starts -----------------------------------------------------------------
    def _begin_straight(self, seg: Segment, s: State) -> None:
        self._start_line(s, self.course_ref)
        if "time_s" in seg.params:
            self.timeout = seg["time_s"] + 1.0
        elif "until_s" in seg.params:
            if seg["until_s"] <= s.t:
                raise self.fail(f"until_s {seg['until_s']:g} s is already past (t = {s.t:.1f} s)", s)
            self.timeout = seg["until_s"] - s.t + 1.0
        else:
            self.timeout = 3.0 * seg["distance_m"] / max(self.speed_target, 1.0) + 60.0

    def _begin_speed(self, seg: Segment, s: State) -> None:
        self._start_line(s, self.course_ref)
        self._set_speed(seg["to_mps"], seg["accel_mps2"], s)
        self.timeout = abs(seg["to_mps"] - s.tas) / seg["accel_mps2"] + 60.0

    def _begin_climb(self, seg: Segment, s: State) -> None:
        sign = 1.0 if seg.type == "climb" else -1.0
        target, rate = seg["to_m"], seg["rate_mps"]
        if (target - self.ap.alt_cmd) * sign <= 0.0:
            verb = "climb" if sign > 0 else "descend"
            raise self.fail(f"cannot {verb} to {target:g} m from {self.ap.alt_cmd:g} m "
                            f"(use {'descend' if sign > 0 else 'climb'})", s)
        if rate > self.limits.max_climb_mps:
            raise self.fail(f"rate {rate:g} m/s exceeds the aircraft's {self.limits.max_climb_mps:g} m/s", s)
        self._start_line(s, self.course_ref)
        self.ap.alt_cmd, self.ap.climb_rate = target, rate
        self.to_m = target
        self.timeout = 1.5 * abs(target - s.h) / rate + 60.0

    _begin_descend = _begin_climb

    def _begin_turn(self, seg: Segment, s: State) -> None:
        v = max(self.speed_target, 1.0)
        if "rate_dps" in seg.params:
            rate = math.radians(seg["rate_dps"])
            bank = math.atan(rate * v / G)
        else:
            bank = math.radians(seg["bank_deg"])
            rate = G * math.tan(bank) / v
        if math.degrees(bank) > self.limits.max_bank_deg:
            raise self.fail(f"a turn at {seg.get('rate_dps', 0):g} deg/s needs {math.degrees(bank):.0f} deg "
                            f"of bank, beyond the aircraft's {self.limits.max_bank_deg:g} deg", s)
        self.sign = 1.0 if seg["by_deg"] > 0 else -1.0
        self.angle = abs(math.radians(seg["by_deg"]))
        self.rate, self.bank = rate, bank
        self.chi0 = self.course_ref
        self.timeout = 1.5 * self.angle / rate + 30.0

    def _begin_circle(self, seg: Segment, s: State) -> None:
        lam = 1 if seg["direction"] == "right" else -1
        radius = seg["radius_m"]
        v = max(self.speed_target, s.ground_speed)
        r_min = v * v / (G * math.tan(math.radians(0.8 * self.limits.max_bank_deg)))
        if radius < r_min:
            raise self.fail(f"radius {radius:g} m is below the {r_min:.0f} m this aircraft can "
                            f"hold at {v:.1f} m/s", s)
        side = s.course + lam * 0.5 * math.pi
        self.center = (s.north + radius * math.cos(side), s.east + radius * math.sin(side))
        self.lam, self.radius = lam, radius
        self.phase = math.atan2(s.east - self.center[1], s.north - self.center[0])
        self.swept = 0.0
        if "laps" in seg.params:
            self.timeout = 1.5 * seg["laps"] * TWO_PI * radius / max(self.speed_target, 1.0) + 60.0
        else:
            self.timeout = seg["time_s"] + 1.0

    def _begin_goto(self, seg: Segment, s: State) -> None:
        if "north_m" in seg.params:
            tn, te = seg["north_m"], seg["east_m"]
        else:
            tn, te = self.local_of_latlon(math.radians(seg["lat_deg"]), math.radians(seg["lon_deg"]))
        dist = math.hypot(tn - s.north, te - s.east)
        chi = math.atan2(te - s.east, tn - s.north) if dist > 1e-6 else self.course_ref
        self._start_line(s, chi)
        self.length = dist
        self.acceptance, self.keeps_climb = seg["acceptance_m"], "alt_m" in seg.params
        if "alt_m" in seg.params:
            self.ap.alt_cmd, self.ap.climb_rate = seg["alt_m"], 2.0
        self.timeout = 3.0 * dist / max(self.speed_target, 1.0) + 120.0


for _i, _name in enumerate(SEGMENT_FIELDS):
    if _name not in ("line_n0", "line_e0", "line_chi", "center_n", "center_e"):
        setattr(SegmentRunner, _name, ArrayField(_i))
