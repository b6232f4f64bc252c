"""P4's CPF-EKF epoch compiled (:mod:`navsim.navigation.estimators.cpf_ekf_kernels`) against the
same formulas written with numpy over the batch (dense batched products: the filter as it was
written before it was compiled, issue 56): each kernel on random states, then a whole flight of
the filter with a divergence reset; the Jacobians against finite differences. A covariance is
compared entry by entry relative to ``sqrt(P_ii P_jj)`` (its entries span ten decades)."""

import numpy as np
import pytest

from navsim.experiment.driver import InitialErrors, perturbed_start
from navsim.flight.truth import Pose, Truth
from navsim.foundations.transform import dcm_from_quat, quat_from_rotvec, quat_multiply, skew
from navsim.navigation.estimators import cpf_ekf_kernels as kernels
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.attitude import UT, dcm_homogeneous, omega_matrix, psi, xi
from navsim.navigation.estimators.base import Innovation
from navsim.navigation.estimators.cpf_ekf import AZ, MB, ME, N_STATES, Q, S, V, WB, CpfEkf, CpfEkfConfig
from navsim.sensors.catalog import load_spec
from navsim.sensors.gnss import emulate_gnss
from navsim.sensors.imu import emulate_imu
from navsim.sensors.magnetometer import emulate_magnetometer

NOISE = dict(gyro_rad_s_rthz=1.5e-4, accel_mps2_rthz=0.4, gyro_bias_walk=1e-5, accel_bias_walk=1e-4,
             mag_bias_walk_uT=0.01, field_walk_uT=0.001, quat_stab=1e-5)


# --- the numpy forms --------------------------------------------------------------------------
def np_rotation_jacobian(q, f, transpose=False):
    """``d (C(q) f) / dq`` ``(B, 3, 4)`` for ``C(q) = (w^2 - v.v) I + 2 v v^T + 2 w [v x]``."""
    w, v = q[:, 0], q[:, 1:]
    s = -1.0 if transpose else 1.0
    vf = np.einsum("bi,bi->b", v, f)
    d_w = 2.0 * w[:, None] * f + s * 2.0 * np.cross(v, f)
    d_v = (-2.0 * np.einsum("bi,bj->bij", f, v) + 2.0 * vf[:, None, None] * np.eye(3)
           + 2.0 * np.einsum("bi,bj->bij", v, f) - s * 2.0 * w[:, None, None] * skew(f))
    return np.concatenate([d_w[:, :, None], d_v], axis=-1)


def np_predict(x, P, sum_w, sum_f, T, w_ie_n, nz):
    B, q = x.shape[0], x[:, Q]
    w, f = sum_w / T, sum_f / T
    F = np.zeros((B, N_STATES, N_STATES))
    Xi = xi(q)
    F[:, Q, Q] = 0.5 * omega_matrix(w)
    F[:, Q, WB] = -0.5 * Xi
    F[:, V, Q] = np_rotation_jacobian(q, f)
    F[:, V, AZ] = -dcm_from_quat(q)[:, :, 2]
    F[:, V, V] = -2.0 * skew(w_ie_n)
    F[:, S, V] = np.eye(3)
    Qc = np.zeros((B, N_STATES, N_STATES))
    Qc[:, Q, Q] = (0.25 * nz["gyro_rad_s_rthz"] ** 2) * Xi @ np.swapaxes(Xi, -1, -2) + nz["quat_stab"] ** 2 * np.eye(4)
    Qc[:, V, V] = nz["accel_mps2_rthz"] ** 2 * np.eye(3)
    Qc[:, AZ, AZ] = nz["accel_bias_walk"] ** 2
    Qc[:, MB, MB] = nz["mag_bias_walk_uT"] ** 2 * np.eye(3)
    Qc[:, WB, WB] = nz["gyro_bias_walk"] ** 2 * np.eye(3)
    Qc[:, ME, ME] = nz["field_walk_uT"] ** 2 * np.eye(3)
    Phi, Qd = kalman.discretize_series(F, Qc, T, order=2)
    return kalman.symmetrize(Phi @ P @ np.swapaxes(Phi, -1, -2) + Qd)


