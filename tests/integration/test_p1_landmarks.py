"""P1's GNSS-denied navigation: landmark camera fixes and the barometer aiding a poor SINS."""

import numpy as np
import pytest
from model_result import unpack

from navsim.experiment.driver import perturbed_start
from navsim.experiment.scenario import parse_scenario
from navsim.flight.truth import Pose, Truth
from navsim.foundations.config import load_yaml
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.measurements import LandmarkFix
from navsim.scoring.landmarks import sighting_metrics
from navsim.sensors import SensorConfig, emulate, load_spec
from navsim.sensors.camera import flight_sightings


def test_landmark_fix_is_linear_in_the_position_error_with_range_dependent_noise():
    truth = Truth.static(10.0, rate_hz=10.0, pose=Pose(lat_deg=30.5, lon_deg=114.3, h_m=80.0))
    spec = load_spec("p1_camera", {"landmarks": [[30.5, 114.3, 0.0]], "noise": "0 m", "noise_ratio": "0 %"})
    cam = emulate(truth, SensorConfig("camera", "p1_camera", spec), 1, [0, 1])
    assert cam.valid.all()                      # the anchor is right below
    errors = np.zeros((2, 9))
    errors[:, 6:] = [[3.0, -2.0, 1.5], [-0.5, 4.0, -2.0]]          # NED position errors, m
    nav = perturbed_start(truth, errors)
    layout = Layout(PRESETS["p0_16"])
    z, H, R, valid = unpack(LandmarkFix("camera", 3.0, 0.01).model(nav, layout, cam, 0))
    dx = np.zeros((2, layout.n))
    dx[:, 6] = nav.lat_rad - truth.lat_rad[0]
    dx[:, 7] = nav.lon_rad - truth.lon_rad[0]
    dx[:, 8] = nav.h_m - truth.h_m[0]
    np.testing.assert_allclose(z, np.einsum("bij,bj->bi", H, dx), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(z, errors[:, 6:], atol=1e-6)
    rng = np.linalg.norm(errors[:, 6:] + [0.0, 0.0, -80.0], axis=-1)    # INS position to the anchor
    np.testing.assert_allclose(R[:, 0, 0], (3.0 + 0.01 * rng) ** 2, rtol=1e-6)
    assert valid.all()


@pytest.fixture(scope="module")
def short_run(repo_root, tmp_path_factory):
    """The shipped scenario cut to its first leg (400 s, 9 anchors), 8 runs."""
    import os
    os.environ.setdefault("NAVSIM_CACHE", str(tmp_path_factory.mktemp("cache")))
    from navsim.experiment.options import RunOptions
    from navsim.experiment.runner import cached_flight, run_monte_carlo
    data = load_yaml(repo_root / "scenarios" / "p1_gnss_denied_landmarks.yaml")
    data["track"] = {"name": "p1_leg", "start": {"type": "air", "lat_deg": 30.5, "lon_deg": 114.3, "alt_m": 80,
                                                  "speed_mps": 14.0, "heading_deg": 0},
                     "segments": [{"type": "straight", "time_s": 400}]}
    lm = data["sensors"]["camera"]["override"]["landmarks"]
    data["sensors"]["camera"]["override"]["landmarks"] = lm[:9]
    scenario = parse_scenario(data, "p1_leg.yaml")
    truth, path, _ = cached_flight(scenario.flight)
    result = run_monte_carlo(scenario, truth, path, RunOptions(runs=8, seed=2, workers=1))
    return scenario, truth, result


def test_landmarks_bring_the_position_back_to_the_fix_noise_after_each_sighting(short_run):
    scenario, truth, result = short_run
    spans = flight_sightings(truth, scenario.sensors)
    assert len(spans) == 9 and all(2.0 < b - a < 10.0 for _, a, b, _ in spans)   # ~6 fixes each
    m = sighting_metrics(result.histories["SINS/landmark/baro"], spans)
    assert m.fraction_within_3sigma == 1.0, m
    assert m.rms_after_m < 3.9                      # below one fix sigma (3 m + 1 % of ~85 m)
    assert m.rms_before_m.median > 3 * m.rms_after_m   # it had drifted in between


def test_free_sins_diverges_and_the_baro_bounds_the_height(short_run):
    scenario, truth, result = short_run
    free = result.histories["free SINS"]
    horiz = np.hypot(free.pos_err_m[..., 0], free.pos_err_m[..., 1])
    # P1's gyro constant of 0.001 rad/s tilts the platform: g * eps * t^3 / 6 = 26 km in 400 s
    assert np.median(horiz[:, -1]) > 5e3
    assert np.median(np.abs(free.pos_err_m[:, -1, 2])) > 100.0      # the height channel diverges
    baro = next(c for c in scenario.sensors if c.kind == "baro").spec
    bound = 3.0 * np.hypot(baro.markov_sigma, baro.noise)
    # (SINS/baro's height stays bounded too, but its position ends hundreds of km off over the
    # whole 1800 s flight, and the wrong gravity takes it to 12.7 m: asserted on this first leg)
    for label in ("SINS/baro", "SINS/landmark/baro"):
        assert np.abs(result.histories[label].pos_err_m[..., 2]).max() < bound, label
    sb = result.histories["SINS/baro"]
    assert np.median(np.hypot(sb.pos_err_m[:, -1, 0], sb.pos_err_m[:, -1, 1])) > 1e3   # no horizontal aid


@pytest.mark.slow
def test_p1_gnss_denied_acceptance_over_100_runs(repo_root):
    """Issue 8: over 100 runs of the shipped 1800 s scenario the landmark filter's position error
    is inside 3 sigma of the camera fix noise after the sightings (measured: 99.94 % of run x
    sighting x axis; the worst, 3.8-5.2 sigma, follows a 180 deg turn, which
    turns the unobservable heading error into ~600 m of position error) and the height error
    stays inside 3 sigma of the baro error model (but in two runs of 100: see below)."""
    from navsim.experiment.options import RunOptions
    from navsim.experiment.runner import cached_flight, run_monte_carlo
    from navsim.experiment.scenario import load_scenario
    scenario = load_scenario(repo_root / "scenarios" / "p1_gnss_denied_landmarks.yaml")
    truth, path, _ = cached_flight(scenario.flight)
    result = run_monte_carlo(scenario, truth, path, RunOptions(runs=100, seed=1, workers=2))
    h = result.histories["SINS/landmark/baro"]
    m = sighting_metrics(h, flight_sightings(truth, scenario.sensors))
    assert m.count == 40 and m.fraction_within_3sigma > 0.999, m
    assert len(m.sightings) == m.count
    # the worst run of 100 at a sighting: at a typical one (the median over the 40) 1.8 sigma;
    # after a turn the heading error, not observable before, is a non-Gaussian share of the
    # position error: at the first anchor after the first turn 3.8 sigma (seed 1, before the
    # random streams per error process), 4.0 and 4.3 (seeds 1 and 2 after), and at seed 1 one
    # run reaches 5.2 sigma at the last two anchors
    assert np.median([s.max_ratio for s in m.sightings]) < 2.5, m.sightings
    assert m.max_ratio < 6.0, m
    baro = next(c for c in scenario.sensors if c.kind == "baro").spec
    # the height inside 3 sigma of the baro model in 98 of the 100 runs: in runs 13 and 28 the
    # heading error, unobservable between anchors, lets the horizontal error reach 775 m (before
    # the last anchors, 1776 s) and 117 m (958 s), and the fixes then pull the height 61 m and
    # 11 m off with sigma_D 1.2-1.4 m: there the error-state filter's small-angle model fails
    inside = (np.abs(h.pos_err_m[..., 2]) < 3.0 * np.hypot(baro.markov_sigma, baro.noise)).all(axis=1)
    assert inside.sum() >= 98, np.flatnonzero(~inside)


@pytest.mark.parametrize("change, key, words", [
    (lambda m: m.update(sensor="baro"), "estimators[2].measurements[0].sensor", "expected a camera sensor"),
    (lambda m: m.update(ratio=-0.1), "estimators[2].measurements[0].ratio", ">= 0.0"),
    (lambda m: m.pop("sigma_m"), "estimators[2].measurements[0].sigma_m", "is missing"),
])
def test_malformed_landmark_measurement_names_the_key(repo_root, change, key, words, assert_scenario_error):
    data = load_yaml(repo_root / "scenarios" / "p1_gnss_denied_landmarks.yaml")
    change(data["estimators"][2]["measurements"][0])
    assert_scenario_error(data, key, words)