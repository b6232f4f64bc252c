"""The compiled strapdown (navsim.navigation.kernels.strapdown) against the numpy reference
(tests/reference_strapdown.py)."""

import numpy as np
import pytest
from reference_strapdown import Strapdown

from navsim.experiment.driver import nav_errors
from navsim.flight import fly, parse_track
from navsim.foundations import earth
from navsim.foundations.transform import dcm_from_quat, euler_from_dcm, rotation, wrap_angle
from navsim.navigation.kernels.update import feed_back, rodrigues
from navsim.navigation.strapdown import BlockStrapdown, state_from_truth
from navsim.sensors.catalog import load_spec
from navsim.sensors.imu import emulate_imu


@pytest.fixture(scope="module")
def imu():
    """A 70 s flight (straight, 120 deg turn, climb) and the increments of a noisy MEMS IMU on it."""
    truth = fly(parse_track({
        "start": {"lat_deg": 30.0, "lon_deg": 122.5, "alt_m": 150, "speed_mps": 15, "heading_deg": 0},
        "segments": [{"type": "straight", "time_s": 20}, {"type": "turn", "by_deg": 120, "bank_deg": 25},
                     {"type": "climb", "to_m": 200, "rate_mps": 2}, {"type": "straight", "time_s": 10}]}))
    data = emulate_imu(truth, load_spec("mpu6050"), 3, range(3), keep_rates=False)
    return truth, data


def integrate_numpy(truth, data, runs, n):
    sd = Strapdown(state_from_truth(truth, 0, len(runs)))
    dth, dv = data.values["dtheta_b_rad"][runs], data.values["dv_b_mps"][runs]
    sum_C, sum_dv = 0.0, 0.0
    for i in range(1, n):
        sd.step(dth[:, i], dv[:, i], data.meta["dt_s"])
        sum_C, sum_dv = sum_C + sd.state.C_nb, sum_dv + sd.dv_n
    return sd.state, (sum_C, sum_dv)


def integrate_blocks(truth, data, runs, n, size):
    sd = BlockStrapdown(state_from_truth(truth, 0, len(runs)))
    dth, dv = data.values["dtheta_b_rad"][runs], data.values["dv_b_mps"][runs]
    for a in range(1, n, size):
        sd.block(dth[:, a:min(a + size, n)], dv[:, a:min(a + size, n)], data.meta["dt_s"])
    assert sd.steps == n - 1
    return sd.state, (sd.sum_C_nb, sd.sum_dv_n_mps)


@pytest.mark.parametrize("size", [100, 7, 1])
def test_the_compiled_strapdown_follows_the_numpy_one(imu, size):
    """Over the whole flight (with turn and climb, 6900 intervals) every state agrees to 1e-9
    relative (position to 1e-12 rad), whatever the block size."""
    truth, data = imu
    n = data.values["dtheta_b_rad"].shape[1]
    ref, ref_dv = integrate_numpy(truth, data, [0, 1, 2], n)
    got, got_dv = integrate_blocks(truth, data, [0, 1, 2], n, size)
    assert np.allclose(got.vel_n_mps, ref.vel_n_mps, rtol=1e-9, atol=1e-9)
    assert np.allclose(got.C_nb, ref.C_nb, rtol=0, atol=1e-12)
    assert np.allclose(got.lat_rad, ref.lat_rad, rtol=0, atol=1e-12)
    assert np.allclose(got.lon_rad, ref.lon_rad, rtol=0, atol=1e-12)
    assert np.allclose(got.h_m, ref.h_m, rtol=0, atol=1e-6)
    assert np.allclose(got_dv[0], ref_dv[0], rtol=1e-9, atol=1e-9)      # sum of C_nb
    assert np.allclose(got_dv[1], ref_dv[1], rtol=1e-9, atol=1e-9)      # sum of dv_n
    # the free-inertial drift over the flight is real (not both integrators standing still)
    assert np.abs(ref.h_m - truth.h_m[-1]).max() > 1.0