def np_renormalize(x, P):
    B, q = x.shape[0], x[:, Q]
    n = np.linalg.norm(q, axis=-1)
    u = q / n[:, None]
    J = np.broadcast_to(np.eye(N_STATES), (B, N_STATES, N_STATES)).copy()
    J[:, Q, Q] = (np.eye(4) - np.einsum("bi,bj->bij", u, u)) / n[:, None, None]
    x = x.copy()
    x[:, Q] = u
    return x, kalman.symmetrize(J @ P @ np.swapaxes(J, -1, -2))


def np_mag_model(x):
    q, M = x[:, Q], x[:, ME]
    C_bn = np.swapaxes(dcm_homogeneous(q), -1, -2)
    h = np.einsum("bij,bj->bi", C_bn, M) + x[:, MB]
    H = np.zeros((x.shape[0], 3, N_STATES))
    H[:, :, Q] = np_rotation_jacobian(q, M, transpose=True)
    H[:, :, MB] = np.eye(3)
    H[:, :, ME] = C_bn
    return h, H


def np_innovation_test(x, P, z, r):
    """``nu^T nu`` and ``tr(S)`` of the three magnetometer innovations at the prior."""
    h, H = np_mag_model(x)
    S_all = H @ P @ np.swapaxes(H, -1, -2) + r * np.eye(3)
    return np.einsum("bi,bi->b", z - h, z - h), np.trace(S_all, axis1=1, axis2=2)


def np_correct_mag(x, P, z, valid, r):
    """The three sequential updates; returns ``x, P, y, s``."""
    B = x.shape[0]
    y, s = np.zeros((B, 3)), np.zeros((B, 3))
    for axis in range(3):
        h, H = np_mag_model(x)
        Hi = H[:, axis:axis + 1]
        x, P, yi, Si, _ = kalman.update(x, P, z[:, axis:axis + 1] - h[:, axis:axis + 1] + (Hi @ x[..., None])[..., 0],
                                        Hi, np.full((B, 1, 1), r), valid)
        y[:, axis], s[:, axis] = yi[:, 0], Si[:, 0, 0]
    return (*np_renormalize(x, P), y, s)


def np_linear(x, P, z, rows, r, valid):
    B, m = x.shape[0], len(rows)
    H = np.zeros((B, m, N_STATES))
    H[:, np.arange(m), rows] = 1.0
    x, P, y, S_, nis = kalman.update(x, P, z, H, np.broadcast_to(np.diag(r), (B, m, m)), valid)
    return (*np_renormalize(x, P), y, S_, nis)


def np_navigation_covariance(x, P, scale):
    B = x.shape[0]
    T = np.zeros((B, 9, N_STATES))
    T[:, 0:3, Q] = -2.0 * np.swapaxes(psi(x[:, Q]), -1, -2)
    T[:, 3:6, V] = np.eye(3)
    T[:, 6:9, S] = scale[:, :, None] * np.eye(3)
    return T @ P @ np.swapaxes(T, -1, -2)


class NumpyCpfEkf(CpfEkf):
    """The CPF-EKF with its epoch in the numpy forms above."""

    def _predict(self):
        if self._elapsed > 0.0:
            self.P = np_predict(self.x, self.P, self._sum_w, self._sum_f, self._elapsed, self.frame.w_ie_n, self.noise)
            self._sum_w[:] = 0.0
            self._sum_f[:] = 0.0
            self._elapsed = 0.0

    def _correct_mag(self, t, data, j):
        z, valid, r = data.values["mag_b_T"][:, j] / UT, data.valid[:, j], self.mag_sigma_uT ** 2
        if self.monitor == "innovation":
            nu2, trace_S = np_innovation_test(self.x, self.P, z, r)
            self._count((nu2 > self.innovation_ratio * trace_S) & valid, t, "innovation")
        self.x, self.P, y, s = np_correct_mag(self.x, self.P, z, valid, r)
        nis = np.where(valid, np.sum(y * y / s, -1), np.nan)
        return Innovation("mag", self.mag, t, y, s[:, :, None] * np.eye(3), nis)

    def _linear(self, name, sensor, t, rows, z, r, valid):
        self.x, self.P, y, S_, nis = np_linear(self.x, self.P, z, rows, r, valid)
        return Innovation(name, sensor, t, y, S_, nis)


