"""Multirotor control: rotor geometry, the mixer derived from it, and a cascade controller.

Frames and signs: body axes x forward, y right, z down, origin at the centre of gravity; NED for
the navigation frame (``pos_n_m`` from a reference point, ``vel_n_mps``); ``C_nb`` rotates a body
vector into NED.

The chain, each loop a proportional law whose gain *is* its closed-loop bandwidth (rad/s), every
loop :data:`SEPARATION` times faster than the one around it (:class:`MultirotorGains`):

* position -> velocity (P, speed limited);
* velocity -> acceleration (PI, with gravity added back), then the thrust vector, its tilt from
  the vertical limited to ``max_tilt_rad`` (the vertical acceleration is kept first);
* thrust direction and yaw (:class:`YawMode`: hold a heading, nose along the course, point at a
  place) -> attitude -> body rates (P on the rotation error of Lee, Leok and McClamroch, 2010);
* body rates -> torques (P, scaled by the inertia, plus the gyroscopic term ``omega x J omega``);
* collective thrust and torques -> per-rotor thrusts (:class:`Mixer`) -> per-motor commands in
  [0, 1] through each rotor's stated thrust map ``thrust_n = thrust_per_cmd2_n * u**2``.

:func:`navsim.flight.simulator.fly` flies it through :mod:`navsim.flight.rotorcraft`, which builds
the mixer's :class:`Rotor` (what the mixer needs of a rotor: thrust axis, lever arm, spin, command
map) from the airframe's rotor table (:class:`navsim.flight.airframe.Rotor`);
tests/integration/test_multirotor_controller.py flies JSBSim's F450 with it directly.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from navsim.foundations.atmosphere import G0 as GRAVITY_MPS2     # standard gravity, m/s^2
#: how much faster each inner loop is than the loop around it (bandwidth ratio); 3 keeps the
#: outer loop's phase loss from the inner one near atan(1/3) = 18 degrees at its crossover
SEPARATION = 3.0
#: bandwidth of the innermost (body-rate) loop, rad/s: under a fifth of a 100 Hz loop's rate;
#: the attitude, velocity and position loops are each :data:`SEPARATION` times slower
RATE_BW_RPS = 20.0
#: bandwidth of the yaw-rate loop, rad/s: far below the roll and pitch rate loops because a
#: yaw torque is made by speeding up the rotors of one spin and slowing the others, and the
#: rotors' angular momentum changes with them; where the motors change speed within a step or
#: two (JSBSim's brushless motor does) that reaction reaches the airframe at once, as a direct
#: feed-through of the yaw command worth about ``I_rotor * dOmega/dQ`` (0.23 s on the F450: 8 to
#: 20 times the drag torque's own effect over a step), which a gain of 20 rad/s turns unstable
YAW_RATE_BW_RPS = 2.5
UP_B = (0.0, 0.0, -1.0)  #: an untilted rotor's thrust axis in body axes (up)
#: below this horizontal speed, m/s, the course is undefined and "nose along the course" holds
COURSE_MIN_SPEED_MPS = 0.5
#: nearer than this horizontal distance, m, "point at a place" holds the heading it has
POINT_MIN_DISTANCE_M = 1.0


@dataclass(frozen=True)
class Rotor:
    """One rotor: where it is, which way it turns and how its command makes thrust.

    Parameters
    ----------
    pos_b_m : tuple of 3 float
        Hub position from the centre of gravity, body axes, m.
    spin : int
        +1 when the rotor turns right-handed about its thrust axis (clockwise seen from behind,
        looking along the thrust: JSBSim's ``<sense>`` 1), -1 the other way. Its reaction torque
        on the airframe is ``-spin * torque_per_thrust_m * thrust_n`` about the thrust axis.
    thrust_per_cmd2_n : float
        Thrust at command ``u`` is ``thrust_per_cmd2_n * u**2``, N (so the thrust at full command).
    torque_per_thrust_m : float
        Drag torque of the rotor per newton of thrust, N m/N (``k_Q / k_T``; for a propeller with
        thrust and power coefficients C_T, C_P and diameter D it is ``C_P D / (2 pi C_T)``).
    axis_b : tuple of 3 float
        Unit thrust direction in body axes; straight up, :data:`UP_B`, unless tilted
        (:func:`tilted_axis`).
    """

    pos_b_m: tuple
    spin: int
    thrust_per_cmd2_n: float
    torque_per_thrust_m: float
    axis_b: tuple = UP_B

    def __post_init__(self):
        if self.spin not in (1, -1):
            raise ValueError(f"spin must be +1 or -1, not {self.spin}")
        if self.thrust_per_cmd2_n <= 0.0:
            raise ValueError("thrust_per_cmd2_n must be positive")
        if abs(float(np.linalg.norm(self.axis_b)) - 1.0) > 1e-9:
            raise ValueError(f"axis_b must be a unit vector, not {self.axis_b}")

    def effect(self) -> np.ndarray:
        """The wrench of one newton of this rotor's thrust: collective thrust (up, N), then roll,
        pitch and yaw torques about the body axes (N m)."""
        a = np.asarray(self.axis_b, float)
        torque = np.cross(np.asarray(self.pos_b_m, float), a) - self.spin * self.torque_per_thrust_m * a
        return np.array([-a[2], *torque])


def tilted_axis(tilt_x_rad: float, tilt_y_rad: float) -> tuple:
    """The thrust axis of a rotor tilted from straight up by ``tilt_x_rad`` about body x (a
    positive tilt leans the thrust towards +y) and then by ``tilt_y_rad`` about body y."""
    cx, sx, cy, sy = math.cos(tilt_x_rad), math.sin(tilt_x_rad), math.cos(tilt_y_rad), math.sin(tilt_y_rad)
    # R_y(tilt_y) R_x(tilt_x) applied to (0, 0, -1)
    return (-sy * cx, sx, -cy * cx)


@dataclass(frozen=True)
class Mixer:
    """Allocation of a wrench (collective thrust N, roll, pitch, yaw torques N m) to per-rotor
    thrusts, and of thrusts to motor commands.

    ``effectiveness`` (4 x n) maps rotor thrusts to the wrench (:meth:`Rotor.effect` per column);
    ``allocation`` is its Moore-Penrose pseudo-inverse (n x 4): below saturation the thrusts it
    gives reproduce the wrench exactly, with the least sum of squared thrusts.

    Saturation rule (:meth:`thrusts`): every thrust must lie in [0, thrust at full command]. Roll
    and pitch are kept first (scaled down only if they alone cannot fit), the collective thrust
    is then moved as little as needed to fit them, and yaw is given up first: scaled down to what
    the remaining margin allows.
    """

    rotors: tuple
    effectiveness: np.ndarray = field(repr=False)
    allocation: np.ndarray = field(repr=False)

    @classmethod
    def from_rotors(cls, rotors) -> "Mixer":
        """The mixer of a rotor geometry (at least four rotors, the wrench fully controllable)."""
        rotors = tuple(rotors)
        if len(rotors) < 4:
            raise ValueError(f"a multirotor needs at least 4 rotors, not {len(rotors)}")
        B = np.column_stack([r.effect() for r in rotors])
        if np.linalg.matrix_rank(B) < 4:
            raise ValueError("the rotors cannot produce every wrench (effectiveness rank < 4)")
        return cls(rotors, B, np.linalg.pinv(B))

    @functools.cached_property
    def max_thrust_n(self) -> np.ndarray:
        """Each rotor's thrust at full command, N."""
        return np.array([r.thrust_per_cmd2_n for r in self.rotors])

    def thrusts(self, wrench) -> np.ndarray:
        """Per-rotor thrusts (N) for ``wrench`` = (collective thrust N, roll, pitch, yaw torques
        N m), saturated by the rule of the class."""
        w = np.asarray(wrench, float)
        t_max = self.max_thrust_n
        f = self.allocation @ w
        if f.min() >= 0.0 and (f <= t_max).all():       # below saturation: the exact allocation
            return f
        col, rp, yaw = self.allocation[:, 0], self.allocation[:, 1:3] @ w[1:3], self.allocation[:, 3] * w[3]
        scale = _largest_fit(col, rp, t_max)
        lo, hi = _collective_range(col, scale * rp, t_max)
        f = col * min(max(w[0], lo), hi) + scale * rp
        return f + _yaw_fit(f, yaw, t_max) * yaw

    def commands(self, thrusts_n) -> np.ndarray:
        """Motor commands in [0, 1] for per-rotor thrusts, N (the inverse of each rotor's
        ``thrust_n = thrust_per_cmd2_n * u**2``)."""
        return np.sqrt(np.minimum(np.maximum(np.asarray(thrusts_n, float) / self.max_thrust_n, 0.0), 1.0))

    def wrench(self, thrusts_n) -> np.ndarray:
        """The wrench that per-rotor thrusts make (collective N, torques N m)."""
        return self.effectiveness @ np.asarray(thrusts_n, float)


def _collective_range(col: np.ndarray, rp: np.ndarray, t_max: np.ndarray) -> tuple:
    """Collective thrusts ``c`` with ``0 <= col * c + rp <= t_max`` for every rotor (``col`` > 0)
    as (low, high); empty when low > high."""
    return float(np.max(-rp / col)), float(np.min((t_max - rp) / col))


def _largest_fit(col: np.ndarray, rp: np.ndarray, t_max: np.ndarray) -> float:
    """The largest scale in [0, 1] of the roll-pitch thrusts ``rp`` for which some collective
    thrust fits every rotor in its range (bisection, to 1e-4)."""
    lo, hi = _collective_range(col, rp, t_max)
    if lo <= hi:
        return 1.0
    a, b = 0.0, 1.0
    for _ in range(14):
        m = 0.5 * (a + b)
        lo, hi = _collective_range(col, m * rp, t_max)
        a, b = (m, b) if lo <= hi else (a, m)
    return a


def _yaw_fit(f: np.ndarray, yaw: np.ndarray, t_max: np.ndarray) -> float:
    """The largest scale in [0, 1] of the yaw thrusts ``yaw`` that keeps ``f + s * yaw`` in
    [0, t_max] (``f`` already in range)."""
    s = 1.0
    up, down = yaw > 1e-12, yaw < -1e-12
    if np.any(up):
        s = min(s, float(np.min((t_max[up] - f[up]) / yaw[up])))
    if np.any(down):
        s = min(s, float(np.min(-f[down] / yaw[down])))
    return max(s, 0.0)


@dataclass(frozen=True)
class YawMode:
    """What the nose does: ``"heading"`` holds ``heading_rad`` (from north, clockwise),
    ``"course"`` points it along the horizontal velocity (holding the last heading below
    :data:`COURSE_MIN_SPEED_MPS`), ``"point"`` points it at ``target_n_m`` (NED, m; holding within
    :data:`POINT_MIN_DISTANCE_M`)."""

    kind: str = "heading"
    heading_rad: float = 0.0
    target_n_m: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        if self.kind not in ("heading", "course", "point"):
            raise ValueError(f"yaw mode must be heading, course or point, not {self.kind!r}")


@dataclass(frozen=True)
class Setpoint:
    """Where the controller flies: ``pos_n_m`` (NED from the reference, m), a velocity
    feed-forward ``vel_n_mps``, an acceleration feed-forward ``acc_n_mps2`` (a circle's
    centripetal acceleration), the horizontal speed limit ``speed_max_mps``, the yaw mode and a
    feed-forward of the heading's rate ``yaw_rate_rps`` (a nose turning with a circle)."""

    pos_n_m: tuple
    vel_n_mps: tuple = (0.0, 0.0, 0.0)
    acc_n_mps2: tuple = (0.0, 0.0, 0.0)
    speed_max_mps: float = 5.0
    yaw: YawMode = YawMode()
    yaw_rate_rps: float = 0.0


@dataclass(frozen=True)
class MultirotorState:
    """The state the controller reads (true or estimated): ``pos_n_m`` NED from the reference
    point (m), ``vel_n_mps`` NED (m/s), ``C_nb`` body-to-NED rotation, ``omega_b_rps`` body rates
    (rad/s)."""

    pos_n_m: np.ndarray
    vel_n_mps: np.ndarray
    C_nb: np.ndarray
    omega_b_rps: np.ndarray


@dataclass(frozen=True)
class MultirotorGains:
    """Gains of the cascade, each a closed-loop bandwidth in rad/s (the inner loops
    :data:`SEPARATION` times faster than the loop around them), and the limits.

    The defaults (rate 20, attitude 6.7, velocity 2.2, position 0.74 rad/s; yaw rate 2.5, heading
    0.83 rad/s) suit a 100 Hz loop (the rate loop's 20 rad/s is a thirtieth of its 628 rad/s)
    and a thrust-to-weight ratio above about 1.5; tuned on the jsbsim wheel's F450.
    """

    rate_bw_rps: float = RATE_BW_RPS                     #: body rates -> angular acceleration
    att_bw_rps: float = RATE_BW_RPS / SEPARATION         #: roll and pitch attitude -> body rates
    yaw_rate_bw_rps: float = YAW_RATE_BW_RPS             #: yaw rate -> yaw acceleration
    yaw_bw_rps: float = YAW_RATE_BW_RPS / SEPARATION     #: heading -> yaw rate
    vel_bw_rps: float = RATE_BW_RPS / SEPARATION ** 2    #: velocity -> acceleration
    pos_bw_rps: float = RATE_BW_RPS / SEPARATION ** 3    #: position -> velocity
    #: corner of the velocity loop's integral (its zero), below the loop's bandwidth by SEPARATION
    vel_i_bw_rps: float = RATE_BW_RPS / SEPARATION ** 3
    vel_i_max_mps2: float = 3.0        #: limit of the integral's acceleration, m/s^2
    #: the integral grows only on an axis whose velocity error, or velocity, is under this, m/s:
    #: it learns the steady push of a wind or a thrust-map error (one the vehicle holds still
    #: against, displaced), not the lag of a manoeuvre, which would leave a slow tail after it; it
    #: shrinks at any error (what a manoeuvre left in it would otherwise hold the vehicle off its
    #: point for good)
    vel_i_band_mps: float = 0.2
    max_tilt_rad: float = math.radians(35.0)   #: largest tilt of the thrust from the vertical
    max_rate_rps: float = math.radians(220.0)  #: largest commanded roll and pitch rate
    max_yaw_rate_rps: float = math.radians(90.0)  #: largest commanded yaw rate
    max_climb_mps: float = 3.0         #: largest climb rate asked by the position loop, m/s
    max_sink_mps: float = 2.0          #: largest sink rate asked by the position loop, m/s
    #: largest yaw step the attitude loop sees at once (so the rotation error stays smooth), rad
    max_yaw_step_rad: float = math.radians(60.0)


class MultirotorController:
    """The cascade of the module: state and setpoint in, motor commands in [0, 1] out.

    Parameters
    ----------
    mixer : Mixer
        The rotors' allocation.
    mass_kg : float
        The vehicle's mass.
    inertia_b_kgm2 : array (3, 3)
        Its inertia tensor about the centre of gravity, body axes.
    gains : MultirotorGains
    """

    def __init__(self, mixer: Mixer, mass_kg: float, inertia_b_kgm2, gains: MultirotorGains = MultirotorGains()):
        self.mixer, self.mass_kg, self.gains = mixer, float(mass_kg), gains
        #: the inertia tensor (kg m^2, body) and the rate loop's gains, as floats (the rate loop's)
        self._J = tuple(tuple(float(x) for x in row) for row in np.asarray(inertia_b_kgm2, float))
        self._rate_k = (gains.rate_bw_rps, gains.rate_bw_rps, gains.yaw_rate_bw_rps)
        self.vel_i_mps2 = np.zeros(3)      # the velocity loop's integral, NED acceleration
        self.heading_rad: float | None = None   # the heading held when a yaw mode has none
        self.last_wrench = np.zeros(4)

    def reset(self) -> None:
        """Forget the integral and the held heading."""
        self.vel_i_mps2[:] = 0.0
        self.heading_rad = None

    def command(self, state: MultirotorState, setpoint: Setpoint, dt_s: float) -> np.ndarray:
        """One step of the cascade: per-motor commands in [0, 1]."""
        acc_n = self.acceleration_n(state, setpoint, dt_s)
        thrust_dir_n, collective_n = self.thrust_vector(acc_n, state.C_nb)
        yaw_rad = self.yaw_setpoint(state, setpoint)
        omega_cmd = self.rate_command(state.C_nb, thrust_dir_n, yaw_rad, setpoint.yaw_rate_rps)
        torque = self.torque(state.omega_b_rps, omega_cmd)
        self.last_wrench = np.array([collective_n, *torque])
        return self.mixer.commands(self.mixer.thrusts(self.last_wrench))

    def acceleration_n(self, state: MultirotorState, setpoint: Setpoint, dt_s: float) -> np.ndarray:
        """Position (P) and velocity (PI) loops and the setpoint's acceleration feed-forward: the
        NED acceleration asked, gravity not in it. (Three-vectors as floats: numpy's cost per
        operation is tens of times an element's at this size.)"""
        g = self.gains
        pos, vel = state.pos_n_m.tolist(), state.vel_n_mps.tolist()
        cmd = [g.pos_bw_rps * (sp - p) + v for sp, p, v in zip(setpoint.pos_n_m, pos, setpoint.vel_n_mps)]
        speed = math.hypot(cmd[0], cmd[1])
        if speed > setpoint.speed_max_mps:
            k = setpoint.speed_max_mps / speed
            cmd[0], cmd[1] = cmd[0] * k, cmd[1] * k
        cmd[2] = min(max(cmd[2], -g.max_climb_mps), g.max_sink_mps)
        gain_i, band, lim = g.vel_bw_rps * g.vel_i_bw_rps * dt_s, g.vel_i_band_mps, g.vel_i_max_mps2
        out, integral = [], self.vel_i_mps2
        for j in range(3):
            err, i_j = cmd[j] - vel[j], float(integral[j])
            if abs(err) < band or abs(vel[j]) < band or err * i_j < 0.0:
                i_j = min(max(i_j + gain_i * err, -lim), lim)
                integral[j] = i_j
            out.append(g.vel_bw_rps * err + i_j + setpoint.acc_n_mps2[j])
        return np.array(out)

    def thrust_vector(self, acc_n: np.ndarray, C_nb: np.ndarray) -> tuple:
        """The thrust direction (unit, NED) for the acceleration ``acc_n``, its tilt limited with
        the vertical kept, and the collective thrust (N): the thrust vector's projection on the
        present thrust axis (body -z)."""
        m = self.mass_kg
        fx, fy, fz = m * float(acc_n[0]), m * float(acc_n[1]), m * (float(acc_n[2]) - GRAVITY_MPS2)
        up = max(-fz, 0.1 * m * GRAVITY_MPS2)      # never ask for thrust downwards
        horiz = math.hypot(fx, fy)
        horiz_max = up * math.tan(self.gains.max_tilt_rad)
        if horiz > horiz_max:
            fx, fy = fx * horiz_max / horiz, fy * horiz_max / horiz
        norm = math.sqrt(fx * fx + fy * fy + up * up)
        c02, c12, c22 = float(C_nb[0, 2]), float(C_nb[1, 2]), float(C_nb[2, 2])
        collective_n = max(-(fx * c02 + fy * c12 - up * c22), 0.0)
        return np.array([fx / norm, fy / norm, -up / norm]), collective_n

    def yaw_setpoint(self, state: MultirotorState, setpoint: Setpoint) -> float:
        """The heading asked by the yaw mode (rad from north), the present one held when the mode
        cannot say."""
        mode = setpoint.yaw
        if self.heading_rad is None:
            self.heading_rad = math.atan2(state.C_nb[1, 0], state.C_nb[0, 0])
        if mode.kind == "heading":
            self.heading_rad = mode.heading_rad
        elif mode.kind == "course":
            if math.hypot(state.vel_n_mps[0], state.vel_n_mps[1]) > COURSE_MIN_SPEED_MPS:
                self.heading_rad = math.atan2(state.vel_n_mps[1], state.vel_n_mps[0])
        else:
            dn, de = mode.target_n_m[0] - state.pos_n_m[0], mode.target_n_m[1] - state.pos_n_m[1]
            if math.hypot(dn, de) > POINT_MIN_DISTANCE_M:
                self.heading_rad = math.atan2(de, dn)
        return self.heading_rad

    def rate_command(self, C_nb: np.ndarray, thrust_dir_n: np.ndarray, yaw_rad: float,
                     yaw_rate_rps: float = 0.0) -> np.ndarray:
        """Attitude loop: the body rates (rad/s) that turn the body towards the attitude with its
        -z along ``thrust_dir_n`` and its nose towards ``yaw_rad`` (limited to
        ``max_yaw_step_rad`` from the present heading), plus the heading's rate ``yaw_rate_rps``
        (about down) fed forward. The rotation error is ``e_R = vee(C_d^T C - C^T C_d) / 2``, each
        of its terms a dot product of the two attitudes' axes (their columns)."""
        g = self.gains
        (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = C_nb.tolist()
        psi = math.atan2(c10, c00)
        step = (yaw_rad - psi + math.pi) % (2.0 * math.pi) - math.pi
        psi_d = psi + min(max(step, -g.max_yaw_step_rad), g.max_yaw_step_rad)
        zx, zy, zz = (-float(v) for v in thrust_dir_n)                  # the body's z asked
        hx, hy = math.cos(psi_d), math.sin(psi_d)                        # the heading asked
        yx, yy, yz = -zz * hy, zz * hx, zx * hy - zy * hx                # z x heading, then unit
        n = math.sqrt(yx * yx + yy * yy + yz * yz)
        yx, yy, yz = yx / n, yy / n, yz / n
        xx, xy, xz = yy * zz - yz * zy, yz * zx - yx * zz, yx * zy - yy * zx   # y x z
        # E[i, j] = (asked axis i) . (present axis j) - (present axis i) . (asked axis j)
        e0 = 0.5 * ((zx * c01 + zy * c11 + zz * c21) - (c02 * yx + c12 * yy + c22 * yz))
        e1 = 0.5 * ((xx * c02 + xy * c12 + xz * c22) - (c00 * zx + c10 * zy + c20 * zz))
        e2 = 0.5 * ((yx * c00 + yy * c10 + yz * c20) - (c01 * xx + c11 * xy + c21 * xz))
        w0, w1, w2 = -g.att_bw_rps * e0, -g.att_bw_rps * e1, -g.yaw_bw_rps * e2
        if yaw_rate_rps:                          # the heading's rate about down, in body axes
            w0, w1, w2 = w0 + yaw_rate_rps * c20, w1 + yaw_rate_rps * c21, w2 + yaw_rate_rps * c22
        lim, lim_yaw = g.max_rate_rps, g.max_yaw_rate_rps
        return np.array([min(max(w0, -lim), lim), min(max(w1, -lim), lim), min(max(w2, -lim_yaw), lim_yaw)])

    def torque(self, omega_b_rps: np.ndarray, omega_cmd: np.ndarray) -> np.ndarray:
        """Rate loop: body torques (N m), ``J k (omega_cmd - omega) + omega x J omega`` with ``k``
        the roll-pitch or the yaw rate bandwidth."""
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._J
        w0, w1, w2 = omega_b_rps.tolist()
        k0, k1, k2 = self._rate_k
        a0, a1, a2 = (k0 * (float(omega_cmd[0]) - w0), k1 * (float(omega_cmd[1]) - w1),
                      k2 * (float(omega_cmd[2]) - w2))
        h0, h1, h2 = j00 * w0 + j01 * w1 + j02 * w2, j10 * w0 + j11 * w1 + j12 * w2, j20 * w0 + j21 * w1 + j22 * w2
        return np.array([j00 * a0 + j01 * a1 + j02 * a2 + w1 * h2 - w2 * h1,
                         j10 * a0 + j11 * a1 + j12 * a2 + w2 * h0 - w0 * h2,
                         j20 * a0 + j21 * a1 + j22 * a2 + w0 * h1 - w1 * h0])
