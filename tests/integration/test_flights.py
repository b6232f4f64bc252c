"""Fly the three shipped tracks in calm air and check them against their specification."""

import math

import numpy as np
import pytest

from navsim.experiment.runner import cached_flight
from navsim.flight import FlightConfig, Truth, fly, load_track, parse_track
from navsim.flight.environment import Environment, parse_environment, steady_wind_n_mps
from navsim.foundations import earth
from navsim.foundations.errors import FlightError
from navsim.foundations.transform import dcm_from_quat, quat_from_rotvec, quat_multiply

SETTLE_S = 20.0   # level segments are judged after this settling time


@pytest.fixture(scope="module")
def flights(shipped_flight):
    """The three tracks flown in calm air through the suite's flight cache: the same flights
    (the same keys) as P0's, P3's and P2's shipped scenarios, flown once for the session."""
    out = {}
    for name in ("p0", "p3", "p2_sea"):
        config = FlightConfig(track=load_track(name))
        out[name] = (config.track, cached_flight(config)[0])
    return out


def expected_commands(track):
    """(segment index, altitude, airspeed) each straight segment should hold, from the track."""
    alt, speed, out = track.start.alt_m, track.start.speed_mps, []
    for i, seg in enumerate(track.segments):
        speed = seg.speed_mps or speed
        if seg.type in ("climb", "descend"):
            alt = seg["to_m"]
        elif seg.type == "speed":
            speed = seg["to_mps"]
        elif seg.type == "straight":
            out.append((i, alt, speed))
    return out


@pytest.mark.parametrize("name, duration", [("p0", 500.0), ("p3", 3000.0), ("p2_sea", 1500.0)])
def test_tracks_fly_to_the_end_without_stall_or_impact(flights, name, duration):
    track, truth = flights[name]
    assert truth.duration_s == pytest.approx(duration, abs=0.02)
    flown = [i for i, *_ in truth.segment_spans() if i >= 0]
    assert flown == list(range(len(track.segments)))          # every segment, in order
    assert np.degrees(truth.alpha_rad[truth.segment >= 0]).max() < 14.0   # below CLmax
    assert truth.h_agl_m[truth.t_s > 5].min() > 10.0
    assert np.all(np.isfinite(truth.f_b_mps2))


@pytest.mark.parametrize("name", ["p0", "p3", "p2_sea"])
def test_level_segments_hold_altitude_and_airspeed(flights, name):
    track, truth = flights[name]
    for i, alt, speed in expected_commands(track):
        m = truth.segment == i
        t0 = truth.t_s[m][0]
        m &= truth.t_s >= t0 + SETTLE_S
        assert np.abs(truth.h_m[m] - alt).max() <= 5.0, (name, i)
        assert np.abs(truth.tas_mps[m] - speed).max() <= 1.0, (name, i)


def test_climbs_and_descents_reach_their_altitude_at_their_rate(flights):
    track, truth = flights["p0"]
    for i, seg in enumerate(track.segments):
        if seg.type in ("climb", "descend"):
            m = truth.segment == i
            rate = -truth.vel_n_mps[m, 2]
            assert abs(truth.h_m[m][-1] - seg["to_m"]) <= 1.05
            # the steady part of the climb follows the commanded rate within 0.5 m/s
            steady = np.abs(truth.h_m[m] - seg["to_m"]) > 15.0
            sign = 1.0 if seg.type == "climb" else -1.0
            assert np.median(sign * rate[steady]) == pytest.approx(seg["rate_mps"], abs=0.5)


def fit_circle(x, y):
    A = np.column_stack([x, y, np.ones_like(x)])
    cx, cy, c = np.linalg.lstsq(A, x * x + y * y, rcond=None)[0]
    return 0.5 * cx, 0.5 * cy, math.sqrt(c + 0.25 * (cx * cx + cy * cy))


