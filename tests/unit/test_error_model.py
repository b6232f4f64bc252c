"""The analytic error model against finite differences of the nonlinear SINS equations."""

import dataclasses

import numpy as np
import pytest

from navsim.foundations import earth
from navsim.foundations.transform import rotation, skew
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.error_model import PRESETS, Layout, system_matrix
from navsim.navigation.estimators.eskf import _covariance_series_fits
from navsim.navigation.estimators.measurements import (
    AirVelocity,
    GnssPosition,
    Height,
    MagneticHeading,
    Velocity,
    ZeroVelocity,
)
from navsim.navigation.strapdown import NavState, rates_n
from navsim.sensors import load_spec

LAYOUT = Layout(PRESETS["p3_15"])


def nominal():
    rng = np.random.default_rng(4)
    lat, lon, h = 0.65, 2.06, 350.0
    v = np.array([12.0, -7.0, 1.5])
    C = rotation(np.array([0.2, -0.1, 2.5]))
    omega_ib_b = rng.normal(size=3) * 0.2
    f_b = np.array([0.5, 0.3, -9.6])
    return lat, lon, h, v, C, omega_ib_b, f_b


def derivatives(lat, lon, h, v, C, omega_ib_b, f_b):
    w_ie, w_en, r_m, r_n = rates_n(np.array([lat]), np.array([h]), v[None])
    w_ie, w_en = w_ie[0], w_en[0]
    g = earth.gravity_n(lat, h)
    C_dot = C @ skew(omega_ib_b) - skew(w_ie + w_en) @ C
    v_dot = C @ f_b - np.cross(2 * w_ie + w_en, v) + g
    pos_dot = np.array([v[0] / (r_m[0] + h), v[1] / ((r_n[0] + h) * np.cos(lat)), -v[2]])
    return C_dot, v_dot, pos_dot


def error_rate(dx):
    """d/dt of the error state dx (estimate minus truth) at the nominal truth."""
    lat, lon, h, v, C, w, f = nominal()
    phi, dv, dp, dbg, dba = dx[0:3], dx[3:6], dx[6:9], dx[9:12], dx[12:15]
    C_est = rotation(-phi) @ C
    # the estimate sees the measured rate minus its bias estimate: true rate + residual bias
    Ct, vt, pt = derivatives(lat, lon, h, v, C, w, f)
    Ce, ve, pe = derivatives(lat + dp[0], lon + dp[1], h + dp[2], v + dv, C_est, w + dbg, f + dba)
    # C_est = exp(-[phi x]) C  =>  [phi_dot x] ~ -(C_est_dot - exp(-[phi x]) C_dot) C^T
    E = -(Ce - rotation(-phi) @ Ct) @ C.T
    phi_dot = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    return np.concatenate([phi_dot, ve - vt, pe - pt, np.zeros(6)])


def test_F_matches_finite_differences():
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(LAYOUT, np.array([lat]), np.array([h]), v[None], C[None], (C @ f)[None])[0]
    steps = np.array([1e-6] * 3 + [1e-3] * 3 + [1e-8, 1e-8, 1e-2] + [1e-6] * 3 + [1e-4] * 3)
    J = np.column_stack([(error_rate(s * e) - error_rate(-s * e)) / (2 * s)
                         for s, e in zip(steps, np.eye(15))])
    # compare column by column, relative to the column's size
    for j in range(15):
        scale = max(np.abs(J[:, j]).max(), 1e-9)
        np.testing.assert_allclose(F[:, j], J[:, j], atol=1e-3 * scale + 1e-12,
                                   err_msg=f"column {LAYOUT.labels()[j]}")


def nav(lat, lon, h, v, C):
    return NavState(np.array([lat]), np.array([lon]), np.array([h]), v[None].copy(), C[None].copy())


class FakeData:
    def __init__(self, values):
        self.values = {k: np.asarray(val)[None, None] if np.ndim(val) == 0 else np.asarray(val)[None, None]
                       for k, val in values.items()}
        self.valid = np.ones((1, 1), bool)
        self.meta = {}


#: an Earth field (NED, tesla) with a declination and an inclination
FIELD_N_T = np.array([2.2e-5, -0.4e-5, 4.5e-5])


