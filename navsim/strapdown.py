"""Batched strapdown mechanization in the local-level NED frame.

State of ``B`` runs (:class:`NavState`): geodetic latitude, longitude, height, NED velocity and
``C_nb``. :func:`step` advances it with one IMU interval's increments ``dtheta_b``, ``dv_b``
(``(B, 3)``) using the previous interval's increments for coning and sculling compensation:

* attitude: ``C_nb <- C_nn(-omega_in^n dt) C_nb C_bb(dtheta + dtheta_prev x dtheta / 12)``;
* velocity: ``v <- v + C_nb [dv + dtheta x dv / 2 + (dtheta_prev x dv + dv_prev x dtheta) / 12]
  - (omega_in dt / 2) x (...) + (g - (2 omega_ie + omega_en) x v) dt``;
* position: trapezoid on the old and new velocities, WGS-84 radii.

Gravity is :func:`navsim.earth.gravity_n` (WGS-84 with J2, as JSBSim), Earth rate and transport
rate are included. Arrays broadcast over the leading run axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim import earth, kernels


@dataclass
class NavState:
    lat_rad: np.ndarray      #: (B,)
    lon_rad: np.ndarray      #: (B,)
    h_m: np.ndarray          #: (B,)
    vel_n_mps: np.ndarray    #: (B, 3)
    C_nb: np.ndarray         #: (B, 3, 3)

    def copy(self) -> "NavState":
        return NavState(self.lat_rad.copy(), self.lon_rad.copy(), self.h_m.copy(),
                        self.vel_n_mps.copy(), self.C_nb.copy())


def cross(a, b):
    """Cross product of ``(..., 3)`` arrays (faster than ``np.cross`` for small batches)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def skew(v):
    """``[v x]`` of ``(..., 3)`` vectors, ``(..., 3, 3)``."""
    v = np.asarray(v, float)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def rotation(rotvec):
    """Rotation matrix ``exp([rotvec x])`` of ``(..., 3)`` rotation vectors (Rodrigues):
    ``I + s K + c K^2`` with ``K^2 = v v^T - |v|^2 I``; the Taylor series of ``s`` and ``c``
    (exact to 1e-16) when every angle is below 0.05 rad, as IMU steps are."""
    rotvec = np.asarray(rotvec, float)
    a2 = np.einsum("...i,...i->...", rotvec, rotvec)
    if np.all(a2 < 2.5e-3):
        s = 1.0 - a2 * (1.0 / 6.0) + a2 * a2 * (1.0 / 120.0) - a2 ** 3 * (1.0 / 5040.0)
        c = 0.5 - a2 * (1.0 / 24.0) + a2 * a2 * (1.0 / 720.0) - a2 ** 3 * (1.0 / 40320.0)
    else:
        small = a2 < 1e-8
        safe = np.where(small, 1.0, np.sqrt(a2))
        s = np.where(small, 1.0 - a2 / 6.0, np.sin(safe) / safe)
        c = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    x, y, z = rotvec[..., 0], rotvec[..., 1], rotvec[..., 2]
    R = np.empty(rotvec.shape[:-1] + (3, 3))
    cx, cy = c * x, c * y
    R[..., 0, 0] = 1.0 - c * (y * y + z * z)
    R[..., 1, 1] = 1.0 - c * (x * x + z * z)
    R[..., 2, 2] = 1.0 - c * (x * x + y * y)
    R[..., 0, 1] = cx * y - s * z
    R[..., 1, 0] = cx * y + s * z
    R[..., 0, 2] = cx * z + s * y
    R[..., 2, 0] = cx * z - s * y
    R[..., 1, 2] = cy * z - s * x
    R[..., 2, 1] = cy * z + s * x
    return R


def rates_n(lat, h, vel_n):
    """Earth rate ``omega_ie^n`` and transport rate ``omega_en^n`` ``(B, 3)``, and the radii."""
    r_m, r_n = earth.radii(lat)
    cl, sl = np.cos(lat), np.sin(lat)
    w_ie = earth.OMEGA_IE_RPS * np.stack([cl, np.zeros_like(cl), -sl], axis=-1)
    vn, ve = vel_n[..., 0], vel_n[..., 1]
    w_en = np.stack([ve / (r_n + h), -vn / (r_m + h), -ve * np.tan(lat) / (r_n + h)], axis=-1)
    return w_ie, w_en, r_m, r_n


