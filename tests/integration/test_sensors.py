"""Sensor emulators on a flown trajectory: ideal sensors, faults, determinism, geometry."""

import math

import numpy as np
import pytest
from model_result import unpack

from navsim.flight import fly, parse_track
from navsim.foundations import atmosphere, earth
from navsim.foundations.transform import dcm_from_quat
from navsim.sensors import SensorConfig, emulate, load_spec, parse_sensors
from navsim.sensors.base import parse_faults
from navsim.sensors.magnetometer import field_along
from navsim.sensors.specs import ideal

ALL = {"imu": "mpu6050", "gnss": "neo_m8n", "baro": "p0_baro", "ads": "p0_ads",
       "radar_altimeter": "p2_radar", "magnetometer": "lsm303d", "camera": "p1_camera"}


@pytest.fixture(scope="module")
def truth():
    return fly(parse_track({
        "start": {"lat_deg": 30.0, "lon_deg": 122.5, "alt_m": 150, "speed_mps": 15, "heading_deg": 0},
        "segments": [{"type": "straight", "time_s": 20}, {"type": "turn", "by_deg": 120, "bank_deg": 25},
                     {"type": "climb", "to_m": 200, "rate_mps": 2}, {"type": "straight", "time_s": 10}]}))


def config(kind, model=None, faults=None, off=None, override=None):
    from navsim.sensors.catalog import load_spec as ls
    spec = ls(model or ALL[kind], override, off or [])
    return SensorConfig(kind, model or ALL[kind], spec,
                        parse_faults(faults, "faults", vector=(kind == "gnss")))


def landmarks_under(truth, every=10):
    """Landmarks on the ground under the track, every ``every`` seconds."""
    k = np.arange(0, truth.n, int(every / truth.dt_s))
    return [[float(np.degrees(truth.lat_rad[i])), float(np.degrees(truth.lon_rad[i])), 0.0] for i in k]


def test_ideal_sensors_reproduce_the_truth(truth):
    B = 3
    imu = emulate(truth, SensorConfig("imu", "x", ideal(load_spec("p0_imu"))), 1, range(B))
    assert np.array_equal(imu.values["omega_ib_b_rps"], np.broadcast_to(truth.omega_ib_b_rps, (B, truth.n, 3)))
    assert np.array_equal(imu.values["f_b_mps2"], np.broadcast_to(truth.f_b_mps2, (B, truth.n, 3)))
    # increments: JSBSim's Adams-Bashforth 3 step of the recorded rates
    om, dt = truth.omega_ib_b_rps, truth.dt_s
    dth = imu.values["dtheta_b_rad"][0]
    np.testing.assert_allclose(dth[4:], dt * (23 * om[3:-1] - 16 * om[2:-2] + 5 * om[1:-3]) / 12, atol=1e-17)
    gnss = emulate(truth, SensorConfig("gnss", "x", ideal(load_spec("p2_gps"))), 1, range(B))
    s = slice(None, None, 100)
    for key in ("lat_rad", "lon_rad", "h_m"):
        assert np.array_equal(gnss.values[key][0], getattr(truth, key)[s])
    assert np.array_equal(gnss.values["vel_n_mps"][1], truth.vel_n_mps[s])
    baro = emulate(truth, SensorConfig("baro", "x", ideal(load_spec("p2_baro"))), 1, range(B))
    assert np.array_equal(baro.values["h_baro_m"][2], truth.h_m[::10])
    ads = emulate(truth, SensorConfig("ads", "x", ideal(load_spec("p0_ads"))), 1, range(B))
    for key in ("p_static_pa", "p_total_pa", "temp_k"):
        assert np.array_equal(ads.values[key][0], getattr(truth, key)[::10])
    np.testing.assert_allclose(ads.values["tas_mps"][0], truth.tas_mps[::10], atol=1e-3)
    np.testing.assert_allclose(ads.values["h_pressure_m"][0], truth.h_m[::10], atol=0.1)
    radar = emulate(truth, SensorConfig("r", "x", ideal(load_spec("p2_radar"))), 1, range(B))
    assert np.array_equal(radar.values["h_agl_m"][1], truth.h_agl_m[::10])
    mag = emulate(truth, SensorConfig("m", "x", ideal(load_spec("lsm303d"))), 1, range(B))
    C_nb = dcm_from_quat(truth.quat_nb[::10])
    np.testing.assert_allclose(np.einsum("nij,nj->ni", C_nb, mag.values["mag_b_T"][0]),
                               mag.errors["field_n_T"], atol=1e-15)
    cam_spec = ideal(load_spec("p1_camera", {"landmarks": landmarks_under(truth)}))
    cam = emulate(truth, SensorConfig("c", "x", cam_spec), 1, range(B))
    v = cam.valid[0]
    assert v.sum() > 10
    assert np.array_equal(cam.values["lat_rad"][0][v], truth.lat_rad[::100][v])