def _air_data(v, C):
    """ADS values that agree with the nominal state in calm air: the air velocity's angles in
    the body, its speed, ISA pressure and temperature near 350 m."""
    u = C.T @ v / np.linalg.norm(v)
    return {"tas_mps": np.linalg.norm(v), "alpha_rad": np.arctan2(u[2], u[0]), "beta_rad": np.arcsin(u[1]),
            "p_static_pa": 97000.0, "temp_k": 286.0}


VANES = AirVelocity("a", dataclasses.replace(load_spec("p0_ads"), velocity_axis="air", vane_noise=0.01))


@pytest.mark.parametrize("model", [GnssPosition("g", np.ones(3)), Velocity("g", np.ones(3)),
                                   Height("b", 1.0, field="h_m"), ZeroVelocity("m", np.ones(3)),
                                   ZeroVelocity("m", np.ones(3), vertical=True),
                                   MagneticHeading("m", 0.01, 0.0, field_n_T=FIELD_N_T, online=False), VANES],
                         ids=["gnss_position", "velocity", "height", "zero_velocity", "zero_velocity_ned",
                              "mag_heading", "air_velocity"])
def test_H_matches_finite_differences(model):
    lat, lon, h, v, C, _, _ = nominal()
    # the sensor agrees with the nominal state: the linearisation point of a closed-loop filter
    data = FakeData({"lat_rad": lat, "lon_rad": lon, "h_m": h, "vel_n_mps": v, "mag_b_T": C.T @ FIELD_N_T,
                     **_air_data(v, C)})

    def z_of(dx):
        dp, dv = dx[6:9], dx[3:6]
        return model.model(nav(lat + dp[0], lon + dp[1], h + dp[2], v + dv, rotation(-dx[:3]) @ C),
                           LAYOUT, data, 0)[0][0]

    _, H, R, valid = model.model(nav(lat, lon, h, v, C), LAYOUT, data, 0)
    steps = np.array([1e-6] * 3 + [1e-3] * 3 + [1e-8, 1e-8, 1e-2] + [1e-6] * 6)
    J = np.column_stack([(z_of(s * e) - z_of(-s * e)) / (2 * s) for s, e in zip(steps, np.eye(15))])
    np.testing.assert_allclose(H[0], J, rtol=1e-5, atol=1e-6)
    assert valid.all() and R.shape == (1, H.shape[1], H.shape[1])


def test_pitot_bias_column_matches_finite_differences():
    """``air_velocity``'s ``pitot_bias`` column: the change of ``z`` with a dynamic-pressure bias
    ``b`` in the data, which moves the airspeed by ``b / (rho V)``."""
    from navsim.foundations.atmosphere import R_AIR
    lat, lon, h, v, C, _, _ = nominal()
    layout = Layout(PRESETS["p3_15"] + ("pitot_bias",))
    air = _air_data(v, C)
    rho_v = air["p_static_pa"] / (R_AIR * air["temp_k"]) * air["tas_mps"]

    def z_of(b):
        data = FakeData({**air, "tas_mps": air["tas_mps"] + b / rho_v})
        return VANES.model(nav(lat, lon, h, v, C), layout, data, 0)[0][0]

    H = VANES.model(nav(lat, lon, h, v, C), layout, FakeData(air), 0)[1][0]
    np.testing.assert_allclose(H[:, layout.slice("pitot_bias").start], (z_of(0.5) - z_of(-0.5)) / 1.0, rtol=1e-9)


def test_series_and_van_loan_agree():
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(LAYOUT, np.array([lat] * 2), np.array([h] * 2), np.stack([v, -v]), np.stack([C, C.T]),
                      np.stack([C @ f, f]))
    Qc = np.diag(np.r_[np.full(3, 1e-8), np.full(3, 1e-6), np.zeros(9)])
    P1, Q1 = kalman.discretize_series(F, Qc, 1.0, order=3)
    P2, Q2 = kalman.discretize_van_loan(F, Qc, 1.0)
    # third order over 1 s: the truncation is O((|F| T)^4 / 24)
    np.testing.assert_allclose(P1, P2, rtol=1e-2, atol=1e-6)
    # the noise reaches the position through attitude and velocity: four integrations, so the
    # third-order series misses part of Qd over 1 s; the sixth order has it
    _, Q6 = kalman.discretize_series(F, Qc, 1.0, order=6)
    for b in range(2):          # correlation-scaled, on the driven (navigation) states
        d = np.sqrt(np.diag(Q2[b]))[:9]
        np.testing.assert_allclose(Q6[b][:9, :9] / np.outer(d, d), Q2[b][:9, :9] / np.outer(d, d), atol=2e-3)
    P8, Q8 = kalman.discretize_series(F, Qc, 1.0, order=8)
    np.testing.assert_allclose(P8, P2, atol=1e-9)


