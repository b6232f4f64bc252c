"""Batched strapdown mechanization in the local-level NED frame.

State of ``B`` runs (:class:`NavState`): geodetic latitude, longitude, height, NED velocity and
``C_nb``. :class:`BlockStrapdown` advances it over a block of IMU intervals, each with its
increments ``dtheta_b``, ``dv_b`` and the previous interval's, for coning and sculling
compensation:

* attitude: ``C_nb <- C_nn(-omega_in^n dt) C_nb C_bb(dtheta + dtheta_prev x dtheta / 12)``;
* velocity: ``v <- v + C_nb [dv + dtheta x dv / 2 + (dtheta_prev x dv + dv_prev x dtheta) / 12]
  - (omega_in dt / 2) x (...) + (g - (2 omega_ie + omega_en) x v) dt``;
* position: trapezoid on the old and new velocities, WGS-84 radii.

Gravity is :func:`navsim.earth.gravity_n` (WGS-84 with J2, as JSBSim), Earth rate and transport
rate are included. Arrays broadcast over the leading run axis. The per-interval loop is compiled
(:mod:`navsim.kernels`, where the same formulas are written out per component).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim import earth, kernels
from navsim.transform import dcm_from_quat


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
    (exact to 1e-16) for angles below 0.05 rad, as IMU steps are, :mod:`math`'s sine and cosine
    above, vector by vector (a batch of rotations equals the rotations one by one, bit for
    bit: numpy's vectorised sine may round differently for another array length)."""
    rotvec = np.asarray(rotvec, float)
    x, y, z = rotvec[..., 0], rotvec[..., 1], rotvec[..., 2]
    a2 = np.asarray(x * x + y * y + z * z)
    with np.errstate(invalid="ignore", over="ignore"):      # a diverged run: its own NaN
        s = np.array(1.0 - a2 * (1.0 / 6.0) + a2 * a2 * (1.0 / 120.0) - a2 ** 3 * (1.0 / 5040.0))
        c = np.array(0.5 - a2 * (1.0 / 24.0) + a2 * a2 * (1.0 / 720.0) - a2 ** 3 * (1.0 / 40320.0))
    for i in np.flatnonzero(a2 >= 2.5e-3):     # rare: element by element, so no run's
        a = math.sqrt(a2.flat[i])               # rotation depends on the others'
        if math.isfinite(a):
            s.flat[i], c.flat[i] = math.sin(a) / a, (1.0 - math.cos(a)) / a2.flat[i]
        else:                                   # a diverged run: NaN, its own only
            s.flat[i] = c.flat[i] = math.nan
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


class BlockStrapdown:
    """The mechanization of the module docstring over a whole block of IMU intervals per call,
    compiled (:func:`navsim.kernels.strapdown_block`, runs side by side in vector lanes).
    ``gravity_every`` IMU steps share one evaluation of gravity, Earth rate, transport rate and
    radii (at UAV speeds they change by less than 1e-7 of themselves in 0.1 s). The tests hold it to a numpy
    reference of the same algorithm (``tests/reference_strapdown.py``) to 1e-9.

    Parameters
    ----------
    state : NavState
        The start; integrated in place.
    gravity_every : int
        IMU steps sharing one evaluation of gravity, rates and radii.

    Attributes
    ----------
    sum_C_nb : (B, 3, 3) array
        ``C_nb`` after each interval since the last :meth:`reset_sums`, added up.
    sum_dv_n_mps : (B, 3) array
        The intervals' specific-force velocity increments in NED since then, added up.
    steps : int
        The intervals since then.
    """

    def __init__(self, state: NavState, gravity_every: int = 10):
        self.state = state
        self.gravity_every = gravity_every
        B = state.lat_rad.shape[0]
        self.dtheta_prev = np.zeros((B, 3))
        self.dv_prev = np.zeros((B, 3))
        self._cache = np.zeros((B, kernels.CACHE_SIZE))
        self._k = 0
        self.reset_sums()

    def reset_sums(self) -> None:
        """Start new sums of ``C_nb`` and ``dv_n`` (a filter epoch)."""
        B = self.state.lat_rad.shape[0]
        self.sum_C_nb = np.zeros((B, 3, 3))
        self.sum_dv_n_mps = np.zeros((B, 3))
        self.steps = 0

    def block(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float, gyro_bias: np.ndarray | None = None,
              accel_bias: np.ndarray | None = None) -> NavState:
        """Advance by the ``K`` intervals of the increments ``dtheta_b`` (rad), ``dv_b`` (m/s),
        ``(B, K, 3)``, of ``dt`` (s) each, less ``gyro_bias`` (rad/s) and ``accel_bias``
        (m/s^2) ``(B, 3)`` times ``dt`` when given; returns the state."""
        s = self.state
        bias = lambda b: np.zeros((dtheta_b.shape[0], 3)) if b is None else np.ascontiguousarray(b, float)
        bg, ba = bias(gyro_bias), bias(accel_bias)
        if self._k == 0:              # no previous interval: no coning/sculling terms
            self.dtheta_prev = np.array(dtheta_b[:, 0] - bg * dt, float)
            self.dv_prev = np.array(dv_b[:, 0] - ba * dt, float)
        for name in ("lat_rad", "lon_rad", "h_m", "vel_n_mps", "C_nb"):
            setattr(s, name, np.ascontiguousarray(getattr(s, name), float))
        kernels.strapdown_block(s.lat_rad, s.lon_rad, s.h_m, s.vel_n_mps, s.C_nb, self.dtheta_prev,
                                self.dv_prev, self._cache, _rows_in_order(dtheta_b), _rows_in_order(dv_b),
                                bg, ba, float(dt), self._k, self.gravity_every, self.sum_C_nb, self.sum_dv_n_mps)
        self._k += dtheta_b.shape[1]
        self.steps += dtheta_b.shape[1]
        return s


def _rows_in_order(x) -> np.ndarray:
    """``x`` as a C-contiguous float array: the kernel reads each run's increments in memory
    order (a view of a whole flight's samples would put the runs megabytes apart; copying the
    block first is measured 15 % faster on P0)."""
    return np.ascontiguousarray(x, float)


def state_from_truth(truth, k: int = 0, runs: int = 1) -> NavState:
    """The true navigation state at truth sample ``k``, repeated for ``runs``."""
    rep = lambda x: np.repeat(np.asarray(x, float)[None], runs, axis=0)
    return NavState(rep(truth.lat_rad[k]), rep(truth.lon_rad[k]), rep(truth.h_m[k]),
                    rep(truth.vel_n_mps[k]), rep(dcm_from_quat(truth.quat_nb[k])))
