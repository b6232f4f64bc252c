"""Closed-loop autopilot and lateral guidance, compiled for the 100 Hz loop of one aircraft or a fleet.

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
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from navsim.foundations.compiled import njit
from navsim.foundations.pymath import py_hypot, py_pow

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
    rate, roll and pitch, roll and pitch rates, sideslip and course over the ground. A fleet's
    kernels hold it as an array of these fields in this order (:data:`SENSED_FIELDS`)."""

    tas: float        #: m/s
    h: float          #: m
    climb: float      #: m/s, up
    roll: float       #: rad
    pitch: float      #: rad
    p: float          #: rad/s
    q: float          #: rad/s
    beta: float       #: rad
    course: float     #: rad


SENSED_FIELDS = Sensed._fields
S_TAS, S_H, S_CLIMB, S_ROLL, S_PITCH, S_P, S_Q, S_BETA, S_COURSE = range(len(SENSED_FIELDS))

#: the autopilot's state, one float each in this order (a run's row of a fleet's array):
#: commands, the integrators, the idle flag (1.0: throttle at idle); a hold of NaN is none
AP_FIELDS = ("speed_cmd", "alt_cmd", "climb_rate", "course_cmd", "bank_ff", "bank_cmd", "pitch_cmd",
             "pitch_hold", "throttle_hold", "i_speed", "i_climb", "i_pitch", "i_roll", "i_beta", "idle")
(SPEED_CMD, ALT_CMD, CLIMB_RATE, COURSE_CMD, BANK_FF, BANK_CMD, PITCH_CMD, PITCH_HOLD, THROTTLE_HOLD,
 I_SPEED, I_CLIMB, I_PITCH, I_ROLL, I_BETA, IDLE) = range(len(AP_FIELDS))
_HOLDS = (PITCH_HOLD, THROTTLE_HOLD)
_AP_START = {"speed_cmd": 14.0, "alt_cmd": 100.0, "pitch_hold": math.nan, "throttle_hold": math.nan}

#: the gains as the kernels read them: :class:`Gains`' fields in order, then the exponent 2.0
#: that :func:`~navsim.foundations.pymath.py_pow` reads at run time
_GAIN = {f.name: i for i, f in enumerate(fields(Gains))}
(V_REF, KP_SPEED, KI_SPEED, FF_CLIMB, K_ALT, CLIMB_MAX, KP_CLIMB, KI_CLIMB, K_OVERSPEED, OVERSPEED_MARGIN,
 PITCH_MAX, PITCH_MIN, KP_PITCH, KI_PITCH, KD_PITCH, K_COURSE, BANK_MAX, KP_ROLL, KI_ROLL, KD_ROLL,
 KP_BETA, KI_BETA, K_PATH, CHI_INF, K_ORBIT) = (_GAIN[f.name] for f in fields(Gains))
SQUARE = len(_GAIN)


def gains_array(g: Gains) -> np.ndarray:
    """``g`` as the kernels read it (see :data:`SQUARE`)."""
    return np.array([getattr(g, f.name) for f in fields(Gains)] + [2.0])


