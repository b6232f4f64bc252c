"""Segment behaviour: what each track segment commands the autopilot and when it ends."""

from __future__ import annotations

import math
from dataclasses import dataclass

from navsim.flight.airframe import FixedWing
from navsim.flight.autopilot import Autopilot, G, line_course, orbit_course
from navsim.flight.track import Segment
from navsim.foundations.errors import FlightError

TWO_PI = 2.0 * math.pi


@dataclass
class State:
    """What the segments look at, SI: local north/east from the track origin, height, speeds."""

    t: float = 0.0              #: time since the start of the track, s
    north: float = 0.0          #: m north of the track's origin
    east: float = 0.0           #: m east of it
    h: float = 0.0              #: geodetic height, m
    tas: float = 0.0            #: true airspeed, m/s
    ground_speed: float = 0.0   #: horizontal speed over the ground, m/s
    course: float = 0.0         #: course over the ground, rad from true north


class SegmentRunner:
    """Drives the autopilot through the segments of a track."""

    def __init__(self, segments, ap: Autopilot, limits: FixedWing, local_of_latlon):
        self.segments = list(segments)
        self.ap = ap
        self.limits = limits
        self.local_of_latlon = local_of_latlon
        self.index = -1
        self.course_ref = ap.course_cmd
        self.line = (0.0, 0.0, ap.course_cmd)
        self.speed_target = ap.speed_cmd
        self.speed_rate = 0.5
        self.finished = False

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
        self.n0, self.e0 = s.north, s.east
        if seg.speed_mps is not None:
            self._set_speed(seg.speed_mps, 0.5, s)
        getattr(self, "_begin_" + seg.type)(seg, s)

    def update(self, s: State, dt: float) -> None:
        """Called every step: refresh the autopilot commands, end the segment when done."""
        ap = self.ap
        if ap.speed_cmd != self.speed_target:
            step = self.speed_rate * dt
            diff = self.speed_target - ap.speed_cmd
            ap.speed_cmd = self.speed_target if abs(diff) <= step else ap.speed_cmd + math.copysign(step, diff)
        seg = self.segments[self.index]
        if getattr(self, "_update_" + seg.type)(seg, s, dt):
            self.next(s)
        elif s.t - self.t0 > self.timeout:
            raise self.fail(f"segment not completed within its {self.timeout:.0f} s time-out "
                            "(the aircraft cannot fly it)", s)

    # --- helpers ------------------------------------------------------------------------------
    def _set_speed(self, speed: float, rate: float, s: State) -> None:
        lim = self.limits
        if not lim.min_speed_mps <= speed <= lim.max_speed_mps:
            raise self.fail(f"airspeed {speed:g} m/s outside the aircraft's range "
                            f"{lim.min_speed_mps:g}..{lim.max_speed_mps:g} m/s", s)
        self.speed_target, self.speed_rate = speed, rate

    def _hold_line(self, s: State) -> None:
        n0, e0, chi = self.line
        g = self.ap.g
        self.ap.course_cmd, _ = line_course(g, s.north, s.east, n0, e0, chi)
        self.ap.bank_ff = 0.0

    def _start_line(self, s: State, chi: float) -> None:
        self.line = (s.north, s.east, chi)
        self.course_ref = chi

    def _along(self, s: State) -> float:
        n0, e0, chi = self.line
        return math.cos(chi) * (s.north - n0) + math.sin(chi) * (s.east - e0)

    # --- straight -----------------------------------------------------------------------------
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

    def _update_straight(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        if "time_s" in seg.params:
            return s.t - self.t0 >= seg["time_s"] - 1e-9
        if "until_s" in seg.params:
            return s.t >= seg["until_s"] - 1e-9
        return self._along(s) >= seg["distance_m"]

    # --- speed change -------------------------------------------------------------------------
    def _begin_speed(self, seg: Segment, s: State) -> None:
        self._start_line(s, self.course_ref)
        self._set_speed(seg["to_mps"], seg["accel_mps2"], s)
        self.timeout = abs(seg["to_mps"] - s.tas) / seg["accel_mps2"] + 60.0

    def _update_speed(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        return self.ap.speed_cmd == self.speed_target and abs(s.tas - self.speed_target) < 0.3

    # --- climb / descend ----------------------------------------------------------------------
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
        self.timeout = 1.5 * abs(target - s.h) / rate + 60.0

    _begin_descend = _begin_climb

    def _update_climb(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        if abs(s.h - seg["to_m"]) < 1.0:
            self.ap.climb_rate = 0.0
            return True
        return False

    _update_descend = _update_climb

    # --- turn ---------------------------------------------------------------------------------
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

    def _update_turn(self, seg: Segment, s: State, dt: float) -> bool:
        turned = min(self.rate * (s.t - self.t0), self.angle)
        ap = self.ap
        ap.course_cmd = self.chi0 + self.sign * turned
        # feed-forward bank, faded out over the last ~2 s of the turn to roll out on course
        remaining = self.angle - turned
        ap.bank_ff = self.sign * self.bank * min(1.0, remaining / (2.0 * self.rate))
        target = self.chi0 + self.sign * self.angle
        err = (target - s.course + math.pi) % TWO_PI - math.pi
        if turned >= self.angle and abs(err) < math.radians(2.0):
            self._start_line(s, target)
            return True
        return False

    # --- circle -------------------------------------------------------------------------------
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

    def _update_circle(self, seg: Segment, s: State, dt: float) -> bool:
        cn, ce = self.center
        ap = self.ap
        ap.course_cmd, _ = orbit_course(ap.g, s.north, s.east, cn, ce, self.radius, self.lam)
        ap.bank_ff = self.lam * math.atan(s.ground_speed ** 2 / (G * self.radius))
        phase = math.atan2(s.east - ce, s.north - cn)
        self.swept += self.lam * ((phase - self.phase + math.pi) % TWO_PI - math.pi)
        self.phase = phase
        if "laps" in seg.params:
            done = self.swept >= seg["laps"] * TWO_PI
        else:
            done = s.t - self.t0 >= seg["time_s"] - 1e-9
        if done:
            self._start_line(s, s.course)
        return done

    # --- go to a waypoint ---------------------------------------------------------------------
    def _begin_goto(self, seg: Segment, s: State) -> None:
        if "north_m" in seg.params:
            tn, te = seg["north_m"], seg["east_m"]
        else:
            tn, te = self.local_of_latlon(math.radians(seg["lat_deg"]), math.radians(seg["lon_deg"]))
        dist = math.hypot(tn - s.north, te - s.east)
        chi = math.atan2(te - s.east, tn - s.north) if dist > 1e-6 else self.course_ref
        self._start_line(s, chi)
        self.length = dist
        if "alt_m" in seg.params:
            self.ap.alt_cmd, self.ap.climb_rate = seg["alt_m"], 2.0
        self.timeout = 3.0 * dist / max(self.speed_target, 1.0) + 120.0

    def _update_goto(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        if self._along(s) >= self.length - seg["acceptance_m"]:
            self.ap.climb_rate = 0.0 if "alt_m" not in seg.params else self.ap.climb_rate
            return True
        return False