class Strapdown:
    """Free-inertial integration of IMU increments, batch-first.

    ``gravity_every`` IMU steps share one evaluation of gravity, Earth rate, transport rate and
    radii (at UAV speeds they change by less than 1e-7 of themselves in 0.1 s).
    """

    def __init__(self, state: NavState, gravity_every: int = 10):
        self.state = state
        self.dtheta_prev = np.zeros_like(state.vel_n_mps)
        self.dv_prev = np.zeros_like(state.vel_n_mps)
        self.gravity_every = gravity_every
        self._g = None
        self._k = 0
        self.first = True

    def step(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float) -> NavState:
        """Advance by one IMU interval; ``self.dv_n`` keeps the interval's specific-force
        velocity increment in NED (for the filters' averaged specific force)."""
        s = self.state
        if self.first:               # no previous interval: no coning/sculling terms
            self.dtheta_prev, self.dv_prev = dtheta_b, dv_b
            self.first = False
        every = self.gravity_every
        if self._k % every == 0:
            self._g = earth.gravity_n(s.lat_rad, s.h_m)
            self._w_ie, self._w_en, self._r_m, self._r_n = rates_n(s.lat_rad, s.h_m, s.vel_n_mps)
            self._w_in = self._w_ie + self._w_en
            self._cor = 2.0 * self._w_ie + self._w_en
            # the navigation frame turns by w_in dt (< 1e-6 rad) a step
            self._C_nn = np.eye(3) - skew(self._w_in * dt)
        self._k += 1
        r_m, r_n, w_in = self._r_m, self._r_n, self._w_in
        dth, dv, dth_p, dv_p = dtheta_b, dv_b, self.dtheta_prev, self.dv_prev
        # rotation and sculling compensation: dv + dth x dv / 2 + (dth_p x dv + dv_p x dth) / 12
        dv_c = dv + cross(0.5 * dth + dth_p * (1.0 / 12.0), dv) + cross(dv_p, dth) * (1.0 / 12.0)
        # coning compensation
        dth_c = dth + cross(dth_p, dth) * (1.0 / 12.0)
        C = s.C_nb
        dv_n = np.einsum("bij,bj->bi", C, dv_c)
        dv_n -= (0.5 * dt) * cross(w_in, dv_n)
        self.dv_n = dv_n
        v_old = s.vel_n_mps
        v_new = v_old + dv_n + (self._g - cross(self._cor, v_old)) * dt
        # attitude
        C = self._C_nn @ (C @ rotation(dth_c))
        s.C_nb = C
        # position (trapezoid)
        v_mid = 0.5 * (v_old + v_new)
        h_new = s.h_m - v_mid[:, 2] * dt
        h_mid = 0.5 * (s.h_m + h_new)
        lat_new = s.lat_rad + v_mid[:, 0] * dt / (r_m + h_mid)
        s.lon_rad = s.lon_rad + v_mid[:, 1] * dt / ((r_n + h_mid) * np.cos(0.5 * (s.lat_rad + lat_new)))
        s.lat_rad, s.h_m, s.vel_n_mps = lat_new, h_new, v_new
        if self._k % 1000 == 0:         # keep C_nb orthonormal
            s.C_nb = 1.5 * C - 0.5 * C @ np.swapaxes(C, -1, -2) @ C
        self.dtheta_prev, self.dv_prev = dth, dv
        return s


class BlockStrapdown:
    """:class:`Strapdown` compiled: a whole block of IMU intervals per call
    (:func:`navsim.kernels.strapdown_block`), the same algorithm to rounding (held to it by a
    test), one loop per run.

    Parameters
    ----------
    state : NavState
        The start; integrated in place.
    gravity_every : int
        IMU steps sharing one evaluation of gravity, rates and radii.
    """

    def __init__(self, state: NavState, gravity_every: int = 10):
        self.state = state
        self.gravity_every = gravity_every
        B = state.lat_rad.shape[0]
        self.dtheta_prev = np.zeros((B, 3))
        self.dv_prev = np.zeros((B, 3))
        self._cache = np.zeros((B, kernels.CACHE_SIZE))
        self._k = 0

    def block(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float) -> np.ndarray:
        """Advance by the ``K`` intervals of ``dtheta_b``, ``dv_b`` ``(B, K, 3)``; returns each
        interval's specific-force velocity increment in NED ``(B, K, 3)``."""
        s = self.state
        dtheta_b = np.ascontiguousarray(dtheta_b, float)
        dv_b = np.ascontiguousarray(dv_b, float)
        if self._k == 0:              # no previous interval: no coning/sculling terms
            self.dtheta_prev, self.dv_prev = dtheta_b[:, 0].copy(), dv_b[:, 0].copy()
        for name in ("lat_rad", "lon_rad", "h_m", "vel_n_mps", "C_nb"):
            setattr(s, name, np.ascontiguousarray(getattr(s, name), float))
        dv_n = np.empty_like(dv_b)
        kernels.strapdown_block(s.lat_rad, s.lon_rad, s.h_m, s.vel_n_mps, s.C_nb, self.dtheta_prev,
                                self.dv_prev, self._cache, dtheta_b, dv_b, float(dt), self._k,
                                self.gravity_every, dv_n)
        self._k += dtheta_b.shape[1]
        return dv_n


def state_from_truth(truth, k: int = 0, runs: int = 1) -> NavState:
    """The true navigation state at truth sample ``k``, repeated for ``runs``."""
    from navsim.transform import dcm_from_quat
    rep = lambda x: np.repeat(np.asarray(x, float)[None], runs, axis=0)
    return NavState(rep(truth.lat_rad[k]), rep(truth.lon_rad[k]), rep(truth.h_m[k]),
                    rep(truth.vel_n_mps[k]), rep(dcm_from_quat(truth.quat_nb[k])))