# --- random cases -----------------------------------------------------------------------------
def _case(seed, B=6):
    """Random states of realistic sizes (a quaternion not quite unit, as after a correction) and
    a random covariance with the filter's spread of scales."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(B, 4))
    q = q / np.linalg.norm(q, axis=1, keepdims=True) * (1.0 + rng.normal(size=(B, 1)) * 1e-3)
    x = np.concatenate([q, rng.normal(size=(B, 3)) * 15, rng.normal(size=(B, 3)) * 100, rng.normal(size=(B, 1)) * 0.1,
                        rng.normal(size=(B, 3)), rng.normal(size=(B, 3)) * 1e-3,
                        rng.normal(size=(B, 3)) * 20 + [20.0, -3.0, 45.0]], axis=1)
    scale = np.array([1e-2] * 4 + [0.3] * 3 + [3.0] * 3 + [0.2] + [2.0] * 3 + [1e-2] * 3 + [0.1] * 3)
    A = rng.normal(size=(B, N_STATES, N_STATES))
    P = (A @ np.swapaxes(A, -1, -2) / N_STATES + 0.1 * np.eye(N_STATES)) * np.outer(scale, scale)
    return rng, x, P


def _close_cov(got, ref, tol):
    d = np.sqrt(np.abs(np.diagonal(ref, axis1=-2, axis2=-1)))
    err = np.abs(got - ref) / (d[..., :, None] * d[..., None, :])
    return err.max() <= tol, err.max()


def _close(got, ref, tol):
    return np.abs(got - ref).max() <= tol * np.abs(ref).max()


@pytest.mark.parametrize("transpose", [False, True])
def test_the_rotation_jacobian_against_finite_differences_and_the_numpy_form(transpose):
    rng = np.random.default_rng(2)
    q, f = rng.normal(size=(4, 4)), rng.normal(size=(4, 3)) * 10
    q /= np.linalg.norm(q, axis=1, keepdims=True)

    def g(qq):        # C(q) f, C in the homogeneous form the filter uses (= dcm_from_quat on |q| = 1)
        return np.einsum("bji,bj->bi" if transpose else "bij,bj->bi", dcm_homogeneous(qq), f)

    assert np.abs(dcm_homogeneous(q) - dcm_from_quat(q)).max() < 1e-15
    num = np.stack([(g(q + e) - g(q - e)) / 2e-6 for e in np.eye(4) * 1e-6], -1)
    J = np.zeros((4, 3, 4))
    for b in range(4):
        kernels.rotation_jacobian(q[b], f[b], -1.0 if transpose else 1.0, J[b], 0, 0)
    assert np.abs(J - num).max() < 1e-7
    assert _close(J, np_rotation_jacobian(q, f, transpose), 1e-15)


def test_the_magnetometer_model_against_finite_differences_and_the_numpy_form():
    _, x, _ = _case(3, B=2)
    h, H = np.empty((2, 3)), np.empty((2, 3, N_STATES))
    C = np.empty((3, 3))
    model = lambda xx, b: (kernels.magnetometer_model(xx, h[b], H[b], C), h[b].copy())[1]
    for b in range(2):
        model(x[b], b)
    H0 = H.copy()
    num = np.zeros_like(H)
    for b in range(2):
        for k in range(N_STATES):
            e = np.zeros(N_STATES)
            e[k] = 1e-6
            num[b, :, k] = (model(x[b] + e, b) - model(x[b] - e, b)) / 2e-6
    assert np.abs(H0 - num).max() < 1e-6
    for b in range(2):
        model(x[b], b)
    h_ref, H_ref = np_mag_model(x)
    assert _close(h, h_ref, 1e-15) and _close(H0, H_ref, 1e-15)


@pytest.mark.parametrize("seed", [1, 2])
def test_the_compiled_prediction_equals_the_numpy_form(seed):
    rng, x, P = _case(seed)
    B = x.shape[0]
    sums, T, w_ie = rng.normal(size=(2, B, 3)), 0.1, rng.normal(size=(B, 3)) * 7e-5
    sums[0] *= 0.1 * T          # a turn of about 0.1 rad/s
    sums[1] = (sums[1] + [0.5, 0.0, -9.8]) * T
    ref = np_predict(x, P, sums[0], sums[1], T, w_ie, NOISE)
    got, got_w, got_f = P.copy(), sums[0].copy(), sums[1].copy()
    kernels.predict_covariance(x, got, got_w, got_f, T, w_ie, np.array([NOISE[k] for k in kernels.NOISE_NAMES]))
    ok, err = _close_cov(got, ref, 1e-13)
    assert ok, err
    assert np.array_equal(got, np.swapaxes(got, -1, -2)) and not got_w.any() and not got_f.any()
    assert _close_cov(P, ref, 1e-3)[1] > 1e-6          # the prediction changed P (not vacuous)


@pytest.mark.parametrize("seed", [3, 4])
def test_the_compiled_magnetometer_updates_and_test_equal_the_numpy_form(seed):
    rng, x, P = _case(seed)
    B = x.shape[0]
    valid = np.arange(B) % 3 != 1
    h, _ = np_mag_model(x)
    z = h + rng.normal(size=(B, 3)) * 2.0
    ref = np_correct_mag(x.copy(), P.copy(), z, valid, 0.25)
    got_x, got_P = x.copy(), P.copy()
    out = [np.empty((B, 3)), np.empty((B, 3, 3)), np.empty(B)]
    kernels.correct_magnetometer(got_x, got_P, z, valid, 0.25, *out)
    y, S_, nis = out
    assert np.array_equal(S_, np.diagonal(S_, axis1=1, axis2=2)[:, :, None] * np.eye(3))
    s_ii = np.diagonal(S_, axis1=1, axis2=2)
    assert np.array_equal(np.isnan(nis), ~valid) and _close(nis[valid], np.sum(y * y / s_ii, -1)[valid], 1e-15)
    out = [y, np.diagonal(S_, axis1=1, axis2=2)]
    assert _close(got_x, ref[0], 1e-14), np.abs(got_x - ref[0]).max()
    ok, err = _close_cov(got_P, ref[1], 1e-12)
    assert ok, err
    for g, r in zip(out, ref[2:]):
        assert _close(g, r, 1e-13)
    assert np.allclose(np.linalg.norm(got_x[:, Q], axis=1), 1.0, rtol=0, atol=1e-15)
    test = np.empty(B), np.empty(B)
    kernels.innovation_test(x, P, z, 0.25, *test)
    for g, r in zip(test, np_innovation_test(x, P, z, 0.25)):
        assert _close(g, r, 1e-13)
    # an invalid run is renormalised only: its field, biases, velocity untouched
    assert np.array_equal(got_x[~valid, 4:], x[~valid, 4:]) and not np.allclose(got_x[valid, 11:14], x[valid, 11:14])


@pytest.mark.parametrize("rows", [[4, 5, 6, 7, 8], [9]])
def test_the_compiled_linear_update_equals_the_numpy_form(rows):
    rng, x, P = _case(5)
    B, m = x.shape[0], len(rows)
    valid = np.arange(B) % 2 == 0
    z, r = x[:, rows] + rng.normal(size=(B, m)), np.linspace(0.1, 4.0, m)
    ref = np_linear(x.copy(), P.copy(), z, rows, r, valid)
    got_x, got_P = x.copy(), P.copy()
    y, S_, nis = np.empty((B, m)), np.empty((B, m, m)), np.empty(B)
    kernels.correct_linear(got_x, got_P, z, np.array(rows), r, valid, y, S_, nis)
    assert _close(got_x, ref[0], 1e-14) and _close_cov(got_P, ref[1], 1e-12)[0]
    assert _close(y, ref[2], 1e-14) and _close(S_, ref[3], 1e-14)
    assert np.array_equal(np.isnan(nis), ~valid) and _close(nis[valid], ref[4][valid], 1e-12)


def test_the_compiled_navigation_covariance_equals_the_numpy_form():
    rng, x, P = _case(6)
    scale = np.stack([1 / 6.4e6 + 0 * x[:, 0], 1 / 4.6e6 + 0 * x[:, 0], -np.ones(x.shape[0])], -1)
    got = np.empty((x.shape[0], 9, 9))
    kernels.navigation_covariance(x, P, scale, got)
    assert _close_cov(got, np_navigation_covariance(x, P, scale), 1e-14)[0]


# --- a whole flight ---------------------------------------------------------------------------
def _flight(est_class, runs, monitor, seconds=20.0):
    """P4's sensors at rest for ``seconds``; run 1's EKF knocked 40 deg in yaw at the start (the
    monitor resets it), the filter stepped IMU sample by sample with an epoch every 0.1 s."""
    truth = Truth.static(seconds, 100.0, Pose(43.88, 125.35, 220.0, 63.0, roll_deg=0.4, pitch_deg=-0.3))
    imu = emulate_imu(truth, load_spec("mpu6050"), 7, runs, keep_rates=False)
    sensors = {"mag": emulate_magnetometer(truth, load_spec("lsm303d"), 7, runs, name="mag"),
               "gps": emulate_gnss(truth, load_spec("neo_m8n"), 7, runs, name="gps")}
    initial = InitialErrors(np.full(3, 2.0), np.full(3, 0.05), np.radians([1.0, 1.0, 2.0]))
    est = est_class(CpfEkfConfig(mag="mag", gnss="gps", monitor=monitor, initial={"mag_bias_uT": 0.5},
                                 cycles=1 if monitor == "innovation" else 3))
    est.initialize(perturbed_start(truth, initial.draw(7, runs), 0),
                   initial.sigma_blocks(truth.lat_rad[0], truth.h_m[0]))
    hit = np.asarray(list(runs)) == 1
    est.x[hit, Q] = quat_multiply(quat_from_rotvec(np.radians([[0, 0, 40.0]])), est.x[hit, Q])
    dth, dv, dt = imu.values["dtheta_b_rad"], imu.values["dv_b_mps"], imu.meta["dt_s"]
    nis = []
    for i in range(1, dth.shape[1]):
        est.propagate(dth[:, i:i + 1], dv[:, i:i + 1], dt)
        if i % 5 == 0:
            nis.append([inn.nis for inn in est.epoch(imu.t_s[i], sensors)])
    return est, nis


@pytest.mark.parametrize("monitor", ["cpf", "innovation"])
def test_a_flight_of_the_compiled_filter_follows_the_numpy_filter(monitor):
    """20 s, 200 epochs, 4 runs, resets by the monitor (the CPF test resets the knocked run at
    0.3 s and another later; the innovation test at ``cycles=1`` fires often): the same resets at
    the same epochs, the state and covariance within rounding of the numpy filter's (measured
    6e-16 of the largest state, 1e-13 of ``sqrt(P_ii P_jj)``)."""
    got, got_nis = _flight(CpfEkf, range(4), monitor)
    ref, ref_nis = _flight(NumpyCpfEkf, range(4), monitor)
    assert got.resets == ref.resets and sum(map(len, got.resets)) >= 1, got.resets
    assert np.abs(got.x - ref.x).max() <= 1e-12 * np.abs(ref.x).max(), np.abs(got.x - ref.x).max()
    ok, err = _close_cov(got.P, ref.P, 1e-11)
    assert ok, err
    for g, r in zip(got_nis, ref_nis):
        np.testing.assert_allclose(np.concatenate(g), np.concatenate(r), rtol=1e-9, atol=0)


def test_a_batch_of_three_flies_as_three_single_runs_bit_for_bit():
    """With the magnetometer and GNSS, run 1 knocked and reset by the CPF monitor."""
    batch, _ = _flight(CpfEkf, range(3), "cpf", seconds=5.0)
    assert [len(r) for r in batch.resets] == [0, 1, 0]
    for i in range(3):
        one, _ = _flight(CpfEkf, [i], "cpf", seconds=5.0)
        assert np.array_equal(one.x[0], batch.x[i]) and np.array_equal(one.P[0], batch.P[i])
        assert one.resets[0] == batch.resets[i] and np.array_equal(one.cpf.q[0], batch.cpf.q[i])


def test_the_divergence_flags_equal_the_numpy_form():
    rng, x, P = _case(7, B=6)
    q = rng.normal(size=(6, 4))
    x[1, 5], P[2, 3, 7], q[3, 0] = np.nan, np.inf, np.nan
    P[4, 9, 9] = -1e-11                                        # a variance below -1e-12
    P[5, 9, 9] = -1e-13                                        # rounding: not a divergence
    got = np.zeros(6, bool)
    kernels.flag_diverged(x, P, q, got)
    ref = ~(np.all(np.isfinite(x), -1) & np.all(np.isfinite(P), (-1, -2)) & np.all(np.isfinite(q), -1)
            & np.all(np.diagonal(P, axis1=1, axis2=2) >= -1e-12, -1))
    assert np.array_equal(got, ref) and got.tolist() == [False, True, True, True, True, False]
    got[:] = True
    kernels.flag_diverged(x[:1], P[:1], q[:1], got[:1])
    assert got[0]                                              # a flag is never cleared
