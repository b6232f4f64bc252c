"""aircraft/octo25 flown by :func:`navsim.flight.fly` under the multirotor cascade
(:mod:`navsim.flight.rotorcraft`): a hover holds its point, a circle its radius, a goto reaches
its point; what the class or the envelope cannot fly is refused, naming the key, the segment and
the limit."""

import ast
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

import navsim
from navsim.cli import main
from navsim.flight import FlightConfig, fly, parse_track
from navsim.flight.airframe import load_airframe, model_location
from navsim.flight.environment import parse_environment
from navsim.flight.multirotor import MultirotorGains
from navsim.flight.properties import AIRCRAFT_DIR, JSBSimIO
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


#: each model's drag torque per thrust, m, from its propeller's data: octo25's k_Q / k_T (its
#: README's table), the F450's C_P D / (2 pi C_T) of DJI_9450.xml (C_T 0.1288, C_P 0.0666, 9.4 in)
TORQUE_PER_THRUST_M = {"octo25": 8.1420e-07 / 3.8732e-05, "f450": 0.0666 * 9.4 * 0.0254 / (2 * math.pi * 0.1288)}


@pytest.mark.parametrize("name", ["octo25", "f450"])
def test_the_mixer_rotors_of_the_rotor_table_are_jsbsims_thrusters(name):
    """octo25's sixteen rotors and the F450's four as the mixer sees them (built from
    navsim.yaml's table) against the thrusters JSBSim loaded from the model: each position
    JSBSim's (structural inches from its centre of gravity: x aft, y right, z up), each thrust
    axis JSBSim's (its orientation's pitch and yaw: x_thruster = (cos p cos y, cos p sin y,
    -sin p) in body axes), each spin right-handed about that axis where JSBSim's propeller sense
    is +1."""
    airframe = load_airframe(AIRCRAFT_DIR / name)
    rotors = [mixer_rotor(r, 40.0) for r in airframe.rotors]
    model, model_dir = model_location(AIRCRAFT_DIR / name, airframe)
    fdm = JSBSimIO(model, 0.01, model_dir).fdm
    cg_in = np.array([fdm[f"inertia/cg-{k}-in"] for k in "xyz"])
    for i, r in enumerate(rotors):
        xyz_in = np.array([fdm[f"propulsion/engine[{i}]/{k}-position"] for k in "xyz"])
        assert np.allclose(r.pos_b_m, (xyz_in - cg_in) * [-0.0254, 0.0254, -0.0254], atol=2e-3), (i, r.pos_b_m)
        p, y = fdm[f"propulsion/engine[{i}]/pitch-angle-rad"], fdm[f"propulsion/engine[{i}]/yaw-angle-rad"]
        axis = (math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), -math.sin(p))
        assert np.allclose(r.axis_b, axis, atol=1e-4), (i, r.axis_b, axis)
        assert r.spin == fdm[f"propulsion/engine[{i}]/propeller-sense"], i
    assert all(r.torque_per_thrust_m == pytest.approx(TORQUE_PER_THRUST_M[name], rel=1e-3) for r in rotors)


def test_octo25_hovers_60_s_within_0_2_m_on_its_recorded_rotor_speeds():
    """The issue's acceptance: 60 s at 20 m in calm air within 0.2 m of the point (0.044 m
    measured, the first second's settling included). The truth records the sixteen rotors'
    speeds: near P4's 6000 r/min, and their thrusts (the rotor table's k_T w^2 along each tilted
    axis) carry the weight."""
    truth = octo_fly([{"type": "hover", "time_s": 60.0}])
    err = np.linalg.norm(local_ned(truth), axis=1)
    print(f"octo25 hover 60 s: max {err.max():.3f} m, RMS {np.sqrt(np.mean(err ** 2)):.4f} m")
    assert truth.duration_s == pytest.approx(60.0, abs=0.02) and err.max() < 0.2
    airframe = load_airframe(AIRCRAFT_DIR / "octo25")
    assert truth.rotor_rpm.shape == (truth.n, 16)
    late = truth.t_s > 10.0
    assert np.all((truth.rotor_rpm[late] > 5500.0) & (truth.rotor_rpm[late] < 6500.0))
    k_t = np.array([r.thrust_coefficient * math.cos(math.radians(r.tilt_deg)) for r in airframe.rotors])
    lift_n = (k_t * (truth.rotor_rpm[late] * 2 * math.pi / 60.0) ** 2).sum(axis=1)
    assert lift_n.mean() == pytest.approx(airframe.mass_kg * 9.80665, rel=0.01), lift_n.mean()


