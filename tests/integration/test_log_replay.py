"""INS/GNSS logs in (``navsim replay`` of KF-GINS text and CSV): an emulated run written by
``navsim sensors --export`` replays to the run's own errors; hostile logs exit 2 naming the file
and the line, writing nothing."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_run import SHORT
from ulog_writer import write_ulog

import navsim
from navsim.cli import main
from navsim.foundations.errors import LogError
from navsim.foundations.transform import quat_from_euler

#: the short P3-like scenario (P3's IMU, GPS and 15-state ES-KF; a 5 s GPS outage), a PDF report
SCENARIO = SHORT + "report: {formats: [pdf]}\n"
#: the round trip's tolerance on the position RMS, relative (the files hold every bit but the
#: degrees' conversion: ~1e-16)
ROUND_TRIP = 1e-6


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """The short scenario's run 0 exported in both formats (``navsim sensors --export``) and
    the same run made by ``navsim.run`` (one run, in memory)."""
    folder = tmp_path_factory.mktemp("logs")
    mp = pytest.MonkeyPatch()
    mp.setenv("NAVSIM_CACHE", str(folder / "cache"))
    scenario = folder / "short.yaml"
    scenario.write_text(SCENARIO)
    try:
        assert main(["sensors", str(scenario), "--runs", "1", "--export", "kfgins", "--export", "csv",
                     "--out", str(folder / "log")]) == 0
        result = navsim.run(scenario, runs=1, workers=1)
    finally:
        mp.undo()
    return folder, result


def _rms(metrics: dict, label: str, what: str) -> np.ndarray:
    return np.array(metrics["estimators"][label]["rms"][what], float)


@pytest.mark.parametrize("args", [["kf-gins.yaml"],
                                  ["imu.csv", "--gnss", "gnss.csv", "--reference", "reference.csv",
                                   "--start", "start.yaml"]], ids=["kfgins", "csv"])
def test_an_exported_run_replays_to_the_runs_own_errors(exported, tmp_path, capsys, args):
    """Every estimator's position, velocity and attitude RMS of the replayed log equal the run's
    within 1e-6 relative (the outage's missing fixes included), and the replay writes a run's
    files: the report, metrics.json, run.json naming the log, the reference to reopen it."""
    folder, result = exported
    log = folder / "log"
    argv = [str(log / args[0])] + [str(log / a) if not a.startswith("--") else a for a in args[1:]]
    out = tmp_path / "out"
    assert main(["replay", *argv, "--scenario", str(folder / "short.yaml"), "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    for label, e in result.metrics.estimators.items():
        for what in ("pos_m", "vel_mps", "att_deg"):
            mine = np.array(getattr(e.rms, what))
            np.testing.assert_allclose(_rms(metrics, label, what), mine, rtol=ROUND_TRIP, err_msg=f"{label} {what}")
    record = json.loads((out / "run.json").read_text())
    assert record["log"]["scored_against"] == "reference" and record["runs"] == 1
    assert {"report.pdf", "reference.npz", "scenario.resolved.yaml"} <= {p.name for p in out.iterdir()}
    again = navsim.open_result(out)                   # reopened with its reference as the flight
    assert again.truth is not None and again.truth.n == len(result.truth.t_s)
    printed = capsys.readouterr().out
    assert "errors against the log's reference" in printed and "KF" in printed


def test_a_solution_is_scored_as_differences_and_the_start_defaults_to_the_reference(exported, tmp_path, capsys):
    """``--solution``: the same numbers, named differences; without a start file the filters
    start on the reference's first state (the free SINS then drifts less than from the run's
    perturbed start)."""
    folder, result = exported
    log = folder / "log"
    out = tmp_path / "out"
    assert main(["replay", str(log / "imu.csv"), "--gnss", str(log / "gnss.csv"), "--solution",
                 str(log / "reference.csv"), "--scenario", str(folder / "short.yaml"), "--out", str(out)]) == 0
    assert "differences from the log's own solution" in capsys.readouterr().out
    record = json.loads((out / "run.json").read_text())
    assert record["log"]["scored_against"] == "solution"
    metrics = json.loads((out / "metrics.json").read_text())
    drift = np.linalg.norm(_rms(metrics, "free SINS", "pos_m"))
    assert drift < np.linalg.norm(result.metrics.estimators["free SINS"].rms.pos_m)


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines(keepends=True)


def _edit(path: Path, fn) -> None:
    lines = _lines(path)
    fn(lines)
    path.write_text("".join(lines))


def _swap(lines, i):
    lines[i], lines[i + 1] = lines[i + 1], lines[i]


def _cut_column(lines, i):
    lines[i] = " ".join(lines[i].split()[:-2]) + "\n"


def _nan(lines, i):
    cells = lines[i].split()
    cells[3] = "nan"
    lines[i] = " ".join(cells) + "\n"


def _degrees_per_second(lines, _):
    for i, line in enumerate(lines):           # the rotation columns as deg/s: a rate, not an increment
        c = line.split()
        lines[i] = " ".join([c[0]] + [repr(float(x) * 5729.6) for x in c[1:4]] + c[4:]) + "\n"


#: (file edited, edit, words the message holds: the file and line, what is wrong)
HOSTILE = {
    "time goes back": ("imu.txt", lambda ls: _swap(ls, 99), ["imu.txt:101", "does not follow"]),
    "a row cut short": ("gnss.txt", lambda ls: _cut_column(ls, 9), ["gnss.txt:10", "columns"]),
    "a NaN row": ("gnss.txt", lambda ls: _nan(ls, 4), ["gnss.txt:5", "finite"]),
    "rates in deg/s": ("imu.txt", lambda ls: _degrees_per_second(ls, 0), ["imu.txt:", "increments in rad"]),
    "an empty GNSS file": ("gnss.txt", lambda ls: ls.clear(), ["gnss.txt", "empty"]),
    "a word in a number": ("truth.nav", lambda ls: ls.__setitem__(7, ls[7].replace(" ", " x", 1)),
                           ["truth.nav:8", "not a number"]),
    "wrong unit in a CSV": ("gnss.csv", lambda ls: ls.__setitem__(0, ls[0].replace("lat[rad]", "lat[m]")),
                            ["gnss.csv:1", "'m'", "lat[rad|"]),
    "a CSV column missing": ("reference.csv", lambda ls: ls.__setitem__(0, ls[0].replace("yaw", "heading")),
                             ["reference.csv:1", "'heading'"]),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_a_hostile_log_exits_2_naming_file_and_line_writing_nothing(exported, tmp_path, capsys, case):
    folder, _ = exported
    name, edit, words = HOSTILE[case]
    log = tmp_path / "log"
    log.mkdir()
    for p in (folder / "log").iterdir():
        if p.suffix in (".txt", ".nav", ".yaml", ".csv"):
            (log / p.name).write_bytes(p.read_bytes())
    _edit(log / name, edit)
    argv = ([str(log / "kf-gins.yaml")] if not name.endswith(".csv") else
            [str(log / "imu.csv"), "--gnss", str(log / "gnss.csv"), "--reference", str(log / "reference.csv")])
    out = tmp_path / "out"
    assert main(["replay", *argv, "--scenario", str(folder / "short.yaml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for word in words:
        assert word in err, (word, err)
    assert not out.exists() or not any(out.iterdir())
    assert sorted(p.name for p in log.iterdir()) == sorted(p.name for p in (folder / "log").iterdir()
                                                             if p.suffix in (".txt", ".nav", ".yaml", ".csv"))


def test_options_of_the_other_kind_of_log_and_a_scenario_without_gnss_are_refused(exported, tmp_path, capsys):
    folder, _ = exported
    log = folder / "log"
    assert main(["replay", str(log / "kf-gins.yaml"), "--imu-rate", "100", "--out", str(tmp_path / "a")]) == 2
    assert "--imu-rate" in capsys.readouterr().err
    no_gnss = tmp_path / "no_gnss.yaml"
    text = SCENARIO.replace("  gps: {model: p3_gps, faults: [{type: outage, start_s: 25, end_s: 30}]}\n", "")
    no_gnss.write_text(text[:text.index("  - label: KF")] + text[text.index("initial_errors:"):text.index("reference:")])
    with pytest.raises(LogError, match="no gnss sensor"):
        navsim.replay_log(navsim.read_log(log / "kf-gins.yaml"), no_gnss)


def _ulog_of(log, path, drop: str | None = None) -> None:
    """The emulated log as a PX4 ULog: sensor_combined (rates in float32, as PX4 logs them),
    sensor_gps (with two fixes of no fix type, to be left out), EKF2's solution (the truth)."""
    us = lambda t: np.round((t + 1.0) * 1e6).astype(np.int64)        # PX4's clock: 1 s at the start
    imu, g, ref = log.imu, log.gnss, log.reference
    dt = np.diff(imu.t_s, prepend=imu.t_s[0] - imu.dt_s)[:, None]
    f32 = lambda a: np.asarray(a, np.float32)
    scalar = lambda t, n: [(t, 0, n)]
    bad = np.r_[np.zeros(len(g.t_s), bool), [True, True]]
    t_gps = np.r_[g.t_s, g.t_s[:2] + 0.5]
    gps = {"timestamp": us(t_gps), "latitude_deg": np.degrees(np.r_[g.lat_rad, g.lat_rad[:2]]),
           "longitude_deg": np.degrees(np.r_[g.lon_rad, g.lon_rad[:2]]), "altitude_msl_m": np.r_[g.h_m, g.h_m[:2]],
           "eph": f32(np.r_[g.sigma_ned_m[:, 0], [9, 9]]), "epv": f32(np.r_[g.sigma_ned_m[:, 2], [9, 9]]),
           "s_variance_m_s": f32(np.r_[g.sigma_vel_mps[:, 0], [9, 9]]), "fix_type": np.where(bad, 0, 3).astype(np.uint8),
           **{f"vel_{a}_m_s": f32(np.r_[g.vel_n_mps[:, j], g.vel_n_mps[:2, j]]) for j, a in enumerate("ned")}}
    order = np.argsort(t_gps, kind="stable")
    gps = {k: v[order] for k, v in gps.items()}
    quat = quat_from_euler(*ref.euler_rad.T)
    topics = {
        "sensor_combined": (scalar("uint64_t", "timestamp") + [("float", 3, "gyro_rad"), ("float", 3, "accelerometer_m_s2")],
                            {"timestamp": us(imu.t_s), "gyro_rad": f32(imu.dtheta_b_rad / dt),
                             "accelerometer_m_s2": f32(imu.dv_b_mps / dt)}),
        "sensor_gps": (scalar("uint64_t", "timestamp") + [("double", 0, k) for k in ("latitude_deg", "longitude_deg",
                                                                                      "altitude_msl_m")]
                       + [("float", 0, k) for k in ("eph", "epv", "vel_n_m_s", "vel_e_m_s", "vel_d_m_s", "s_variance_m_s")]
                       + [("uint8_t", 0, "fix_type")], gps),
        "vehicle_global_position": (scalar("uint64_t", "timestamp") + [("double", 0, "lat"), ("double", 0, "lon"),
                                                                      ("float", 0, "alt")],
                                    {"timestamp": us(ref.t_s), "lat": np.degrees(ref.lat_rad),
                                     "lon": np.degrees(ref.lon_rad), "alt": f32(ref.h_m)}),
        "vehicle_local_position": (scalar("uint64_t", "timestamp") + [("float", 0, k) for k in ("vx", "vy", "vz")],
                                   {"timestamp": us(ref.t_s), **{k: f32(ref.vel_n_mps[:, j])
                                                                 for j, k in enumerate(("vx", "vy", "vz"))}}),
        "vehicle_attitude": (scalar("uint64_t", "timestamp") + [("float", 4, "q")],
                             {"timestamp": us(ref.t_s), "q": f32(quat)}),
    }
    write_ulog(path, {k: v for k, v in topics.items() if k != drop})


