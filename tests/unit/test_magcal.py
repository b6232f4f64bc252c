"""The online magnetometer calibration (navsim.navigation.magcal) on synthetic data of known hard and soft
iron, and the magnetic-heading measurement's H against finite differences."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navsim.foundations.transform import rotation
from navsim.navigation import magcal
from navsim.navigation.estimators.measurements import magnetic_heading
from navsim.sensors.magnetometer import wmm_field_n_T

FIELD_N_T = np.array([33.8e-6, -2.9e-6, 36.9e-6])         # WMM near Wuhan, |m| = 50.1 uT
R_T = float(np.linalg.norm(FIELD_N_T))
HARD_T = np.array([25e-6, -15e-6, 10e-6])
SOFT = np.array([[1.04, 0.03, -0.02], [0.03, 0.97, 0.04], [-0.02, 0.04, 1.01]])


def measurements(B, N, noise_T, seed, soft=SOFT):
    """``(B, N, 3)`` body-field measurements over uniformly random attitudes."""
    rng = np.random.default_rng(seed)
    C_bn = Rotation.random(B * N, random_state=rng).as_matrix().reshape(B, N, 3, 3)
    m = np.einsum("ij,bnjk,k->bni", soft, C_bn, FIELD_N_T) + HARD_T
    return m + rng.standard_normal(m.shape) * noise_T


def fit(m, noise_T=0.0, forgetting=1.0, chunk=None):
    f = magcal.EllipsoidRLS(np.full(m.shape[0], R_T), noise_T, forgetting)
    chunk = chunk or m.shape[1]
    for a in range(0, m.shape[1], chunk):
        f.update(m[:, a:a + chunk])
    return f


def test_noise_free_fit_recovers_hard_and_soft_iron_exactly():
    hard, soft, ok = fit(measurements(4, 200, 0.0, 1)).estimate()
    assert ok.all()
    np.testing.assert_allclose(hard, np.broadcast_to(HARD_T, (4, 3)), atol=1e-12)
    np.testing.assert_allclose(soft, np.broadcast_to(SOFT, (4, 3, 3)), atol=1e-7)   # the weak prior


def test_a_hard_iron_as_large_as_the_field_is_recovered():
    # |b| = |m|: the origin lies on the ellipsoid (where a fit normalised by k = -1 fails)
    hard_true = FIELD_N_T[::-1] * 1.0
    m = measurements(2, 300, 0.0, 8) - HARD_T + hard_true
    hard, soft, ok = fit(m).estimate()
    assert ok.all()
    herr, serr = magcal.calibration_errors(hard, soft, hard_true, SOFT, R_T)
    assert np.max(herr) < 1e-7 and np.max(serr) < 1e-7


def test_noise_compensation_removes_the_errors_in_variables_bias():
    # noise of 4 % of the field: the plain algebraic fit inflates the ellipsoid by 3 sigma^2 / 2
    # = 0.24 % (E|u|^2 = 1 + 3 sigma^2); the compensated one is unbiased. Both average 40 runs of
    # 5000 samples (standard error of the mean 0.008 %).
    noise = 0.04 * R_T
    m = measurements(40, 5000, noise, 2)
    scale = {}
    for label, model_noise in (("plain", 0.0), ("compensated", noise)):
        _, soft, _ = fit(m, model_noise).estimate()
        scale[label] = np.trace(soft, axis1=1, axis2=2) / np.trace(SOFT) - 1.0
    sem = scale["compensated"].std() / np.sqrt(40)
    assert np.mean(scale["plain"]) == pytest.approx(1.5 * 0.04 ** 2, rel=0.15)
    assert abs(np.mean(scale["compensated"])) < 3 * sem
    hard, soft, _ = fit(m, noise).estimate()
    herr, serr = magcal.calibration_errors(hard, soft, HARD_T, SOFT, R_T)
    assert np.max(herr) < 0.01 and np.max(serr) < 0.01


def test_a_batch_of_three_equals_three_single_runs():
    m = measurements(3, 300, 0.5e-6, 3)
    valid = np.random.default_rng(4).random((3, 300)) > 0.1
    batch = magcal.EllipsoidRLS(np.full(3, R_T), 0.5e-6, 0.995)
    batch.update(m[:, :170], valid[:, :170])
    batch.update(m[:, 170:], valid[:, 170:])
    for i in range(3):
        one = magcal.EllipsoidRLS(np.full(1, R_T), 0.5e-6, 0.995)
        one.update(m[i:i + 1, :170], valid[i:i + 1, :170])
        one.update(m[i:i + 1, 170:], valid[i:i + 1, 170:])
        assert np.array_equal(one.theta()[0], batch.theta()[i])


def test_information_form_equals_the_covariance_form_rls_with_forgetting():
    lam, m = 0.99, measurements(2, 400, 0.3e-6, 5)
    info = fit(m, 0.0, lam, chunk=37)
    theta = np.broadcast_to(magcal.SPHERE, (2, 9)).copy()
    P = np.broadcast_to(np.eye(9) * 1e6, (2, 9, 9)).copy()            # prior_sigma 1e3
    for k in range(m.shape[1]):                                         # the textbook recursion
        phi, y = magcal.regressor(m[:, k] / R_T)
        Pphi = np.einsum("bij,bj->bi", P, phi)
        gain = Pphi / (lam + np.einsum("bi,bi->b", phi, Pphi))[:, None]
        theta = theta + gain * (y - np.einsum("bi,bi->b", phi, theta))[:, None]
        P = (P - gain[:, :, None] * Pphi[:, None, :]) / lam
    np.testing.assert_allclose(info.theta(), theta, rtol=1e-6, atol=1e-9)


def test_soft_iron_is_scored_by_its_symmetric_factor():
    U = Rotation.from_rotvec([0.02, -0.03, 0.05]).as_matrix()
    S = SOFT @ U                                                        # S = P U, P symmetric
    np.testing.assert_allclose(magcal.symmetric_soft_iron(S), SOFT, atol=1e-12)
    # the ellipsoid of S U equals that of S: the fit returns the symmetric factor
    hard, soft, _ = fit(measurements(2, 200, 0.0, 6, soft=S)).estimate()
    herr, serr = magcal.calibration_errors(hard, soft, HARD_T, S, R_T)
    assert np.max(herr) < 1e-7 and np.max(serr) < 1e-7


def test_level_turns_alone_do_not_determine_the_ellipsoid():
    # heading only: the body field draws one horizontal circle, and a family of ellipsoids fits
    yaw = np.linspace(0, 4 * np.pi, 800)
    C_bn = np.swapaxes(Rotation.from_euler("z", yaw[:, None]).as_matrix(), 1, 2)
    m = (np.einsum("ij,njk,k->ni", SOFT, C_bn, FIELD_N_T) + HARD_T)[None]
    f = fit(m)
    w = np.linalg.eigvalsh(magcal.normal_equations(f.moments)[0][0])
    assert w[0] / w[-1] < 1e-12 and magcal.turns(yaw)[-1] == pytest.approx(2.0)


def test_forgetting_factor_out_of_range_is_refused():
    with pytest.raises(ValueError, match="forgetting"):
        magcal.EllipsoidRLS(np.ones(1), forgetting=1.2)


def test_heading_measurement_H_matches_finite_differences():
    rng = np.random.default_rng(7)
    B = 5
    C_nb = Rotation.from_euler("ZYX", np.c_[rng.uniform(-np.pi, np.pi, B), rng.uniform(-0.3, 0.3, (B, 2))]
                               ).as_matrix()
    field = np.broadcast_to(FIELD_N_T, (B, 3))
    mag_cal_b = np.einsum("bji,bj->bi", C_nb, field)                  # a perfect calibration
    z0, H = magnetic_heading(C_nb, mag_cal_b, field)
    np.testing.assert_allclose(z0, 0.0, atol=1e-12)
    eps = 1e-6
    for i in range(3):
        phi = np.zeros((B, 3))
        phi[:, i] = eps
        zp, _ = magnetic_heading(rotation(-phi) @ C_nb, mag_cal_b, field)   # C_est = (I - [phi x]) C
        zm, _ = magnetic_heading(rotation(phi) @ C_nb, mag_cal_b, field)
        np.testing.assert_allclose((zp - zm) / (2 * eps), H[:, i], rtol=1e-6, atol=1e-9)
    # a pure heading error: INS yaw 1 deg too large reads z = +1 deg
    yaw_err = np.radians(1.0)
    z, _ = magnetic_heading(Rotation.from_euler("z", yaw_err).as_matrix() @ C_nb, mag_cal_b, field)
    np.testing.assert_allclose(z, yaw_err, rtol=1e-9)


def test_the_world_magnetic_model_on_the_equator_and_the_prime_meridian():
    """ahrs' WMM computes nothing at a latitude or longitude of exactly 0 (a replayed log without
    a position puts the vehicle there); navsim's call is the field a hair away: the WMM's
    equatorial field of about 30 uT, horizontal, pointing north."""
    n, e, d = wmm_field_n_T(0.0, 0.0, 0.0, "2025-01-01")
    assert np.allclose((n, e, d), wmm_field_n_T(1e-6, 1e-6, 0.0, "2025-01-01"), rtol=1e-6)
    assert 2e-5 < n < 3.5e-5 and abs(e) < 0.3 * n and abs(d) < 1.0 * n
