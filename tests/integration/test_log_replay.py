"""INS/GNSS logs in (``navsim replay`` of KF-GINS text and CSV): an emulated run written by
``navsim sensors --export`` replays to the run's own errors; hostile logs exit 2 naming the file
and the line, writing nothing."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_run import SHORT

import navsim
from navsim.cli import main
from navsim.foundations.errors import LogError

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