def test_a_steady_wind_pushes_octo25_and_its_integral_brings_it_back():
    """Hovering in a 7 m/s west wind (force 4), started still in it: blown up to 0.88 m off at
    first, it leans into the wind (its drag: about 10 deg of roll, left) and the velocity loop's
    integral, learning the push while the vehicle holds still against it, brings it back within
    0.05 m after 20 s (0.0001 m measured)."""
    env = parse_environment({"wind": {"speed_mps": 7.0, "from_deg": 270}}, "environment", None)
    truth = fly(FlightConfig(track=parse_track({"start": START, "segments": [{"type": "hover", "time_s": 40.0}]}),
                             environment=env, aircraft="octo25"))
    err = np.linalg.norm(local_ned(truth), axis=1)
    late = truth.t_s > 20.0
    roll_deg = np.degrees(truth.euler_rad[late, 0]).mean()
    print(f"octo25 hover in 7 m/s wind: max {err.max():.3f} m, after 20 s {err[late].max():.5f} m, roll {roll_deg:.1f} deg")
    assert 0.2 < err.max() < 2.0 and err[late].max() < 0.05 and -15.0 < roll_deg < -5.0


def test_octo25_goes_to_a_point_and_circles_it_holding_the_radius():
    """A goto 30 m north and 10 m up, then a 20 m circle at 5 m/s, the nose at its centre: the
    radius held within 0.5 m RMS (P4's circle: the issue's bound; 0.20 m measured), the height
    within 0.5 m."""
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
    # the nose towards the centre: without the heading's rate fed forward a first-order heading
    # loop would lag it by the turn rate over its bandwidth, (5 / 20) / 0.83 rad = 17 deg; with
    # it, by under a tenth of that
    mid = steady & (truth.t_s < truth.t_s[circle][-1] - 5.0)       # at speed, not slowing to the end
    bearing = np.arctan2(20.0 - ned[mid, 1], 30.0 - ned[mid, 0])
    off = np.degrees((truth.euler_rad[mid, 2] - bearing + math.pi) % (2 * math.pi) - math.pi)
    lag = math.degrees((5.0 / 20.0) / MultirotorGains().yaw_bw_rps)
    print(f"nose behind the centre: mean {-off.mean():.2f} deg (std {off.std():.2f}), "
          f"without feed-forward {lag:.1f} deg")
    assert np.abs(off).max() < 0.1 * lag


