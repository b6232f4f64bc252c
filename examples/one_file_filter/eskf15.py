"""eskf15: a 15-state error-state Kalman filter for one vehicle, in one file (filterpy-style),
written by ``navsim new estimator eskf15``: change it into yours.

Run it on P3's flight beside navsim's own 15-state ES-KF, and its test::

    navsim run eskf15_p3.yaml --plugin eskf15.py
    python -m pytest test_eskf15.py

States (navsim's error states: estimate minus truth): attitude error ``phi`` (rad, N E D, with
``C_nb_est = (I - [phi x]) C_nb``), velocity error (m/s), position error (latitude and longitude
in rad, height in m), and the residual gyro and accelerometer biases ``b - b_est`` (rad/s, m/s²,
body). The error dynamics over an epoch, with the mean attitude ``C`` and specific force ``f_n``
since the last one (Earth rate and transport rate left out: a prototype)::

    phi' = -C db_g      dv' = [f_n x] phi + C db_a      dL' = dv_N / (R_M + h)
    dlambda' = dv_E / ((R_N + h) cos L)      dh' = -dv_D      db_g' = w_g      db_a' = w_a

A GNSS fix corrects position (and velocity, when the receiver gives it), the errors are fed
back into the strapdown and the bias estimates, the state is zeroed (closed loop).

Scenario keys: ``imu`` (the filter's IMU model, a catalog name), ``gnss`` (the sensor's name),
``sigma_m`` (N E D, m), ``sigma_mps`` (m/s), ``period_s`` (s).
"""

import numpy as np

from navsim.plugin import (VehicleFilter, VehicleInnovation, VehicleSolution, VehicleStrapdown, imu_spec, radii,
                           register, remove_errors, skew)

ATT, VEL, POS, BG, BA = (slice(i, i + 3) for i in range(0, 15, 3))


@register("eskf15")
class Eskf15(VehicleFilter):
    """P3's 15 states for one vehicle, numpy only."""

    def __init__(self, imu="p3_imu", gnss="gps", sigma_m=(2.0, 2.0, 1.0), sigma_mps=0.05, period_s=1.0):
        spec = imu_spec(imu)
        g, a = spec.gyro, spec.accel
        self.period_s, self.gnss = float(period_s), gnss
        self.sigma_m, self.sigma_mps = np.asarray(sigma_m, float), float(sigma_mps)
        # continuous process-noise densities: white noise on att and vel, the biases' random walk
        self.q = np.concatenate([g.noise_density ** 2, a.noise_density ** 2,
                                 np.maximum(g.random_walk, 1e-12) ** 2, np.maximum(a.random_walk, 1e-12) ** 2])
        self.bias_sigma0 = np.concatenate([np.hypot(g.bias_sigma, g.bias), np.hypot(a.bias_sigma, a.bias)])

    def initialize(self, nav0, P0):
        self.ins = VehicleStrapdown(nav0)
        self.P = np.zeros((15, 15))
        self.P[:9, :9] = P0
        self.P[9:, 9:] = np.diag(self.bias_sigma0 ** 2)
        self.bg, self.ba, self.dt = np.zeros(3), np.zeros(3), None

    def predict(self, imu):
        self.ins.step(imu, self.bg, self.ba)
        self.dt = imu.dt

    def _time_update(self):
        C, f_n, T = self.ins.since_epoch(self.dt)
        nav = self.ins.nav
        lat, h = nav.lat_rad[0], nav.h_m[0]
        r_m, r_n = radii(lat)
        F = np.zeros((15, 15))
        F[ATT, BG] = -C
        F[VEL, ATT] = skew(f_n)
        F[VEL, BA] = C
        F[6, 3] = 1.0 / (r_m + h)
        F[7, 4] = 1.0 / ((r_n + h) * np.cos(lat))
        F[8, 5] = -1.0
        Phi = np.eye(15) + F * T + F @ F * (T * T / 2)
        Q = np.zeros((15, 15))
        Q[np.r_[0:6, 9:15], np.r_[0:6, 9:15]] = self.q * T
        self.P = Phi @ self.P @ Phi.T + Q

    def _correct(self, z, H, R, name):
        """One Kalman update (Joseph form) of the zero error state; returns the innovation."""
        S = H @ self.P @ H.T + R
        K = np.linalg.solve(S, H @ self.P).T
        x = K @ z
        IKH = np.eye(15) - K @ H
        self.P = IKH @ self.P @ IKH.T + K @ R @ K.T
        remove_errors(self.ins.nav, x[ATT], x[VEL], x[POS])
        self.bg += x[BG]
        self.ba += x[BA]
        return VehicleInnovation(name, self.gnss, z, S)

    def update(self, t_s, samples):
        if self.dt is not None:                 # an epoch before any IMU interval has nothing to predict
            self._time_update()
        fix = samples.get(self.gnss)
        if fix is None:
            return []
        nav, v = self.ins.nav, fix.values
        r_m, r_n = radii(nav.lat_rad[0])
        h = nav.h_m[0]
        to_rad = np.array([1.0 / (r_m + h), 1.0 / ((r_n + h) * np.cos(nav.lat_rad[0])), 1.0])
        z = np.array([nav.lat_rad[0] - v["lat_rad"], nav.lon_rad[0] - v["lon_rad"], h - v["h_m"]])
        H = np.zeros((3, 15))
        H[:, POS] = np.eye(3)
        out = [self._correct(z, H, np.diag((self.sigma_m * to_rad) ** 2), "gnss_position")]
        if "vel_n_mps" in v:
            H = np.zeros((3, 15))
            H[:, VEL] = np.eye(3)
            out.append(self._correct(nav.vel_n_mps[0] - v["vel_n_mps"], H, np.eye(3) * self.sigma_mps ** 2,
                                     "velocity"))
        return out

    def solution(self):
        return VehicleSolution(nav=self.ins.nav, P=self.P[:9, :9].copy(), gyro_bias=self.bg.copy(),
                               accel_bias=self.ba.copy())