def _random_covariance(rng, sigma):
    A = rng.normal(size=(len(sigma), len(sigma))) * 0.3 + np.eye(len(sigma))
    C = A @ A.T
    d = np.sqrt(np.diag(C))
    return C / np.outer(d, d) * np.outer(sigma, sigma)


def test_covariance_series_is_the_exact_discretised_predict():
    """``propagate_in_place`` (the covariance equation's Taylor series) against Van Loan's exact
    ``Phi P Phi^T + Qd`` over 1 s, on P0's 16 states (the baro Markov decay included)."""
    layout = Layout(PRESETS["p0_16"])
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(layout, np.array([lat] * 2), np.array([h] * 2), np.stack([v, -v]), np.stack([C, C.T]),
                      np.stack([C @ f, f]))
    F[:, 15, 15] = -1.0 / 600.0
    Qc = np.diag(np.r_[np.full(3, 1e-12), np.full(3, 1e-6), np.zeros(3), np.full(6, 1e-14), 0.03])
    rng = np.random.default_rng(11)
    sigma = np.r_[np.full(3, 1e-4), np.full(3, 0.1), 1e-6, 1e-6, 5.0, np.full(3, 1e-6), np.full(3, 1e-3), 3.0]
    P0 = np.stack([_random_covariance(rng, sigma) for _ in range(2)])
    x0 = rng.normal(size=(2, 16)) * sigma
    Phi, Qd = kalman.discretize_van_loan(F, Qc, 1.0)
    exact_P = Phi @ P0 @ np.swapaxes(Phi, -1, -2) + Qd
    exact_x = (Phi @ x0[..., None])[..., 0]
    scale = np.sqrt(np.einsum("bii->bi", exact_P))
    errors = {}
    for order in (3, 6, 8):
        x, P = x0.copy(), P0.copy()
        kalman.propagate_in_place(x, P, F, Qc, 1.0, order)
        assert np.array_equal(P, np.swapaxes(P, -1, -2))
        errors[order] = np.abs((P - exact_P) / (scale[:, :, None] * scale[:, None, :])).max()
        np.testing.assert_allclose(x / sigma, exact_x / sigma, atol=1e-6 if order == 3 else 1e-12)
    assert errors[3] > 1e-9            # the order is honoured: third order truncates visibly
    assert errors[6] < 1e-12 and errors[8] < 1e-12
    # the same as the series' Phi and Qd, then predict
    Phi6, Qd6 = kalman.discretize_series(F, Qc, 1.0, order=8)
    _, P_series = kalman.predict(x0, P0, Phi6, Qd6)
    x, P = x0.copy(), P0.copy()
    kalman.propagate_in_place(x, P, F, Qc, 1.0, 8)
    np.testing.assert_allclose(P / (scale[:, :, None] * scale[:, None, :]),
                               P_series / (scale[:, :, None] * scale[:, None, :]), atol=1e-13)


