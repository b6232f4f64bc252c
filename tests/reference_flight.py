"""The scalar Python autopilot, segment runner and watchdog: the reference the compiled
:mod:`navsim.flight.autopilot`, :mod:`navsim.flight.segments` and :mod:`navsim.flight.fleet` are
held to, bit for bit (the same algorithms, one aircraft and one step a call, as navsim flew them
before they were compiled)."""

import math

from navsim.flight import properties as P
from navsim.flight.autopilot import G, Gains, Sensed  # noqa: F401  (Sensed: what step takes)
from navsim.flight.fleet import MAX_PITCH_RAD, MAX_ROLL_RAD, STALL_PERSIST_S, WIND_PERSIST_S
from navsim.flight import segments
from navsim.flight.segments import TWO_PI, State  # noqa: F401
from navsim.flight.track import Segment  # noqa: F401


class Autopilot:
    """State of the loops (integrators) and the current commands.

    The guidance modes set ``course_cmd`` and ``bank_ff``; the vertical mode sets either an
    altitude to hold (``alt_cmd``) or a climb rate (``climb_cmd``) towards ``alt_cmd``.
    ``pitch_hold`` (rad) overrides the vertical loops (launch).
    """

    def __init__(self, gains: Gains | None = None):
        self.g = gains or Gains()
        self.speed_cmd = 14.0
        self.alt_cmd = 100.0
        self.climb_rate = 0.0          # >0: climb or descend to alt_cmd at this rate
        self.course_cmd = 0.0
        self.bank_ff = 0.0
        self.bank_cmd = 0.0
        self.pitch_cmd = 0.0
        self.pitch_hold: float | None = None
        self.throttle_hold: float | None = None
        self.i_speed = 0.0
        self.i_climb = 0.0
        self.i_pitch = 0.0
        self.i_roll = 0.0
        self.i_beta = 0.0
        self.idle = False

    def step(self, dt: float, s: "Sensed") -> tuple[float, float, float, float]:
        """One update of ``dt`` seconds on the aircraft's state ``s``; returns (elevator,
        aileron, rudder, throttle) normalised commands."""
        v = max(s.tas, 5.0)
        sched = min(max((self.g.v_ref_mps / v) ** 2, 0.3), 3.0)
        elev, climb_cmd = self._vertical(dt, s, v, sched)
        thr = self._throttle(dt, s, climb_cmd)
        ail, rud = self._lateral(dt, s, sched)
        return elev, ail, rud, thr

    def _vertical(self, dt: float, s: "Sensed", v: float, sched: float) -> tuple[float, float]:
        """Altitude -> climb rate -> pitch -> elevator: the elevator and the commanded climb rate."""
        g = self.g
        err_h = self.alt_cmd - s.h
        if self.climb_rate > 0.0:
            lim = self.climb_rate
        else:
            lim = g.climb_max_mps
        climb_cmd = min(max(g.k_alt * err_h, -lim), lim)
        over = s.tas - self.speed_cmd - g.overspeed_margin_mps
        if self.idle and climb_cmd < 0.0 and over > 0.0:
            # at idle throttle nothing else slows a descent: give up sink rate for speed
            climb_cmd = min(climb_cmd + g.k_overspeed * over, 0.0)
        err_climb = climb_cmd - s.climb
        gamma_ff = math.asin(min(max(climb_cmd / v, -0.5), 0.5))
        if self.pitch_hold is not None:
            pitch_cmd = self.pitch_hold
        else:
            pitch_cmd = gamma_ff + self.i_climb + g.kp_climb * err_climb
            if g.pitch_min_rad < pitch_cmd < g.pitch_max_rad:
                self.i_climb += g.ki_climb * err_climb * dt
            pitch_cmd = min(max(pitch_cmd, g.pitch_min_rad), g.pitch_max_rad)
        self.pitch_cmd = pitch_cmd
        err_pitch = pitch_cmd - s.pitch
        elev = -sched * (g.kp_pitch * err_pitch + self.i_pitch - g.kd_pitch * s.q)
        if -1.0 < elev < 1.0:
            self.i_pitch += g.ki_pitch * err_pitch * dt
        return min(max(elev, -1.0), 1.0), climb_cmd

    def _throttle(self, dt: float, s: "Sensed", climb_cmd: float) -> float:
        """Speed -> throttle (with the climb-rate feed-forward)."""
        g = self.g
        err_v = self.speed_cmd - s.tas
        if self.throttle_hold is not None:
            return self.throttle_hold
        thr = self.i_speed + g.kp_speed * err_v + g.ff_climb * climb_cmd
        if 0.0 < thr < 1.0 or (thr >= 1.0 and err_v < 0) or (thr <= 0.0 and err_v > 0):
            self.i_speed += g.ki_speed * err_v * dt
        self.idle = thr <= 0.0
        return min(max(thr, 0.0), 1.0)

    def _lateral(self, dt: float, s: "Sensed", sched: float) -> tuple[float, float]:
        """Course -> bank -> aileron, and sideslip -> rudder (turn coordination)."""
        g = self.g
        err_course = (self.course_cmd - s.course + math.pi) % (2.0 * math.pi) - math.pi
        bank_cmd = self.bank_ff + g.k_course * err_course
        bank_cmd = min(max(bank_cmd, -g.bank_max_rad), g.bank_max_rad)
        self.bank_cmd = bank_cmd
        err_roll = bank_cmd - s.roll
        ail = sched * (g.kp_roll * err_roll + self.i_roll - g.kd_roll * s.p)
        if -1.0 < ail < 1.0:
            self.i_roll += g.ki_roll * err_roll * dt
        ail = min(max(ail, -1.0), 1.0)
        rud = -sched * (g.kp_beta * s.beta + self.i_beta)
        if -1.0 < rud < 1.0:
            self.i_beta += g.ki_beta * s.beta * dt
        return ail, min(max(rud, -1.0), 1.0)