def test_a_circle_is_centred_beside_the_way_flown_and_a_hover_keeps_the_nose_it_has():
    """A goto east with the nose along the course, a right circle (centred south of the goto's
    end: to the right of east), then a hover holding the heading it has at the circle's end."""
    truth = octo_fly([{"type": "goto", "north_m": 0.0, "east_m": 30.0, "yaw": "course"},
                      {"type": "circle", "radius_m": 15.0, "laps": 0.5, "direction": "right"},
                      {"type": "hover", "time_s": 10.0}])
    ned = local_ned(truth)
    circle, hover = truth.segment == 1, truth.segment == 2
    assert np.degrees(abs(truth.euler_rad[truth.segment == 0][-1, 2] - math.pi / 2)) < 3.0   # nose east
    r = np.hypot(ned[circle, 0] + 15.0, ned[circle, 1] - 30.0)
    assert np.abs(r - 15.0).max() < 1.0                                # centre (-15, 30): south
    # half a lap clockwise from (0, 30) round (-15, 30) ends at (-30, 30), flying west
    assert np.linalg.norm(ned[hover][-1, :2] - [-30.0, 30.0]) < 0.3
    # the nose settles on the heading it was given last (the course as the point slowed below
    # 0.5 m/s), a few degrees on from where the lagging nose was, and stays there
    yaw = np.degrees(np.unwrap(truth.euler_rad[hover, 2]))
    settled = truth.t_s[hover] > truth.t_s[hover][0] + 5.0
    assert np.ptp(yaw) < 6.0 and np.ptp(yaw[settled]) < 0.2, (np.ptp(yaw), np.ptp(yaw[settled]))


def test_a_circle_beyond_the_tilt_limit_fails_naming_the_segment_and_the_limit():
    with pytest.raises(FlightError) as info:
        octo_fly([{"type": "hover", "time_s": 1.0}, {"type": "circle", "radius_m": 5.0, "laps": 1, "speed_mps": 9.0}])
    text = str(info.value)
    assert "segment 1" in text and "max_tilt_deg (25 deg)" in text and "5 m circle at 9 m/s" in text, text


def write(tmp_path, segments, start=START, aircraft="octo25", **extra):
    path = tmp_path / "octo.yaml"
    path.write_text(yaml.safe_dump({"name": "octo", "aircraft": aircraft,
                                    "track": {"start": start, "segments": segments}, **extra}, sort_keys=False))
    return path


