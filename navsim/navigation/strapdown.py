"""Batched strapdown mechanization in the local-level NED frame.

State of ``B`` runs (:class:`NavState`): geodetic latitude, longitude, height, NED velocity and
``C_nb``. :class:`BlockStrapdown` advances it over a block of IMU intervals, each with its
increments ``dtheta_b``, ``dv_b`` and the previous interval's, for coning and sculling
compensation:

* attitude: ``C_nb <- C_nn(-omega_in^n dt) C_nb C_bb(dtheta + dtheta_prev x dtheta / 12)``;
* velocity: ``v <- v + C_nb [dv + dtheta x dv / 2 + (dtheta_prev x dv + dv_prev x dtheta) / 12]
  - (omega_in dt / 2) x (...) + (g - (2 omega_ie + omega_en) x v) dt``;
* position: trapezoid on the old and new velocities, WGS-84 radii.

Gravity is :func:`navsim.foundations.earth.gravity_n` (WGS-84 with J2, as JSBSim), Earth rate and transport
rate are included. Arrays broadcast over the leading run axis. The per-interval loop is compiled
(:mod:`navsim.navigation.kernels.strapdown`, where the same formulas are written out per component).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from navsim.foundations import earth
from navsim.foundations.transform import dcm_from_quat
from navsim.navigation.kernels.strapdown import CACHE_SIZE, strapdown_block


@dataclass
class NavState:
    """The navigation state of ``B`` runs: geodetic position (WGS-84), velocity in NED and the
    body-to-NED direction-cosine matrix."""

    lat_rad: np.ndarray      #: (B,) latitude, rad
    lon_rad: np.ndarray      #: (B,) longitude, rad
    h_m: np.ndarray          #: (B,) height above the ellipsoid, m
    vel_n_mps: np.ndarray    #: (B, 3) velocity north, east, down, m/s
    C_nb: np.ndarray         #: (B, 3, 3) body (FRD) to NED, dimensionless

    def copy(self) -> "NavState":
        """A copy whose arrays are copies."""
        return NavState(self.lat_rad.copy(), self.lon_rad.copy(), self.h_m.copy(),
                        self.vel_n_mps.copy(), self.C_nb.copy())

    def contiguous(self) -> "NavState":
        """Each field made a contiguous float array, in place (what the compiled kernels change
        in place: the strapdown, the filters' feedback); returns itself."""
        for f in fields(self):
            setattr(self, f.name, np.ascontiguousarray(getattr(self, f.name), float))
        return self


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
    compiled (:func:`navsim.navigation.kernels.strapdown.strapdown_block`, runs side by side in vector lanes).
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
        self._cache = np.zeros((B, CACHE_SIZE))
        self._k = 0
        self.reset_sums()

    def reset_sums(self) -> None:
        """Start new sums of ``C_nb`` and ``dv_n`` (a filter epoch)."""
        B = self.state.lat_rad.shape[0]
        self.sum_C_nb = np.zeros((B, 3, 3))
        self.sum_dv_n_mps = np.zeros((B, 3))
        self.steps = 0

    def follow(self, state: NavState, sum_C_nb: np.ndarray, sum_dv_n_mps: np.ndarray, steps: int) -> None:
        """Take ``steps`` intervals as flown instead of mechanizing them (a covariance analysis
        along the truth, :mod:`navsim.navigation.covariance`): ``state`` at their end, their
        sums of ``C_nb`` and of the specific-force increments in NED added to the sums."""
        self.state = state
        self.sum_C_nb = self.sum_C_nb + sum_C_nb
        self.sum_dv_n_mps = self.sum_dv_n_mps + sum_dv_n_mps
        self.steps += steps

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
        s.contiguous()
        strapdown_block(s.lat_rad, s.lon_rad, s.h_m, s.vel_n_mps, s.C_nb, self.dtheta_prev,
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