def line_course(g: Gains, north: float, east: float, n0: float, e0: float,
                chi_line: float) -> tuple[float, float]:
    """Course command and cross-track error (m, + right of the line) to follow the straight
    line through ``(n0, e0)`` with course ``chi_line``."""
    cross = -math.sin(chi_line) * (north - n0) + math.cos(chi_line) * (east - e0)
    return chi_line - g.chi_inf_rad * (2.0 / math.pi) * math.atan(g.k_path * cross), cross


def orbit_course(g: Gains, north: float, east: float, cn: float, ce: float, radius: float,
                 direction: int) -> tuple[float, float]:
    """Course command and radial error (m) to orbit ``(cn, ce)`` at ``radius``; ``direction``
    +1 clockwise (right turns), -1 anticlockwise."""
    d = math.hypot(north - cn, east - ce)
    phase = math.atan2(east - ce, north - cn)
    chi = phase + direction * (0.5 * math.pi + math.atan(g.k_orbit * (d - radius) / radius))
    return chi, d - radius


class SegmentRunner(segments.SegmentRunner):
    """navsim's runner (its segments' starts are Python still) stepping each segment in Python."""
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

    def _hold_line(self, s: State) -> None:
        n0, e0, chi = self.line
        g = self.ap.g
        self.ap.course_cmd, _ = line_course(g, s.north, s.east, n0, e0, chi)
        self.ap.bank_ff = 0.0

    def _along(self, s: State) -> float:
        n0, e0, chi = self.line
        return math.cos(chi) * (s.north - n0) + math.sin(chi) * (s.east - e0)

    def _update_straight(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        if "time_s" in seg.params:
            return s.t - self.t0 >= seg["time_s"] - 1e-9
        if "until_s" in seg.params:
            return s.t >= seg["until_s"] - 1e-9
        return self._along(s) >= seg["distance_m"]

    def _update_speed(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        return self.ap.speed_cmd == self.speed_target and abs(s.tas - self.speed_target) < 0.3

    def _update_climb(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        if abs(s.h - seg["to_m"]) < 1.0:
            self.ap.climb_rate = 0.0
            return True
        return False

    _update_descend = _update_climb

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

    def _update_goto(self, seg: Segment, s: State, dt: float) -> bool:
        self._hold_line(s)
        if self._along(s) >= self.length - seg["acceptance_m"]:
            self.ap.climb_rate = 0.0 if "alt_m" not in seg.params else self.ap.climb_rate
            return True
        return False

    _update_descend = _update_climb


class Watchdog:
    """The failure checks of every step, on the true state: NaN, ground or sea impact, stall
    (angle of attack above the stall for :data:`STALL_PERSIST_S`), loss of control, a steady
    wind above the airspeed (for :data:`WIND_PERSIST_S`: the aircraft cannot make way)."""

    def __init__(self, limits, dt: float):
        self.stall_alpha = math.radians(limits.stall_alpha_deg + 1.0)
        self.stall_steps = int(round(STALL_PERSIST_S / dt))
        self.wind_steps = int(round(WIND_PERSIST_S / dt))
        self.over_alpha = self.over_wind = 0

    def check(self, row, ground_ok: bool = False, stall_ok: bool = False) -> str | None:
        """The reason the flight failed at this ``row``, or None. ``ground_ok``: skip the
        impact check (on the launcher); ``stall_ok``: skip the stall check (booster phase)."""
        isfinite = math.isfinite
        if not (isfinite(row[P.COL_H]) and isfinite(row[P.COL_TAS]) and isfinite(row[P.COL_ROLL])):
            return "the state became NaN (numerical failure)"
        if row[P.COL_HAGL] < 0.5 and not ground_ok:
            return f"ground or sea impact (height above surface {row[P.COL_HAGL]:.1f} m)"
        if row[P.COL_ALPHA] > self.stall_alpha and not stall_ok:
            self.over_alpha += 1
            if self.over_alpha >= self.stall_steps:
                return (f"stall (angle of attack {math.degrees(row[P.COL_ALPHA]):.1f} deg "
                        f"at {row[P.COL_TAS]:.1f} m/s for {STALL_PERSIST_S:g} s)")
        else:
            self.over_alpha = 0
        if abs(row[P.COL_ROLL]) > MAX_ROLL_RAD or abs(row[P.COL_PITCH]) > MAX_PITCH_RAD:
            return (f"loss of control (roll {math.degrees(row[P.COL_ROLL]):.0f} deg, "
                    f"pitch {math.degrees(row[P.COL_PITCH]):.0f} deg)")
        return self._headwind(row)

    def _headwind(self, row) -> str | None:
        """The failure of a steady wind above the airspeed for :data:`WIND_PERSIST_S`, or None."""
        wind = math.hypot(row[P.COL_WSN], row[P.COL_WSE])
        if wind <= row[P.COL_TAS]:
            self.over_wind = 0
            return None
        self.over_wind += 1
        if self.over_wind < self.wind_steps:
            return None
        return (f"the steady wind ({wind:.1f} m/s) is above the airspeed ({row[P.COL_TAS]:.1f} m/s) "
                f"for {WIND_PERSIST_S:g} s: the aircraft cannot hold its track")