def test_what_the_envelope_or_the_class_cannot_fly_is_refused_at_validation(tmp_path, capsys):
    """Exit 2 before any flight, naming the key and the limit: a speed above max_speed_mps, a
    circle beyond the tilt limit, navigation in the loop off the ground (a takeoff), turbulence in
    calm air (at the start or after a change of the wind), yaw and heading both."""
    for segments, words in (([{"type": "goto", "north_m": 50, "east_m": 0, "speed_mps": 12.0}],
                             ["octo.yaml: track.segments[0].speed_mps", "max_speed_mps (10 m/s)"]),
                            ([{"type": "circle", "radius_m": 5.0, "laps": 1, "speed_mps": 9.0}],
                             ["octo.yaml: track.segments[0].radius_m", "needs a 59 deg tilt", "max_tilt_deg (25 deg)"])):
        assert main(["fly", str(write(tmp_path, segments)), "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert all(w in err for w in words) and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()
    scenario = write(tmp_path, [{"type": "takeoff", "agl_m": 10.0}], start=GROUND_START,
                     environment={"surface_m": 10.0},
                     sensors={"imu": {"model": "p0_imu"}, "gps": {"model": "p3_gps"}},
                     estimators=[{"label": "KF", "type": "eskf", "states": "p3_15", "noise": {"imu": "p0_imu"},
                                  "measurements": [{"type": "gnss_position", "sensor": "gps", "sigma_m": 2}]}],
                     closed_loop={"fly_on": "KF", "time_limit_s": 60})
    assert main(["validate", str(scenario)]) == 2
    err = capsys.readouterr().err
    assert "octo.yaml: track.start.type" in err and "starts on the ground" in err and "hover" in err, err
    for extra, segment, words in (({"environment": {"turbulence": {"type": "milspec", "wind20_mps": 5}}},
                                   {"type": "hover", "time_s": 5.0}, "in a 0 m/s wind on a multirotor"),
                                  ({"environment": {"wind": {"speed_mps": 7.0, "from_deg": 270},
                                                    "wind_changes": [{"at_s": 2.0, "speed_mps": 1.0, "from_deg": 270}],
                                                    "turbulence": {"type": "milspec", "wind20_mps": 5}}},
                                   {"type": "hover", "time_s": 5.0}, "in a 1 m/s wind on a multirotor"),
                                  ({}, {"type": "hover", "time_s": 5.0, "yaw": "course", "heading_deg": 90},
                                   "octo.yaml: track.segments[0].heading_deg")):
        assert main(["validate", str(write(tmp_path, [segment], **extra))]) == 2
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err, err


def test_jsbsims_own_f450_hovers_and_flies_a_50_m_square_with_no_code_of_its_own():
    """The issue's acceptance for the jsbsim package's F450 quadrotor, flown from
    aircraft/f450/navsim.yaml alone (the package's model, its rotor table, the command
    properties of its flight control system): 60 s hover within 0.3 m (0.008 m measured), then
    a 50 m square at 5 m/s, each corner passed within 0.5 m, the path within 1 m of the
    square's sides, and back home within 0.1 m after a 5 s hover. navsim's code names it nowhere (its comments and docstrings may)."""
    package = Path(navsim.__file__).parent
    assert not [p for p in package.rglob("*.py") if "f450" in " ".join(_code_words(p.read_text())).lower()]
    f450 = FlightConfig(track=parse_track({"start": START, "segments": [{"type": "hover", "time_s": 60.0}]}),
                        aircraft="f450")
    truth = fly(f450)
    err = np.linalg.norm(local_ned(truth), axis=1)
    print(f"F450 hover 60 s: max {err.max():.4f} m, RMS {np.sqrt(np.mean(err ** 2)):.4f} m")
    assert truth.duration_s == pytest.approx(60.0, abs=0.02) and err.max() < 0.3
    corners = np.array([[50.0, 0.0], [50.0, 50.0], [0.0, 50.0], [0.0, 0.0]])
    square = [{"type": "goto", "north_m": n, "east_m": e} for n, e in corners] + [{"type": "hover", "time_s": 5.0}]
    truth = fly(dataclasses.replace(f450, track=parse_track({"start": START, "segments": square})))
    ned = local_ned(truth)
    ne = ned[:, :2]
    near = [np.linalg.norm(ne - c, axis=1).min() for c in corners]
    side = np.stack([_distance_to_segment(ne, a, b) for a, b in zip(np.roll(corners, 1, axis=0), corners)])
    off = side.min(axis=0)
    print(f"F450 50 m square in {truth.duration_s:.1f} s: passes each corner within {max(near):.3f} m, path off "
          f"the sides max {off.max():.3f} m, RMS {np.sqrt(np.mean(off ** 2)):.3f} m, height max "
          f"{np.abs(ned[:, 2]).max():.3f} m, back home within {np.linalg.norm(ned[-1]):.4f} m")
    assert max(near) < 0.5 and off.max() < 1.0 and np.linalg.norm(ned[-1]) < 0.1


def _distance_to_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each point of ``p`` (N, 2)'s distance to the segment from ``a`` to ``b``."""
    u = np.clip((p - a) @ (b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return np.linalg.norm(p - (a + u[:, None] * (b - a)), axis=1)


def _code_words(source: str) -> list[str]:
    """The identifiers and string constants of a module's code, its docstrings left out."""
    tree = ast.parse(source)
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant)}
    words = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            words.append(node.value)
        elif isinstance(node, (ast.Name, ast.arg, ast.Attribute, ast.FunctionDef, ast.ClassDef, ast.alias)):
            words.append(getattr(node, "id", None) or getattr(node, "arg", None) or getattr(node, "attr", None)
                         or getattr(node, "name", ""))
    return words


def test_octo25_holds_its_point_and_its_circle_in_force_4_with_moderate_turbulence():
    """Force 4 (7 m/s from the west) with JSBSim's MIL-F-8785C turbulence (wind at 20 ft 7 m/s,
    severity 3: gusts of 0.7-1.4 m/s std at 20 m, carried past at the wind's speed): the
    hover, after 10 s of leaning into the wind, within 0.5 m of its point and 0.25 m RMS; then a
    20 m circle at 5 m/s, its radius within 0.5 m RMS (the issue's figures in calm air). Without
    a wind there is no turbulence to carry past a hover: refused (the test of refusals)."""
    env = parse_environment({"wind": {"speed_mps": 7.0, "from_deg": 270},
                             "turbulence": {"type": "milspec", "wind20_mps": 7.0, "severity": 3, "seed": 1}},
                            "environment", None)
    segments = [{"type": "hover", "time_s": 60.0}, {"type": "goto", "north_m": 30.0, "east_m": 0.0},
                {"type": "circle", "radius_m": 20.0, "laps": 2, "direction": "right", "yaw": "center"}]
    truth = fly(FlightConfig(track=parse_track({"start": START, "segments": segments}), environment=env,
                             aircraft="octo25"))
    ned = local_ned(truth)
    gust_std = (truth.wind_n_mps - truth.wind_steady_n_mps)[truth.t_s > 10.0].std(axis=0)
    hover = (truth.segment == 0) & (truth.t_s > 10.0)
    err = np.linalg.norm(ned[hover], axis=1)
    circle = (truth.segment == 2) & (truth.t_s > truth.t_s[truth.segment == 2][0] + 5.0)
    r_err = np.hypot(ned[circle, 0] - 30.0, ned[circle, 1] - 20.0) - 20.0
    print(f"octo25 in force 4 and turbulence (gust std {np.round(gust_std, 2)} m/s): hover max {err.max():.3f} m, "
          f"RMS {np.sqrt(np.mean(err ** 2)):.3f} m; circle radius RMS {np.sqrt(np.mean(r_err ** 2)):.3f} m, "
          f"max {np.abs(r_err).max():.3f} m")
    assert np.all(gust_std > 0.3)
    assert err.max() < 0.5 and np.sqrt(np.mean(err ** 2)) < 0.25 and np.sqrt(np.mean(r_err ** 2)) < 0.5


#: standing on a surface 10 m up, heading 30 deg
GROUND_START = {"type": "ground", "lat_deg": 30.0, "lon_deg": 120.0, "alt_m": 10.0, "heading_deg": 30.0}
#: off the ground to 20 m, over to a point, down, up again to 5 m and down slower
TAKEOFF_LAND = [{"type": "takeoff", "agl_m": 20.0}, {"type": "hover", "time_s": 5},
                {"type": "goto", "north_m": 20, "east_m": 10}, {"type": "land"},
                {"type": "takeoff", "agl_m": 5}, {"type": "land", "rate_mps": 0.5}]


@pytest.mark.parametrize("aircraft, rate_hz, rest_m", [("octo25", 100.0, 0.45), ("f450", 200.0, 0.1524)])
def test_a_multirotor_takes_off_from_the_ground_and_lands_where_it_was_sent(aircraft, rate_hz, rest_m):
    """Standing on its skids (octo25's 0.45 m, the F450's 0.15 m below the centre of gravity;
    the F450's contacts, 3000 N/m and 100 N s/m under 1.4 kg, need JSBSim at 200 Hz to stand):
    up to 20 m (within 0.5 m at once, 0.05 m after a 5 s hover), over to (20, 10) and down at
    0.7 m/s, its motors stopped at the touch; up again to 5 m and down at 0.5 m/s. Each landing
    sinks at its rate and touches at it (within 0.1 m/s), within 0.05 m of its point, level
    within 2 deg (the F450 stands 1.1 deg nose-down on its three contacts), the rotors stopped,
    standing on its contacts."""
    env = parse_environment({"surface_m": 10.0}, "environment", None)
    truth = fly(FlightConfig(track=parse_track({"start": GROUND_START, "segments": TAKEOFF_LAND}), environment=env,
                             aircraft=aircraft, rate_hz=rate_hz))
    ned = local_ned(truth, GROUND_START)
    seg = truth.segment
    assert truth.h_agl_m[0] == pytest.approx(rest_m, abs=0.01)
    assert abs(truth.h_agl_m[seg == 0][-1] - 20.0) < 0.5 and abs(truth.h_agl_m[seg == 1][-1] - 20.0) < 0.05
    for land, rate in ((3, 0.7), (5, 0.5)):
        m = seg == land
        sink, agl = truth.vel_n_mps[m, 2], truth.h_agl_m[m]
        touch = sink[np.flatnonzero(agl > rest_m + 0.05)[-1]]        # the last sample before the contacts
        print(f"{aircraft} landing {land}: sinks at {np.median(sink[agl > 1.0]):.3f} m/s (rate {rate}; up to "
              f"{sink.max():.2f} as it starts), touches at {touch:.2f} m/s, stands at {agl[-1]:.3f} m, "
              f"{np.linalg.norm(ned[m][-1, :2] - [20.0, 10.0]):.4f} m from its point")
        assert abs(np.median(sink[agl > 1.0]) - rate) < 0.02 and abs(touch - rate) < 0.1
        assert agl[-1] == pytest.approx(rest_m, abs=0.02)
        assert np.linalg.norm(ned[m][-1, :2] - [20.0, 10.0]) < 0.05
        assert np.degrees(np.abs(truth.euler_rad[m][-1, :2])).max() < 2.0 and truth.rotor_rpm[m][-1].max() < 50.0
    assert abs(truth.h_agl_m[seg == 4].max() - 5.0) < 0.5


def test_a_takeoff_or_a_landing_out_of_order_is_refused(tmp_path, capsys):
    """A takeoff in the air, a segment after a landing but a takeoff, a flight off a surface it
    does not stand on, a takeoff on a fixed wing: exit 2 naming the key."""
    for start, segments, extra, words in (
            (START, [{"type": "takeoff", "agl_m": 10}], {}, ["track.segments[0].type", "'takeoff' segment in the air"]),
            (GROUND_START, [{"type": "takeoff", "agl_m": 10}, {"type": "land"}, {"type": "hover", "time_s": 5}],
             {"environment": {"surface_m": 10.0}}, ["track.segments[2].type", "'hover' segment on the ground"]),
            (GROUND_START, [{"type": "takeoff", "agl_m": 10}], {},
             ["track.start.alt_m", "standing at 10 m on a surface at 0 m"])):
        assert main(["validate", str(write(tmp_path, segments, start=start, **extra))]) == 2
        err = capsys.readouterr().err
        assert all(w in err for w in words) and "Traceback" not in err, (words, err)
    assert main(["validate", str(write(tmp_path, [{"type": "takeoff", "agl_m": 10}], start=GROUND_START,
                                       aircraft="survey10"))]) == 2
    assert "cannot be flown by a fixed_wing" in capsys.readouterr().err


def test_a_hovering_start_lands_and_a_takeoff_below_the_skids_fails():
    """A hover start flies out and lands (its height over the surface down to where it stands);
    a takeoff to less than its standing height plus the impact margin fails naming the
    segment (exit 3)."""
    truth = octo_fly([{"type": "goto", "north_m": 10.0, "east_m": 0.0}, {"type": "land", "rate_mps": 1.0}])
    assert truth.h_agl_m[-1] == pytest.approx(0.45, abs=0.02) and truth.rotor_rpm[-1].max() < 50.0
    assert np.linalg.norm(local_ned(truth)[-1, :2] - [10.0, 0.0]) < 0.1
    env = parse_environment({"surface_m": 10.0}, "environment", None)
    with pytest.raises(FlightError, match=r"segment 0.*a takeoff to 0.5 m, where the aircraft stands at 0.45 m"):
        fly(FlightConfig(track=parse_track({"start": GROUND_START, "segments": [{"type": "takeoff", "agl_m": 0.5}]}),
                         environment=env, aircraft="octo25"))
