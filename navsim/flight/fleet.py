"""A fleet of fixed-wing aircraft stepped together: every aircraft's failure checks, segment
and autopilot in one compiled call per step.

JSBSim holds one aircraft per instance, so the physics steps each aircraft in turn; what
decides the commands does not need to. :func:`fleet_step` takes the true rows of the ``B``
aircraft of a step (``rows``, ``(B, len(RAW_PROPERTIES))``, SI) and, for each aircraft still
flying (``live``), senses its state (from the truth, or from a navigation solution: ``on_nav``),
runs the watchdog, the segment and the autopilot, and writes its commands (``controls``:
elevator, aileron, rudder, throttle). What is rare stays Python: an aircraft that fails, has
flown its segment, starts its track or abandons its mission stops with a code (:data:`FAILS`,
:data:`FLOWN`, ...) for its owner to act on and to finish its step (:func:`finish_step`).

:func:`~navsim.flight.simulator.fly` flies a fleet of one; the closed loop
(:mod:`navsim.experiment.closed_loop`) one aircraft per Monte Carlo run. An aircraft's
autopilot and segment runner keep their state as rows of the fleet's arrays
(:func:`fleet_arrays`), so Python and the kernels read and write the same numbers.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from navsim.flight import properties as P
from navsim.flight.autopilot import (S_BETA, S_CLIMB, S_COURSE, S_H, S_P, S_PITCH, S_Q, S_ROLL, S_TAS,
                                     SENSED_FIELDS, autopilot_step)
from navsim.flight.segments import (COURSE, EAST, FLOWN, GROUND_SPEED, H, KIND, NORTH, STATE_FIELDS, TAS, TIMED_OUT,
                                    UNSTARTED, State, T, segment_update)
from navsim.foundations.compiled import njit
from navsim.foundations.pymath import py_hypot

#: how long a steady wind above the airspeed is flown before the flight fails, s
WIND_PERSIST_S = 10.0
STALL_PERSIST_S = 1.0    #: alpha above stall for this long is a stall
MAX_ROLL_RAD = math.radians(75.0)
MAX_PITCH_RAD = math.radians(50.0)

#: what :func:`fleet_step` leaves in ``code`` for an aircraft: stepped (its commands written);
#: its segments not started; its segment flown or timed out (:data:`FLOWN`, :data:`TIMED_OUT`
#: of :mod:`~navsim.flight.segments`); its mission to be abandoned (the watched receiver lost
#: for longer than ``lost_s``); one of the failures of :data:`FAILS`
STEPPED, NOT_STARTED, ABORT = 10, 11, 12
NAN, IMPACT, STALL, LOSS_OF_CONTROL, HEADWIND = 20, 21, 22, 23, 24
FAILS = (NAN, IMPACT, STALL, LOSS_OF_CONTROL, HEADWIND)
#: the watchdog's counters: steps over the stall angle of attack, steps under a headwind
OVER_ALPHA, OVER_WIND = range(2)
#: the fleet's constants (``limits``): stall angle of attack (rad) and steps, headwind steps,
#: the lost-fix time (s), the track origin and the metres per radian north and east
(STALL_ALPHA, STALL_STEPS, WIND_STEPS, LOST_S, LAT0, LON0, K_NORTH, K_EAST) = range(8)


class FleetArrays(NamedTuple):
    """What :func:`fleet_step` reads and writes, ``B`` aircraft (rows of the arrays)."""

    gains: np.ndarray      #: the autopilot's gains (:func:`~navsim.flight.autopilot.gains_array`)
    limits: np.ndarray     #: the fleet's constants, indexed STALL_ALPHA .. K_EAST
    ap: np.ndarray         #: (B, len(AP_FIELDS)) the autopilots' states
    seg: np.ndarray        #: (B, len(SEGMENT_FIELDS)) the segment runners' states
    watch: np.ndarray      #: (B, 2) the watchdogs' counters
    state: np.ndarray      #: (B, len(STATE_FIELDS)) what the segments saw this step
    sensed: np.ndarray     #: (B, len(SENSED_FIELDS)) what the autopilots saw this step
    controls: np.ndarray   #: (B, 4) the commands written
    code: np.ndarray       #: (B,) int64, what became of each aircraft's step
    live: np.ndarray       #: (B,) bool, stepped
    flying: np.ndarray     #: (B,) bool, on its mission (abandoned when the fix is lost)
    last_fix: np.ndarray   #: (B,) time of the watched receiver's last fix, s
    rows: np.ndarray       #: (B, len(RAW_PROPERTIES)) the true state, SI
    nav_llh: np.ndarray    #: (B, 3) navigation latitude, longitude (rad), height (m)
    nav_vel: np.ndarray    #: (B, 3) navigation velocity, NED m/s
    nav_C: np.ndarray      #: (B, 3, 3) navigation C_nb
    on_nav: np.ndarray     #: (1,) bool: guide on the navigation arrays, else on the truth


def fleet_arrays(crafts: list, watches: list, lost_s: float = math.inf) -> FleetArrays:
    """The arrays of ``crafts`` (:class:`~navsim.flight.simulator.Aircraft`, one track origin)
    and their ``watches`` (:class:`Watchdog`): their autopilots', runners' and watchdogs' states
    become views of the fleet's rows, so Python and the kernels share them; ``lost_s``: how
    long a lost fix is flown before the mission is abandoned (where ``flying``)."""
    B, c0 = len(crafts), crafts[0]
    f = FleetArrays(gains=c0.ap.gains, limits=np.array([*watches[0].limits, lost_s, c0.lat0, c0.lon0, c0.k_north,
                                                        c0.k_east], float),
                    ap=np.array([c.ap.x for c in crafts]), seg=np.array([c.runner.x for c in crafts]),
                    watch=np.array([w.x for w in watches]), state=np.zeros((B, len(STATE_FIELDS))),
                    sensed=np.zeros((B, len(SENSED_FIELDS))), controls=np.zeros((B, 4)),
                    code=np.zeros(B, np.int64), live=np.ones(B, bool), flying=np.zeros(B, bool),
                    last_fix=np.zeros(B), rows=np.zeros((B, len(P.RAW_PROPERTIES))), nav_llh=np.zeros((B, 3)),
                    nav_vel=np.zeros((B, 3)), nav_C=np.zeros((B, 3, 3)), on_nav=np.zeros(1, bool))
    for b, (c, w) in enumerate(zip(crafts, watches)):
        c.ap.x, c.runner.x, w.x = f.ap[b], f.seg[b], f.watch[b]
    return f


@njit(cache=True)
def watch_check(w: np.ndarray, lim: np.ndarray, row: np.ndarray, ground_ok: bool, stall_ok: bool) -> int:
    """The failure of the true ``row`` (a code of :data:`FAILS`) or :data:`STEPPED`; ``w``: the
    watchdog's counters (in place); ``ground_ok``: no impact check (on the launcher);
    ``stall_ok``: no stall check (booster phase)."""
    if not (math.isfinite(row[P.COL_H]) and math.isfinite(row[P.COL_TAS]) and math.isfinite(row[P.COL_ROLL])):
        return NAN
    if row[P.COL_HAGL] < 0.5 and not ground_ok:
        return IMPACT
    if row[P.COL_ALPHA] > lim[STALL_ALPHA] and not stall_ok:
        w[OVER_ALPHA] += 1.0
        if w[OVER_ALPHA] >= lim[STALL_STEPS]:
            return STALL
    else:
        w[OVER_ALPHA] = 0.0
    if abs(row[P.COL_ROLL]) > MAX_ROLL_RAD or abs(row[P.COL_PITCH]) > MAX_PITCH_RAD:
        return LOSS_OF_CONTROL
    if py_hypot(row[P.COL_WSN], row[P.COL_WSE]) <= row[P.COL_TAS]:
        w[OVER_WIND] = 0.0
        return STEPPED
    w[OVER_WIND] += 1.0
    return HEADWIND if w[OVER_WIND] >= lim[WIND_STEPS] else STEPPED


@njit(cache=True)
def _sense(f: FleetArrays, b: int, t: float) -> None:
    """Aircraft ``b``'s state for its segment and its autopilot, from its truth or (``on_nav``)
    the navigation's position, velocity and attitude; airspeed, rates and sideslip true."""
    row, s, a, lim = f.rows[b], f.state[b], f.sensed[b], f.limits
    s[T], s[TAS] = t, row[P.COL_TAS]
    if f.on_nav[0]:
        v, C = f.nav_vel[b], f.nav_C[b]
        s[NORTH] = (f.nav_llh[b, 0] - lim[LAT0]) * lim[K_NORTH]
        s[EAST] = (f.nav_llh[b, 1] - lim[LON0]) * lim[K_EAST]
        s[H], s[COURSE], s[GROUND_SPEED] = f.nav_llh[b, 2], math.atan2(v[1], v[0]), py_hypot(v[0], v[1])
        a[S_CLIMB], a[S_ROLL] = -v[2], math.atan2(C[2, 1], C[2, 2])
        a[S_PITCH] = -math.asin(min(max(C[2, 0], -1.0), 1.0))
    else:
        s[NORTH] = (row[P.COL_LAT] - lim[LAT0]) * lim[K_NORTH]
        s[EAST] = (row[P.COL_LON] - lim[LON0]) * lim[K_EAST]
        vn, ve = row[P.COL_VN], row[P.COL_VE]
        s[H], s[COURSE], s[GROUND_SPEED] = row[P.COL_H], math.atan2(ve, vn), py_hypot(vn, ve)
        a[S_CLIMB], a[S_ROLL], a[S_PITCH] = -row[P.COL_VD], row[P.COL_ROLL], row[P.COL_PITCH]
    a[S_TAS], a[S_H], a[S_COURSE] = row[P.COL_TAS], s[H], s[COURSE]
    a[S_P], a[S_Q], a[S_BETA] = row[P.COL_P], row[P.COL_Q], row[P.COL_BETA]


