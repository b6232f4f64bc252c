import json
import subprocess
import sys

import pytest

from navsim.cli import build_parser, main


def test_fly_writes_plots_truth_and_summary(tmp_path, capsys):
    scenario = tmp_path / "s.yaml"
    scenario.write_text("""
name: short
track:
  start: {lat_deg: 37.0, lon_deg: 118.0, alt_m: 250, speed_mps: 14, heading_deg: 45}
  segments:
    - {type: straight, time_s: 20, label: leg}
    - {type: turn, by_deg: -90, label: left turn}
    - {type: straight, time_s: 10}
environment: {wind: {speed_mps: 3, from_deg: 200}}
""")
    out = tmp_path / "out"
    assert main(["fly", str(scenario), "--out", str(out)]) == 0
    for name in ("flight_3d.png", "flight_ground.png", "flight_time.png", "truth.npz",
                 "run.json", "scenario.yaml"):
        assert (out / name).stat().st_size > 0, name
    record = json.loads((out / "run.json").read_text())
    assert record["failure"] is None and record["samples"] > 3000
    assert "numpy" in record["versions"] and "git_revision" in record
    text = capsys.readouterr().out
    assert "left turn" in text and "real time" in text


def test_failed_flight_exits_3_and_keeps_what_was_flown(tmp_path, capsys):
    scenario = tmp_path / "s.yaml"
    scenario.write_text("""
track:
  start: {lat_deg: 37.0, lon_deg: 118.0, alt_m: 60, speed_mps: 14}
  segments:
    - {type: straight, time_s: 5}
    - {type: descend, to_m: -20, rate_mps: 4, label: into the sea}
""")
    out = tmp_path / "out"
    assert main(["fly", str(scenario), "--out", str(out)]) == 3
    err = capsys.readouterr().err
    assert "segment 1 (into the sea)" in err and "impact" in err
    assert (out / "truth.npz").exists() and (out / "flight_time.png").exists()


@pytest.mark.parametrize("text, words", [
    ("track: p0\nenvironment: {wind: {speed_mps: -3}}\n", "environment.wind.speed_mps: is -3.0"),
    ("track: p0\nflght: {rate_hz: 100}\n", "did you mean 'flight'"),
    ("track: [1, 2\n", "not valid YAML"),
    ("name: x\n", "track: is missing"),
])
def test_malformed_scenario_exit_2_without_traceback(tmp_path, text, words, capsys):
    """In this process (``python -m navsim`` itself: test_help_on_every_command): exit 2, the
    file and the words on stderr, no exception out of ``main``."""
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and words in err and "Traceback" not in err


def test_help_on_every_command(capsys):
    """``python -m navsim --help`` through the module's entry point; every command's help in
    this process (a subprocess each cost 2.4 s of imports)."""
    proc = subprocess.run([sys.executable, "-m", "navsim", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "usage: navsim" in proc.stdout
    for command in build_parser()._subparsers._group_actions[0].choices:
        with pytest.raises(SystemExit) as done:
            main([command, "--help"])
        assert done.value.code == 0 and f"usage: navsim {command}" in capsys.readouterr().out, command


def test_list(capsys, monkeypatch):
    """Every section aligned and wrapped to the terminal (80 columns here), nothing cut."""
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "survey10" in out and "p2_sea" in out
    for section in ("sensors", "tracks", "estimators", "state presets", "measurement types"):
        assert f"\n{section}" in out, section
    assert max(len(line) for line in out.splitlines()) <= 80
    presets = out.split("state presets (states:):\n")[1].splitlines()[:3]
    assert presets[0].split() == ["p3_15", "15", "states", "att,", "vel,", "pos,", "gyro_bias,", "accel_bias"]
    assert len({line.index("states") for line in presets}) == 1          # the columns line up
    rows = [ln for ln in out.split("measurement types")[1].splitlines()[1:] if ln.startswith("  ") and ln[2] != " "]
    assert [r.split()[0] for r in rows] == sorted(r.split()[0] for r in rows) and "zero_velocity" in out


def test_sensors_command_plots_each_sensor(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    scenario = tmp_path / "s.yaml"
    scenario.write_text("""
name: short_sensors
track:
  start: {lat_deg: 30.0, lon_deg: 122.5, alt_m: 120, speed_mps: 15}
  segments: [{type: straight, time_s: 30}]
sensors:
  imu: {model: p2_imu}
  gps: {model: p2_gps, faults: [{type: outage, start_s: 10, end_s: 15}]}
  radar: {model: p2_radar, faults: [{type: bias, start_s: 5, end_s: 8, value_m: 10}]}
  mag: {model: lsm303d}
montecarlo: {runs: 3, seed: 4}
""")
    out = tmp_path / "out"
    assert main(["sensors", str(scenario), "--out", str(out)]) == 0
    for name in ("imu", "gps", "radar", "mag"):
        assert (out / f"sensor_{name}.png").stat().st_size > 10000
    text = capsys.readouterr().out
    assert "p2_radar" in text and "3 run(s), seed 4" in text
    # GPS: 5 of 31 fixes lost to the outage
    assert "83.9" in text
    # the IMU's Allan deviation at rest: its white noise is the datasheet's (2000 s, to 5 %)
    assert (out / "allan_imu.png").stat().st_size > 20000
    assert (out / "spectrum_imu.png").stat().st_size > 20000          # its error spectrum
    line = next(ln for ln in text.splitlines() if ln.startswith("imu: white noise read from its Allan"))
    ratios = dict(part.split() for part in line.split(": ")[-1].split(", "))
    assert set(ratios) == {"gyro", "accel"} and all(abs(float(v) - 1) < 0.05 for v in ratios.values()), line


def test_malformed_sensor_section_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("track: p0\nsensors:\n  imu: {model: p0_imu, override: {gyro: {bias_sigma: 3 m}}}\n")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "sensors.imu.override.gyro.bias_sigma" in err and "deg/h" in err