def test_same_seed_same_data_whatever_the_batch(truth):
    for kind in ALL:
        override = {"landmarks": landmarks_under(truth)} if kind == "camera" else None
        c = config(kind, override=override)
        batch = emulate(truth, c, 1234, range(8))
        for i in range(8):
            one = emulate(truth, c, 1234, [i])
            for key, value in batch.values.items():
                assert np.array_equal(value[i:i + 1], one.values[key]), (kind, key, i)
            assert np.array_equal(batch.valid[i:i + 1], one.valid)
        other = emulate(truth, c, 1235, range(2))
        noisy = [k for k in batch.values if k not in ("fix_type", "h_acc_m", "v_acc_m", "s_acc_mps", "landmark")]
        assert any(not np.array_equal(batch.values[k][:2], other.values[k]) for k in noisy), kind


def test_p2_fault_windows_add_exactly_their_error(truth):
    faults = [{"type": "bias", "start_s": 10, "end_s": 20, "value_m": 10},
              {"type": "bias", "start_s": 30, "end_s": 35, "value_m": 8}]
    clean = emulate(truth, config("radar_altimeter"), 7, range(3))
    faulty = emulate(truth, config("radar_altimeter", faults=faults), 7, range(3))
    diff = faulty.values["h_agl_m"] - clean.values["h_agl_m"]
    t = clean.t_s
    expected = np.where((t >= 10) & (t < 20), 10.0, 0.0) + np.where((t >= 30) & (t < 35), 8.0, 0.0)
    np.testing.assert_allclose(diff, np.broadcast_to(expected, diff.shape), atol=1e-9)
    # P2's GPS height error of 80 m during 1050-1060 s, here 40-50 s
    g_clean = emulate(truth, config("gnss", "p2_gps"), 7, range(3))
    g_bad = emulate(truth, config("gnss", "p2_gps", faults=[{"type": "bias", "start_s": 40, "end_s": 50,
                                                              "value_m": [0, 0, -80]}]), 7, range(3))
    dh = g_bad.values["h_m"] - g_clean.values["h_m"]
    win = (g_clean.t_s >= 40) & (g_clean.t_s < 50)
    np.testing.assert_allclose(dh[:, win], 80.0, atol=1e-9)
    np.testing.assert_allclose(dh[:, ~win], 0.0, atol=1e-9)


def test_outages_produce_no_samples(truth):
    c = config("gnss", "p2_gps", faults=[{"type": "outage", "start_s": 12, "end_s": 30}])
    data = emulate(truth, c, 1, range(2))
    t = data.t_s
    out = (t >= 12) & (t < 30)
    assert not data.valid[:, out].any() and data.valid[:, ~out].all()
    assert (data.values["fix_type"][:, out] == 0).all() and (data.values["fix_type"][:, ~out] == 3).all()


