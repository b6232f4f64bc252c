"""The ES-KF's wind and gust states (issue 35): their scenario keys refused when malformed,
their models in F and Q, the gusts leaving R where a state carries them, and MIL-HDBK-1797's
gust intensities and scale lengths."""

import math

import numpy as np
import pytest
import yaml

from navsim.flight.environment import (parse_environment, steady_wind_n_mps, turbulence_scale_m,
                                       turbulence_sigma_mps, wind_from)
from navsim.foundations.errors import ScenarioError
from navsim.navigation.estimators.error_model import Layout, PRESETS, add_markov_decay, process_noise, system_matrix
from navsim.navigation.estimators.eskf import ErrorStateKF, ExtraStates
from navsim.sensors.catalog import load_spec


def _scenario(repo_root, **wind_entry):
    """P0's matched-ADS scenario with its ES-KF's states and keys changed."""
    data = yaml.safe_load((repo_root / "scenarios" / "p0_matched_ads.yaml").read_text())
    est = data["estimators"][0]
    est["states"] = est["states"] + ["wind"]
    est["wind"] = {"model": "markov", "sigma_mps": 5.0, "tau_s": 600.0}
    for key, value in wind_entry.items():
        if value is None:
            est.pop(key, None)
        else:
            est[key] = value
    return data


@pytest.mark.parametrize("change, key, words", [
    ({"wind": {"model": "markov", "sigma_mps": -1.0, "tau_s": 600.0}}, "estimators[0].wind.sigma_mps", "-1"),
    ({"wind": {"model": "markov", "sigma_mps": 5.0, "tau_s": -60.0}}, "estimators[0].wind.tau_s", "-60"),
    ({"wind": {"model": "random_walk", "sigma_mps": 5.0}}, "estimators[0].wind.walk_mps_per_rts", "is missing"),
    ({"wind": {"model": "gusty", "sigma_mps": 5.0}}, "estimators[0].wind.model", "gusty"),
    ({"wind": None}, "estimators[0].wind", "the 'wind' state needs its model"),
    ({"measurements": [{"type": "gnss_position", "sensor": "bd", "sigma_m": [8, 8, 8]},
                       {"type": "air_velocity", "sensor": "ads", "model": "p0_ads", "wind_n_mps": [1, 0, 0],
                        "override": {"velocity_axis": "air", "vane_noise": "0.5 deg"}},
                       {"type": "air_velocity", "sensor": "ads", "model": "p0_ads",
                        "override": {"velocity_axis": "air", "vane_noise": "0.5 deg"}}]},
     "estimators[0].measurements", "different wind_n_mps"),
    ({"states": ["att", "vel", "pos", "gyro_bias", "accel_bias"]}, "estimators[0].wind", "no wind state"),
    ({"measurements": [{"type": "gnss_position", "sensor": "bd", "sigma_m": [8, 8, 8]}],
      "states": ["att", "vel", "pos", "gyro_bias", "accel_bias", "wind"]}, "estimators[0].states",
     "observed by no measurement"),
    ({"states": ["att", "vel", "pos", "gyro_bias", "accel_bias", "pitot_bias", "wind", "gust"]},
     "estimators[0].gust", "the 'gust' state needs its model"),
    ({"gust": {"sigma_mps": 1.5, "tau_s": 20.0}}, "estimators[0].gust", "no gust state"),
    ({"states": ["att", "vel", "pos", "gyro_bias", "accel_bias", "pitot_bias", "wind", "gust"],
      "gust": {"sigma_mps": 1.5, "tau_s": -20.0}}, "estimators[0].gust.tau_s", "-20"),
    ({"states": ["att", "vel", "pos", "gyro_bias", "accel_bias", "pitot_bias", "wind", "gust_down"],
      "gust": {"sigma_mps": 1.5, "tau_s": 20.0, "sigma_down_mps": -1.0}}, "estimators[0].gust.sigma_down_mps", "-1"),
    ({"states": ["att", "vel", "pos", "gyro_bias", "accel_bias", "pitot_bias", "wind", "gust"],
      "gust": {"sigma_mps": 1.5}}, "estimators[0].gust.tau_s", "is missing"),
])
def test_a_malformed_wind_state_is_refused(change, key, words, repo_root, assert_scenario_error):
    assert_scenario_error(_scenario(repo_root, **change), key, words)


