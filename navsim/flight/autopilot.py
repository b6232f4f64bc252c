"""Closed-loop autopilot and lateral guidance, in scalar Python for the 100 Hz loop.

Loops (all commands normalised, surfaces -1..1 map to +/-25 deg):

* airspeed -> throttle: PI plus a climb-rate feed-forward;
* altitude -> climb rate (P, limited) -> pitch (PI plus flight-path feed-forward) -> elevator
  (PID on pitch with pitch-rate damping);
* course -> bank (P plus the bank feed-forward of the guidance) -> aileron (PI plus roll-rate
  damping);
* sideslip -> rudder (PI): turn coordination.

Surface gains are scheduled with dynamic pressure, ``(V_ref / V)^2``, so the loops keep their
bandwidth from 10 to 25 m/s. Lateral guidance is the vector-field path following of Beard and
McLain (*Small Unmanned Aircraft*, 2012, ch. 10): straight lines and orbits.

Gains are documented in :class:`Gains`; they were tuned on ``survey10`` for a roll bandwidth near
3 rad/s, a pitch bandwidth near 3 rad/s, a climb-rate loop near 0.5 rad/s, altitude 0.3 rad/s,
course 0.4 rad/s and airspeed 0.3 rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

G = 9.80665


@dataclass
class Gains:
    """Autopilot gains. Units: normalised command per SI unit of the error."""

    v_ref_mps: float = 14.0          #: airspeed at which surface gains are nominal
    kp_speed: float = 0.06           #: throttle per m/s
    ki_speed: float = 0.03           #: throttle per m
    ff_climb: float = 0.06           #: throttle per m/s of commanded climb rate
    k_alt: float = 0.3               #: climb rate per metre of altitude error, 1/s
    climb_max_mps: float = 3.0       #: climb/sink rate limit when holding altitude
    kp_climb: float = 0.04           #: pitch (rad) per m/s of climb-rate error
    ki_climb: float = 0.02           #: pitch (rad) per m of climb error
    k_overspeed: float = 1.0         #: sink rate given up (m/s) per m/s of overspeed at idle
    overspeed_margin_mps: float = 1.5  #: overspeed tolerated at idle before sink rate is given up
    pitch_max_rad: float = math.radians(25.0)
    pitch_min_rad: float = math.radians(-20.0)
    kp_pitch: float = 1.5            #: elevator per rad
    ki_pitch: float = 1.0            #: elevator per rad s
    kd_pitch: float = 0.25           #: elevator per rad/s
    k_course: float = 0.6            #: bank (rad) per rad of course error
    bank_max_rad: float = math.radians(35.0)
    kp_roll: float = 1.6             #: aileron per rad
    ki_roll: float = 0.3             #: aileron per rad s
    kd_roll: float = 0.05            #: aileron per rad/s
    kp_beta: float = 2.0             #: rudder per rad of sideslip
    ki_beta: float = 0.5             #: rudder per rad s
    k_path: float = 0.02             #: line following: 1/m
    chi_inf_rad: float = math.radians(60.0)  #: line following: approach angle far from the line
    k_orbit: float = 2.0             #: orbit following gain


class Sensed(NamedTuple):
    """What the autopilot reads of the aircraft at a step (SI): true airspeed, height, climb
    rate, roll and pitch, roll and pitch rates, sideslip and course over the ground."""

    tas: float        #: m/s
    h: float          #: m
    climb: float      #: m/s, up
    roll: float       #: rad
    pitch: float      #: rad
    p: float          #: rad/s
    q: float          #: rad/s
    beta: float       #: rad
    course: float     #: rad


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
