"""P4's complementary filter (CPF): a quaternion attitude filter of the Mahony type, batched.

The gyro (high frequency) is integrated by Runge-Kutta; the low-frequency references pull the
attitude back with a proportional-integral correction of the body rate::

    w = w_gyro - b - C_bn w_ie + kp_acc e_acc + kp_mag e_mag,    b_dot = -ki (e_acc + e_mag)

* ``e_acc = a_meas x a_ref``: the low-passed specific force (``accel_tau_s``) against the one the
  attitude predicts, ``C_bn (a_n - g_n)``, where ``a_n`` is the vehicle's acceleration from the
  GNSS velocity (P4: the CPF fuses accelerometer, magnetometer and GPS) -- without it a banked
  turn would pull the roll toward zero. Skipped while ``| |f| - |a_n - g| | > acc_gate g``.
* ``e_mag``: the heading error only (about the NED down axis, so the magnetometer cannot tilt
  the attitude): the angle between the measured field turned into NED and the reference field
  (the WMM, or ``field_n_T``). A sample whose magnitude departs from the reference by more than
  ``mag_gate`` (relative) or whose dip angle (in the CPF's levelled frame) by more than
  ``dip_gate_deg`` is rejected -- standard complementary-filter checks, and what keeps the CPF
  usable as P4's reference when a magnetic disturbance misleads the EKF.
* with ``course_min_speed_mps`` set, the heading error is taken from the GNSS course instead of
  the magnetometer whenever the ground speed exceeds it: a fixed-wing in calm air flies with
  (nearly) zero sideslip, so its course is its heading (not true of P4's octocopter, which
  keeps the magnetometer: leave it unset).

Registered as ``cpf``; :mod:`.cpf_ekf` runs one beside its EKF as the divergence monitor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations.config import Node
from navsim.foundations.transform import euler_from_quat
from navsim.navigation.estimators.attitude import (
    UT,
    LocalFrame,
    quat_of_dcm,
    reference_field_uT,
    rotate_n_to_b,
)
from navsim.navigation.estimators.attitude_config import attitude_params, attitude_schema
from navsim.navigation.estimators.attitude_kernels import GAIN_NAMES, cpf_block, cpf_heading_error, euler_angles
from navsim.navigation.estimators.base import Innovation, Solution, register, sample
from navsim.navigation.strapdown import NavState


@dataclass(frozen=True)
class CpfGains:
    """The complementary filter's gains and gates (see the module docstring): a scenario entry's
    ``cpf`` keys (:data:`~navsim.navigation.estimators.attitude_config.CPF_GAINS`)."""

    kp_acc: float = 0.5             #: the tilt correction's gain, rad/s per unit error
    kp_mag: float = 0.5             #: the heading correction's gain, rad/s per unit error
    ki: float = 0.05                #: the gyro bias's integral gain
    accel_tau_s: float = 0.2        #: the specific force's low-pass time constant, s
    acc_gate: float = 0.1           #: tilt correction skipped beyond this specific-force mismatch, g
    mag_gate: float = 0.05          #: a field sample rejected beyond this relative magnitude error
    dip_gate_deg: float = 3.0       #: ... or beyond this dip angle error, deg
    accel_ref_tau_s: float = 0.5    #: the GNSS acceleration's smoothing time constant, s
    course_min_speed_mps: float | None = None   #: the GNSS course as heading above this ground speed


class ComplementaryCore:
    """The CPF's state and steps (used by the ``cpf`` estimator and inside ``cpf_ekf``), set by
    a :class:`CpfGains`."""

    def __init__(self, gains: CpfGains = CpfGains()):
        g = gains
        self.kp_acc, self.kp_mag, self.ki = g.kp_acc, g.kp_mag, g.ki
        self.accel_tau_s, self.acc_gate, self.mag_gate = g.accel_tau_s, g.acc_gate, g.mag_gate
        self.accel_ref_tau_s = g.accel_ref_tau_s
        self.dip_gate = np.radians(g.dip_gate_deg)
        self._gates = np.array([self.mag_gate, self.dip_gate])     #: as cpf_heading_error reads them
        self.course_min_speed_mps = g.course_min_speed_mps

    def start(self, q0: np.ndarray, frame: LocalFrame) -> None:
        B = q0.shape[0]
        self.q, self.frame = q0.copy(), frame
        self.b = np.zeros((B, 3))
        self.f_lp = np.zeros((B, 3))          #: the low-passed specific force, m/s^2
        self._lp_started = False
        self.e_mag = np.zeros((B, 3))
        self.a_n = np.zeros((B, 3))
        self._v_prev = self._t_prev = None
        self.mag_rejected = np.zeros(B, int)
        self.on_course = np.zeros(B, bool)
        self.heading_t = np.zeros(B)          #: when it last had a heading reference, s
        self.field_uT = None

    def propagate(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float) -> None:
        """The ``K`` IMU intervals of ``(B, K, 3)`` increments, compiled
        (:func:`~navsim.navigation.estimators.attitude_kernels.cpf_block`): the specific force
        low-passed (``accel_tau_s``) and checked against the reference (``acc_gate``), the
        corrected rate integrated by a fourth-order Runge-Kutta step (P4's eq. 5)."""
        if dtheta_b.shape[1] == 0:
            return
        gains = np.array([getattr(self, name) for name in GAIN_NAMES], float)
        cpf_block(self.q, self.b, self.f_lp, self._lp_started, self.a_n, self.e_mag, self.frame.g_n,
                  self.frame.w_ie_n, gains, dtheta_b, dv_b, dt)
        self._lp_started = True

    def aid(self, t: float, sensors: dict, mag: str | None, gnss: str | None, field_n_T=None,
            t_prev: float | None = None) -> None:
        """Take the latest magnetometer and GNSS samples in ``(t_prev, t]`` (if any) as the new
        references."""
        data, j = sample(sensors, gnss, t, t_prev)
        if data is not None and "vel_n_mps" in data.values:
            v, ok = data.values["vel_n_mps"][:, j], data.valid[:, j]
            if self._v_prev is not None and t > self._t_prev:
                a = (v - self._v_prev) / (t - self._t_prev)
                k = min((t - self._t_prev) / self.accel_ref_tau_s, 1.0)
                self.a_n = np.where(ok[:, None] & self._ok_prev[:, None], self.a_n + (a - self.a_n) * k, self.a_n)
            self._v_prev, self._t_prev, self._ok_prev = v, t, ok
            if self.course_min_speed_mps is not None:
                self._course_yaw(v, ok)
                self.heading_t = np.where(self.on_course, t, self.heading_t)
        data, j = sample(sensors, mag, t, t_prev)
        if data is None:
            return
        if self.field_uT is None:
            self.field_uT = reference_field_uT(self.frame, data, field_n_T)
        cpf_heading_error(self.q, np.ascontiguousarray(data.values["mag_b_T"][:, j]) / UT,
                          np.ascontiguousarray(data.valid[:, j]), self.field_uT, self._gates, self.on_course, float(t),
                          self.e_mag, self.heading_t, self.mag_rejected)

    def _course_yaw(self, vel_n: np.ndarray, ok: np.ndarray) -> None:
        """Heading error from the GNSS course where the ground speed is high enough."""
        self.on_course = ok & (np.hypot(vel_n[:, 0], vel_n[:, 1]) > self.course_min_speed_mps)
        yaw = euler_from_quat(self.q)[:, 2]
        d = (yaw - np.arctan2(vel_n[:, 1], vel_n[:, 0]) + np.pi) % (2 * np.pi) - np.pi
        e_n = np.zeros_like(vel_n)
        e_n[:, 2] = -d
        self.e_mag = np.where(self.on_course[:, None], rotate_n_to_b(self.q, e_n), self.e_mag)

    def euler(self) -> np.ndarray:
        """Roll, pitch, yaw ``(B, 3)`` of the CPF's attitude (compiled: :func:`~.attitude_kernels.euler_angles`)."""
        out = np.empty((self.q.shape[0], 3))
        euler_angles(self.q, out)
        return out


@register("cpf")
class ComplementaryFilter:
    """P4's complementary filter on its own (see the module docstring).

    Parameters
    ----------
    mag, gnss : str or None
        The magnetometer and GNSS sensors it reads (names in the scenario).
    period_s : float
        How often it takes the magnetometer and GNSS references (their rates: 10 Hz).
    cpf : dict
        The fields of :class:`CpfGains` it sets: the gains ``kp_acc``, ``kp_mag``, ``ki``
        (rad/s per unit error; time constants ``1/kp``), the gates, ``course_min_speed_mps``.
    field_n_T : list of 3 or None
        The Earth field it assumes (NED, T); None: the WMM at the start.

    Its solution's velocity and position are the last GNSS fix (it estimates only the attitude);
    ``P_nav`` is None.
    """

    SCHEMA = attitude_schema("cpf")

    def __init__(self, mag: str | None = "mag", gnss: str | None = None, baro: str | None = None,
                 period_s: float = 0.1, field_n_T=None, cpf: dict | None = None):
        self.mag, self.gnss, self.baro, self.period_s = mag, gnss, baro, period_s
        self.field_n_T = field_n_T
        self.core = ComplementaryCore(CpfGains(**(cpf or {})))

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """``mag``, ``gnss``, ``baro`` (sensor names), ``period_s``, ``field_uT``, ``cpf`` (gains):
        :func:`~navsim.navigation.estimators.attitude_config.attitude_params`."""
        return attitude_params(node, "cpf", sensors)

    def initialize(self, nav0: NavState, sigma0: dict | None = None) -> None:
        self.frame = LocalFrame(nav0.lat_rad.copy(), nav0.lon_rad.copy(), nav0.h_m.copy())
        self.core.start(quat_of_dcm(nav0.C_nb), self.frame)
        self.vel_n = nav0.vel_n_mps.copy()
        self.pos_n = np.zeros_like(self.vel_n)
        self.diverged = np.zeros(nav0.lat_rad.shape[0], bool)
        self.t_prev = -self.period_s

    def propagate(self, dtheta_b, dv_b, dt: float) -> None:
        """The ``K`` IMU intervals of ``(B, K, 3)`` increments."""
        self.core.propagate(dtheta_b, dv_b, dt)

    def epoch(self, t: float, sensors: dict) -> list[Innovation]:
        self.core.aid(t, sensors, self.mag, self.gnss, self.field_n_T, self.t_prev)
        data, j = sample(sensors, self.gnss, t, self.t_prev)
        self.t_prev = t
        if data is not None:
            ok = data.valid[:, j, None]
            fix = self.frame.ned(data.values["lat_rad"][:, j], data.values["lon_rad"][:, j], data.values["h_m"][:, j])
            self.pos_n = np.where(ok, fix, self.pos_n)
            if "vel_n_mps" in data.values:
                self.vel_n = np.where(ok, data.values["vel_n_mps"][:, j], self.vel_n)
        self.diverged |= ~np.all(np.isfinite(self.core.q), axis=-1)
        return []

    def solution(self) -> Solution:
        return Solution(nav=self.frame.nav_state(self.core.q, self.vel_n, self.pos_n),
                        gyro_bias=self.core.b.copy(), accel_bias=np.zeros_like(self.core.b),
                        extra={"diverged": self.diverged})