def test_the_wind_states_model_in_F_and_Q():
    """A Markov wind decays with its tau and is driven by 2 sigma^2 / tau; a random walk does
    not decay; the states start with the model's sigma."""
    layout = Layout(PRESETS["p3_15"] + ("wind", "wind_down"))
    imu = load_spec("p0_imu")
    for wind, decay in (({"sigma_mps": 4.0, "sigma_down_mps": 1.0, "tau_s": 300.0,
                          "walk_mps_per_rts": 4.0 * math.sqrt(2 / 300.0),
                          "walk_down_mps_per_rts": 1.0 * math.sqrt(2 / 300.0)}, -1 / 300.0),
                        ({"sigma_mps": 4.0, "sigma_down_mps": 1.0, "tau_s": math.inf, "walk_mps_per_rts": 0.02,
                          "walk_down_mps_per_rts": 0.01}, 0.0)):
        est = ErrorStateKF.from_imu_spec(layout, imu, [], ExtraStates(wind=wind))
        F = system_matrix(layout, np.array([0.6]), np.array([300.0]), np.array([[13.0, 1.0, 0.0]]),
                          np.eye(3)[None], np.array([[0.0, 0.0, -9.8]]))
        F = add_markov_decay(F, layout, est.noise)[0]
        Q = process_noise(layout, est.noise)
        for block in ("wind", "wind_down"):
            s = layout.slice(block)
            np.testing.assert_allclose(np.diag(F[s, s]), decay)
            assert not F[s, :s.start].any() and not F[:s.start, s].any()      # the INS errors do not see it
            walk = wind["walk_mps_per_rts" if block == "wind" else "walk_down_mps_per_rts"]
            np.testing.assert_allclose(np.diag(Q[s, s]), walk ** 2)
        np.testing.assert_allclose(est.noise_sigma0()["wind"], 4.0)
        np.testing.assert_allclose(est.noise_sigma0()["wind_down"], 1.0)


def test_the_gust_states_model_in_F_Q_and_R():
    """A gust state is a first-order Markov process (decay -1 / tau, driven by 2 sigma^2 / tau,
    started at sigma) with a tau of its own vertically; with it the air-velocity measurement
    takes the gusts out of R on its axes only."""
    layout = Layout(PRESETS["p3_15"] + ("wind", "gust"))
    gust = {"sigma_mps": 1.5, "sigma_down_mps": 1.2, "tau_s": 22.0, "tau_down_s": 11.0}
    wind = {"sigma_mps": 4.0, "sigma_down_mps": 4.0, "tau_s": math.inf, "walk_mps_per_rts": 0.02,
            "walk_down_mps_per_rts": 0.02}
    est = ErrorStateKF.from_imu_spec(layout, load_spec("p0_imu"), [], ExtraStates(wind=wind, gust=gust))
    F = add_markov_decay(np.zeros((1, layout.n, layout.n)), layout, est.noise)[0]
    Q = process_noise(layout, est.noise)
    s = layout.slice("gust")
    np.testing.assert_allclose(np.diag(F[s, s]), -1 / 22.0)
    np.testing.assert_allclose(np.diag(Q[s, s]), 2 * 1.5 ** 2 / 22.0)
    np.testing.assert_allclose(est.noise_sigma0()["gust"], 1.5)
    down = Layout(PRESETS["p3_15"] + ("gust_down",))
    F = add_markov_decay(np.zeros((1, down.n, down.n)), down, est.noise)[0]
    assert F[-1, -1] == pytest.approx(-1 / 11.0)
    assert process_noise(down, est.noise)[-1, -1] == pytest.approx(2 * 1.2 ** 2 / 11.0)


def test_gust_scale_lengths_follow_mil_hdbk_1797():
    """Low altitude: L_u = 2 L_v = h / (0.177 + 0.000823 h)^1.2 (1000 ft at 1000 ft),
    L_w = h / 2; h at least 10 ft."""
    L_u, L_v, L_w = turbulence_scale_m(1000 * 0.3048)
    assert L_u == pytest.approx(1000 * 0.3048) and L_v == pytest.approx(500 * 0.3048) and L_w == pytest.approx(L_v)
    L_u, L_v, L_w = turbulence_scale_m(30.0)
    h_ft = 30.0 / 0.3048
    assert L_u == pytest.approx(0.3048 * h_ft / (0.177 + 0.000823 * h_ft) ** 1.2) and L_u > L_w
    assert turbulence_scale_m(0.0) == turbulence_scale_m(10 * 0.3048)


def test_gust_intensities_follow_mil_hdbk_1797():
    """Low altitude: sigma_w = 0.1 W20; sigma_u / sigma_w = 1 / (0.177 + 0.000823 h)^0.4, which
    is 1 at 1000 ft (where the low-altitude model meets the medium one) and grows below."""
    h, v = turbulence_sigma_mps(15.0, 1000 * 0.3048)
    assert v == pytest.approx(1.5) and h == pytest.approx(1.5 / (0.177 + 0.823) ** 0.4)
    h_low, _ = turbulence_sigma_mps(15.0, 50.0)
    assert h_low > h > v * 0.999


