"""Seeded statistical tests of the sensor emulators against their specifications."""

import dataclasses
import math

import allantools
import numpy as np
import pytest
from scipy.signal import lfilter

from navsim.flight.truth import Truth
from navsim.sensors import load_spec
from navsim.sensors.base import gauss_markov, run_generators
from navsim.sensors.catalog import available
from navsim.sensors.imu import FLICKER_FLOOR, GM_ALLAN_PEAK, allan_variance, emulate_imu, gm_allan_peak
from navsim.sensors.kernels import first_order
from navsim.sensors.radar import emulate_radar_altimeter
from navsim.sensors.specs import AxisErrors, ImuSpec, RadarAltimeterSpec

DEG = math.pi / 180


def test_gm_allan_peak_constant():
    assert GM_ALLAN_PEAK == pytest.approx(gm_allan_peak(), abs=1e-4)


def test_allan_deviation_recovers_arw_and_bias_instability():
    N = 0.15 * DEG / 60          # 0.15 deg/sqrt(h), rad/sqrt(s)
    B = 3.0 * DEG / 3600         # 3 deg/h
    VRW = 60e-6 * 9.80665        # 60 ug/rtHz
    BA = 30e-6 * 9.80665         # 30 ug
    tau_c = 20.0
    spec = ImuSpec(rate_hz=100.0,
                   gyro=AxisErrors(noise_density=np.full(3, N), bias_instability=np.full(3, B),
                                   bias_instability_tau_s=tau_c),
                   accel=AxisErrors(noise_density=np.full(3, VRW), bias_instability=np.full(3, BA),
                                    bias_instability_tau_s=tau_c))
    truth = Truth.static(2 * 3600.0)
    data = emulate_imu(truth, spec, seed=11, runs=range(4))
    taus = np.array([0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 30, 40, 60, 80, 120, 200])
    for key, white, floor in (("omega_ib_b_rps", N, B), ("f_b_mps2", VRW, BA)):
        x = data.values[key] - data.values[key].mean(axis=1, keepdims=True)
        avar = []
        for run in range(x.shape[0]):
            for axis in range(3):
                t2, ad, _, _ = allantools.oadev(x[run, :, axis], rate=100.0, data_type="freq", taus=taus)
                avar.append(ad ** 2)
        avar = np.mean(avar, axis=0)
        # white noise from the short-tau end of the curve
        assert math.sqrt(avar[0] * t2[0]) == pytest.approx(white, rel=0.10)
        # bias instability: the hump above the white noise, read in the flicker convention
        hump = np.sqrt(np.max(avar - white ** 2 / t2))
        assert hump / FLICKER_FLOOR == pytest.approx(floor, rel=0.10)


CATALOG_IMUS = sorted(name for name, kind in available().items() if kind == "imu")


def _allan_ratio(spec, duration_s: float, taus: np.ndarray, runs: int = 2) -> dict:
    """Per triad, the emulated Allan deviation at rest (mean variance over runs and axes) over
    the datasheet's (:func:`allan_variance`), at ``taus``."""
    data = emulate_imu(Truth.static(duration_s, rate_hz=spec.rate_hz), spec, seed=7, runs=range(runs))
    out = {}
    for key, e in (("omega_ib_b_rps", spec.gyro), ("f_b_mps2", spec.accel)):
        x = data.values[key] - data.values[key].mean(axis=1, keepdims=True)
        avar = np.mean([allantools.oadev(x[r, :, a], rate=spec.rate_hz, data_type="freq", taus=taus)[1] ** 2
                        for r in range(runs) for a in range(3)], axis=0)
        out[key] = np.sqrt(avar / allan_variance(e, taus).mean(axis=0))
    return out


@pytest.mark.parametrize("name", CATALOG_IMUS)
def test_every_catalog_imu_has_its_datasheet_white_noise(name):
    """The Allan deviation at rest from one sample to 1 s is the datasheet's within 5 %, the
    quantization included once (the MPU6050 gyro read 1.12 when it was drawn on top of the
    density); the installation's vibration is not the sensor's and is left off."""
    spec = dataclasses.replace(load_spec(name), vibration=())
    dt = 1.0 / spec.rate_hz
    taus = np.array([1, 2, 5, 10, 20, 50, 100]) * dt
    for key, ratio in _allan_ratio(spec, 600.0, taus).items():
        assert ratio == pytest.approx(1.0, abs=0.05), (key, ratio)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in CATALOG_IMUS
                                  if any(np.any(getattr(getattr(load_spec(n), t), k)) for t in ("gyro", "accel")
                                         for k in ("bias_instability", "markov_sigma", "random_walk"))])
