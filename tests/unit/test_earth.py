import numpy as np
import pytest

from navsim.foundations import earth


def test_ecef_of_reference_points():
    np.testing.assert_allclose(earth.lla_to_ecef(0.0, 0.0, 0.0), [earth.A_M, 0, 0], atol=1e-9)
    np.testing.assert_allclose(earth.lla_to_ecef(np.pi / 2, 0.0, 0.0), [0, 0, earth.B_M], atol=1e-6)
    np.testing.assert_allclose(earth.lla_to_ecef(0.0, np.pi / 2, 100.0), [0, earth.A_M + 100, 0],
                               atol=1e-6)


def test_lla_ecef_round_trip_batched():
    rng = np.random.default_rng(1)
    lat = rng.uniform(-1.5, 1.5, 200)
    lon = rng.uniform(-np.pi, np.pi, 200)
    h = rng.uniform(-100, 20000, 200)
    r = earth.lla_to_ecef(lat, lon, h)
    assert r.shape == (200, 3)
    lat2, lon2, h2 = earth.ecef_to_lla(r)
    np.testing.assert_allclose(lat2, lat, atol=1e-12)
    np.testing.assert_allclose(lon2, lon, atol=1e-12)
    np.testing.assert_allclose(h2, h, atol=1e-6)


def test_radii_match_finite_differences_of_ecef():
    lat, h, d = 0.65, 0.0, 1e-6
    r_m, r_n = earth.radii(lat)
    ds_north = np.linalg.norm(earth.lla_to_ecef(lat + d, 0.3, h) - earth.lla_to_ecef(lat, 0.3, h))
    ds_east = np.linalg.norm(earth.lla_to_ecef(lat, 0.3 + d, h) - earth.lla_to_ecef(lat, 0.3, h))
    assert ds_north / d == pytest.approx(r_m, rel=1e-6)
    assert ds_east / d == pytest.approx(r_n * np.cos(lat), rel=1e-6)


def test_normal_gravity_at_equator_and_pole():
    # Somigliana normal gravity of WGS-84: 9.7803253359 (equator), 9.8321849378 (pole) m/s^2;
    # a J2-only field reproduces them within a few mGal.
    g_eq = earth.gravity_n(0.0, 0.0)
    g_pole = earth.gravity_n(np.radians(89.999), 0.0)
    assert g_eq[2] == pytest.approx(9.7803253359, abs=2e-4)
    assert g_pole[2] == pytest.approx(9.8321849378, abs=2e-4)
    # gravity is normal to the ellipsoid: no horizontal component in NED
    for lat in np.radians([10.0, 37.4, 60.0]):
        g = earth.gravity_n(lat, 300.0)
        assert abs(g[0]) < 1e-4 * g[2] and abs(g[1]) < 1e-12


def test_gravity_decreases_with_height_at_free_air_gradient():
    g0 = earth.gravity_n(0.6, 0.0)[2]
    g1 = earth.gravity_n(0.6, 1000.0)[2]
    assert (g0 - g1) / 1000.0 == pytest.approx(3.086e-6, rel=0.01)


def test_C_en_is_a_rotation_and_points_down():
    C = earth.C_en(np.array([0.3, -1.0]), np.array([2.0, 0.5]))
    assert C.shape == (2, 3, 3)
    np.testing.assert_allclose(C @ np.swapaxes(C, -1, -2), np.broadcast_to(np.eye(3), (2, 3, 3)),
                               atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(C), 1.0)
    r = earth.lla_to_ecef(0.3, 2.0, 0.0)
    up = r - earth.lla_to_ecef(0.3, 2.0, -1.0)
    np.testing.assert_allclose(C[0][:, 2], -up, atol=1e-9)