def test_the_wind_estimate_is_recorded_and_converges(repo_root, shipped_flight):
    """A short flight in a steady 6 m/s wind, BD and air data: the wind-state filter's estimate
    and 1-sigma are recorded (NaN on the vertical axis it does not estimate), its sigma shrinks
    from the model's 8 m/s, and after 60 s the estimate is within 3 sigma of the wind; a filter
    without the state records none."""
    import navsim
    data = yaml.safe_load((repo_root / ".ci" / "wheel_check.yaml").read_text())
    data["track"]["segments"] = [{"type": "straight", "time_s": 90}, {"type": "turn", "by_deg": 180, "bank_deg": 20},
                                 {"type": "straight", "time_s": 30}]
    data["environment"] = {"wind": {"north_mps": 3.0, "east_mps": -5.2}}
    data["sensors"]["ads"] = {"model": "p0_ads", "override": {"velocity_axis": "air", "vane_noise": "0.5 deg"}}
    est = data["estimators"][1]
    est["states"] = ["att", "vel", "pos", "gyro_bias", "accel_bias", "baro", "wind"]
    est["wind"] = {"model": "random_walk", "sigma_mps": 8.0, "walk_mps_per_rts": 0.02}
    est["measurements"][1] = {"type": "air_velocity", "sensor": "ads", "model": "p0_ads",
                              "override": {"velocity_axis": "air", "vane_noise": "0.5 deg"}}
    res = navsim.run(navsim.load_scenario(data), 4, 3, 1)
    h = res.histories["ES-KF"]
    assert res.histories["free SINS"].wind_n_mps is None and h.wind_n_mps.shape == h.pos_err_m.shape
    assert np.isnan(h.wind_n_mps[..., 2]).all() and np.isfinite(h.wind_n_mps[..., :2]).all()
    np.testing.assert_allclose(h.wind_sigma_mps[:, 0, :2], 8.0)
    late = h.t_s >= 60
    assert (h.wind_sigma_mps[:, late, :2] < 1.5).all()
    err = h.wind_n_mps[:, late, :2] - np.array([3.0, -5.2])
    assert (np.abs(err) < 3 * h.wind_sigma_mps[:, late, :2] + 0.2).mean() > 0.95


@pytest.mark.parametrize("changes, key, words", [
    ([{"at_s": 0, "force": 3}], "environment.wind_changes[0].at_s", "> 0"),
    ([{"at_s": 60, "force": 3}, {"at_s": 30, "force": 4}], "environment.wind_changes[1].at_s", "> 60"),
    ([{"at_s": 60}], "environment.wind_changes[0]", "gives no wind"),
    ([{"at_s": 60, "force": 9}], "environment.wind_changes[0].force", "9"),
    ([{"at_s": 60, "speed_mps": -2}], "environment.wind_changes[0].speed_mps", "-2"),
    ([], "environment.wind_changes", "too short"),
])
def test_malformed_wind_changes_are_refused(changes, key, words):
    with pytest.raises(ScenarioError) as info:
        parse_environment({"wind": {"force": 3, "from_deg": 270}, "wind_changes": changes}, file="s.yaml")
    assert info.value.key == key and words in str(info.value)


def test_the_steady_wind_between_its_changes():
    """Held before the first change and after the last; between two, speed and direction linear
    (the shorter way round: 350 -> 10 deg passes north), a calm end taking the other's direction."""
    env = parse_environment({"wind": {"speed_mps": 4, "from_deg": 350},
                             "wind_changes": [{"at_s": 100, "speed_mps": 4, "from_deg": 350},
                                              {"at_s": 200, "speed_mps": 8, "from_deg": 10},
                                              {"at_s": 300, "north_mps": 0, "east_mps": 0}]})
    np.testing.assert_allclose(steady_wind_n_mps(env, 50.0), wind_from(4, 350), atol=1e-12)
    np.testing.assert_allclose(steady_wind_n_mps(env, 150.0), wind_from(6, 0), atol=1e-12)
    np.testing.assert_allclose(steady_wind_n_mps(env, 250.0), wind_from(4, 10), atol=1e-12)
    np.testing.assert_allclose(steady_wind_n_mps(env, 1e4), 0.0, atol=1e-12)


def test_a_wind_change_after_the_flight_is_refused(repo_root, assert_scenario_error):
    data = yaml.safe_load((repo_root / "scenarios" / "p0_matched_ads.yaml").read_text())
    data["environment"] = {"wind_changes": [{"at_s": 100, "force": 4}, {"at_s": 9000, "force": 5}]}
    assert_scenario_error(data, "environment.wind_changes[1].at_s", "after the end of the flight")
