"""Magnetometer calibration by recursive least squares: recovery, batching, observability, and
the field-vector measurement's Jacobian."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navsim.magcal import AttitudeRLS, EllipsoidRLS, errors, symmetric_part

M_N = np.array([33e-6, -3.5e-6, 35e-6])          # NED, tesla
F = np.linalg.norm(M_N)


def readings(attitudes, B=3, seed=1, noise=0.1e-6):
    rng = np.random.default_rng(seed)
    S = np.eye(3) + rng.normal(0, 0.03, (B, 3, 3))
    b = rng.normal(0, 10e-6, (B, 3))
    out = []
    for yaw, pitch, roll in attitudes:
        m_b = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix().T @ M_N
        out.append((np.einsum("bij,j->bi", S, m_b) + b + rng.normal(0, noise, (B, 3)), m_b))
    return out, S, b


def two_turns(n=400, bank_deg=25.0):
    yaw = np.linspace(0, 2 * np.pi, n)
    return [(y, 0.05, np.radians(bank_deg)) for y in yaw] + [(-y, 0.05, -np.radians(bank_deg)) for y in yaw]


def fit(samples, B):
    e, a = EllipsoidRLS(B), AttitudeRLS(B)
    for m, m_b in samples:
        e.update(m, np.ones(B, bool))
        a.update(m, np.broadcast_to(m_b, (B, 3)), np.ones(B, bool))
    return e, a


def test_attitude_aided_rls_recovers_hard_and_soft_iron_in_two_turns():
    samples, S, b = readings(two_turns())
    _, a = fit(samples, 3)
    hard, soft = errors(*a.estimate(), b, S, F)
    assert np.all(hard < 1e-3) and np.all(soft < 1e-3), (hard, soft)


def test_ellipsoid_fit_needs_more_than_two_level_turns():
    """P1's attitude-free fit: exact from attitudes all over the sphere, but the readings of two
    planar turns lie on two conics that a whole family of quadrics contains."""
    rng = np.random.default_rng(4)
    sphere = np.column_stack([rng.uniform(-np.pi, np.pi, 1500), rng.uniform(-1.2, 1.2, 1500),
                              rng.uniform(-np.pi, np.pi, 1500)])
    samples, S, b = readings(sphere)
    e, _ = fit(samples, 3)
    hard, soft = errors(*e.estimate(F), b, symmetric_part(S), F)
    assert np.all(hard < 1e-3) and np.all(soft < 1e-3), (hard, soft)
    samples, S, b = readings(two_turns())
    e, _ = fit(samples, 3)
    hard, soft = errors(*e.estimate(F), b, symmetric_part(S), F)
    assert np.all(hard > 0.1), hard                          # not observable: > 10 % off


def test_a_batch_of_three_equals_three_single_runs():
    samples, S, b = readings(two_turns(n=100))
    _, a3 = fit(samples, 3)
    for r in range(3):
        _, a1 = fit([(m[r:r + 1], m_b) for m, m_b in samples], 1)
        for x3, x1 in zip(a3.estimate(), a1.estimate()):
            np.testing.assert_array_equal(x3[r:r + 1], x1)


def test_magnetic_field_jacobian_against_finite_differences():
    from navsim.estimators.error_model import PRESETS, Layout
    from navsim.estimators.measurements import MagneticField
    from navsim.sensors.base import SensorData
    from navsim.strapdown import NavState, rotation
    layout = Layout(PRESETS["p3_15"])
    B = 2
    C = Rotation.from_euler("ZYX", [[0.7, 0.1, 0.3], [-2.0, -0.05, -0.4]]).as_matrix()
    nav = NavState(np.radians([36.07, 36.07]), np.radians([120.38, 120.38]), np.array([150.0, 150.0]),
                   np.zeros((B, 3)), C)
    model = MagneticField("mag", 0.5e-6, calibrate_until_s=0.0)
    m_n = model.field_n_T(nav)
    truth_b = np.einsum("bji,bj->bi", C, m_n)             # an ideal, calibrated sensor
    data = SensorData("mag", "magnetometer", np.array([0.0, 1.0]),
                      {"mag_b_T": np.stack([truth_b, truth_b], 1)}, np.ones((B, 2), bool))
    model.model(nav, layout, data, 0)                      # calibration epoch (nothing to learn)
    model._frozen = (np.zeros((B, 3)), np.broadcast_to(np.eye(3), (B, 3, 3)))
    z0, H, R, valid = model.model(nav, layout, data, 1)
    assert valid.all() and np.abs(z0).max() < 1e-15
    phi = np.array([[2e-4, -1e-4, 3e-4], [-1e-4, 2e-4, -2e-4]])
    nav_err = NavState(nav.lat_rad, nav.lon_rad, nav.h_m, nav.vel_n_mps, rotation(-phi) @ C)  # (I - [phi x]) C
    z1, *_ = model.model(nav_err, layout, data, 1)
    dx = np.zeros((B, layout.n))
    dx[:, layout.slice("att")] = phi
    np.testing.assert_allclose(z1, np.einsum("bij,bj->bi", H, dx), rtol=2e-3, atol=1e-12)


def test_estimates_are_snapshots_not_views_of_the_running_state():
    samples, S, b = readings(two_turns(n=50))
    a = AttitudeRLS(3)
    m, m_b = samples[0]
    a.update(m, np.broadcast_to(m_b, (3, 3)), np.ones(3, bool))
    first = a.estimate()
    kept = [x.copy() for x in first]
    for m, m_b in samples[1:]:
        a.update(m, np.broadcast_to(m_b, (3, 3)), np.ones(3, bool))
    for x, k in zip(first, kept):
        np.testing.assert_array_equal(x, k)