@njit(cache=True)
def fleet_step(f: FleetArrays, t: float, dt: float) -> int:
    """One step at time ``t`` of every live aircraft of ``f`` (see the module docstring);
    returns how many stopped with a code other than :data:`STEPPED`."""
    stopped = 0
    for b in range(f.live.size):
        if not f.live[b]:
            continue
        _sense(f, b, t)
        code = watch_check(f.watch[b], f.limits, f.rows[b], False, False)
        if code == STEPPED and f.flying[b] and t - f.last_fix[b] > f.limits[LOST_S]:
            code = ABORT
        if code == STEPPED and f.seg[b, KIND] == UNSTARTED:
            code = NOT_STARTED
        if code == STEPPED:
            done = segment_update(f.gains, f.ap[b], f.seg[b], f.state[b], dt)
            code = FLOWN if done == FLOWN else TIMED_OUT if done == TIMED_OUT else STEPPED
        if code == STEPPED:
            autopilot_step(f.gains, f.ap[b], f.sensed[b], dt, f.controls[b])
        else:
            stopped += 1
        f.code[b] = code
    return stopped


def state_of(f: FleetArrays, b: int) -> State:
    """Aircraft ``b``'s segment State of this step (for the Python that acts on its code)."""
    return State(*f.state[b].tolist())


