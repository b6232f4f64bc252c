"""The IMU generated block by block (ImuStream, as a chunk does) against the whole record."""

import numpy as np
import pytest

from navsim.flight import fly, parse_track
from navsim.sensors.catalog import load_spec
from navsim.sensors.imu import ImuStream, emulate_imu


@pytest.fixture(scope="module")
def truth():
    return fly(parse_track({
        "start": {"lat_deg": 31.0, "lon_deg": 121.0, "alt_m": 150, "speed_mps": 15, "heading_deg": 30},
        "segments": [{"type": "straight", "time_s": 8}, {"type": "turn", "by_deg": 60, "bank_deg": 25}]}))


@pytest.mark.parametrize("model", ["p0_imu", "consumer_mems_imu", "tactical_imu", "p2_imu"])
def test_blocks_of_any_size_give_the_whole_records_numbers(truth, model):
    """Increments (scale factors, misalignment, bias instability, Markov bias, random walk,
    white noise, quantization where the datasheet has them) and the true biases at the blocks'
    ends equal the whole record's bit for bit, for uneven blocks starting at sample 1 and a
    normals buffer smaller than some blocks."""
    spec = load_spec(model)
    whole = emulate_imu(truth, spec, 5, range(3), keep_rates=False)
    stream = ImuStream(truth, spec, 5, range(3), block=40)
    stream.record_bias()
    ends = sorted({*range(7, stream.n, 37), *range(100, stream.n, 100), stream.n})
    got, i0 = [], 1
    for i1 in ends:
        got.append(stream.block(i0, i1)[0])
        i0 = i1
    for k, name in enumerate(("dtheta_b_rad", "dv_b_mps")):
        assert np.array_equal(np.concatenate([g[k] for g in got], axis=1), whole.values[name][:, 1:]), name
    idx = np.array([0] + [e - 1 for e in ends])
    biases = stream.bias(idx)
    for key in ("gyro_bias", "accel_bias"):
        ref = np.broadcast_to(whole.errors[key], (3, stream.n, 3)) if whole.errors[key].shape[1] > 1 else \
            np.repeat(whole.errors[key], stream.n, axis=1)
        assert np.array_equal(biases[key], ref[:, idx]), key
        # what a bias state sees: the bias plus (scale factor + misalignment) times the truth
        triad = key.split("_")[0]
        x = {"gyro": truth.omega_ib_b_rps, "accel": truth.f_b_mps2}[triad][idx]
        seen = ref[:, idx] + np.einsum("bij,ej->bei", whole.errors[f"{triad}_matrix"] - np.eye(3), x)
        np.testing.assert_allclose(biases[f"{key}_seen"], seen, rtol=1e-12, atol=1e-15)
    assert np.any(whole.errors["gyro_bias"] != 0)


def test_a_streamed_batch_equals_single_runs(truth):
    spec = load_spec("consumer_mems_imu")
    batch = ImuStream(truth, spec, 2, range(3)).block(1, 500)[0]
    for r in range(3):
        one = ImuStream(truth, spec, 2, [r]).block(1, 500)[0]
        assert np.array_equal(one[0][0], batch[0][r]) and np.array_equal(one[1][0], batch[1][r])