def test_updates_in_turn_in_one_call_equal_single_updates():
    rng = np.random.default_rng(12)
    P = np.stack([_random_covariance(rng, np.linspace(0.5, 3.0, 6)) for _ in range(3)])
    x = rng.normal(size=(3, 6))
    first = (rng.normal(size=(3, 2)), rng.normal(size=(3, 2, 6)), np.broadcast_to(np.diag([0.5, 2.0]), (3, 2, 2)),
             np.array([True, False, True]))
    second = (rng.normal(size=(3, 1)), rng.normal(size=(3, 1, 6)), np.full((3, 1, 1), 0.3), None)
    x1, P1, y1, S1, nis1 = kalman.update(x, P, *first)
    x2, P2, y2, S2, nis2 = kalman.update(x1, P1, *second)
    xi, Pi = x.copy(), P.copy()
    u = kalman.update_in_place(xi, Pi, [first, second])
    np.testing.assert_allclose(xi, x2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Pi, P2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(u.y[0], y1, rtol=1e-12)
    np.testing.assert_allclose(u.S[1], S2, rtol=1e-12)
    np.testing.assert_allclose(u.nis[0], nis1, rtol=1e-12)
    assert np.isnan(u.nis[0][1]) and not u.bad.any()
    # a run whose S is singular is spoiled and flagged alone
    singular = (np.zeros((3, 1)), np.zeros((3, 1, 6)), np.zeros((3, 1, 1)), np.array([False, True, False]))
    xi, Pi = x.copy(), P.copy()
    u = kalman.update_in_place(xi, Pi, [singular, second])
    assert u.bad.tolist() == [False, True, False] and np.isnan(Pi[1]).all()
    np.testing.assert_allclose(Pi[[0, 2]], kalman.update(x, P, *second)[1][[0, 2]], rtol=1e-12)


def test_joseph_update_is_the_optimal_update_and_keeps_P_psd():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 6, 6))
    P = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(6)
    H = rng.normal(size=(4, 2, 6))
    R = np.broadcast_to(np.diag([0.5, 2.0]), (4, 2, 2))
    x = rng.normal(size=(4, 6))
    z = rng.normal(size=(4, 2))
    x1, P1, y, S, nis = kalman.update(x, P, z, H, R)
    K = P @ np.swapaxes(H, -1, -2) @ np.linalg.inv(S)
    np.testing.assert_allclose(P1, P - K @ H @ P, atol=1e-9)
    np.testing.assert_allclose(x1, x + (K @ y[..., None])[..., 0], atol=1e-12)
    assert np.all(np.linalg.eigvalsh(P1) > 0)
    np.testing.assert_allclose(nis, np.einsum("bi,bij,bj->b", y, np.linalg.inv(S), y))
    valid = np.array([True, False, True, False])
    x2, P2, _, _, nis2 = kalman.update(x, P, z, H, R, valid)
    assert np.array_equal(x2[1], x[1]) and np.array_equal(P2[3], P[3]) and np.isnan(nis2[1])


def test_the_filter_falls_back_to_phi_p_phi_where_the_covariance_series_would_not_hold():
    """Below order 6, or with a state decaying faster than 5 % per period, the ES-KF predicts
    with the series' Phi and Qd (P3's third order keeps its numbers); from order 6 on slow
    states, with the covariance's own series."""
    layout = Layout(PRESETS["p0_16"])
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(layout, np.array([lat]), np.array([h]), v[None], C[None], (C @ f)[None])
    F[:, 15, 15] = -1.0 / 600.0
    assert _covariance_series_fits(F, 1.0, 6) and not _covariance_series_fits(F, 1.0, 3)
    F[:, 15, 15] = -1.0                                  # a 1 s Markov state over a 1 s period
    assert not _covariance_series_fits(F, 1.0, 6)


def test_the_bias_sigma_is_the_sigma_of_the_estimated_sum():
    """P2's gyro bias estimate is its constant plus its Markov part: the sigma reported is that
    of the sum, their cross-covariance included (``T P T^T`` with ``T = [I I]``)."""
    from navsim.navigation.estimators.eskf import ErrorStateKF
    layout = Layout(PRESETS["p2_18"])
    A = np.random.default_rng(1).normal(size=(2, 18, 18))
    P = A @ np.swapaxes(A, 1, 2)
    holder = type("Holder", (), {"layout": layout, "P": P})()
    gyro, accel = ErrorStateKF._bias_sigma(holder)
    T = np.zeros((3, 18))
    T[:, layout.slice("gyro_bias")] = T[:, layout.slice("gyro_markov")] = np.eye(3)
    np.testing.assert_allclose(gyro, np.sqrt(np.diagonal(T @ P @ T.T, axis1=1, axis2=2)), rtol=1e-12)
    T = np.zeros((3, 18))
    T[:, layout.slice("accel_markov")] = np.eye(3)             # no constant accelerometer block in p2_18
    np.testing.assert_allclose(accel, np.sqrt(np.diagonal(T @ P @ T.T, axis1=1, axis2=2)), rtol=1e-12)
