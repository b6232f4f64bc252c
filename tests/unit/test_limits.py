"""Issue 31's validation items: numbers at their limits, windows inside the flight, a misspelt
key named, sensor rates, bounded reads, a flight-only scenario, the memory a run needs."""

from __future__ import annotations

import copy
import math
import os
from pathlib import Path

import pytest
import yaml

from navsim import api, cli
from navsim.experiment.scenario import load_scenario, parse_scenario
from navsim.foundations.config import MAX_BYTES, load_yaml
from navsim.foundations.errors import NavsimError, ScenarioError

ROOT = Path(__file__).resolve().parents[2]
P0 = load_yaml(ROOT / "scenarios" / "p0_bd_sins_ads.yaml")
FILE = str(ROOT / "scenarios" / "p0_bd_sins_ads.yaml")
#: a short flight (60 s) with a GNSS, for windows and memory
SHORT = {"name": "short", "track": {"start": {"lat_deg": 37.0, "lon_deg": 117.0, "alt_m": 300, "speed_mps": 14.0},
                                    "segments": [{"type": "straight", "time_s": 60}]},
         "sensors": {"imu": {"model": "p0_imu"}, "gps": {"model": "p3_gps"}},
         "estimators": [{"label": "kf", "type": "eskf", "noise": {"imu": "p0_imu"},
                         "measurements": [{"type": "gnss_position", "sensor": "gps", "sigma_m": 3}]}]}


@pytest.fixture
def no_flight(monkeypatch):
    """Every way to fly fails the test: the checks come before anything is flown."""
    def flown(*args, **kwargs):
        pytest.fail("a flight was flown")
    for name in ("navsim.experiment.runner.cached_flight", "navsim.api.runs.cached_flight", "navsim.api.budgets.cached_flight",
                 "navsim.api.results.cached_flight", "navsim.cli.flights.cached_flight",
                 "navsim.cli.flights.fly_or_save", "navsim.cli.fly.fly", "navsim.flight.simulator.fly",
                 "navsim.experiment.runner.fly"):
        monkeypatch.setattr(name, flown, raising=False)


def _set(data, path, value):
    out = copy.deepcopy(data)
    node = out
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return out


def _refused(data, match=None, file=FILE):
    with pytest.raises(ScenarioError, match=match) as exc:
        parse_scenario(data, file)
    assert exc.value.exit_code == 2
    return str(exc.value)


KF = ("estimators", 1)


@pytest.mark.parametrize("path, value", [
    (KF + ("period_s",), 1e308),                        # OverflowError in the period check
    (KF + ("period_s",), 10**400),
    (KF + ("baro", "tau_s"), 1e308),
    (KF + ("measurements", 0, "sigma_m"), [8, 8, 1e-308]),
    (KF + ("measurements", 0, "sigma_m"), [8, 8, 10**400]),
    (KF + ("measurements", 1, "sigma_mps"), 1e300),
    (KF + ("measurements", 2, "sigma_m"), 1e-300),
    (("montecarlo", "runs"), 10**12),
    (("montecarlo", "runs"), 2**64),
    (("initial_errors", "pos_m"), 1e9),                 # accepted unflagged
    (("initial_errors", "att_arcsec"), [20, 20, 10**60]),
    (("initial_errors", "vel_mps"), 1e6),
    (("reference", "claims", 3, "at_most"), [8, 8, 10**60]),
    (("sensors", "bd", "override"), {"rate_hz": 10**400}),
    (("sensors", "bd", "override"), {"position_sigma": "1e308 m"}),
    (("sensors", "bd", "override"), {"markov_tau": "0 s"}),
    (("sensors", "bd", "override"), {"position_sigma": []}),
    (("environment",), {"turbulence": {"seed": 2**40}}),
    (("track",), {"start": {"lat_deg": 37.0, "lon_deg": 117.0, "alt_m": 300, "speed_mps": 14.0},
                  "segments": [{"type": "straight", "time_s": 1e308}]}),
])
def test_a_number_beyond_its_range_is_refused(path, value):
    message = _refused(_set(P0, path, value))
    assert "Traceback" not in message and len(message) < 600


@pytest.mark.parametrize("path, value", [
    (KF + ("period_s",), 1e-308), (KF + ("period_s",), -0.0), (KF + ("period_s",), float("nan")),
    (KF + ("period_s",), float("inf")), (KF + ("period_s",), True), (("metrics", "windows", 0, "end_s"), 1e308)])
def test_a_number_refused_already_stays_refused(path, value):
    """Regression guards (today's code refuses these too, by the period and window checks)."""
    _refused(_set(P0, path, value))


@pytest.mark.parametrize("path, value", [
    (("environment",), {"wind": {"north_mps": 5 * math.cos(math.pi / 2), "east_mps": 5.0}}),   # 3.06e-16
    (("sensors", "imu", "override"), {"gyro": {"bias_sigma": "5e-13 rad/s"}}),
])
def test_tiny_legitimate_numbers_are_taken(path, value):
    """The floor of non-zero magnitudes refuses only what squares to zero (1e-308), not a
    rounding residue of a computed wind (3e-16 m/s) nor a bias written in SI (5e-13 rad/s, a
    strategic-grade gyro's 1e-7 deg/h): the review found both refused at a 1e-12 floor."""
    data = _set(P0, path, value) if path[-1] != "override" else _set(P0, path, {**P0["sensors"]["imu"].get("override", {}), **value})
    parse_scenario(data, FILE)