def test_interference_grows_noise_near_the_power_line_until_lock_is_lost(truth):
    # a power line crossing the first straight leg, 20 m below the aircraft
    k = int(10.0 / truth.dt_s)
    lat, lon = np.degrees(truth.lat_rad[k]), np.degrees(truth.lon_rad[k])
    line = [[lat, lon - 0.01, 130.0], [lat, lon + 0.01, 130.0]]
    c = config("gnss", "p2_gps", faults=[{"type": "interference", "source": line, "radius_m": 150,
                                          "lost_m": 25}])
    data = emulate(truth, c, 1, range(50))
    t = data.t_s
    assert not data.valid[:, (t > 9) & (t < 11)].any()                # lock lost over the line
    near = (t >= 6) & (t <= 8)
    clean = emulate(truth, config("gnss", "p2_gps"), 1, range(50))
    err = data.errors["pos_error_n_m"]
    assert err[:, near].std() > 3 * clean.errors["pos_error_n_m"][:, near].std()
    assert data.values["h_acc_m"][0, near].min() > 3 * clean.values["h_acc_m"][0, near].max()
    # on the first leg the growth follows 1 + (radius / d)^2, d the distance to the line
    leg = t <= 18
    north, _ = earth.local_ne(truth.lat_rad[::100], truth.lon_rad[::100], truth.lat_rad[k], truth.lon_rad[k])
    d = np.hypot(north, truth.h_m[::100] - 130.0)
    ratio = data.values["h_acc_m"][0] / clean.values["h_acc_m"][0]
    np.testing.assert_allclose(ratio[leg], 1 + (150.0 / d[leg]) ** 2, rtol=1e-3)


def test_gnss_latency_and_lever_arm(truth):
    late = config("gnss", "p2_gps", off=["position_sigma", "velocity_sigma"],
                  override={"latency": "0.2 s"})
    data = emulate(truth, late, 1, range(1))
    # a 0.2 s old fix lags by velocity x 0.2 s
    straight = slice(2, 18)                   # the first leg, before the turn
    north_err = data.errors["pos_error_n_m"][0, straight, 0]
    np.testing.assert_allclose(north_err, -0.2 * truth.vel_n_mps[::100][straight, 0], atol=0.02)
    arm = config("gnss", "p2_gps", off=["position_sigma", "velocity_sigma"],
                 override={"lever_arm": "[0.5, 0, -0.2] m"})
    data = emulate(truth, arm, 1, range(1))
    assert np.linalg.norm(data.errors["pos_error_n_m"][0], axis=-1) == pytest.approx(
        np.full(data.t_s.size, math.hypot(0.5, 0.2)), abs=1e-6)


def test_ads_p0_formula_and_ground_velocity(truth):
    ads = emulate(truth, SensorConfig("ads", "x", ideal(load_spec("p0_ads", {"formula": "p0"}))), 1, [0])
    # P0's incompressible airspeed is within 0.1 % of the true airspeed at 15 m/s
    np.testing.assert_allclose(ads.values["tas_mps"][0], truth.tas_mps[::10], rtol=1e-3)
    np.testing.assert_allclose(ads.values["h_pressure_m"][0], atmosphere.pressure_altitude(truth.p_static_pa[::10]),
                               atol=0.5)
    # ground velocity from airspeed along the body axis, no wind estimate: calm air -> truth
    # up to the angle of attack and sideslip
    err = np.linalg.norm(ads.values["vel_n_mps"][0] - truth.vel_n_mps[::10], axis=-1)
    assert np.all(err <= truth.tas_mps[::10] * (np.abs(truth.alpha_rad[::10]) + np.abs(truth.beta_rad[::10]) + 1e-3))


def test_ads_vanes_give_the_ground_velocity_in_calm_air(truth):
    ideal_air = ideal(load_spec("p0_ads", {"velocity_axis": "air"}))
    ads = emulate(truth, SensorConfig("ads", "x", ideal_air), 1, [0])
    # airspeed along the vane-measured air-relative direction: calm air -> the ground velocity
    np.testing.assert_allclose(ads.values["vel_n_mps"][0], truth.vel_n_mps[::10], atol=0.02)
    np.testing.assert_array_equal(ads.values["alpha_rad"][0], truth.alpha_rad[::10])
    # vane noise tilts the direction by about V * sigma
    noisy = emulate(truth, SensorConfig("ads", "x", load_spec("p0_ads", {"velocity_axis": "air", "vane_noise": "0.5 deg",
                                                                         "static_noise": "0 Pa", "total_noise": "0 Pa",
                                                                         "static_bias_sigma": "0 Pa", "total_bias_sigma": "0 Pa"})), 1, [0])
    err = noisy.values["vel_n_mps"][0] - truth.vel_n_mps[::10]
    assert np.sqrt((err ** 2).sum(-1).mean()) == pytest.approx(14.0 * math.radians(0.5) * math.sqrt(2), rel=0.15)