def test_a_batch_of_three_equals_three_single_runs_bit_for_bit(imu):
    truth, data = imu
    n = 2001
    batch, batch_dv = integrate_blocks(truth, data, [0, 1, 2], n, 100)
    for r in range(3):
        one, one_dv = integrate_blocks(truth, data, [r], n, 100)
        for name in ("lat_rad", "lon_rad", "h_m", "vel_n_mps", "C_nb"):
            assert np.array_equal(getattr(one, name)[0], getattr(batch, name)[r]), name
        assert np.array_equal(one_dv[0][0], batch_dv[0][r]) and np.array_equal(one_dv[1][0], batch_dv[1][r])


def test_runs_across_tiles_large_angles_and_a_nan_stay_their_own(imu):
    """The kernel works on tiles of runs in vector lanes: 70 runs (a full tile and a part)
    equal their single runs bit for bit; a run tumbling at 20 to 40 rad/s (angles above 0.05
    rad per interval, the sine-cosine branch) follows the numpy reference, and a NaN spoils
    only its own run."""
    truth, data = imu
    n, B = 301, 70
    dth = np.repeat(data.values["dtheta_b_rad"][:, :n], 24, axis=0)[:B].copy()
    dv = np.repeat(data.values["dv_b_mps"][:, :n], 24, axis=0)[:B].copy()
    dth += np.arange(B)[:, None, None] * 1e-7                    # every run different
    dth[5, :, 0] += 0.3 + 0.1 * np.sin(np.arange(n) / 10.0)      # run 5 tumbles about x
    dv[66, 150, 1] = np.nan
    dt = data.meta["dt_s"]

    def blocks(runs):
        sd = BlockStrapdown(state_from_truth(truth, 0, len(runs)))
        for a in range(1, n, 100):
            sd.block(dth[runs, a:a + 100], dv[runs, a:a + 100], dt)
        return sd.state

    batch = blocks(list(range(B)))
    for r in (0, 5, 63, 64, 66, 69):
        one = blocks([r])
        for name in ("lat_rad", "lon_rad", "h_m", "vel_n_mps", "C_nb"):
            assert np.array_equal(getattr(one, name)[0], getattr(batch, name)[r], equal_nan=True), (r, name)
    assert np.isnan(batch.vel_n_mps[66]).all() and np.isfinite(np.delete(batch.vel_n_mps, 66, axis=0)).all()
    ref = Strapdown(state_from_truth(truth, 0, 1))
    for i in range(1, n):
        ref.step(dth[5:6, i], dv[5:6, i], dt)
    assert np.allclose(batch.C_nb[5], ref.state.C_nb[0], rtol=0, atol=1e-12)
    assert np.allclose(batch.vel_n_mps[5], ref.state.vel_n_mps[0], rtol=1e-9, atol=1e-9)
    assert abs(np.arccos((np.trace(batch.C_nb[5]) - 1) / 2) - np.arccos((np.trace(batch.C_nb[0]) - 1) / 2)) > 0.1


def test_rotation_matches_scipy_and_does_not_depend_on_the_batch():
    """exp([v x]) against scipy for small (series) and large (sine, cosine) angles, one vector
    or a stack; a rotation in a stack with a large one equals it alone, bit for bit."""
    from scipy.spatial.transform import Rotation

    from navsim.foundations.transform import rotation
    v = np.random.default_rng(4).normal(size=(50, 3)) * np.logspace(-9, 0.5, 50)[:, None]
    ref = Rotation.from_rotvec(v).as_matrix()
    assert np.abs(rotation(v) - ref).max() < 1e-15 and np.abs(rotation(v[None]) - ref[None]).max() < 1e-15
    for k in (0, 25, 49):
        assert np.abs(rotation(v[k]) - ref[k]).max() < 1e-15
        assert np.array_equal(rotation(v[k:k + 1])[0], rotation(v)[k])
    bad = v.copy()
    bad[3] = np.inf                                  # a diverged run spoils its own rotation only
    R = rotation(bad)
    assert np.isnan(R[3]).all() and np.array_equal(np.delete(R, 3, 0), np.delete(rotation(v), 3, 0))


