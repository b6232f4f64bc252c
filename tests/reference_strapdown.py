"""The numpy strapdown mechanization, one call per IMU interval: the reference the compiled
:class:`navsim.navigation.strapdown.BlockStrapdown` is held to (the same algorithm, written with numpy
array operations instead of one loop per run; see :mod:`navsim.navigation.strapdown`)."""

import numpy as np

from navsim.foundations import earth
from navsim.foundations.transform import cross, rotation, skew
from navsim.navigation.strapdown import NavState, rates_n


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