@njit(cache=True)
def _clip(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


@njit(cache=True)
def _vertical(g, x, s, dt: float, v: float, sched: float) -> tuple:
    """Altitude -> climb rate -> pitch -> elevator: the elevator and the commanded climb rate."""
    err_h = x[ALT_CMD] - s[S_H]
    lim = x[CLIMB_RATE] if x[CLIMB_RATE] > 0.0 else g[CLIMB_MAX]
    climb_cmd = _clip(g[K_ALT] * err_h, -lim, lim)
    over = s[S_TAS] - x[SPEED_CMD] - g[OVERSPEED_MARGIN]
    if x[IDLE] != 0.0 and climb_cmd < 0.0 and over > 0.0:
        # at idle throttle nothing else slows a descent: give up sink rate for speed
        climb_cmd = min(climb_cmd + g[K_OVERSPEED] * over, 0.0)
    err_climb = climb_cmd - s[S_CLIMB]
    gamma_ff = math.asin(_clip(climb_cmd / v, -0.5, 0.5))
    if not math.isnan(x[PITCH_HOLD]):
        pitch_cmd = x[PITCH_HOLD]
    else:
        pitch_cmd = gamma_ff + x[I_CLIMB] + g[KP_CLIMB] * err_climb
        if g[PITCH_MIN] < pitch_cmd < g[PITCH_MAX]:
            x[I_CLIMB] += g[KI_CLIMB] * err_climb * dt
        pitch_cmd = _clip(pitch_cmd, g[PITCH_MIN], g[PITCH_MAX])
    x[PITCH_CMD] = pitch_cmd
    err_pitch = pitch_cmd - s[S_PITCH]
    elev = -sched * (g[KP_PITCH] * err_pitch + x[I_PITCH] - g[KD_PITCH] * s[S_Q])
    if -1.0 < elev < 1.0:
        x[I_PITCH] += g[KI_PITCH] * err_pitch * dt
    return _clip(elev, -1.0, 1.0), climb_cmd


@njit(cache=True)
def _throttle(g, x, s, dt: float, climb_cmd: float) -> float:
    """Speed -> throttle (with the climb-rate feed-forward)."""
    err_v = x[SPEED_CMD] - s[S_TAS]
    if not math.isnan(x[THROTTLE_HOLD]):
        return x[THROTTLE_HOLD]
    thr = x[I_SPEED] + g[KP_SPEED] * err_v + g[FF_CLIMB] * climb_cmd
    if 0.0 < thr < 1.0 or (thr >= 1.0 and err_v < 0) or (thr <= 0.0 and err_v > 0):
        x[I_SPEED] += g[KI_SPEED] * err_v * dt
    x[IDLE] = 1.0 if thr <= 0.0 else 0.0
    return _clip(thr, 0.0, 1.0)


@njit(cache=True)
def _lateral(g, x, s, dt: float, sched: float) -> tuple:
    """Course -> bank -> aileron, and sideslip -> rudder (turn coordination)."""
    err_course = (x[COURSE_CMD] - s[S_COURSE] + math.pi) % (2.0 * math.pi) - math.pi
    bank_cmd = _clip(x[BANK_FF] + g[K_COURSE] * err_course, -g[BANK_MAX], g[BANK_MAX])
    x[BANK_CMD] = bank_cmd
    err_roll = bank_cmd - s[S_ROLL]
    ail = sched * (g[KP_ROLL] * err_roll + x[I_ROLL] - g[KD_ROLL] * s[S_P])
    if -1.0 < ail < 1.0:
        x[I_ROLL] += g[KI_ROLL] * err_roll * dt
    ail = _clip(ail, -1.0, 1.0)
    rud = -sched * (g[KP_BETA] * s[S_BETA] + x[I_BETA])
    if -1.0 < rud < 1.0:
        x[I_BETA] += g[KI_BETA] * s[S_BETA] * dt
    return ail, _clip(rud, -1.0, 1.0)


@njit(cache=True)
def autopilot_step(g: np.ndarray, x: np.ndarray, s: np.ndarray, dt: float, out: np.ndarray) -> None:
    """One update of ``dt`` seconds of the autopilot state ``x`` (:data:`AP_FIELDS`, in place)
    with gains ``g`` (:func:`gains_array`) on the sensed state ``s`` (:data:`SENSED_FIELDS`):
    ``out`` gets the (elevator, aileron, rudder, throttle) normalised commands."""
    v = max(s[S_TAS], 5.0)
    sched = _clip(py_pow(g[V_REF] / v, g[SQUARE:]), 0.3, 3.0)
    out[0], climb_cmd = _vertical(g, x, s, dt, v, sched)
    out[3] = _throttle(g, x, s, dt, climb_cmd)
    out[1], out[2] = _lateral(g, x, s, dt, sched)


class ArrayField:
    """One entry of an object's float array ``x`` (a kernel's state) as a Python attribute:
    read as a float (``kind`` "hold": NaN reads None; "flag": a bool), written as a float."""

    def __init__(self, index: int, kind: str = "float"):
        self.index, self.kind = index, kind

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        v = float(obj.x[self.index])
        if self.kind == "hold":
            return None if math.isnan(v) else v
        return bool(v) if self.kind == "flag" else v

    def __set__(self, obj, value) -> None:
        obj.x[self.index] = math.nan if value is None else float(value)


class Autopilot:
    """State of the loops (integrators) and the current commands, held in the float array
    ``x`` (:data:`AP_FIELDS`; a fleet's kernels step many at once, each a row of one array)
    and read and written here as attributes.

    The guidance modes set ``course_cmd`` and ``bank_ff``; the vertical mode sets either an
    altitude to hold (``alt_cmd``) or a climb rate (``climb_cmd``) towards ``alt_cmd``.
    ``pitch_hold`` (rad) overrides the vertical loops (launch). The gains ``g`` are read into
    the kernels' array ``gains`` here, once: a change to ``g`` afterwards is not flown.
    """

    def __init__(self, gains: Gains | None = None):
        self.g = gains or Gains()
        self.gains = gains_array(self.g)
        self.x = np.array([_AP_START.get(name, 0.0) for name in AP_FIELDS])
        self._out = np.zeros(4)

    def step(self, dt: float, s: "Sensed") -> tuple[float, float, float, float]:
        """One update of ``dt`` seconds on the aircraft's state ``s``; returns (elevator,
        aileron, rudder, throttle) normalised commands."""
        autopilot_step(self.gains, self.x, np.array(s, dtype=float), dt, self._out)
        elev, ail, rud, thr = self._out.tolist()
        return elev, ail, rud, thr


for _i, _name in enumerate(AP_FIELDS):
    setattr(Autopilot, _name, ArrayField(_i, "hold" if _i in _HOLDS else "flag" if _i == IDLE else "float"))


@njit(cache=True)
def line_course(g: np.ndarray, north: float, east: float, n0: float, e0: float,
                chi_line: float) -> tuple:
    """Course command and cross-track error (m, + right of the line) to follow the straight
    line through ``(n0, e0)`` with course ``chi_line`` (``g``: :func:`gains_array`)."""
    cross = -math.sin(chi_line) * (north - n0) + math.cos(chi_line) * (east - e0)
    return chi_line - g[CHI_INF] * (2.0 / math.pi) * math.atan(g[K_PATH] * cross), cross


@njit(cache=True)
def orbit_course(g: np.ndarray, north: float, east: float, cn: float, ce: float, radius: float,
                 direction: float) -> tuple:
    """Course command and radial error (m) to orbit ``(cn, ce)`` at ``radius``; ``direction``
    +1 clockwise (right turns), -1 anticlockwise (``g``: :func:`gains_array`)."""
    d = py_hypot(north - cn, east - ce)
    phase = math.atan2(east - ce, north - cn)
    chi = phase + direction * (0.5 * math.pi + math.atan(g[K_ORBIT] * (d - radius) / radius))
    return chi, d - radius