def test_huge_integers_in_yaml_text_are_refused(tmp_path):
    path = tmp_path / "big.yaml"
    text = (ROOT / "scenarios" / "p0_bd_sins_ads.yaml").read_text().replace("period_s: 1.0", "period_s: 1" + "0" * 400)
    path.write_text(text)
    with pytest.raises(ScenarioError, match="period_s"):
        load_scenario(path)
    path.write_text(text.replace("period_s: 1" + "0" * 400, "period_s: 1" + "0" * 5000))   # past int's digit limit
    with pytest.raises(ScenarioError):
        load_scenario(path)


# --- 2. windows inside the flight -------------------------------------------------------------


@pytest.mark.parametrize("path, value, key", [
    (("sensors", "gps", "faults"), [{"type": "outage", "start_s": 60.0}], "sensors.gps.faults[0].start_s"),
    (("sensors", "gps", "faults"), [{"type": "outage", "start_s": 70, "end_s": 90}], "sensors.gps.faults[0].start_s"),   # guard
    (("metrics",), {"windows": [{"name": "late", "start_s": 61, "end_s": 62}]}, "metrics.windows[0].start_s"),
    (("metrics",), {"windows": [{"name": "late", "start_s": 10, "end_s": 62}]}, "metrics.windows[0].end_s"),   # guard
])
def test_a_window_outside_the_flight_is_refused(path, value, key):
    message = _refused(_set(SHORT, path, value), file="short.yaml")
    assert key in message and "60 s" in message and "flight" in message


def test_a_closed_loop_window_after_the_time_limit_is_refused():
    data = load_yaml(ROOT / "scenarios" / "p1_return_to_land.yaml")
    """A closed-loop flight may outlast its track (652 s) up to its time limit (1400 s): a fault
    starting at 1000 s is taken (a return leg flown on), one at 1500 s is refused, naming 1400."""
    late = _set(data, ("sensors", "gps", "faults", 0), {"type": "outage", "start_s": 1500.0, "end_s": 1600.0})
    message = _refused(late, file="rtl.yaml")
    assert "sensors.gps.faults[0].start_s" in message and "1400" in message
    parse_scenario(_set(data, ("sensors", "gps", "faults", 0), {"type": "outage", "start_s": 1000.0,
                                                                "end_s": 1400.0}), "rtl.yaml")
    parse_scenario(data, "rtl.yaml")


# --- 3. a misspelt key ------------------------------------------------------------------------


def test_a_misspelt_required_key_is_named_with_its_close_match():
    m = P0["estimators"][1]["measurements"][1]
    bad = _set(P0, KF + ("measurements", 1), {"type": "velocity", "sensor": "ads", "sigma_mp": m["sigma_mps"]})
    message = _refused(bad)
    assert "'sigma_mp' is not a known key; did you mean 'sigma_mps'?" in message
    assert "estimators[1].measurements[1].sigma_mp" in message


# --- 4. a sensor faster than the truth --------------------------------------------------------


@pytest.mark.parametrize("rate", [200, 30])
def test_a_sensor_rate_the_truth_cannot_give_is_refused(rate):
    message = _refused(_set(P0, ("sensors", "bd", "override"), {"rate_hz": rate}))
    assert "sensors.bd.rate_hz" in message and str(rate) in message and "100 Hz" in message


# --- 5. bounded reads -------------------------------------------------------------------------


def test_an_endless_file_is_refused_after_a_bounded_read():
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    with pytest.raises(ScenarioError, match="larger than"):
        load_yaml("/dev/zero")