def _kalman_case(B=7, n=16, m=3, seed=0):
    rng = np.random.default_rng(seed)
    F = rng.normal(size=(B, n, n)) * 0.1 * (rng.uniform(size=(n, n)) < 0.3)
    Qc = np.diag(rng.uniform(0.1, 1.0, n))
    A = rng.normal(size=(B, n, n))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(n)
    return F, Qc, P, rng.normal(size=(B, n)), rng.normal(size=(B, m, n)), rng.normal(size=(B, m)), rng


def test_the_compiled_kalman_steps_equal_their_formulas():
    """Series discretisation, prediction and the Joseph update against the formulas written
    with numpy (dense products, an explicit inverse), to 1e-14 of the largest entry; a run
    without a sample keeps its state and gets NaN NIS."""
    import math

    from navsim.navigation.estimators import kalman
    F, Qc, P, x, H, z, rng = _kalman_case()
    n, T, order = F.shape[-1], 1.0, 6
    Phi, Qd = kalman.discretize_series(F, Qc, T, order)
    ref_Phi, term = np.broadcast_to(np.eye(n), F.shape).copy(), np.broadcast_to(np.eye(n), F.shape).copy()
    M = np.broadcast_to(Qc, F.shape).copy()
    ref_Qd = M * T
    for k in range(1, order + 1):
        term = term @ F * (T / k)
        ref_Phi += term
        if k < order:
            M = F @ M + M @ np.swapaxes(F, -1, -2)
            ref_Qd += M * T ** (k + 1) / math.factorial(k + 1)
    close = lambda a, b: np.abs(a - b).max() <= 1e-14 * np.abs(b).max()
    assert close(Phi, ref_Phi) and close(Qd, ref_Qd) and np.array_equal(Qd, np.swapaxes(Qd, -1, -2))
    x1, P1 = kalman.predict(x, P, Phi, Qd)
    assert close(x1, (Phi @ x[..., None])[..., 0])
    assert close(P1, Phi @ P @ np.swapaxes(Phi, -1, -2) + Qd) and np.array_equal(P1, np.swapaxes(P1, -1, -2))
    R = np.diag([2.0, 3.0, 1.5])
    valid = np.array([True, False, True, True, False, True, True])
    xu, Pu, y, S, nis = kalman.update(x, P, z, H, R, valid)
    Ht = np.swapaxes(H, -1, -2)
    S_ref = H @ P @ Ht + R
    K = P @ Ht @ np.linalg.inv(S_ref)
    IKH = np.eye(n) - K @ H
    v = valid
    assert close(y, z - (H @ x[..., None])[..., 0]) and close(S, S_ref)
    assert close(xu[v], (x + (K @ (z - (H @ x[..., None])[..., 0])[..., None])[..., 0])[v])
    assert close(Pu[v], (IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2))[v])
    assert close(nis[v], np.einsum("bi,bi->b", y, np.linalg.solve(S_ref, y[..., None])[..., 0])[v])
    assert np.array_equal(xu[~v], x[~v]) and np.array_equal(Pu[~v], P[~v]) and np.isnan(nis[~v]).all()


def test_the_compiled_kalman_steps_of_a_batch_equal_single_runs_bit_for_bit():
    from navsim.navigation.estimators import kalman
    F, Qc, P, x, H, z, _ = _kalman_case()
    Phi, Qd = kalman.discretize_series(F, Qc, 1.0, 6)
    xp, Pp = kalman.predict(x, P, Phi, Qd)
    xu, Pu, *_ = kalman.update(xp, Pp, z, H, np.eye(3), None)
    for b in range(F.shape[0]):
        one = slice(b, b + 1)
        Phi1, Qd1 = kalman.discretize_series(F[one], Qc, 1.0, 6)
        x1, P1 = kalman.predict(x[one], P[one], Phi1, Qd1)
        x1, P1, *_ = kalman.update(x1, P1, z[one], H[one], np.eye(3), None)
        assert np.array_equal(Phi1[0], Phi[b]) and np.array_equal(Qd1[0], Qd[b])
        assert np.array_equal(x1[0], xu[b]) and np.array_equal(P1[0], Pu[b])


