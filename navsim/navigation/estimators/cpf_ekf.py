"""P4's 20-state quaternion EKF for attitude, with the complementary-filter divergence monitor
(CPF-EKF), batched over runs.

State (``x`` ``(B, 20)``; the magnetic states in uT to keep ``P`` well scaled):

====== ===== ============================================================================
slice  size  state
====== ===== ============================================================================
0:4    4     ``q_nb``, scalar first (body FRD to NED)
4:7    3     velocity NED, m/s
7:10   3     position NED about the start point, m (flat Earth, P4's ``S``)
10     1     z-accelerometer bias, m/s^2
11:14  3     magnetometer bias (hard iron), body, uT
14:17  3     gyro bias, rad/s
17:20  3     Earth magnetic field NED, uT
====== ===== ============================================================================

Prediction (every IMU sample): the quaternion by a fourth-order Runge-Kutta step of the
bias- and Earth-rate-corrected gyro (P4 eq. 5), velocity from the accelerometer turned by the
mid-step attitude plus gravity and Coriolis (eq. 6), position by the trapezoid (eq. 7), the
other states constant. The covariance is predicted every ``period_s`` with the Jacobian ``F``
(eq. 8) at the period's mean rate and specific force, discretised to second order, and the
process noise ``G Q G^T`` of the gyro and accelerometer noise (eq. 9-10; the accelerometer's
includes the vibration the filter's IMU model declares) plus random walks of the bias and
field states and P4's stabilising ``Qs`` on the quaternion.

Corrections:

* magnetometer, axis by axis (sequential scalar EKF updates, eq. 11-16):
  ``m_b = C_bn(q) M + m_bias``, each axis relinearised at the estimate left by the previous one;
* GNSS velocity (3) and horizontal position (2), baro height, by the linear Kalman filter
  (eq. 17-19): ``z = H x`` with ``H`` a selection.

The quaternion is kept on the unit sphere: after every correction ``q <- q / |q|`` and its
covariance is projected onto the sphere's tangent space, ``P <- J P J^T`` with
``J = blockdiag(I - q q^T, I)`` (the normalisation's Jacobian), so the filter never carries
uncertainty in a norm it cannot observe. ``P_nav`` for the runner maps ``dq`` to the NED
attitude error by ``phi = -2 Psi(q)^T dq``.

Divergence monitor (``monitor``):

* ``cpf`` (P4): a :class:`~navsim.navigation.estimators.cpf.ComplementaryCore` runs beside the EKF on the
  same data; when ``(roll1-roll2)^2 + (pitch1-pitch2)^2 + (yaw1-yaw2)^2 > threshold_rad2``
  (differences wrapped; P4: N = 0.27416, about 30 deg) for ``cycles`` consecutive epochs (P4: 3)
  -- and the CPF has had a heading reference (an accepted magnetometer sample or the GNSS
  course) within ``cpf_trust_s``, a coasting CPF being no reference -- the EKF is declared
  divergent and re-initialised: the CPF's attitude and gyro bias (the
  EKF's own was corrupted by the divergence), the initial covariance
  (with ``reset_sigma`` overriding the initial sigmas of the sensor states: a divergence says
  the magnetic model is wrong, so its uncertainty may be re-opened), the Earth-field state
  back to the reference field; velocity, position, the accelerometer and magnetometer bias
  estimates are kept with their variances (their cross-covariances with the rest dropped).
* ``innovation``: the classical test ``nu^T nu > r tr(H P H^T + R)`` on the three magnetometer
  innovations (P4 eq. 20, ``r = innovation_ratio``) for ``cycles`` consecutive magnetometer
  epochs, same reset;
* ``none``: P4's EKF alone.

Each reset is an event ``(t_s, cause)`` in ``solution().extra["resets"]`` (one list per run).

The per-sample prediction is compiled in :mod:`.attitude_kernels`, the epoch's covariance
prediction, corrections and renormalisation in :mod:`.cpf_ekf_kernels`; the monitor, the resets
and the sensors' samples stay here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations.config import Node
from navsim.navigation.estimators import cpf_ekf_kernels as kernels
from navsim.navigation.estimators.attitude import (
    UT,
    LocalFrame,
    normalize,
    psi,
    quat_of_dcm,
    reference_field_uT,
)
from navsim.navigation.estimators.attitude_config import attitude_params, attitude_schema, cpf_ekf_options
from navsim.navigation.estimators.attitude_kernels import (AZ, MB0, ME0, N_STATES, Q0, S0, V0, WB0, cpf_ekf_block,
                                                           euler_distance2)
from navsim.navigation.estimators.base import Innovation, Solution, register, sample
from navsim.navigation.estimators.cpf import ComplementaryCore, CpfGains
from navsim.navigation.strapdown import NavState

Q, V, S, MB, WB, ME = (slice(Q0, Q0 + 4), slice(V0, V0 + 3), slice(S0, S0 + 3), slice(MB0, MB0 + 3),
                       slice(WB0, WB0 + 3), slice(ME0, ME0 + 3))
MONITORS = ("cpf", "innovation", "none")
INITIAL_DEFAULTS = {"gyro_bias_rad_s": np.radians(1.0), "accel_z_bias_mps2": 0.2, "mag_bias_uT": 5.0,
                    "field_uT": 0.05}


def _dps(d: dict) -> dict:
    """``gyro_bias_dps`` (datasheet unit) as ``gyro_bias_rad_s``."""
    d = dict(d)
    if "gyro_bias_dps" in d:
        d["gyro_bias_rad_s"] = np.radians(d.pop("gyro_bias_dps"))
    return d


def _merge_known(what: str, defaults: dict, given: dict | None) -> dict:
    """``defaults`` updated with ``given``; an unknown key is a ValueError naming the known ones."""
    given = _dps(given or {})
    unknown = sorted(set(given) - set(defaults))
    if unknown:
        raise ValueError(f"{what}: unknown key(s) {', '.join(unknown)} (known: {', '.join(defaults)})")
    return {**defaults, **{k: float(v) for k, v in given.items()}}


@dataclass(frozen=True)
class CpfEkfConfig:
    """The CPF-EKF's settings (a scenario entry's keys, read by
    :func:`~navsim.navigation.estimators.attitude_config.cpf_ekf_options`).

    Attributes
    ----------
    mag, gnss, baro : str or None
        The sensors it reads (names in the scenario). Without GNSS (a replayed log), a zero
        horizontal velocity with ``no_gnss_sigma_mps`` (off unless given; ``navsim replay`` uses
        1 m/s) keeps the tilt observable, as PX4 does without aiding.
    noise : dict
        The filter's own IMU model, 1-sigma densities: ``gyro_rad_s_rthz``, ``accel_mps2_rthz``
        (white, vibration included), ``gyro_bias_walk`` (rad/s/rt s), ``accel_bias_walk``
        (m/s^2/rt s), ``mag_bias_walk_uT``, ``field_walk_uT`` (uT/rt s), ``quat_stab`` (P4's
        ``Qs``, per rt s).
    initial : dict
        1-sigma of the initial sensor states: ``gyro_bias_rad_s``, ``accel_z_bias_mps2``,
        ``mag_bias_uT``, ``field_uT``.
    mag_sigma_uT, gnss_pos_sigma_m, gnss_vel_sigma_mps, baro_sigma_m : float
        The measurement noise the filter assumes.
    monitor : {"cpf", "innovation", "none"}
    threshold_rad2, cycles, innovation_ratio : float, int, float
        P4's N (0.27416), the consecutive cycles (3) and the classical test's ``r``.
    cpf_trust_s : float
        How long the CPF stays a reference after its last heading reference.
    reset_sigma : dict
        Sigmas (keys of ``initial``) a reset re-opens instead of keeping the state's own.
    cpf : dict
        Gains of the complementary filter (the fields of :class:`~navsim.navigation.estimators.cpf.CpfGains`).
    field_n_T : list of 3 or None
        The reference Earth field (NED, T); None: the WMM at the start.
    period_s : float
        The filter epoch, s.
    """

    mag: str | None = "mag"
    gnss: str | None = "gps"
    baro: str | None = None
    period_s: float = 0.1
    noise: dict | None = None
    initial: dict | None = None
    mag_sigma_uT: float = 0.5
    gnss_pos_sigma_m: float = 2.0
    gnss_vel_sigma_mps: float = 0.1
    baro_sigma_m: float = 1.0
    no_gnss_sigma_mps: float | None = None
    monitor: str = "cpf"
    threshold_rad2: float = 0.27416
    cycles: int = 3
    innovation_ratio: float = 3.0
    cpf: dict | None = None
    field_n_T: object = None
    reset_sigma: dict | None = None
    cpf_trust_s: float = 30.0


@register("cpf_ekf")
class CpfEkf:
    """P4's CPF-EKF (see the module docstring), set by a :class:`CpfEkfConfig`."""

    SCHEMA = attitude_schema("cpf_ekf")

    def __init__(self, config: CpfEkfConfig = CpfEkfConfig()):
        c = config
        if c.monitor not in MONITORS:
            raise ValueError(f"monitor '{c.monitor}': expected one of {', '.join(MONITORS)}")
        self.config = c
        self.mag, self.gnss, self.baro, self.period_s = c.mag, c.gnss, c.baro, c.period_s
        self.noise = _merge_known("noise", {"gyro_rad_s_rthz": 1.5e-4, "accel_mps2_rthz": 0.4,
                                            "gyro_bias_walk": 1e-5, "accel_bias_walk": 1e-4,
                                            "mag_bias_walk_uT": 0.01, "field_walk_uT": 0.001,
                                            "quat_stab": 1e-5}, c.noise)
        self._noise = np.array([self.noise[k] for k in kernels.NOISE_NAMES])
        self.initial = _merge_known("initial", dict(INITIAL_DEFAULTS), c.initial)
        self.mag_sigma_uT, self.baro_sigma_m = c.mag_sigma_uT, c.baro_sigma_m
        self.gnss_pos_sigma_m, self.gnss_vel_sigma_mps = c.gnss_pos_sigma_m, c.gnss_vel_sigma_mps
        self.no_gnss_sigma_mps = c.no_gnss_sigma_mps
        self.monitor, self.threshold_rad2, self.cycles = c.monitor, c.threshold_rad2, int(c.cycles)
        self.innovation_ratio, self.field_n_T = c.innovation_ratio, c.field_n_T
        self.cpf_gains = dict(c.cpf or {})
        self.reset_sigma = {k: v for k, v in _merge_known("reset_sigma", dict(INITIAL_DEFAULTS),
                                                          c.reset_sigma).items() if k in _dps(c.reset_sigma or {})}
        self.cpf_trust_s = c.cpf_trust_s

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The CPF's keys plus ``imu`` (the filter's noise model, a catalog entry), ``sigma``,
        ``initial``, ``reset_sigma``, ``noise``, ``monitor`` and its thresholds:
        :func:`~navsim.navigation.estimators.attitude_config.attitude_params`."""
        return attitude_params(node, "cpf_ekf", sensors)

    @classmethod
    def from_params(cls, params: dict):
        return cls(CpfEkfConfig(**cpf_ekf_options(params)))

    # --- contract -----------------------------------------------------------------------------
    def initialize(self, nav0: NavState, sigma0: dict) -> None:
        B = nav0.lat_rad.shape[0]
        self.B = B
        self.frame = LocalFrame(nav0.lat_rad.copy(), nav0.lon_rad.copy(), nav0.h_m.copy())
        self.x = np.zeros((B, N_STATES))
        self.x[:, Q] = quat_of_dcm(nav0.C_nb)
        self.x[:, V] = nav0.vel_n_mps
        self.sigma0 = sigma0
        self.P = self._initial_P(self.x[:, Q])
        self.field_ready = False
        self.cpf = ComplementaryCore(CpfGains(**self.cpf_gains))
        self.cpf.start(self.x[:, Q], self.frame)
        self._sum_w = np.zeros((B, 3))
        self._sum_f = np.zeros((B, 3))
        self._elapsed = 0.0
        self.count = np.zeros(B, int)
        self.resets = [[] for _ in range(B)]
        self.diverged = np.zeros(B, bool)
        self.distance2 = np.zeros(B)
        self.t_prev = -self.period_s

    def _initial_P(self, q: np.ndarray, reset: bool = False) -> np.ndarray:
        s0, ini = self.sigma0, {**self.initial, **(self.reset_sigma if reset else {})}
        B = q.shape[0]
        P = np.zeros((B, N_STATES, N_STATES))
        Ps = psi(q)
        P[:, Q, Q] = 0.25 * Ps @ (np.asarray(s0["att"], float) ** 2 * np.eye(3)) @ np.swapaxes(Ps, -1, -2)
        P[:, V, V] = np.diag(np.asarray(s0["vel"], float) ** 2)
        pos_m = np.asarray(s0["pos"], float) / np.abs(self.frame.pos_to_filter_units())
        P[:, S, S] = pos_m[:, :, None] ** 2 * np.eye(3)
        P[:, AZ, AZ] = ini["accel_z_bias_mps2"] ** 2
        P[:, MB, MB] = np.eye(3) * ini["mag_bias_uT"] ** 2
        P[:, WB, WB] = np.eye(3) * ini["gyro_bias_rad_s"] ** 2
        P[:, ME, ME] = np.eye(3) * ini["field_uT"] ** 2
        return P

    def propagate(self, dtheta_b, dv_b, dt: float) -> None:
        """The ``K`` IMU intervals of ``(B, K, 3)`` increments (RK4 attitude, velocity and
        position, compiled: :func:`~navsim.navigation.estimators.attitude_kernels.cpf_ekf_block`;
        the CPF beside)."""
        cpf_ekf_block(self.x, self._sum_w, self._sum_f, self.frame.g_n, self.frame.w_ie_n, dtheta_b, dv_b, dt)
        for _ in range(dtheta_b.shape[1]):
            self._elapsed += dt                   # summed as the samples come (not K dt)
        self.cpf.propagate(dtheta_b, dv_b, dt)

    def epoch(self, t: float, sensors: dict) -> list[Innovation]:
        self._predict()
        out = []
        t_prev, self.t_prev = self.t_prev, t
        mag_data, j = sample(sensors, self.mag, t, t_prev)
        if not self.field_ready and (mag_data is not None or self.field_n_T is not None):
            self.field_ref = reference_field_uT(self.frame, mag_data, self.field_n_T)
            self.x[:, ME] = self.field_ref
            self.field_ready = True
        if mag_data is not None:
            out.append(self._correct_mag(t, mag_data, j))
        out += self._correct_linear(t, sensors, t_prev, mag_data is not None)
        self.cpf.aid(t, sensors, self.mag, self.gnss, self.field_n_T, t_prev)
        if self.monitor == "cpf":
            euler_distance2(self.x[:, Q], self.cpf.q, self.distance2)
            trusted = t - self.cpf.heading_t <= self.cpf_trust_s
            self._count((self.distance2 > self.threshold_rad2) & trusted, t, "cpf")
        kernels.flag_diverged(self.x, self.P, self.cpf.q, self.diverged)
        return out

    def solution(self) -> Solution:
        x = self.x
        P_nav = np.empty((self.B, 9, 9))
        kernels.navigation_covariance(x, self.P, self.frame.pos_to_filter_units(), P_nav)
        accel_bias, accel_sigma = np.zeros((self.B, 3)), np.full((self.B, 3), np.nan)
        accel_bias[:, 2], accel_sigma[:, 2] = x[:, AZ], np.sqrt(self.P[:, AZ, AZ])    # the z axis only
        gyro_sigma = np.sqrt(np.diagonal(self.P[:, WB][:, :, WB], axis1=1, axis2=2))
        return Solution(nav=self.frame.nav_state(normalize(x[:, Q]), x[:, V], x[:, S]), P_nav=P_nav,
                        gyro_bias=x[:, WB].copy(), accel_bias=accel_bias,
                        gyro_bias_sigma=gyro_sigma, accel_bias_sigma=accel_sigma,
                        extra={"diverged": self.diverged, "resets": self.resets, "P": self.P.copy(),
                               "mag_bias_T": x[:, MB] * UT, "field_n_T": x[:, ME] * UT,
                               "cpf_euler_rad": self.cpf.euler(), "distance2_rad2": self.distance2.copy()})

    # --- filter steps (compiled: :mod:`.cpf_ekf_kernels`) -----------------------------------------
    def _predict(self) -> None:
        """The covariance over the IMU samples since the last epoch, at their mean corrected
        rate and specific force (:func:`~.cpf_ekf_kernels.predict_covariance`)."""
        if self._elapsed <= 0.0:
            return
        kernels.predict_covariance(self.x, self.P, self._sum_w, self._sum_f, self._elapsed, self.frame.w_ie_n,
                                   self._noise)
        self._elapsed = 0.0

    def _correct_mag(self, t: float, data, j: int) -> Innovation:
        """The three sequential magnetometer updates (:func:`~.cpf_ekf_kernels.correct_magnetometer`),
        with ``monitor: innovation`` after P4's classical test on their prior innovations
        (:func:`~.cpf_ekf_kernels.innovation_test`), whose reset the updates start from."""
        z = np.ascontiguousarray(data.values["mag_b_T"][:, j]) / UT
        valid = np.ascontiguousarray(data.valid[:, j])
        r = self.mag_sigma_uT ** 2
        if self.monitor == "innovation":          # on the prior: a reset comes before the updates
            nu2, trace_S = np.empty(self.B), np.empty(self.B)
            kernels.innovation_test(self.x, self.P, z, r, nu2, trace_S)
            self._count((nu2 > self.innovation_ratio * trace_S) & valid, t, "innovation")
        y, S_, nis = np.empty((self.B, 3)), np.empty((self.B, 3, 3)), np.empty(self.B)
        kernels.correct_magnetometer(self.x, self.P, z, valid, r, y, S_, nis)
        return Innovation("mag", self.mag, t, y, S_, nis)

    def _correct_linear(self, t: float, sensors: dict, t_prev: float, mag_epoch: bool) -> list[Innovation]:
        """GNSS velocity + horizontal position, baro height: the linear KF (P4 eq. 17-19)."""
        out = []
        data, j = sample(sensors, self.gnss, t, t_prev)
        B = self.B
        if data is not None:
            pos = self.frame.ned(data.values["lat_rad"][:, j], data.values["lon_rad"][:, j], data.values["h_m"][:, j])
            rows, zs, rs = [S0, S0 + 1], [pos[:, :2]], [self.gnss_pos_sigma_m ** 2] * 2
            if "vel_n_mps" in data.values:
                rows, zs, rs = [V0, V0 + 1, V0 + 2] + rows, [data.values["vel_n_mps"][:, j]] + zs, [self.gnss_vel_sigma_mps ** 2] * 3 + rs
            out.append(self._linear("gnss", self.gnss, t, rows, np.concatenate(zs, -1), rs, data.valid[:, j]))
        elif self.gnss is None and mag_epoch and self.no_gnss_sigma_mps:
            # no GNSS at all (a replayed log): a zero horizontal velocity keeps the tilt observable
            out.append(self._linear("zero_velocity", "-", t, [V0, V0 + 1], np.zeros((B, 2)),
                                    [self.no_gnss_sigma_mps ** 2] * 2, np.ones(B, bool)))
        data, j = sample(sensors, self.baro, t, t_prev)
        if data is not None:
            z = (self.frame.h0 - data.values["h_baro_m"][:, j])[:, None]
            out.append(self._linear("height", self.baro, t, [S0 + 2], z, [self.baro_sigma_m ** 2], data.valid[:, j]))
        return out

    def _linear(self, name, sensor, t, rows, z, r, valid) -> Innovation:
        """The linear update of the states ``rows`` with ``z``, variances ``r``
        (:func:`~.cpf_ekf_kernels.correct_linear`)."""
        B, m = self.B, len(rows)
        y, S_, nis = np.empty((B, m)), np.empty((B, m, m)), np.empty(B)
        kernels.correct_linear(self.x, self.P, np.ascontiguousarray(z, float), np.asarray(rows, np.int64),
                               np.asarray(r, float), np.ascontiguousarray(valid, bool), y, S_, nis)
        return Innovation(name, sensor, t, y, S_, nis)

    def _count(self, test: np.ndarray, t: float, cause: str) -> None:
        """Consecutive-cycle counter of the divergence test; reset the runs that reach ``cycles``."""
        self.count = np.where(test, self.count + 1, 0)
        hit = self.count >= self.cycles
        if np.any(hit):
            self._reset(hit, t, cause)
            self.count[hit] = 0

    def _reset(self, hit: np.ndarray, t: float, cause: str) -> None:
        """Re-initialise the EKF of the runs ``hit`` from the CPF's attitude (P4)."""
        q = self.cpf.q
        self.x[hit, Q] = q[hit]
        self.x[hit, WB] = self.cpf.b[hit]            # its covariance re-initialised below
        if self.field_ready:
            self.x[hit, ME] = self.field_ref[hit]
        keep = self.P.copy()
        P0 = self._initial_P(self.x[:, Q], reset=True)
        # the accelerometer and magnetometer bias estimates are kept, with the uncertainty they had
        # unless reset_sigma re-opens it; the gyro bias, taken from the CPF, gets its initial sigma
        for blk, key in ((AZ, "accel_z_bias_mps2"), (MB, "mag_bias_uT")):
            if key not in self.reset_sigma:
                P0[:, blk, blk] = keep[:, blk, blk]
        P0[:, V, V], P0[:, S, S] = keep[:, V, V], keep[:, S, S]
        self.P = np.where(hit[:, None, None], P0, self.P)
        for b in np.flatnonzero(hit):
            self.resets[b].append((float(t), cause))