def finish_step(f: FleetArrays, b: int, dt: float) -> None:
    """The autopilot's part of aircraft ``b``'s step, once its owner has acted on its code."""
    autopilot_step(f.gains, f.ap[b], f.sensed[b], dt, f.controls[b])


def resume(runner, s: State, code: int, dt: float) -> None:
    """Act on a segment code of :func:`fleet_step` for ``runner`` (a
    :class:`~navsim.flight.segments.SegmentRunner`): start its track and step its first segment,
    or go on to its next segment; FlightError past a segment's time-out."""
    if code == NOT_STARTED:
        runner.next(s)
        if not runner.finished:
            runner.update(s, dt)
    else:
        runner.step(s, code)


def failure(code: int, row) -> str:
    """The reason of the watchdog's failure ``code`` at the true ``row``."""
    if code == NAN:
        return "the state became NaN (numerical failure)"
    if code == IMPACT:
        return f"ground or sea impact (height above surface {row[P.COL_HAGL]:.1f} m)"
    if code == STALL:
        return (f"stall (angle of attack {math.degrees(row[P.COL_ALPHA]):.1f} deg "
                f"at {row[P.COL_TAS]:.1f} m/s for {STALL_PERSIST_S:g} s)")
    if code == LOSS_OF_CONTROL:
        return (f"loss of control (roll {math.degrees(row[P.COL_ROLL]):.0f} deg, "
                f"pitch {math.degrees(row[P.COL_PITCH]):.0f} deg)")
    wind = math.hypot(row[P.COL_WSN], row[P.COL_WSE])
    return (f"the steady wind ({wind:.1f} m/s) is above the airspeed ({row[P.COL_TAS]:.1f} m/s) "
            f"for {WIND_PERSIST_S:g} s: the aircraft cannot hold its track")


class Watchdog:
    """The failure checks of every step, on the true state: NaN, ground or sea impact, stall
    (angle of attack above the stall for :data:`STALL_PERSIST_S`), loss of control, a steady
    wind above the airspeed (for :data:`WIND_PERSIST_S`: the aircraft cannot make way). Its
    counters are the float array ``x`` (a row of a fleet's ``watch``)."""

    def __init__(self, limits, dt: float):
        self.limits = (math.radians(limits.stall_alpha_deg + 1.0), int(round(STALL_PERSIST_S / dt)),
                       int(round(WIND_PERSIST_S / dt)))
        self._lim = np.array([*self.limits, math.inf, 0.0, 0.0, 0.0, 0.0])
        self.x = np.zeros(2)

    def check(self, row, ground_ok: bool = False, stall_ok: bool = False) -> str | None:
        """The reason the flight failed at this ``row``, or None. ``ground_ok``: skip the
        impact check (on the launcher); ``stall_ok``: skip the stall check (booster phase)."""
        code = watch_check(self.x, self._lim, np.asarray(row, float), ground_ok, stall_ok)
        return None if code == STEPPED else failure(code, row)


__all__ = ["FleetArrays", "Watchdog", "fleet_arrays", "fleet_step", "watch_check", "finish_step", "resume",
           "state_of", "failure", "STEPPED", "NOT_STARTED", "ABORT", "FAILS"]