def test_the_compiled_navigation_errors_equal_their_formulas(imu):
    """``montecarlo.nav_errors`` (compiled) against the same errors written with numpy, for a
    truth sample shared by the runs and for one per run, with a yaw error across +-pi."""
    truth, _ = imu
    k, B = 1234, 4
    rng = np.random.default_rng(5)
    nav = state_from_truth(truth, k, B)
    nav.C_nb = rotation(rng.normal(size=(B, 3)) * 1e-2) @ nav.C_nb
    nav.C_nb[3] = rotation(np.array([0.0, 0.0, 3.1])) @ nav.C_nb[3]
    nav.vel_n_mps = nav.vel_n_mps + rng.normal(size=(B, 3))
    nav.lat_rad, nav.lon_rad = nav.lat_rad + rng.normal(size=B) * 1e-6, nav.lon_rad + rng.normal(size=B) * 1e-6
    nav.h_m = nav.h_m + rng.normal(size=B) * 5

    def numpy_errors(C_true, vel, lat, lon, h, euler):
        E = nav.C_nb @ np.swapaxes(C_true, -1, -2)
        phi = 0.5 * np.stack([E[:, 1, 2] - E[:, 2, 1], E[:, 2, 0] - E[:, 0, 2], E[:, 0, 1] - E[:, 1, 0]], -1)
        r_m, r_n = earth.radii(lat)
        dlat, dlon, dh = nav.lat_rad - lat, nav.lon_rad - lon, nav.h_m - h
        pos_m = np.stack([dlat * (r_m + h), dlon * (r_n + h) * np.cos(lat), -dh], -1)
        return (phi, nav.vel_n_mps - vel, pos_m, np.stack([dlat, dlon, dh], -1),
                wrap_angle(euler_from_dcm(nav.C_nb) - euler))

    got = nav_errors(nav, truth, k)
    want = numpy_errors(dcm_from_quat(truth.quat_nb[k]), truth.vel_n_mps[k], truth.lat_rad[k], truth.lon_rad[k],
                        truth.h_m[k], truth.euler_rad[k])
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-15)
    assert abs(got[4][3, 2]) > 3.0 and abs(got[4][3, 2]) < np.pi      # wrapped, not 3.1 - 2 pi

    class PerRun:            # one true state per run: sample k of the runs are samples k..k+3
        lat_rad, lon_rad, h_m = (truth.lat_rad[None, k:k + B], truth.lon_rad[None, k:k + B], truth.h_m[None, k:k + B])
        vel_n_mps, quat_nb, euler_rad = (truth.vel_n_mps[None, k:k + B], truth.quat_nb[None, k:k + B],
                                         truth.euler_rad[None, k:k + B])
    got = nav_errors(nav, PerRun, 0)
    s = slice(k, k + B)
    want = numpy_errors(dcm_from_quat(truth.quat_nb[s]), truth.vel_n_mps[s], truth.lat_rad[s], truth.lon_rad[s],
                        truth.h_m[s], truth.euler_rad[s])
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-15)


def test_the_compiled_feedback_equals_the_rotation_and_subtractions():
    """``feed_back``: ``C <- rotation(phi) C`` (its compiled Rodrigues, below and above the
    series' 0.05 rad, to 1e-15), the velocity and position less their errors; a NaN error
    spoils its own run only."""
    rng = np.random.default_rng(7)
    B, n = 5, 16
    x = rng.normal(0, 1e-3, (B, n))
    x[1, 0:3] = [0.2, -0.1, 0.3]                  # above the series' range
    x[4, 3] = np.nan
    C = np.stack([rotation(rng.normal(0, 1, 3)) for _ in range(B)])
    vel, lat, lon, h = rng.normal(0, 10, (B, 3)), rng.uniform(0, 1, B), rng.uniform(0, 2, B), rng.uniform(0, 500, B)
    want = (rotation(x[:, 0:3]) @ C, vel - x[:, 3:6], lat - x[:, 6], lon - x[:, 7], h - x[:, 8])
    got = [a.copy() for a in (C, vel, lat, lon, h)]
    feed_back(x, 0, 3, 6, *got)
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-15 * np.nanmax(np.abs(w)))
    assert np.isnan(got[1][4, 0]) and np.isfinite(got[1][:4]).all()
    R = np.empty((3, 3))
    rodrigues(np.nan, 0.0, 0.0, R)
    assert np.isnan(R).any()