def test_a_large_file_is_refused(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text("a: 1\n" + "#" * MAX_BYTES)
    with pytest.raises(ScenarioError, match="larger than"):
        load_yaml(path)


def test_a_file_parsed_again_gives_its_new_text_and_a_fresh_copy(tmp_path):
    """Parses are kept by the text's digest: a file rewritten at once with other bytes of the
    same size (within one timestamp tick) is read as it is now, and changing what one call
    returned does not change what the next returns; a broken text is refused every time."""
    path = tmp_path / "a.yaml"
    path.write_text("a: {b: 1}\n")
    first = load_yaml(path)
    first["a"]["b"] = 99
    assert load_yaml(path) == {"a": {"b": 1}}
    path.write_text("a: {b: 2}\n")
    assert load_yaml(path) == {"a": {"b": 2}}
    path.write_text("a: {b: [}\n")
    for _ in range(2):
        with pytest.raises(ScenarioError, match="not valid YAML"):
            load_yaml(path)


# --- 6. a flight-only scenario ----------------------------------------------------------------


def test_a_scenario_without_estimators_is_refused_before_flying(tmp_path, no_flight, capsys):
    scenario = ROOT / "scenarios" / "p0_flight.yaml"
    with pytest.raises(ScenarioError, match="has no estimators") as exc:
        api.run(scenario)
    assert str(scenario) in str(exc.value)
    code = cli.main(["run", str(scenario), "--runs", "2", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "has no estimators" in err and "navsim fly" in err and "Traceback" not in err


def test_scenario_error_takes_a_path():
    assert "x/y.yaml: a: bad" in str(ScenarioError("bad", file=Path("x/y.yaml"), key="a"))


# --- 7. the memory a run needs ----------------------------------------------------------------


def test_a_flight_too_large_for_memory_is_refused_before_flying(tmp_path, monkeypatch, no_flight, capsys):
    monkeypatch.setattr("navsim.experiment.resources.available_memory", lambda: 2**30, raising=False)   # 1 GiB
    long = _set(SHORT, ("track", "segments", 0, "time_s"), 500_000.0)    # 5e7 samples at 100 Hz
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(long))
    for command in (["run", str(path)], ["fly", str(path)], ["sensors", str(path)]):
        code = cli.main(command + ["--out", str(tmp_path / "out")])
        err = capsys.readouterr().err
        assert code == 2 and "GiB" in err and "memory" in err and "Traceback" not in err, (command, err)
    with pytest.raises(NavsimError, match="memory"):
        api.run(path)


def test_too_many_runs_are_refused(tmp_path, no_flight, capsys):
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(SHORT))
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", str(path), "--runs", "1000000000000"])
    assert exc.value.code == 2
    with pytest.raises(NavsimError, match="runs"):
        api.run(path, runs=10**12)


def test_chunks_larger_than_the_disk_are_refused(tmp_path, monkeypatch, no_flight):
    monkeypatch.setattr("navsim.experiment.resources._free_disk", lambda out: 1000, raising=False)
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(SHORT))
    with pytest.raises(NavsimError, match="on disk"):
        api.run(path, runs=10, out=tmp_path / "out")


def test_runs_held_in_memory_or_emulated_at_once_are_planned(tmp_path, monkeypatch, no_flight, capsys):
    """100,000 runs of the 60 s flight without an output folder hold every history in memory
    (about 0.5 GB per 1000 runs here), and ``navsim sensors`` emulates all its runs at once:
    both are refused against 1 GiB before flying; the same runs streamed to a folder are not
    refused for memory (one chunk at a time)."""
    monkeypatch.setattr("navsim.experiment.resources.available_memory", lambda: 2**30, raising=False)
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(SHORT))
    with pytest.raises(NavsimError, match="held in memory"):
        api.run(path, runs=100_000)
    from navsim.experiment import resources
    resources.check_run(load_scenario(path), 100_000, None, tmp_path / "out")       # streamed: fits
    code = cli.main(["sensors", str(path), "--runs", "1000000", "--out", str(tmp_path / "s")])
    err = capsys.readouterr().err
    assert code == 2 and "sensors need about" in err and "Traceback" not in err, err


@pytest.mark.parametrize("body, words", [
    ("grid:\n" + "".join(f"  estimators[0].measurements[0].sigma_m{'' if i == 0 else f'_{i}'}: [{', '.join(['1'] * 10)}]\n"
                         for i in range(6)), ["has 1e+06 points", "at most 10000"]),
    ("points: [" + ", ".join(["{montecarlo.seed: 1}"] * 10_001) + "]\n", ["has 10001 points"]),
    ("runs: 10000000000\npoints: [{montecarlo.seed: 1}]\n", ["runs", "<= 1e+06"]),
], ids=["grid-of-a-million", "10001-points", "1e10-runs"])
def test_a_sweep_too_large_is_refused_before_its_points_are_built(tmp_path, body, words):
    """A grid whose product has a million points is refused from the lists' lengths alone
    (today: every point is built and parsed, hours), as are 10,001 listed points and 1e10 runs
    per point."""
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(SHORT))
    (tmp_path / "sweep.yaml").write_text("scenario: s.yaml\n" + body)
    from navsim.experiment.sweep import parse_sweep
    with pytest.raises(ScenarioError) as exc:
        parse_sweep(tmp_path / "sweep.yaml")
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_the_memory_plan_counts_each_workers_flight_and_chunk():
    """Each busy worker holds a flight and a chunk of its own (the review found one of each
    counted whatever --workers); a closed loop plans its own chunk size (25) and its time limit."""
    from navsim.experiment import resources
    sc = parse_scenario(SHORT, FILE)
    one, two = resources.needs(sc, 1000, 250, 1), resources.needs(sc, 1000, 250, 2)
    assert two.chunk == 2 * one.chunk and two.flight == 3 * one.flight and two.disk == one.disk
    assert resources.needs(sc, 100, 250, 4).chunk == one.chunk * 100 // 250     # one chunk: one busy worker
    rtl = load_scenario(ROOT / "scenarios" / "p1_return_to_land.yaml")
    assert resources.needs(rtl, 100).chunk == 25 * resources.needs(rtl, 1).chunk
    assert resources.needs(rtl, 1).flight == resources.flight_bytes(rtl, 1400.0)
