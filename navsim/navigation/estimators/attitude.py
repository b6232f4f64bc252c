"""Pieces shared by the quaternion attitude estimators of P4 (:mod:`.cpf`, :mod:`.cpf_ekf`).

* quaternion kinematics, batched over the leading run axis: ``q_nb`` scalar first, body FRD to
  NED; ``omega_matrix`` (``q_dot = Omega(w) q / 2``), ``xi`` (``q * [0, w] = Xi(q) w``) and
  ``psi`` (``[0, p] * q = Psi(q) p``); one Runge-Kutta step of the attitude (P4's eq. 5);
* the local navigation frame: flat-Earth NED metres about the start point (P4's ``S``), with
  constant gravity and Earth rate of the start point;
* the sensors' samples at a filter epoch, the Earth field the filters assume (the WMM at the
  start, as an on-board model would give it), the navigation state handed to the runner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations import earth
from navsim.foundations.transform import cross, quat_multiply
from navsim.navigation.estimators.attitude_kernels import dcm_of
from navsim.navigation.strapdown import NavState
from navsim.sensors.magnetometer import WMM_DATE, wmm_field_n_T

UT = 1e-6       #: tesla per microtesla (the filters keep the magnetic field in uT)


def omega_matrix(w: np.ndarray) -> np.ndarray:
    """``Omega(w)`` ``(B, 4, 4)`` with ``q * [0, w] = Omega(w) q``."""
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -x, -y, -z], -1), np.stack([x, o, z, -y], -1),
                     np.stack([y, -z, o, x], -1), np.stack([z, y, -x, o], -1)], -2)


def xi(q: np.ndarray) -> np.ndarray:
    """``Xi(q)`` ``(B, 4, 3)`` with ``q * [0, w] = Xi(q) w``."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([np.stack([-x, -y, -z], -1), np.stack([w, -z, y], -1),
                     np.stack([z, w, -x], -1), np.stack([-y, x, w], -1)], -2)


def psi(q: np.ndarray) -> np.ndarray:
    """``Psi(q)`` ``(B, 4, 3)`` with ``[0, p] * q = Psi(q) p`` (a rotation ``p`` in NED)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([np.stack([-x, -y, -z], -1), np.stack([w, z, -y], -1),
                     np.stack([-z, w, x], -1), np.stack([y, -x, w], -1)], -2)


def dcm_homogeneous(q: np.ndarray) -> np.ndarray:
    """``C_nb = (w^2 - v.v) I + 2 v v^T + 2 w [v x]`` ``(B, 3, 3)``: equal to
    :func:`navsim.foundations.transform.dcm_from_quat` on unit quaternions, and the form whose derivative the
    EKF's Jacobians are (so that ``h`` and ``H`` agree for any ``q``)."""
    w, v = q[:, 0], q[:, 1:]
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    K = K - np.swapaxes(K, -1, -2)
    return ((w * w - np.einsum("bi,bi->b", v, v))[:, None, None] * np.eye(3)
            + 2.0 * np.einsum("bi,bj->bij", v, v) + 2.0 * w[:, None, None] * K)


