import math

import numpy as np
import pytest

from navsim.foundations.errors import ScenarioError
from navsim.sensors import parse_sensors
from navsim.sensors.catalog import available, load_spec
from navsim.sensors.specs import ERROR_FIELDS, ImuSpec, ideal, kind_of
from navsim.sensors.units import UnitError, to_si

DEG = math.pi / 180


@pytest.mark.parametrize("text, dim, si", [
    ("0.2 deg/h", "angular_rate", 0.2 * DEG / 3600),
    ("1 deg/rth", "angle_random_walk", DEG / 60),            # 1 deg/sqrt(h) = 1/60 deg/sqrt(s)
    ("60 deg/h/rtHz", "angle_random_walk", DEG / 60),         # the same ARW written per rtHz
    ("1e-4 g", "acceleration", 9.80665e-4),
    ("100 ug/rtHz", "velocity_random_walk", 9.80665e-4),
    ("0.06 m/s/rth", "velocity_random_walk", 0.001),
    ("3 %", "ratio", 0.03),
    ("500 ppm", "ratio", 5e-4),
    ("20 arcsec", "angle", 20 * DEG / 3600),
    ("5 mG", "magnetic_field", 5e-7),
    ("1013.25 hPa", "pressure", 101325.0),
    ("100 ft", "length", 30.48),
])
def test_datasheet_units(text, dim, si):
    assert to_si(text, dim) == pytest.approx(si, rel=1e-12)


def test_vector_and_mapping_values():
    np.testing.assert_allclose(to_si("[1, 2, 3] mg", "acceleration"), np.array([1, 2, 3]) * 9.80665e-3)
    assert to_si({"value": 2, "unit": "deg"}, "angle") == pytest.approx(2 * DEG)
    assert to_si(0, "angular_rate") == 0.0


@pytest.mark.parametrize("value, dim, words", [
    ("3 m", "angular_rate", "not a unit of angular rate"),
    (0.2, "angular_rate", "has no unit"),
    ("fast", "speed", "not a number with a unit"),
    ("[1, 2] m", "length", "three values"),
])
def test_bad_units(value, dim, words):
    with pytest.raises(UnitError, match=words):
        to_si(value, dim)


def test_every_catalog_entry_loads_with_its_kind():
    entries = available()
    assert {"p0_imu", "p0_bd2", "p0_baro", "p0_ads", "p2_imu", "p2_gps", "p2_radar", "p2_baro",
            "p3_imu", "p3_gps", "mpu6050", "lsm303d", "neo_m8n", "consumer_mems_imu",
            "industrial_mems_imu", "tactical_imu", "p1_camera"} <= set(entries)
    for name, kind in entries.items():
        spec = load_spec(name)
        assert kind_of(spec) == kind, f"{name}: listed as a {kind}, loads as a {type(spec).__name__}"
        ideal(spec)                             # the kind's error sources are the spec's fields


def test_paper_numbers_reach_the_specs_in_si():
    p0 = load_spec("p0_imu")
    np.testing.assert_allclose(p0.gyro.bias_sigma, 0.2 * DEG / 3600)
    np.testing.assert_allclose(p0.accel.bias_sigma, 1e-4 * 9.80665)
    p2 = load_spec("p2_imu")
    assert p2.gyro.markov_tau_s == 3600 and p2.accel.markov_tau_s == 1800
    np.testing.assert_allclose(p2.accel.markov_sigma, 2e-4 * 9.80665)
    gps = load_spec("p2_gps")
    np.testing.assert_allclose(gps.position_sigma, [20, 20, 30])
    np.testing.assert_allclose(load_spec("p3_gps").position_sigma, [2, 2, 1])
    assert load_spec("p0_bd2").velocity_output is False
    radar = load_spec("p2_radar")
    assert (radar.noise, radar.noise_ratio, radar.max_range) == (0.3, 0.03, 1500.0)


def test_override_off_and_ideal():
    spec = load_spec("p0_imu", {"gyro": {"bias_sigma": "0.5 deg/h"}}, ["accel.noise_density"])
    np.testing.assert_allclose(spec.gyro.bias_sigma, 0.5 * DEG / 3600)
    assert not np.any(spec.accel.noise_density) and np.any(spec.gyro.noise_density)
    perfect = ideal(load_spec("mpu6050"))
    assert perfect.vibration == () and math.isinf(perfect.gyro.range)
    assert not np.any(perfect.gyro.bias_sigma) and perfect.gyro.quantization == 0.0
    assert isinstance(load_spec("mpu6050", off="all"), ImuSpec)
    assert set(ERROR_FIELDS) == {"imu", "gnss", "baro", "ads", "radar_altimeter", "magnetometer", "camera"}


@pytest.mark.parametrize("sensors, key, words", [
    ({"imu": {"model": "p0_imu", "override": {"gyro": {"noise_densty": "1 deg/rth"}}}},
     "sensors.imu.override.gyro.noise_densty", "did you mean 'noise_density'"),
    ({"imu": {"model": "p0_imu", "override": {"gyro": {"bias_sigma": "0.2 m"}}}},
     "sensors.imu.override.gyro.bias_sigma", "not a unit of angular rate"),
    ({"imu": {"model": "p0_imu", "override": {"gyro": {"bias_sigma": 0.2}}}},
     "sensors.imu.override.gyro.bias_sigma", "has no unit"),
    ({"imu": {"model": "p0_imu", "override": {"accel": {"noise_density": "-3 ug/rtHz"}}}},
     "sensors.imu.override.accel.noise_density", "negative"),
    ({"imu": {"model": "p0_imus"}}, "sensors.imu.model", "did you mean 'p0_imu'"),
    ({"gnss": {"model": "p2_gps", "off": ["noise"]}}, "sensors.gnss.off", "not an error source"),
    ({"gnss": {"model": "p2_gps", "faults": [{"type": "bias", "start_s": 5, "end_s": 3, "value_m": 1}]}},
     "sensors.gnss.faults[0].end_s", "after start_s"),
    ({"gnss": {"model": "p2_gps", "faults": [{"type": "jam"}]}},
     "sensors.gnss.faults[0].type", "one of outage"),
    ({"gnss": {"model": "p2_gps", "modle": 1}}, "sensors.gnss.modle", "not a known key"),
])
def test_malformed_sensor_configs_name_the_key(sensors, key, words):
    with pytest.raises(ScenarioError) as info:
        parse_sensors(sensors, "s.yaml")
    text = str(info.value)
    assert f"{key}:" in text and words in text, text
