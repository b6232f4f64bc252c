"""The replay's IMU resampling, grid placement and log checks, on synthetic data."""

import numpy as np
import pytest

from navsim.foundations.errors import LogError
from navsim.replay.run import imu_increments, on_grid
from navsim.replay.ulog import _position, check_structure, require


def _jittered(n=2000, rate=250.0, seed=4):
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate * (1.0 + 0.02 * rng.standard_normal(n - 1))
    dt[700] = 16 / rate                              # a logger dropout
    return np.concatenate([[0.0], np.cumsum(dt)]), rng


def test_constant_rates_give_exact_increments_despite_jitter_and_a_gap():
    t, _ = _jittered()
    w = np.array([0.1, -0.2, 0.3])
    f = np.array([0.5, 0.0, -9.8])
    for rate in (250.0, 50.0):
        grid, dth, dv = imu_increments(t, np.tile(w, (len(t), 1)), np.tile(f, (len(t), 1)), rate)
        np.testing.assert_allclose(np.diff(grid), 1.0 / rate, rtol=1e-9)
        np.testing.assert_allclose(dth[1:], np.tile(w / rate, (len(grid) - 1, 1)), rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(dv[1:], np.tile(f / rate, (len(grid) - 1, 1)), rtol=1e-9, atol=1e-15)
        assert np.all(dth[0] == 0)


def test_increments_sum_to_the_integral_of_the_logged_rates():
    t, rng = _jittered()
    w = rng.standard_normal((len(t), 3))
    grid, dth, _ = imu_increments(t, w, w, 250.0)
    # each sample's rate holds over the interval ending at its timestamp
    k = np.searchsorted(t, grid[-1], side="left")
    exact = (w[1:k] * np.diff(t[:k])[:, None]).sum(0) + w[k] * (grid[-1] - t[k - 1])
    np.testing.assert_allclose(dth.sum(0), exact, rtol=1e-10, atol=1e-12)


def test_samples_go_to_the_first_grid_time_at_or_after_theirs():
    grid = np.arange(0.0, 1.0, 0.02)
    t = np.array([-0.01, 0.0, 0.005, 0.011, 0.019, 0.5, 2.0])
    data = on_grid("mag", "magnetometer", t, {"mag_b_T": np.arange(7.0)}, grid)
    # 0.005, 0.011 and 0.019 share 0.02: the latest is kept; 2.0 is past the grid
    np.testing.assert_allclose(data.t_s, [0.0, 0.02, 0.5])
    np.testing.assert_allclose(data.values["mag_b_T"][0], [1.0, 4.0, 5.0])
    assert data.values["mag_b_T"].shape == (1, 3) and data.valid.shape == (1, 3)


def test_require_names_the_missing_topic_and_fields():
    topics = {"sensor_combined": {"timestamp": [1], "gyro_rad[0]": [0.0]}}
    with pytest.raises(LogError, match=r"f.ulg: has no 'vehicle_attitude' messages.*\n  hint: .*sensor_combined"):
        require(topics, "vehicle_attitude", ["q[0]"], "f.ulg", "the reference")
    with pytest.raises(LogError, match=r"'sensor_combined' lacks the field\(s\) gyro_rad\[1\], gyro_rad\[2\]"):
        require(topics, "sensor_combined", ["gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"], "f.ulg", "the IMU")


def test_structure_check_finds_a_cut_message():
    header = b"ULog\x01\x12\x35\x01" + bytes(8)
    msg = (5).to_bytes(2, "little") + b"D" + bytes(5)
    assert check_structure(header + msg + msg) is None
    assert "is truncated" in check_structure(header + msg + msg[:6])
    assert "not a ULog" in check_structure(b"hello world" * 3)


def test_position_only_from_a_valid_global_reference():
    lp = {"ref_lat": [0.0, 47.4, 47.4, 1e9], "ref_lon": [0.0, 8.5, 8.5, 3.0], "xy_global": [1, 1, 1, 1],
          "ref_alt": [0.0, 400.0, 400.0, 0.0], "z": [-2.0, -2.0, -2.0, -2.0], "z_global": [0, 1, 1, 1]}
    notes = []
    lat, lon, h = _position({"vehicle_local_position": lp}, notes)
    assert np.degrees([lat, lon]).round(6).tolist() == [47.4, 8.5] and h == 402.0 and notes == []
    lat, lon, h = _position({"vehicle_local_position": {**lp, "xy_global": [0, 0, 0, 0]}}, notes)
    assert lat is None and "no global position" in notes[0]
