"""The compiled strapdown (navsim.kernels) against the numpy one (navsim.strapdown.Strapdown)."""

import numpy as np
import pytest

from navsim.flight import fly, parse_track
from navsim.sensors.catalog import load_spec
from navsim.sensors.imu import emulate_imu
from navsim.strapdown import BlockStrapdown, Strapdown, state_from_truth


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
    dv_n = []
    for i in range(1, n):
        sd.step(dth[:, i], dv[:, i], data.meta["dt_s"])
        dv_n.append(sd.dv_n)
    return sd.state, np.stack(dv_n, 1)


def integrate_blocks(truth, data, runs, n, size):
    sd = BlockStrapdown(state_from_truth(truth, 0, len(runs)))
    dth, dv = data.values["dtheta_b_rad"][runs], data.values["dv_b_mps"][runs]
    out = [sd.block(dth[:, a:min(a + size, n)], dv[:, a:min(a + size, n)], data.meta["dt_s"])
           for a in range(1, n, size)]
    return sd.state, np.concatenate(out, 1)


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
    assert np.allclose(got_dv, ref_dv, rtol=1e-9, atol=1e-12)
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
        assert np.array_equal(one_dv[0], batch_dv[r])