def test_differential_pitot_keeps_the_static_bias_out_of_the_airspeed(truth):
    runs = range(200)
    only_static_bias = {"static_noise": "0 Pa", "total_noise": "0 Pa", "total_bias_sigma": "0 Pa",
                        "temperature_noise": "0 K", "static_bias_sigma": "20 Pa"}
    diff = emulate(truth, SensorConfig("ads", "x", load_spec("p0_ads", only_static_bias)), 1, runs)
    absolute = emulate(truth, SensorConfig("ads", "x", load_spec("p0_ads", {**only_static_bias, "pitot": "absolute"})), 1, runs)
    # dq = 20 Pa -> dV = dq / (rho V) ~ 1.3 m/s with two absolute sensors; ~0 with a differential one
    assert np.abs(diff.errors["tas_error_mps"]).max() < 0.05
    assert np.std(absolute.errors["tas_error_mps"][:, 0]) == pytest.approx(
        20.0 / (truth.p_static_pa[0] / (287.05 * truth.temp_k[0]) * truth.tas_mps[0]), rel=0.2)


def test_magnetometer_field_and_iron(truth):
    t = truth.t_s[::10]
    m_n = field_along(truth, t, "2025-01-01")
    # WMM at 30 N 122.5 E (East China Sea): ~49 uT total, ~-6 deg declination, ~47 deg inclination
    total = np.linalg.norm(m_n, axis=1)
    assert total.mean() == pytest.approx(49e-6, rel=0.05)
    assert math.degrees(math.atan2(m_n[0, 1], m_n[0, 0])) == pytest.approx(-6.0, abs=2.0)
    data = emulate(truth, config("magnetometer", override={"hard_iron": "[10, -5, 2] uT"},
                                 off=["hard_iron_sigma", "soft_iron_sigma", "noise"]), 1, [0])
    C_nb = dcm_from_quat(truth.quat_nb[::10])
    clean = np.einsum("nji,nj->ni", C_nb, m_n)
    np.testing.assert_allclose(data.values["mag_b_T"][0] - clean, np.broadcast_to([10e-6, -5e-6, 2e-6], clean.shape),
                               atol=1e-12)


def test_vibration_peaks_of_p4(truth):
    spec = load_spec("mpu6050", off=[f for f in (
        "gyro.bias", "gyro.bias_sigma", "gyro.bias_instability", "gyro.noise_density", "gyro.scale_factor_sigma",
        "gyro.misalignment_sigma", "gyro.quantization", "accel.bias", "accel.bias_sigma",
        "accel.bias_instability", "accel.noise_density", "accel.scale_factor_sigma",
        "accel.misalignment_sigma", "accel.quantization", "accel.range", "gyro.range")])
    data = emulate(truth, SensorConfig("imu", "mpu6050", spec), 1, range(4))
    vib = data.values["f_b_mps2"] - truth.f_b_mps2[None, ::2]
    peak = np.array([0.488, 0.488, 0.732]) * 9.80665
    # band-limited Gaussian scaled so that 3 sigma is the published peak
    np.testing.assert_allclose(vib.std(axis=(0, 1)), peak / 3, rtol=0.02)
    # its spectrum sits in the band (8-22 Hz)
    f = np.fft.rfftfreq(vib.shape[1], 1 / 50)
    psd = (np.abs(np.fft.rfft(vib[..., 2], axis=1)) ** 2).mean(axis=0)
    assert psd[(f > 8) & (f < 22)].sum() > 0.9 * psd.sum()


