"""P4's per-sample propagation, compiled: the CPF-EKF's state prediction and the complementary
filter's step over a block of ``K`` IMU intervals, one loop per run (numba, cached); and the
complementary filter's heading error from a magnetometer sample (:func:`cpf_heading_error`) and
P4's divergence test's distance between two attitudes (:func:`euler_distance2`).

The formulas are P4's (eq. 5-7 and the CPF's Mahony step), written per run in the order of
operations of :mod:`.attitude`'s numpy forms (``rk4_step``, ``rotate_b_to_n``,
``rotate_n_to_b``); ``tests/unit/test_attitude_kernels.py`` holds them to the same formulas
written with numpy, one sample at a time over the batch, bit for bit. A run's arithmetic never
depends on the other runs.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.kernels.linalg import quat_dcm

_OPTIONS = dict(cache=True, error_model="numpy")     # a diverged run gives NaN, as numpy does

#: the CPF-EKF's state layout the kernels read (:mod:`.cpf_ekf` builds its slices from these):
#: the quaternion (4), velocity (3), position (3), the z-accelerometer bias, the magnetometer
#: bias (3), the gyro bias (3), the Earth field (3); 20 states
Q0, V0, S0, AZ, MB0, WB0, ME0, N_STATES = 0, 4, 7, 10, 11, 14, 17, 20
#: the complementary filter's gains in the order :func:`cpf_block` reads them
GAIN_NAMES = ("kp_acc", "kp_mag", "ki", "accel_tau_s", "acc_gate")


@njit(inline="always", **_OPTIONS)
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(inline="always", **_OPTIONS)
def _rotate(w, u0, u1, u2, v0, v1, v2):
    """``v + 2 w (u x v) + 2 u x (u x v)``: ``C_nb v`` with ``u`` the vector part of ``q_nb``,
    ``C_bn v`` with its negative."""
    t0, t1, t2 = _cross(u0, u1, u2, v0, v1, v2)
    t0, t1, t2 = 2.0 * t0, 2.0 * t1, 2.0 * t2
    c0, c1, c2 = _cross(u0, u1, u2, t0, t1, t2)
    return v0 + w * t0 + c0, v1 + w * t1 + c1, v2 + w * t2 + c2


@njit(**_OPTIONS)
def _rk4(q, w0, w1, w2, dt, out):
    """One Runge-Kutta step of ``q_dot = q * [0, w] / 2`` (as :func:`.attitude.rk4_step`) into
    ``out`` (4,), renormalised."""
    h = 0.5 * dt
    wx, wy, wz = w0 * h, w1 * h, w2 * h
    a2 = wx * wx + wy * wy + wz * wz
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    c0 = 1.0 - 0.5 * a2 + a2 * a2 / 24.0
    c1 = 1.0 - a2 / 6.0
    out[0] = c0 * q0 + c1 * (-q1 * wx - q2 * wy - q3 * wz)
    out[1] = c0 * q1 + c1 * (q0 * wx + q2 * wz - q3 * wy)
    out[2] = c0 * q2 + c1 * (q0 * wy - q1 * wz + q3 * wx)
    out[3] = c0 * q3 + c1 * (q0 * wz + q1 * wy - q2 * wx)
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    for i in range(4):
        out[i] = out[i] / n


@njit(**_OPTIONS)
def cpf_ekf_block(x, sum_w, sum_f, g_n, w_ie_n, dth, dv, dt):
    """The CPF-EKF's state over the block: ``x`` ``(B, 20)`` (the layout :data:`Q0`, :data:`V0`,
    :data:`S0`, :data:`AZ`, :data:`WB0`) and the sums of the corrected rate and specific force
    times ``dt`` ``(B, 3)`` the covariance prediction averages, in place."""
    q_new, q_mid = np.empty(4), np.empty(4)
    for b in range(x.shape[0]):
        for j in range(dth.shape[1]):
            q = x[b, Q0:Q0 + 4]
            r0, r1, r2 = _rotate(q[0], -q[1], -q[2], -q[3], w_ie_n[b, 0], w_ie_n[b, 1], w_ie_n[b, 2])
            w0 = dth[b, j, 0] / dt - x[b, WB0] - r0
            w1 = dth[b, j, 1] / dt - x[b, WB0 + 1] - r1
            w2 = dth[b, j, 2] / dt - x[b, WB0 + 2] - r2
            f0, f1, f2 = dv[b, j, 0] / dt, dv[b, j, 1] / dt, dv[b, j, 2] / dt - x[b, AZ]
            _rk4(q, w0, w1, w2, dt, q_new)
            for i in range(4):
                q_mid[i] = q[i] + q_new[i]
            n = math.sqrt(q_mid[0] * q_mid[0] + q_mid[1] * q_mid[1] + q_mid[2] * q_mid[2] + q_mid[3] * q_mid[3])
            a0, a1, a2 = _rotate(q_mid[0] / n, q_mid[1] / n, q_mid[2] / n, q_mid[3] / n, f0, f1, f2)
            v0, v1, v2 = x[b, V0], x[b, V0 + 1], x[b, V0 + 2]
            c0, c1, c2 = _cross(w_ie_n[b, 0], w_ie_n[b, 1], w_ie_n[b, 2], v0, v1, v2)
            a0, a1, a2 = a0 + g_n[b, 0] - 2.0 * c0, a1 + g_n[b, 1] - 2.0 * c1, a2 + g_n[b, 2] - 2.0 * c2
            n0, n1, n2 = v0 + a0 * dt, v1 + a1 * dt, v2 + a2 * dt
            x[b, S0] += 0.5 * (v0 + n0) * dt
            x[b, S0 + 1] += 0.5 * (v1 + n1) * dt
            x[b, S0 + 2] += 0.5 * (v2 + n2) * dt
            x[b, V0], x[b, V0 + 1], x[b, V0 + 2] = n0, n1, n2
            for i in range(4):
                x[b, Q0 + i] = q_new[i]
            sum_w[b, 0] += w0 * dt
            sum_w[b, 1] += w1 * dt
            sum_w[b, 2] += w2 * dt
            sum_f[b, 0] += f0 * dt
            sum_f[b, 1] += f1 * dt
            sum_f[b, 2] += f2 * dt


@njit(**_OPTIONS)
def _accel_error(q, f_lp, a_n, g_n, acc_gate):
    """The CPF's accelerometer error ``f_lp / |f_lp| x f_ref_b / |f_ref_b|`` (zero where the
    gate rejects the sample or either is zero)."""
    r0, r1, r2 = _rotate(q[0], -q[1], -q[2], -q[3], a_n[0] - g_n[0], a_n[1] - g_n[1], a_n[2] - g_n[2])
    nm = math.sqrt(f_lp[0] * f_lp[0] + f_lp[1] * f_lp[1] + f_lp[2] * f_lp[2])
    nr = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    ng = math.sqrt(g_n[0] * g_n[0] + g_n[1] * g_n[1] + g_n[2] * g_n[2])
    if abs(nm - nr) <= acc_gate * ng and nm > 0.0 and nr > 0.0:
        return _cross(f_lp[0] / nm, f_lp[1] / nm, f_lp[2] / nm, r0 / nr, r1 / nr, r2 / nr)
    return 0.0, 0.0, 0.0


@njit(**_OPTIONS)
def cpf_block(q, bias, f_lp, started, a_n, e_mag, g_n, w_ie_n, gains, dth, dv, dt):
    """The complementary filter over the block (as :meth:`.cpf.ComplementaryCore.step`):
    ``q`` ``(B, 4)``, the gyro bias ``bias`` and the low-passed specific force ``f_lp``
    ``(B, 3)`` in place; ``started`` False takes the first sample as ``f_lp``. ``gains``: the
    values of :data:`GAIN_NAMES`, in that order."""
    kp_acc, kp_mag, ki, tau, acc_gate = gains[0], gains[1], gains[2], gains[3], gains[4]
    k_lp = min(dt / tau, 1.0)
    q_new = np.empty(4)
    for b in range(q.shape[0]):
        for j in range(dth.shape[1]):
            f0, f1, f2 = dv[b, j, 0] / dt, dv[b, j, 1] / dt, dv[b, j, 2] / dt
            if not started and j == 0:
                f_lp[b, 0], f_lp[b, 1], f_lp[b, 2] = f0, f1, f2
            else:
                f_lp[b, 0] += (f0 - f_lp[b, 0]) * k_lp
                f_lp[b, 1] += (f1 - f_lp[b, 1]) * k_lp
                f_lp[b, 2] += (f2 - f_lp[b, 2]) * k_lp
            e0, e1, e2 = _accel_error(q[b], f_lp[b], a_n[b], g_n[b], acc_gate)
            r0, r1, r2 = _rotate(q[b, 0], -q[b, 1], -q[b, 2], -q[b, 3], w_ie_n[b, 0], w_ie_n[b, 1], w_ie_n[b, 2])
            w0 = dth[b, j, 0] / dt - bias[b, 0] - r0 + kp_acc * e0 + kp_mag * e_mag[b, 0]
            w1 = dth[b, j, 1] / dt - bias[b, 1] - r1 + kp_acc * e1 + kp_mag * e_mag[b, 1]
            w2 = dth[b, j, 2] / dt - bias[b, 2] - r2 + kp_acc * e2 + kp_mag * e_mag[b, 2]
            bias[b, 0] = bias[b, 0] - ki * (e0 + e_mag[b, 0]) * dt
            bias[b, 1] = bias[b, 1] - ki * (e1 + e_mag[b, 1]) * dt
            bias[b, 2] = bias[b, 2] - ki * (e2 + e_mag[b, 2]) * dt
            _rk4(q[b], w0, w1, w2, dt, q_new)
            for i in range(4):
                q[b, i] = q_new[i]


@njit(**_OPTIONS)
def _dip(v0, v1, v2):
    return math.atan2(v2, math.hypot(v0, v1))


@njit(**_OPTIONS)
def cpf_heading_error(q, m_b, valid, ref, gates, on_course, t, e_mag, heading_t, rejected):
    """The complementary filter's heading error from a magnetometer sample (as
    :meth:`.cpf.ComplementaryCore.aid` states it), every run in place: the measured field
    ``m_b`` ``(B, 3)`` (uT) turned into NED by ``q`` ``(B, 4)``, its heading against the
    reference field's ``ref`` ``(B, 3)``, wrapped; a sample is accepted where ``valid`` and its
    magnitude (relative) and dip angle are within ``gates`` = (``mag_gate``, dip gate in rad)
    of the reference's. An accepted sample sets ``heading_t`` to ``t``; a rejected valid one
    counts in ``rejected``; ``e_mag`` ``(B, 3)`` becomes the body-frame error about the NED
    down axis (zero where rejected), except where ``on_course`` (the GNSS course steers)."""
    C = np.empty((3, 3))
    for b in range(q.shape[0]):
        w, x, y, z = q[b, 0], q[b, 1], q[b, 2], q[b, 3]
        m0, m1, m2 = m_b[b, 0], m_b[b, 1], m_b[b, 2]
        quat_dcm(w, x, y, z, C)
        n0 = C[0, 0] * m0 + C[0, 1] * m1 + C[0, 2] * m2
        n1 = C[1, 0] * m0 + C[1, 1] * m1 + C[1, 2] * m2
        n2 = C[2, 0] * m0 + C[2, 1] * m1 + C[2, 2] * m2
        r0, r1, r2 = ref[b, 0], ref[b, 1], ref[b, 2]
        dpsi = math.atan2(n1, n0) - math.atan2(r1, r0)
        dpsi = (dpsi + math.pi) % (2 * math.pi) - math.pi
        ratio = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2) / math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        ok = (valid[b] and abs(ratio - 1.0) <= gates[0]
              and abs(_dip(n0, n1, n2) - _dip(r0, r1, r2)) <= gates[1])
        if valid[b] and not ok:
            rejected[b] += 1
        if ok:
            heading_t[b] = t
        if not on_course[b]:
            e = -dpsi if ok else 0.0
            e_mag[b, 0], e_mag[b, 1], e_mag[b, 2] = _rotate(w, -x, -y, -z, 0.0, 0.0, e)


@njit(inline="always", **_OPTIONS)
def _euler(w, x, y, z):
    """Roll, pitch, yaw of ``q_nb`` (as :func:`navsim.foundations.transform.euler_from_quat`)."""
    s = 2.0 * (w * y - z * x)
    if s > 1.0:
        s = 1.0
    elif s < -1.0:
        s = -1.0
    return (math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)), math.asin(s),
            math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


@njit(**_OPTIONS)
def euler_angles(q, out):
    """Roll, pitch, yaw ``(B, 3)`` of the attitudes ``q`` ``(B, 4)`` into ``out`` (as
    :func:`navsim.foundations.transform.euler_from_quat`, the same operations)."""
    for b in range(q.shape[0]):
        out[b, 0], out[b, 1], out[b, 2] = _euler(q[b, 0], q[b, 1], q[b, 2], q[b, 3])


@njit(**_OPTIONS)
def dcm_of(q, out):
    """``C_nb`` ``(B, 3, 3)`` of the attitudes ``q`` ``(B, 4)`` into ``out`` (as
    :func:`navsim.foundations.transform.dcm_from_quat`, the same operations)."""
    for b in range(q.shape[0]):
        quat_dcm(q[b, 0], q[b, 1], q[b, 2], q[b, 3], out[b])


@njit(**_OPTIONS)
def euler_distance2(q1, q2, out):
    """P4's eq. 21 between the attitudes ``q1`` and ``q2`` ``(B, 4)`` of every run, into ``out``
    ``(B,)``: ``(roll1-roll2)^2 + (pitch1-pitch2)^2 + (yaw1-yaw2)^2`` (rad^2), each difference
    wrapped to [-pi, pi) (as :func:`.attitude.euler_distance2` of their Euler angles)."""
    for b in range(q1.shape[0]):
        a = _euler(q1[b, 0], q1[b, 1], q1[b, 2], q1[b, 3])
        c = _euler(q2[b, 0], q2[b, 1], q2[b, 2], q2[b, 3])
        s = 0.0
        for i in range(3):
            d = (a[i] - c[i] + math.pi) % (2.0 * math.pi) - math.pi
            s += d * d
        out[b] = s


__all__ = ["AZ", "GAIN_NAMES", "MB0", "ME0", "N_STATES", "Q0", "S0", "V0", "WB0", "cpf_block", "cpf_ekf_block",
           "cpf_heading_error", "dcm_of", "euler_angles", "euler_distance2"]
