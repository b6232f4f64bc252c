"""Edges of flights and sensors (issue 50): a 1 Hz sensor on a flight whose length is not a
multiple of its period, JSBSim's Tustin turbulence, P0's flight in P0's calm air, a fault window
running past the end of the flight."""

import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from navsim import cli
from navsim.experiment.scenario import check_scenario, load_scenario, parse_scenario
from navsim.flight import FlightConfig, Truth, fly, parse_track
from navsim.flight.environment import parse_environment, turbulence_sigma_mps
from navsim.sensors import emulate, parse_sensors
from navsim.sensors.base import truth_step
from navsim.sensors.plots import channels, plot_sensor

ROOT = Path(__file__).resolve().parents[2]
START = {"type": "air", "lat_deg": 37.38, "lon_deg": 117.97, "alt_m": 300, "speed_mps": 13.9,
         "heading_deg": 90}


def straight(time_s: float) -> dict:
    """A track: the air start and one straight of ``time_s``."""
    return {"name": f"straight{time_s:g}", "start": START, "segments": [{"type": "straight", "time_s": time_s}]}


# --- 1. a 1 Hz sensor on a flight of 60, 96, 120 s --------------------------------------------------

@pytest.mark.parametrize("duration_s", [60.0, 96.0, 120.0, 500.0])
def test_a_1hz_gnss_is_plotted_against_the_truth_at_its_own_times(tmp_path, duration_s):
    truth = Truth.static(duration_s, rate_hz=100.0)
    (cfg,) = parse_sensors({"bd": {"model": "p0_bd2"}})
    data = emulate(truth, cfg, seed=3, runs=[0])
    assert np.array_equal(truth.t_s[truth_step(data, truth)], data.t_s)   # the same instants
    for label, _, t, meas, true in channels(data, truth):
        assert len(t) == len(meas) == len(true), label
    assert plot_sensor(data, truth, tmp_path / "bd.png").is_file()


def test_navsim_sensors_on_a_custom_straight_writes_every_picture(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "straight60.yaml"
    path.write_text(yaml.safe_dump({"name": "straight60", "track": straight(60.0), "montecarlo": {"runs": 2},
                                    "sensors": {"bd": {"model": "p0_bd2"}, "baro": {"model": "p0_baro"},
                                                "ads": {"model": "p0_ads"}}}))
    code = cli.main(["sensors", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "out").glob("*.png")) == \
        ["sensor_ads.png", "sensor_baro.png", "sensor_bd.png"]


# --- 2. Tustin turbulence ---------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["tustin", "milspec"])
def test_turbulence_flies_and_moves_the_air(kind):
    env = parse_environment({"turbulence": {"type": kind, "wind20_mps": 4.5, "severity": 2, "seed": 7}})
    truth = fly(FlightConfig(track=parse_track(straight(20.0)), environment=env))
    assert truth.duration_s == pytest.approx(20.0, abs=0.02)
    for values in (truth.lat_rad, truth.h_m, truth.vel_n_mps, truth.omega_ib_b_rps, truth.wind_n_mps):
        assert np.all(np.isfinite(values))
    gust_std = (truth.wind_n_mps - truth.wind_steady_n_mps).std(axis=0)
    sigma_mps = max(turbulence_sigma_mps(4.5, 300.0))        # MIL-HDBK-1797 at 300 m: 0.45 m/s
    assert np.all(gust_std > 0.02 * sigma_mps), gust_std     # turbulence there, in every axis
    assert np.all(gust_std < 5.0 * sigma_mps), gust_std      # of about the size asked (20 s of it)


def test_the_shipped_p0_flight_flies_in_tustin_turbulence():
    data = yaml.safe_load((ROOT / "scenarios" / "p0_flight.yaml").read_text())
    data["environment"] = {"turbulence": {"type": "tustin", "wind20_mps": 4.5, "severity": 2, "seed": 7}}
    p0_start = yaml.safe_load((ROOT / "navsim" / "tracks" / "p0.yaml").read_text())["start"]
    data["track"] = {"name": "p0_short", "start": p0_start,       # P0's start, a short track
                     "segments": [{"type": "straight", "time_s": 5}, {"type": "turn", "by_deg": 30, "bank_deg": 20}]}
    scenario = parse_scenario(data, "p0_flight.yaml")
    truth = fly(scenario.flight)
    assert truth.duration_s > 5.0 and np.all(np.isfinite(truth.h_m)) and np.all(np.isfinite(truth.wind_n_mps))


# --- 3. P0's flight in P0's conditions --------------------------------------------------------

def test_p0_scenarios_other_than_the_wind_studies_fly_in_calm_air():
    """P0 flies in calm air (the ADS velocity neglects the wind): p0_flight, listed as P0's flight,
    too; the wind studies say 'wind' in their name."""
    paths = [p for p in sorted((ROOT / "scenarios").glob("p0_*.yaml")) if "wind" not in p.stem]
    assert ROOT / "scenarios" / "p0_flight.yaml" in paths
    for path in paths:
        env = load_scenario(path).flight.environment
        assert env.wind_n_mps == (0.0, 0.0, 0.0) and not env.wind_changes and env.turbulence == "none", path.name
    assert "calm air" in load_scenario(ROOT / "scenarios" / "p0_flight.yaml").description


# --- 4. a fault window running past the end of the flight ---------------------------------------

def fault_scenario(end_s):
    return {"name": "late_fault", "track": straight(60.0),
            "sensors": {"bd": {"model": "p0_bd2", "faults": [{"type": "outage", "start_s": 40, "end_s": end_s}]}}}


def test_a_fault_window_running_past_the_flight_is_named_in_a_warning(caplog):
    scenario = parse_scenario(fault_scenario(90.0), "late.yaml")
    with caplog.at_level(logging.WARNING):
        check_scenario(scenario, 60.0)
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    msg = record.getMessage()
    for words in ("late.yaml", "sensors.bd.faults[0]", "outage", "40", "90", "60"):
        assert words in msg, msg


def test_a_fault_window_within_the_flight_or_open_ended_is_not_warned_about(caplog):
    with caplog.at_level(logging.WARNING):
        for end_s in (60.0, 50.0, None):
            data = fault_scenario(end_s)
            if end_s is None:
                del data["sensors"]["bd"]["faults"][0]["end_s"]
            check_scenario(parse_scenario(data, "ok.yaml"), 60.0)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_the_cli_shows_the_clipped_fault_once(tmp_path):
    path = tmp_path / "late.yaml"
    path.write_text(yaml.safe_dump(fault_scenario(90.0)))
    env = dict(os.environ, NAVSIM_CACHE=str(tmp_path / "cache"))
    done = subprocess.run([sys.executable, "-m", "navsim", "sensors", str(path), "--runs", "1", "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("sensors.bd.faults[0]") == 1 and "90" in done.stderr, done.stderr