def normalize(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def rk4_step(q: np.ndarray, w_b: np.ndarray, dt: float) -> np.ndarray:
    """One fourth-order Runge-Kutta step of ``q_dot = q * [0, w] / 2`` with the body rate ``w_b``
    ``(B, 3)`` constant over ``dt`` (P4's eq. 5), renormalised. For a constant rate the four
    stages sum to ``(I + A + A^2/2 + A^3/6 + A^4/24) q`` with ``A = Omega(w) dt / 2`` and
    ``A^2 = -a^2 I`` (``a = |w| dt / 2``), which is evaluated as such:
    ``(1 - a^2/2 + a^4/24) q + (1 - a^2/6) A q`` -- the same numbers, without 4x4 products."""
    h = 0.5 * dt
    wx, wy, wz = w_b[:, 0] * h, w_b[:, 1] * h, w_b[:, 2] * h
    a2 = wx * wx + wy * wy + wz * wz
    q0, q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    c0 = 1.0 - 0.5 * a2 + a2 * a2 / 24.0
    c1 = 1.0 - a2 / 6.0
    out = np.empty_like(q)
    out[:, 0] = c0 * q0 + c1 * (-q1 * wx - q2 * wy - q3 * wz)
    out[:, 1] = c0 * q1 + c1 * (q0 * wx + q2 * wz - q3 * wy)
    out[:, 2] = c0 * q2 + c1 * (q0 * wy - q1 * wz + q3 * wx)
    out[:, 3] = c0 * q3 + c1 * (q0 * wz + q1 * wy - q2 * wx)
    return normalize(out)


def quat_of_dcm(C: np.ndarray) -> np.ndarray:
    """``q_nb`` ``(B, 4)`` of ``C_nb`` ``(B, 3, 3)`` (Shepperd's method via scipy)."""
    from scipy.spatial.transform import Rotation
    xyzw = Rotation.from_matrix(C).as_quat()
    q = np.concatenate([xyzw[..., 3:], xyzw[..., :3]], -1)
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def euler_distance2(e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """P4's eq. 21: ``(roll1-roll2)^2 + (pitch1-pitch2)^2 + (yaw1-yaw2)^2``, rad^2, each
    difference wrapped to [-pi, pi) (a yaw of 179 deg and one of -179 deg are 2 deg apart)."""
    d = (e1 - e2 + np.pi) % (2.0 * np.pi) - np.pi
    return np.einsum("bi,bi->b", d, d)


@dataclass
class LocalFrame:
    """Flat-Earth NED metres about the start point, with its gravity and Earth rate."""

    lat0: np.ndarray          #: (B,) rad
    lon0: np.ndarray
    h0: np.ndarray            #: (B,) m

    def __post_init__(self):
        r_m, r_n = earth.radii(self.lat0)
        self.k_n = r_m + self.h0
        self.k_e = (r_n + self.h0) * np.cos(self.lat0)
        self.g_n = earth.gravity_n(self.lat0, self.h0)                     # (B, 3)
        cl, sl = np.cos(self.lat0), np.sin(self.lat0)
        self.w_ie_n = earth.OMEGA_IE_RPS * np.stack([cl, 0 * cl, -sl], -1)

    def ned(self, lat, lon, h) -> np.ndarray:
        return np.stack([(lat - self.lat0) * self.k_n, (lon - self.lon0) * self.k_e, self.h0 - h], -1)

    def nav_state(self, q: np.ndarray, vel_n: np.ndarray, pos_n: np.ndarray) -> NavState:
        C_nb = np.empty((q.shape[0], 3, 3))
        dcm_of(np.ascontiguousarray(q, float), C_nb)           # dcm_from_quat, compiled
        return NavState(self.lat0 + pos_n[:, 0] / self.k_n, self.lon0 + pos_n[:, 1] / self.k_e,
                        self.h0 - pos_n[:, 2], vel_n.copy(), C_nb)

    def pos_to_filter_units(self) -> np.ndarray:
        """``(B, 3)`` factors from NED metres to the runner's (dlat, dlon, dh)."""
        return np.stack([1.0 / self.k_n, 1.0 / self.k_e, -np.ones_like(self.k_n)], -1)


def reference_field_uT(frame: LocalFrame, mag_data, field_n_T=None) -> np.ndarray:
    """The Earth field ``(B, 3)`` NED in uT a filter assumes: ``field_n_T`` if given, else the
    WMM at the start point on the magnetometer's date (the on-board model)."""
    B = frame.lat0.shape[0]
    if field_n_T is not None:
        return np.broadcast_to(np.asarray(field_n_T, float) / UT, (B, 3)).copy()
    date = (mag_data.meta.get("date") if mag_data is not None else None) or WMM_DATE
    f = [wmm_field_n_T(round(float(np.degrees(a)), 4), round(float(np.degrees(b)), 4),
                       round(float(c), 0), date) for a, b, c in zip(frame.lat0, frame.lon0, frame.h0)]
    return np.asarray(f) / UT


def rotate_b_to_n(q: np.ndarray, v_b: np.ndarray) -> np.ndarray:
    """``C_nb v_b`` for unit ``q_nb``, as ``v + 2 w (u x v) + 2 u x (u x v)`` (no matrix)."""
    w, u = q[:, :1], q[:, 1:]
    t = 2.0 * cross(u, v_b)
    return v_b + w * t + cross(u, t)


def rotate_n_to_b(q: np.ndarray, v_n: np.ndarray) -> np.ndarray:
    """``C_bn v_n`` for unit ``q_nb``."""
    w, u = q[:, :1], -q[:, 1:]
    t = 2.0 * cross(u, v_n)
    return v_n + w * t + cross(u, t)


__all__ = ["UT", "LocalFrame", "euler_distance2", "normalize", "omega_matrix", "psi",
           "quat_multiply", "quat_of_dcm", "reference_field_uT", "rk4_step", "rotate_b_to_n", "rotate_n_to_b",
           "xi"]
