"""P1's magnetometer: online calibration in two turns on the GNSS-aided attitude, then heading
aiding through a GNSS outage."""

import numpy as np
import pytest

from navsim.config import load_yaml
from navsim.metrics import calibration_metrics
from navsim.scenario import load_scenario


def run(repo_root, runs, workers=1):
    from navsim.runner import cached_flight, run_monte_carlo
    scenario = load_scenario(repo_root / "scenarios" / "p1_mag_calibration.yaml")
    truth, path, _ = cached_flight(scenario.flight)
    return scenario, run_monte_carlo(scenario, truth, path, runs, 3, workers)


def heading_rms_deg(h, a, b):
    m = (h.t_s >= a) & (h.t_s <= b)
    return float(np.degrees(np.sqrt(np.mean(h.att_err_rad[:, m, 2] ** 2))))


def test_two_turns_calibrate_the_magnetometer_within_2_percent(repo_root, tmp_path, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    scenario, result = run(repo_root, 3)
    h = result.histories["SINS/GNSS/magnetometer"]
    c = calibration_metrics(h, result.truth_bias)["mag"]
    assert c["t_s"] == pytest.approx(121.0, abs=0.5)
    assert c["hard_iron_pct"]["max"] < 2.0 and c["soft_iron_pct"]["max"] < 2.0, c
    # before the turns the errors were the installation's: tens of % of the field
    truth = result.truth_bias["mag.hard_iron_T"]
    assert np.all(np.linalg.norm(truth, axis=-1) / result.truth_bias["mag.field_T"] > 0.2)
    # through the GNSS outage the calibrated magnetometer holds the heading better
    with_mag = heading_rms_deg(h, 300, 800)
    without = heading_rms_deg(result.histories["SINS/GNSS"], 300, 800)
    assert with_mag < without, (with_mag, without)


@pytest.mark.parametrize("change, key, words", [
    (lambda m: m.update(sensor="gps"), "estimators[1].measurements[2].sensor", "expected a magnetometer"),
    (lambda m: m.update(calibrate_until_s=50), "estimators[1].measurements[2].calibrate_until_s", "> 80.0"),
    (lambda m: m.pop("sigma_uT"), "estimators[1].measurements[2].sigma_uT", "is missing"),
])
def test_malformed_magnetic_field_measurement_names_the_key(repo_root, change, key, words, assert_scenario_error):
    data = load_yaml(repo_root / "scenarios" / "p1_mag_calibration.yaml")
    change(data["estimators"][1]["measurements"][2])
    assert_scenario_error(data, key, words)


@pytest.mark.slow
def test_p1_magnetometer_acceptance_over_100_runs(repo_root):
    """Issue 8: after two full turns hard iron within 2 % of the field and soft iron within 2 %
    (Frobenius) in every one of 100 runs; the heading error with the calibrated magnetometer
    through the outage is below the GNSS-only filter's."""
    scenario, result = run(repo_root, 100, workers=2)
    h = result.histories["SINS/GNSS/magnetometer"]
    c = calibration_metrics(h, result.truth_bias)["mag"]
    assert c["hard_iron_pct"]["max"] < 2.0 and c["soft_iron_pct"]["max"] < 2.0, c
    assert heading_rms_deg(h, 300, 800) < heading_rms_deg(result.histories["SINS/GNSS"], 300, 800)