def test_a_px4_log_with_gnss_replays_through_a_scenario_scored_against_ekf2(exported, tmp_path, capsys):
    """A ULog written from the exported run (rates, EKF2's altitude and velocity in float32)
    replays with ``--scenario``: position and velocity scored against EKF2's solution (here the
    truth), starting on its first state; every estimator's RMS equals that of the same log
    replayed from CSV with the truth as its solution within 1e-3 relative or float32's resolution
    (EKF2's quaternion: 2e-5 deg), the fixes without a 3-D fix left out."""
    folder, _ = exported
    log = navsim.read_log(folder / "log" / "kf-gins.yaml")
    ulg = tmp_path / "flight.ulg"
    _ulog_of(log, ulg)
    out = tmp_path / "out"
    assert main(["replay", str(ulg), "--scenario", str(folder / "short.yaml"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "differences from the log's own solution" in printed and "without a 3-D fix left out" in printed
    metrics = json.loads((out / "metrics.json").read_text())
    csv = folder / "log"
    same = navsim.replay_log(navsim.read_log(csv / "imu.csv", csv / "gnss.csv", csv / "reference.csv", solution=True),
                             folder / "short.yaml")
    for label, e in same.metrics.estimators.items():
        for what, atol in (("pos_m", 1e-3), ("vel_mps", 1e-4), ("att_deg", 2e-5)):   # atol: float32's resolution
            np.testing.assert_allclose(_rms(metrics, label, what), np.array(getattr(e.rms, what)), rtol=1e-3,
                                       atol=atol, err_msg=f"{label} {what}")
    record = json.loads((out / "run.json").read_text())
    assert record["log"]["format"] == "ulog" and record["log"]["scored_against"] == "solution"


def test_a_px4_log_without_gnss_or_ekf2_exits_2_naming_the_topic(exported, tmp_path, capsys):
    folder, _ = exported
    log = navsim.read_log(folder / "log" / "kf-gins.yaml")
    for topic, words in (("sensor_gps", ["has no GNSS", "sensor_gps or vehicle_gps_position"]),
                         ("vehicle_local_position", ["no 'vehicle_local_position'"])):
        ulg = tmp_path / f"no_{topic}.ulg"
        _ulog_of(log, ulg, drop=topic)
        out = tmp_path / f"out_{topic}"
        assert main(["replay", str(ulg), "--scenario", str(folder / "short.yaml"), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert all(w in err for w in words) and str(ulg) in err and "Traceback" not in err, err
        assert not out.exists() or not any(out.iterdir())


def test_rates_in_other_units_replay_as_the_increments_do(exported, tmp_path):
    """The IMU CSV as rates in deg/s and g (each the mean over the interval ending at its time)
    replays to the increments' numbers within 1e-6: the rate path and the unit conversions."""
    folder, _ = exported
    log = folder / "log"
    head, *rows = (log / "imu.csv").read_text().splitlines()
    a = np.array([[float(x) for x in r.split(",")] for r in rows])
    dt = np.diff(a[:, 0], prepend=a[0, 0] - (a[1, 0] - a[0, 0]))[:, None]
    rates = np.c_[a[:, :1], np.degrees(a[:, 1:4] / dt), a[:, 4:7] / dt / 9.80665]
    first = np.r_[[a[0, 0] - dt[0, 0]], np.zeros(6)]              # a sample at the start: its rate unused
    (tmp_path / "imu.csv").write_text(
        "time[s]," + ",".join(f"gyro_{c}[deg/s]" for c in "xyz") + "," + ",".join(f"accel_{c}[g]" for c in "xyz")
        + "\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in np.r_[[first], rates]) + "\n")
    got = [navsim.replay_log(navsim.read_log(imu, log / "gnss.csv", log / "reference.csv", log / "start.yaml"),
                             folder / "short.yaml") for imu in (tmp_path / "imu.csv", log / "imu.csv")]
    for label, e in got[1].metrics.estimators.items():
        np.testing.assert_allclose(got[0].metrics.estimators[label].rms.pos_m, e.rms.pos_m, rtol=1e-6)


def test_fixes_without_velocity_replay_through_the_default_scenario_without_its_velocity_update(exported, tmp_path,
                                                                                              capsys):
    folder, _ = exported
    log = folder / "log"
    lines = (log / "gnss.csv").read_text().splitlines()
    (tmp_path / "gnss.csv").write_text("\n".join(",".join(line.split(",")[:7]) for line in lines) + "\n")
    out = tmp_path / "out"
    assert main(["replay", str(log / "imu.csv"), "--gnss", str(tmp_path / "gnss.csv"), "--reference",
                 str(log / "reference.csv"), "--settle", "5", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "velocity measurement of SINS/GPS 15-state left out" in printed
    assert "SINS/GPS 15-state" in json.loads((out / "metrics.json").read_text())["estimators"]
    assert main(["replay", str(log / "imu.csv"), "--gnss", str(tmp_path / "gnss.csv"), "--reference",
                 str(log / "reference.csv"), "--out", str(tmp_path / "late")]) == 2
    assert "settle_s 100 s" in capsys.readouterr().err
