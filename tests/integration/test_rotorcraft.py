"""aircraft/octo25 flown by :func:`navsim.flight.fly` under the multirotor cascade
(:mod:`navsim.flight.rotorcraft`): a hover holds its point, a circle its radius, a goto reaches
its point; what the class or the envelope cannot fly is refused, naming the key, the segment and
the limit."""

import math

import numpy as np
import pytest
import yaml

from navsim.cli import main
from navsim.flight import FlightConfig, fly, parse_track
from navsim.flight.airframe import load_airframe
from navsim.flight.multirotor import MultirotorGains
from navsim.flight.properties import AIRCRAFT_DIR
from navsim.flight.rotorcraft import mixer_rotor
from navsim.foundations.earth import radii
from navsim.foundations.errors import FlightError

START = {"type": "hover", "lat_deg": 30.0, "lon_deg": 120.0, "alt_m": 20.0, "heading_deg": 0.0, "speed_mps": 5.0}


def octo_fly(segments, start=START):
    return fly(FlightConfig(track=parse_track({"start": start, "segments": segments}), aircraft="octo25"))


def local_ned(truth, start=START):
    """North, east, down (m) of the truth from the start point."""
    lat0, lon0 = math.radians(start["lat_deg"]), math.radians(start["lon_deg"])
    r_m, r_n = radii(lat0)
    return np.column_stack([(truth.lat_rad - lat0) * r_m, (truth.lon_rad - lon0) * r_n * math.cos(lat0),
                            start["alt_m"] - truth.h_m])


def test_the_mixer_rotor_of_the_rotor_table_lifts_up_and_cancels_its_pairs_torque():
    """octo25's sixteen rotors as the mixer sees them: thrust axes 10 deg off the vertical, each
    coaxial pair turning opposite ways (no net yaw torque at equal thrusts, without the tilt)."""
    airframe = load_airframe(AIRCRAFT_DIR / "octo25")
    rotors = [mixer_rotor(r, 40.0) for r in airframe.rotors]
    up = np.array([-r.axis_b[2] for r in rotors])
    assert np.allclose(up, math.cos(math.radians(10.0)))
    assert [r.spin for r in rotors] == [-r.spin for r in airframe.rotors]
    assert rotors[0].torque_per_thrust_m == pytest.approx(8.1420e-07 / 3.8732e-05)


def test_octo25_hovers_60_s_within_0_2_m():
    """The issue's acceptance: 60 s at 20 m in calm air within 0.2 m of the point (0.041 m
    measured, the first second's settling included)."""
    truth = octo_fly([{"type": "hover", "time_s": 60.0}])
    err = np.linalg.norm(local_ned(truth), axis=1)
    print(f"octo25 hover 60 s: max {err.max():.3f} m, RMS {np.sqrt(np.mean(err ** 2)):.4f} m")
    assert truth.duration_s == pytest.approx(60.0, abs=0.02) and err.max() < 0.2


def test_octo25_goes_to_a_point_and_circles_it_holding_the_radius():
    """A goto 30 m north and 10 m up, then a 20 m circle at 5 m/s, the nose at its centre: the
    radius held within 0.5 m RMS (P4's circle: the issue's bound), the height within 0.5 m."""
    truth = octo_fly([{"type": "goto", "north_m": 30.0, "east_m": 0.0, "alt_m": 30.0},
                      {"type": "circle", "radius_m": 20.0, "laps": 1, "direction": "right", "yaw": "center"}])
    ned = local_ned(truth)
    goto, circle = truth.segment == 0, truth.segment == 1
    assert np.linalg.norm(ned[goto][-1] - [30.0, 0.0, -10.0]) < 1.0
    # centred 20 m to the right of the heading flown (north): at (30, 20)
    r = np.hypot(ned[circle, 0] - 30.0, ned[circle, 1] - 20.0)
    steady = circle & (truth.t_s > truth.t_s[circle][0] + 5.0)
    r_steady = np.hypot(ned[steady, 0] - 30.0, ned[steady, 1] - 20.0)
    rms = np.sqrt(np.mean((r_steady - 20.0) ** 2))
    print(f"octo25 circle r 20 m at 5 m/s: radius RMS error {rms:.3f} m, max {np.abs(r - 20).max():.3f} m, "
          f"height max error {np.abs(ned[circle, 2] + 10.0).max():.3f} m")
    assert rms < 0.5 and np.abs(ned[circle, 2] + 10.0).max() < 0.5
    # the nose towards the centre, lagging it as a first-order heading loop lags a ramp: by the
    # turn rate over the loop's bandwidth, (5 / 20) / 0.83 rad = 17 deg (no yaw-rate
    # feed-forward yet)
    mid = steady & (truth.t_s < truth.t_s[circle][-1] - 5.0)       # at speed, not slowing to the end
    bearing = np.arctan2(20.0 - ned[mid, 1], 30.0 - ned[mid, 0])
    off = np.degrees((truth.euler_rad[mid, 2] - bearing + math.pi) % (2 * math.pi) - math.pi)
    lag = math.degrees((5.0 / 20.0) / MultirotorGains().yaw_bw_rps)
    print(f"nose behind the centre: mean {-off.mean():.1f} deg (std {off.std():.2f}), the loop's lag {lag:.1f} deg")
    assert abs(-off.mean() - lag) < 3.0 and off.std() < 2.0


def test_a_circle_beyond_the_tilt_limit_fails_naming_the_segment_and_the_limit():
    with pytest.raises(FlightError) as info:
        octo_fly([{"type": "hover", "time_s": 1.0}, {"type": "circle", "radius_m": 5.0, "laps": 1, "speed_mps": 9.0}])
    text = str(info.value)
    assert "segment 1" in text and "max_tilt_deg (25 deg)" in text and "5 m circle at 9 m/s" in text, text


def write(tmp_path, segments, **extra):
    path = tmp_path / "octo.yaml"
    path.write_text(yaml.safe_dump({"name": "octo", "aircraft": "octo25",
                                    "track": {"start": START, "segments": segments}, **extra}, sort_keys=False))
    return path


def test_navsim_fly_exits_3_on_a_speed_above_the_envelope_and_2_on_a_closed_loop(tmp_path, capsys):
    assert main(["fly", str(write(tmp_path, [{"type": "goto", "north_m": 50, "east_m": 0, "speed_mps": 12.0}])),
                 "--out", str(tmp_path / "out")]) == 3
    err = capsys.readouterr().err
    assert "speed 12 m/s above the aircraft's max_speed_mps (10 m/s)" in err and "Traceback" not in err, err
    scenario = write(tmp_path, [{"type": "hover", "time_s": 5.0}],
                     sensors={"imu": {"model": "p0_imu"}, "gps": {"model": "p3_gps"}},
                     estimators=[{"label": "KF", "type": "eskf", "states": "p3_15", "noise": {"imu": "p0_imu"},
                                  "measurements": [{"type": "gnss_position", "sensor": "gps", "sigma_m": 2}]}],
                     closed_loop={"fly_on": "KF", "time_limit_s": 60})
    assert main(["validate", str(scenario)]) == 2
    err = capsys.readouterr().err
    assert "octo.yaml: closed_loop" in err and "multirotor" in err and "fixed wing only" in err, err