def test_every_catalog_imu_has_its_datasheet_bias_instability(name):
    """The Allan deviation at rest from 1 s to five correlation times (bias instability, Markov
    bias, random walk on top of the white noise) is the datasheet's within 5 %: 400
    correlation times at 1 Hz (the quantization, white at the sensor's rate, is checked there)."""
    spec = load_spec(name)
    spec = dataclasses.replace(spec, vibration=(), rate_hz=1.0,
                               gyro=dataclasses.replace(spec.gyro, quantization=0.0),
                               accel=dataclasses.replace(spec.accel, quantization=0.0))
    tau_c = [t.bias_instability_tau_s if np.any(t.bias_instability) else t.markov_tau_s for t in (spec.gyro, spec.accel)]
    taus = np.unique(np.round(np.geomspace(1.0, 5 * max(tau_c), 30)))
    for key, ratio in _allan_ratio(spec, 400 * max(tau_c), taus, runs=4).items():
        assert np.all(np.abs(ratio - 1.0) < 0.05), (key, ratio.round(3))


@pytest.mark.parametrize("sigma, tau, dt", [(0.1 * DEG / 3600, 3600.0, 2.0),   # P2 gyro Markov
                                            (2e-4 * 9.80665, 1800.0, 1.0),     # P2 accel Markov
                                            (3.0, 10.0, 0.01)])
def test_gauss_markov_has_its_sigma_and_tau(sigma, tau, dt):
    n = int(20 * tau / dt)
    x = gauss_markov(run_generators(5, range(200), "gm"), n, dt, [sigma], tau)[..., 0]
    assert x.std() == pytest.approx(sigma, rel=0.10)
    lag = int(round(tau / dt))
    rho = np.mean(x[:, lag:] * x[:, :-lag]) / np.mean(x * x)
    assert -lag * dt / math.log(rho) == pytest.approx(tau, rel=0.10)


def test_imu_markov_bias_matches_p2():
    spec = load_spec("p2_imu")
    truth = Truth.static(200.0, rate_hz=10.0)
    spec = spec.__class__(**{**spec.__dict__, "rate_hz": 10.0})
    data = emulate_imu(truth, spec, seed=3, runs=range(300))
    b = data.errors["gyro_bias"] - spec.gyro.bias  # constant + Markov
    # across runs at one instant: variance = bias_sigma^2 + markov_sigma^2
    expected = math.hypot(spec.gyro.bias_sigma[0], spec.gyro.markov_sigma[0])
    assert b[:, -1, :].std() == pytest.approx(expected, rel=0.10)


def test_radar_error_std_follows_03_m_plus_3_percent():
    heights = np.repeat([20.0, 100.0, 400.0, 1000.0], 2500)
    truth = Truth.static(len(heights) / 10 - 0.1, rate_hz=10.0, h_agl_m=heights)
    spec = RadarAltimeterSpec(rate_hz=10.0)
    data = emulate_radar_altimeter(truth, spec, seed=9, runs=range(4))
    err = data.values["h_agl_m"] - heights
    for h in (20.0, 100.0, 400.0, 1000.0):
        assert err[:, heights == h].std() == pytest.approx(0.3 + 0.03 * h, rel=0.10)
    # out of range: no output
    high = Truth.static(10.0, rate_hz=10.0, h_agl_m=2000.0)
    assert not emulate_radar_altimeter(high, spec, 1, range(2)).valid.any()


def test_radar_slant_error_grows_with_bank():
    truth = Truth.static(100.0, rate_hz=10.0, h_agl_m=200.0)
    level = emulate_radar_altimeter(truth, RadarAltimeterSpec(), 1, range(2))
    truth.euler_rad[:, 0] = math.radians(35.0)
    from navsim.foundations.transform import quat_from_euler
    truth.quat_nb = quat_from_euler(*truth.euler_rad.T)
    banked = emulate_radar_altimeter(truth, RadarAltimeterSpec(), 1, range(2))
    slant = 200.0 / math.cos(math.radians(15.0)) - 200.0
    assert np.mean(banked.values["h_agl_m"] - level.values["h_agl_m"]) == pytest.approx(slant, rel=0.1)
    assert np.std(banked.errors["h_error_m"]) > 1.3 * np.std(level.errors["h_error_m"])


def test_the_compiled_first_order_filter_is_lfilters_bit_for_bit():
    """The Gauss-Markov processes' recursion (navsim.sensors.kernels.first_order) against
    scipy.signal.lfilter([1], [1, -a]) along the samples."""
    w = np.random.default_rng(11).normal(size=(3, 2000, 2))
    want = lfilter([1.0], [1.0, -0.995], w, axis=1)
    first_order(w, 0.995)
    np.testing.assert_array_equal(w, want)