def test_circle_radius_within_ten_percent(flights):
    track, truth = flights["p0"]
    i = next(i for i, s in enumerate(track.segments) if s.type == "circle")
    m = truth.segment == i
    north, east = earth.local_ne(truth.lat_rad, truth.lon_rad, truth.lat_rad[0], truth.lon_rad[0])
    # after the first quarter lap, once the orbit is captured
    k = np.flatnonzero(m)
    k = k[len(k) // 4:]
    cn, ce, r_fit = fit_circle(north[k], east[k])
    radius = track.segments[i]["radius_m"]
    assert r_fit == pytest.approx(radius, rel=0.10)
    d = np.hypot(north[k] - cn, east[k] - ce)
    assert np.abs(d - radius).max() <= 0.10 * radius


def test_turn_changes_course_by_its_angle(flights):
    track, truth = flights["p3"]
    for i, seg in enumerate(track.segments):
        if seg.type == "turn":
            before = truth.segment == i - 1
            after = truth.segment == i + 1
            c0 = np.arctan2(*truth.vel_n_mps[before][-1, 1::-1])
            c1 = np.arctan2(*truth.vel_n_mps[after][-1, 1::-1])
            turned = (c1 - c0 + np.pi) % (2 * np.pi) - np.pi
            assert np.degrees(turned) == pytest.approx(seg["by_deg"], abs=2.0)


def test_p2_launch_and_low_level_leg(flights):
    track, truth = flights["p2_sea"]
    launch = truth.segment == -1
    assert np.degrees(truth.euler_rad[0, 1]) == pytest.approx(14.0, abs=1e-6)
    assert launch.sum() > 0 and truth.h_agl_m[0] == pytest.approx(2.0, abs=0.05)
    low = len(track.segments) - 1
    m = truth.segment == low
    t = truth.t_s[m]
    assert t[0] < 960 - SETTLE_S and t[-1] >= 1060
    steady = m & (truth.t_s >= t[0] + SETTLE_S)
    assert np.abs(truth.h_agl_m[steady] - 50.0).max() <= 3.0
    assert np.abs(truth.h_m[steady] - 50.0).max() <= 3.0


def strapdown_eci(truth: Truth, n: int) -> np.ndarray:
    """Integrate the recorded f_b and omega_ib_b in the inertial frame (trapezoid, J2
    gravitation); return the position error against the recorded trajectory, m."""
    dt = truth.dt_s
    w = earth.OMEGA_IE_RPS
    r = earth.lla_to_ecef(truth.lat_rad[0], truth.lon_rad[0], truth.h_m[0])
    C_en = earth.C_en(truth.lat_rad[0], truth.lon_rad[0])
    v = C_en @ truth.vel_n_mps[0] + np.cross([0.0, 0.0, w], r)
    from scipy.spatial.transform import Rotation
    q = np.roll(Rotation.from_matrix(C_en @ dcm_from_quat(truth.quat_nb[0])).as_quat(), 1)
    f, om = truth.f_b_mps2, truth.omega_ib_b_rps
    a = dcm_from_quat(q) @ f[0] + earth.gravitation(r)
    r_hist = np.empty((n, 3))
    for k in range(n):
        q = quat_multiply(q, quat_from_rotvec(0.5 * (om[k] + om[k + 1]) * dt))
        q /= np.linalg.norm(q)
        a_next = dcm_from_quat(q) @ f[k + 1] + earth.gravitation(r + v * dt + 0.5 * a * dt * dt)
        v_next = v + 0.5 * (a + a_next) * dt
        r = r + 0.5 * (v + v_next) * dt
        v, a = v_next, a_next
        r_hist[k] = r
    t = (np.arange(n) + 1) * dt
    c, s = np.cos(w * t), np.sin(w * t)
    r_e = np.column_stack([c * r_hist[:, 0] + s * r_hist[:, 1], -s * r_hist[:, 0] + c * r_hist[:, 1],
                           r_hist[:, 2]])
    r_true = earth.lla_to_ecef(truth.lat_rad[1:n + 1], truth.lon_rad[1:n + 1], truth.h_m[1:n + 1])
    return np.linalg.norm(r_e - r_true, axis=1)


def test_truth_is_self_consistent_over_100_s(flights):
    _, truth = flights["p0"]
    err = strapdown_eci(truth, int(round(100.0 / truth.dt_s)))
    assert err[-1] < 0.5
    # and it is not trivially zero: a 1e-3 m/s^2 error on f_b would show as ~5 m
    biased = truth.slice(0, truth.n)
    biased.f_b_mps2 = truth.f_b_mps2 + np.array([1e-3, 0.0, 0.0])
    assert strapdown_eci(biased, 10000)[-1] > 2.0


def test_truth_save_load_round_trip(flights, tmp_path):
    _, truth = flights["p0"]
    truth.save(tmp_path / "t.npz")
    assert Truth.load(tmp_path / "t.npz") == truth


SHORT = {"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 200, "speed_mps": 14},
         "segments": [{"type": "straight", "time_s": 10}]}


def test_flight_is_deterministic():
    a = fly(parse_track(SHORT))
    b = fly(parse_track(SHORT))
    assert a == b


def test_wind_and_turbulence():
    wind = Environment(wind_n_mps=(0.0, 4.5, 0.0))
    track = parse_track({**SHORT, "segments": [{"type": "straight", "time_s": 30}]})
    truth = fly(FlightConfig(track=track, environment=wind))
    # velocity over the ground = air velocity + wind, from the first sample on
    vel_air = truth.vel_n_mps - truth.wind_n_mps
    np.testing.assert_allclose(np.linalg.norm(vel_air, axis=1), truth.tas_mps, atol=1e-6)
    assert np.allclose(truth.wind_n_mps, [0.0, 4.5, 0.0], atol=1e-9)
    # flying north across a wind blowing east: the aircraft crabs into the wind
    # (heading left of north by asin(4.5 / 14)) and its ground track stays on the line
    crab = np.degrees(truth.euler_rad[:, 2])
    assert np.median(crab) == pytest.approx(-np.degrees(np.arcsin(4.5 / 14.0)), abs=1.0)
    assert np.abs(truth.vel_n_mps[:, 1]).max() < 0.3
    turb = Environment(turbulence="milspec", turbulence_wind20_mps=5.0, turbulence_severity=3,
                       turbulence_seed=3)
    t1 = fly(FlightConfig(track=track, environment=turb))
    t2 = fly(FlightConfig(track=track, environment=Environment(
        turbulence="milspec", turbulence_wind20_mps=5.0, turbulence_severity=3, turbulence_seed=4)))
    assert np.std(t1.wind_n_mps[:, 0]) > 0.1
    assert not np.allclose(t1.wind_n_mps, t2.wind_n_mps)           # the seed picks the gusts


def test_a_veering_strengthening_wind_and_a_gust_front_are_flown_and_recorded():
    """The steady wind goes through its changes (veering 270 -> 330 deg and strengthening 4.4 ->
    9.35 m/s over 20 s, then a gust front: 3 m/s more in 3 s); the truth records it, the
    turbulence about it, and the aircraft holds its course through it."""
    env = parse_environment({"wind": {"force": 3, "from_deg": 270},
                             "wind_changes": [{"at_s": 10, "force": 3, "from_deg": 270},
                                              {"at_s": 30, "force": 5, "from_deg": 330},
                                              {"at_s": 40, "force": 5, "from_deg": 330},
                                              {"at_s": 43, "speed_mps": 12.35, "from_deg": 330}],
                             "turbulence": {"type": "milspec", "wind20_mps": 5.0, "severity": 3, "seed": 3}})
    track = parse_track({**SHORT, "segments": [{"type": "straight", "time_s": 60}]})
    truth = fly(FlightConfig(track=track, environment=env))
    want = np.array([steady_wind_n_mps(env, t) for t in truth.t_s])
    np.testing.assert_allclose(truth.wind_steady_n_mps, want, atol=1e-9)
    speed = np.hypot(want[:, 0], want[:, 1])
    at = lambda t: int(round(t / truth.dt_s))
    assert speed[at(5)] == pytest.approx(4.4) and speed[at(20)] == pytest.approx(0.5 * (4.4 + 9.35))
    np.testing.assert_allclose(want[at(20)] / speed[at(20)], [-np.cos(np.radians(300)), -np.sin(np.radians(300)), 0],
                               atol=1e-12)                               # veered the shorter way, through 300
    assert speed[at(41.5)] == pytest.approx(9.35 + 1.5) and speed[at(50)] == pytest.approx(12.35)
    gusts = truth.wind_n_mps - truth.wind_steady_n_mps
    assert 0.1 < np.std(gusts[:, 0]) < 3.0 and abs(np.mean(gusts[:, 0])) < 1.0
    course = np.degrees(np.arctan2(truth.vel_n_mps[:, 1], truth.vel_n_mps[:, 0]))
    assert np.abs(course[at(10):]).max() < 15.0          # the track is north: held through the front


@pytest.mark.parametrize("segments, words", [
    ([{"type": "circle", "radius_m": 10, "laps": 1}], "radius 10 m is below"),
    ([{"type": "climb", "to_m": 100}], "cannot climb to 100 m from 200 m"),
    ([{"type": "speed", "to_mps": 6}], "airspeed 6 m/s outside"),
    ([{"type": "straight", "time_s": 5}, {"type": "descend", "to_m": -50, "rate_mps": 4}],
     "ground or sea impact"),
])
def test_unflyable_tracks_fail_naming_segment_and_time(segments, words):
    track = parse_track({**SHORT, "segments": segments})
    with pytest.raises(FlightError) as info:
        fly(track)
    err = info.value
    assert words in str(err)
    assert err.segment == len(segments) - 1 and err.time_s is not None
    assert f"segment {err.segment} (" in str(err) and "t = " in str(err)


@pytest.mark.parametrize("turbulence", ["none", "milspec"])
def test_p0_in_force_3_wind(turbulence):
    env = Environment(wind_n_mps=(0.0, 4.4, 0.0), turbulence=turbulence,
                      turbulence_wind20_mps=4.5, turbulence_severity=2, turbulence_seed=7)
    track = load_track("p0")
    truth = fly(FlightConfig(track=track, environment=env))
    assert truth.duration_s == pytest.approx(500.0, abs=0.02)
    dh, dv = [], []
    for i, alt, speed in expected_commands(track):
        m = truth.segment == i
        m &= truth.t_s >= truth.t_s[m][0] + SETTLE_S
        dh.append(truth.h_m[m] - alt)
        dv.append(truth.tas_mps[m] - speed)
    dh, dv = np.concatenate(dh), np.concatenate(dv)
    if turbulence == "none":
        assert np.abs(dh).max() <= 5.0 and np.abs(dv).max() <= 1.0
    else:
        # gusts move the airspeed faster than any throttle loop: judge RMS, bound the peaks
        assert np.std(truth.wind_n_mps[:, 2]) > 0.05                 # the gusts are there
        assert np.sqrt(np.mean(dh ** 2)) < 2.0 and np.abs(dh).max() <= 5.0
        assert np.sqrt(np.mean(dv ** 2)) < 0.5 and np.abs(dv).max() <= 2.0


@pytest.mark.parametrize("alt_m, speed_mps", [(50.0, 12.0), (1000.0, 14.0), (1500.0, 22.0)])
def test_trimmed_air_start_at_any_altitude_and_speed(alt_m, speed_mps):
    track = parse_track({"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": alt_m,
                                   "speed_mps": speed_mps, "heading_deg": 300},
                         "segments": [{"type": "straight", "time_s": 10}]})
    truth = fly(track)
    # trimmed: no transient at release
    assert truth.h_m[0] == pytest.approx(alt_m, abs=1e-6)
    assert np.abs(truth.h_m - alt_m).max() < 0.2
    assert np.abs(truth.tas_mps - speed_mps).max() < 0.1
    assert np.abs(np.degrees(truth.euler_rad[:, 0])).max() < 0.5
    assert np.abs(np.degrees(truth.euler_rad[:, 2]) - (300 - 360)).max() < 0.5
    assert np.abs(truth.f_b_mps2[:, 2] + 9.8).max() < 0.1               # 1 g lift


def test_climbs_above_1000_m():
    track = parse_track({"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 300,
                                   "speed_mps": 14.0},
                         "segments": [{"type": "climb", "to_m": 1100, "rate_mps": 4.0},
                                      {"type": "straight", "time_s": 30}]})
    truth = fly(track)
    m = truth.segment == 1
    assert np.abs(truth.h_m[m] - 1100).max() < 2.0
    assert truth.throttle[truth.segment == 0].max() < 0.9                # with throttle to spare