def test_parse_sensors_from_scenario_text():
    cfg = parse_sensors({"gps": {"model": "p2_gps", "faults": [
        {"type": "bias", "start_s": 1050, "end_s": 1060, "value_m": [0, 0, -80]}]},
        "ra": {"model": "p2_radar", "faults": [{"type": "bias", "start_s": 960, "end_s": 970, "value_m": 10}]}})
    assert [c.kind for c in cfg] == ["gnss", "radar_altimeter"]
    np.testing.assert_allclose(cfg[0].faults[0].value, [0, 0, -80])


@pytest.mark.parametrize("kind, override", [(k, None) for k in ALL] + [
    ("gnss", {"velocity_output": True}), ("ads", {"velocity_axis": "air", "vane_noise": "0.1 deg"})])
def test_declared_output_fields_are_what_each_emulator_produces(truth, kind, override):
    """The fields a measurement's ``field`` is checked against (navsim.sensors.output_fields)
    are exactly the values the emulator gives."""
    from navsim.sensors import output_fields
    cfg = config(kind, override=override)
    if kind == "camera":
        cfg = config(kind, override={"landmarks": landmarks_under(truth)})
    assert set(output_fields(cfg.spec)) == set(emulate(truth, cfg, 1, range(2)).values)



@pytest.mark.parametrize("pitot", ["differential", "absolute"])
def test_air_velocity_R_describes_the_ads_error(truth, pitot):
    """The air_velocity model's R, derived from the filter's ADS model (here the truth's), is
    the covariance of what the ADS gets wrong: at the true navigation state the NIS averages
    3, with the pitot's per-run bias in R, and with that bias taken out as its state would
    (the bias column of H times the run's bias), with R of the noise alone."""
    from navsim.navigation.estimators.error_model import Layout
    from navsim.navigation.estimators.measurements import AirVelocity
    from navsim.navigation.strapdown import NavState

    spec = load_spec("p0_ads", {"velocity_axis": "air", "vane_noise": "0.5 deg", "pitot": pitot})
    data = emulate(truth, SensorConfig("ads", "x", spec), 3, range(300))
    step, B = 10, data.valid.shape[0]
    qc = data.values["p_total_pa"] - data.values["p_static_pa"]
    bias_pa = (qc - (truth.p_total_pa - truth.p_static_pa)[::step]).mean(axis=1)   # the noise averages out
    model = AirVelocity("ads", spec)
    for layout in (Layout(("att", "vel", "pos")), Layout(("att", "vel", "pos", "pitot_bias"))):
        nis, along = [], []
        for j in range(0, data.t_s.size, 3):
            k = j * step
            nav = NavState(np.full(B, truth.lat_rad[k]), np.full(B, truth.lon_rad[k]), np.full(B, truth.h_m[k]),
                           np.broadcast_to(truth.vel_n_mps[k], (B, 3)).copy(),
                           np.broadcast_to(dcm_from_quat(truth.quat_nb[k]), (B, 3, 3)).copy())
            z, H, R, _ = unpack(model.model(nav, layout, data, j))
            if layout.has("pitot_bias"):
                z = z - H[:, :, layout.slice("pitot_bias").start] * bias_pa[:, None]
            nis.append(np.einsum("bi,bij,bj->b", z, np.linalg.inv(R), z))
            u_n = air_n_direction(nav, data, j)            # along the airspeed: the pitot's share
            along.append(np.einsum("bi,bi->b", u_n, z) ** 2 / np.einsum("bi,bij,bj->b", u_n, R, u_n))
        assert np.mean(nis) == pytest.approx(3.0, rel=0.06), layout.blocks
        # along the airspeed (without the bias state: where the differential pitot's 2 Pa bias is
        # 14 % of the variance; the absolute one's 20 Pa is one draw a run, too few to judge)
        if layout.has("pitot_bias") or pitot == "differential":
            assert np.mean(along) == pytest.approx(1.0, rel=0.06), layout.blocks


def air_n_direction(nav, data, j):
    """The measured airspeed's direction in NED ``(B, 3)`` (the vanes' angles, the attitude)."""
    a, b = data.values["alpha_rad"][:, j], data.values["beta_rad"][:, j]
    u = np.stack([np.cos(a) * np.cos(b), np.sin(b), np.sin(a) * np.cos(b)], -1)
    return np.einsum("bij,bj->bi", nav.C_nb, u)
