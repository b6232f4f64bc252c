"""``navsim run``: scenarios end to end, determinism across workers, failures kept apart, and
a corpus of malformed scenarios that must each get a clear error and exit code 2."""

import json
import re

import numpy as np
import pytest

import navsim
from navsim.cli import main

SHORT = """
name: short_run
description: a short P3-like run for the tests
track:
  start: {lat_deg: 37.0, lon_deg: 118.0, alt_m: 300, speed_mps: 14, heading_deg: 30}
  segments:
    - {type: straight, time_s: 20}
    - {type: turn, by_deg: 90, bank_deg: 25}
    - {type: straight, time_s: 20}
sensors:
  imu: {model: p3_imu}
  gps: {model: p3_gps, faults: [{type: outage, start_s: 25, end_s: 30}]}
estimators:
  - {label: free SINS, type: sins}
  - label: KF
    type: eskf
    states: p3_15
    noise: {imu: p3_imu}
    measurements:
      - {type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}
      - {type: velocity, sensor: gps, sigma_mps: 0.05}
initial_errors: {pos_m: [5, 5, 3], vel_mps: [0.2, 0.2, 0.1], att_arcsec: 60}
montecarlo: {runs: 6, seed: 4}
metrics:
  settle_s: 10
  windows: [{name: turn, start_s: 20, end_s: 30}]
reference:
  source: a test
  kind: population
  values:
    KF: {rms.pos_m: [1, 1, 1], windows.turn.height_m.std: 0.5}
"""


@pytest.fixture
def short(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "short.yaml"
    path.write_text(SHORT)
    return path


@pytest.fixture
def short_pdf(short):
    """The short scenario with its report as a PDF only, for the tests that read the numbers (the
    PNGs, every page drawn a second time, cost 2-3.5 s a run)."""
    short.write_text(SHORT + "report: {formats: [pdf]}\n")
    return short


def run(path, out, *extra):
    return main(["run", str(path), "--out", str(out), *extra])


def test_run_writes_report_metrics_and_histories(short, tmp_path, capsys):
    out = tmp_path / "out"
    assert run(short, out) == 0
    for name in ("report.pdf", "metrics.json", "scenario.resolved.yaml", "chunks/index.json", "run.json",
                 "summary.png", "scenario.png", "errors_pos.png", "consistency.png", "biases.png", "flight_3d.png"):
        assert (out / name).stat().st_size > 0, name
    m = json.loads((out / "metrics.json").read_text())
    assert m["runs"] == 6 and m["runs_done"] == 6 and m["seed"] == 4 and m["wall_s"] > 0
    kf, free = m["estimators"]["KF"], m["estimators"]["free SINS"]
    for key in ("rms", "final", "max_abs", "p99"):
        assert len(kf[key]["pos_m"]) == 3 and len(kf[key]["vel_mps"]) == 3 and len(kf[key]["att_deg"]) == 3
    assert set(kf["windows"]["turn"]["height_m"]) == {"max_pos", "max_neg", "std", "rms", "p95_abs"}
    assert 0.0 <= kf["nees"]["fraction_inside"] <= 1.0 and kf["diverged_runs"] == 0
    assert "gnss_position:gps" in kf["nis"]
    assert max(kf["rms"]["pos_m"]) < max(free["rms"]["pos_m"])
    captured = capsys.readouterr()
    text = captured.out
    # off a terminal the progress is plain lines (a log, a batch job): every tenth and the end
    assert "short_run: 6 runs: 6/6 runs (100 %)" in captured.err and "flight custom: 99%, " in captured.err
    assert "Paper against ours: 0 of 0 paper checks pass (2 shown without a verdict)" in text and "6/6 runs" in text
    assert not (out / "runs.npz").exists()                    # the per-run data once: in chunks/
    # what the scenario measures over its window, a line per estimator, the drift with its interval
    m = json.loads((out / "metrics.json").read_text())["estimators"]["KF"]["windows"]["turn"]["horizontal_m"]
    lines = text[text.index("Metrics windows:"):].splitlines()
    assert lines[3].split()[:4] == ["turn", "(20-30", "s)", "free"] and lines[4].split()[0] == "KF"
    assert f"{m['final']:.3g} [" in lines[4], lines[4]
    hist = navsim.open_result(out).histories["KF"].pos_err_m
    assert hist.shape[0::2] == (6, 3) and hist.shape[1] >= 45
    # the first run flew the track, the second reads the flight from the cache (its report a PDF
    # only: the report is not part of the flight's key)
    assert json.loads((out / "run.json").read_text())["flight_cached"] is False
    short.write_text(SHORT + "report: {formats: [pdf]}\n")
    assert run(short, tmp_path / "out2") == 0
    assert json.loads((tmp_path / "out2" / "run.json").read_text())["flight_cached"] is True


def test_workers_do_not_change_the_numbers(short_pdf, tmp_path, monkeypatch):
    import navsim.experiment.runner
    monkeypatch.setattr(navsim.experiment.runner, "CHUNK_RUNS", 2)          # 3 chunks for 6 runs
    assert run(short_pdf, tmp_path / "w1", "--workers", "1") == 0
    assert run(short_pdf, tmp_path / "w2", "--workers", "2") == 0
    a = json.loads((tmp_path / "w1" / "metrics.json").read_text())
    b = json.loads((tmp_path / "w2" / "metrics.json").read_text())
    timing_free = lambda m: {k: {q: v for q, v in e.items() if q != "cost"} for k, e in m["estimators"].items()}
    assert timing_free(a) == timing_free(b)           # the cost is a wall time, the rest must match
    assert all("cost" in e for e in b["estimators"].values())
    assert np.array_equal(navsim.open_result(tmp_path / "w1").histories["KF"].pos_err_m,
                          navsim.open_result(tmp_path / "w2").histories["KF"].pos_err_m)


def test_a_failing_chunk_is_flagged_and_the_others_complete(short_pdf, tmp_path, monkeypatch, capsys):
    import navsim.experiment.runner
    monkeypatch.setattr(navsim.experiment.runner, "CHUNK_RUNS", 2)
    real = navsim.experiment.runner._chunk

    def flaky(args):
        if list(args[3])[0] == 2:
            raise MemoryError("worker killed")
        return real(args)

    monkeypatch.setattr(navsim.experiment.runner, "_chunk", flaky)
    assert run(short_pdf, tmp_path / "out") == 0
    m = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert m["runs_done"] == 4 and set(m["failed_runs"]) == {"2", "3"}
    assert "worker killed" in m["failed_runs"]["2"]
    assert "2 run(s) failed" in capsys.readouterr().out


def interrupt_at(monkeypatch, first_run: int) -> None:
    """Ctrl-C when the chunk starting at ``first_run`` begins (the chunks run in this process)."""
    import navsim.experiment.runner
    real = navsim.experiment.runner._chunk

    def interrupt(args):
        if list(args[3])[0] == first_run:
            raise KeyboardInterrupt
        return real(args)

    monkeypatch.setattr(navsim.experiment.runner, "_chunk", interrupt)


def test_interrupted_run_keeps_what_finished(short_pdf, tmp_path, monkeypatch):
    import navsim.experiment.runner
    monkeypatch.setattr(navsim.experiment.runner, "CHUNK_RUNS", 2)
    interrupt_at(monkeypatch, 4)
    assert run(short_pdf, tmp_path / "out") == 130
    m = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert m["interrupted"] is True and m["runs_done"] == 4
    assert (tmp_path / "out" / "report.pdf").exists()


# p2_sea_height and p3_sins_gps run through navsim.run with their reports in test_report_pages.py,
# P3's 20 runs in test_budget.py, P2's filters in test_p2_height.py: not a third time here (22 s)
@pytest.mark.parametrize("name", ["p0_bd_sins_ads", "p0_two_step",
                                  "p1_emi_powerline", "p1_federated",
                                  # a closed loop flies JSBSim per run (42 s): its features have
                                  # tests of their own on a short track (test_closed_loop.py)
                                  pytest.param("p1_return_to_land", marks=pytest.mark.slow),
                                  "p1_gnss_denied_landmarks"])
def test_shipped_scenarios_run_with_few_runs(name, repo_root, tmp_path, monkeypatch, shipped_flight):
    """The first through ``navsim run`` with its report, flown from an empty cache of its own;
    the others' runs and metrics written by ``navsim.run`` (their reports, 8 s each at 2 runs,
    are drawn by test_report_pages.py), their flights from the suite's cache
    (``shipped_flight`` points NAVSIM_CACHE there), as the other tests fly them."""
    out = tmp_path / name
    scenario = repo_root / "scenarios" / f"{name}.yaml"
    if name == "p0_bd_sins_ads":
        monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
        assert main(["run", str(scenario), "--runs", "2", "--workers", "1", "--out", str(out)]) == 0
        assert (out / "report.pdf").stat().st_size > 50_000
    else:
        shipped_flight(name)
        navsim.run(scenario, 2, workers=1, out=out)
    m = json.loads((out / "metrics.json").read_text())
    assert m["runs_done"] == 2 and m["estimators"] and all(e["diverged_runs"] == 0 for e in m["estimators"].values())


BASE = SHORT.replace("reference:\n  source: a test\n  kind: population\n  values:\n    KF: {rms.pos_m: [1, 1, 1], windows.turn.height_m.std: 0.5}\n", "")

# (text transformation, key path the message must name, words it must contain)
CORPUS = [
    (lambda s: s.replace("name: short_run", "name: [1]"), "name", "expected a string"),
    (lambda s: s.replace("track:", "trak:"), "trak", "did you mean 'track'"),
    (lambda s: s.replace("{type: straight, time_s: 20}\n    - {type: turn", "{type: straight, time_s: -20}\n    - {type: turn"),
     "track.segments[0].time_s", "> 0.0"),
    (lambda s: s.replace("bank_deg: 25", "bank_deg: 25, bnak: 3"), "track.segments[1].bnak", "did you mean 'bank_deg'"),
    (lambda s: s.replace("speed_mps: 14,", ""), "track.start.speed_mps", "is missing"),
    (lambda s: s.replace("model: p3_imu}", "model: p3_imuu}"), "sensors.imu.model", "did you mean 'p3_imu'"),
    (lambda s: s.replace("sensors:\n  imu: {model: p3_imu}", "sensors:\n  imu: {model: p3_imu, override: {gyro: {bias_sigma: 3}}}"),
     "sensors.imu.override.gyro.bias_sigma", "has no unit"),
    (lambda s: s.replace("sensors:\n  imu: {model: p3_imu}", "sensors:\n  imu: {model: p3_imu, override: {gyro: {bias_sigma: -3 deg/h}}}"),
     "sensors.imu.override.gyro.bias_sigma", "negative"),
    (lambda s: s.replace("sensors:\n  imu: {model: p3_imu}", "sensors:\n  imu: {model: p3_imu, override: {accel: {bias_sigma: 3 deg/h}}}"),
     "sensors.imu.override.accel.bias_sigma", "not a unit of acceleration"),
    (lambda s: s.replace("{type: outage, start_s: 25", "{type: outrage, start_s: 25"), "sensors.gps.faults[0].type", "one of outage"),
    (lambda s: s.replace("start_s: 25, end_s: 30", "start_s: 25, end_s: 20"), "sensors.gps.faults[0].end_s", "after start_s"),
    (lambda s: s.replace("type: eskf", "type: ekf"), "estimators[1].type", "did you mean 'eskf'"),
    (lambda s: s.replace("states: p3_15", "states: p3_16"), "estimators[1].states", "did you mean 'p3_15'"),
    (lambda s: s.replace("states: p3_15", "states: [att, vel, pos, gyro_bais]"), "estimators[1].states", "gyro_bias"),
    (lambda s: s.replace("sensor: gps, sigma_m", "sensor: gnss, sigma_m"), "estimators[1].measurements[0].sensor", "did you mean 'gps'"),
    (lambda s: s.replace("sigma_m: [2, 2, 1]", "sigma_m: [2, 2]"), "estimators[1].measurements[0].sigma_m", "a list of three"),
    (lambda s: s.replace("{type: velocity, sensor", "{type: speed, sensor"), "estimators[1].measurements[1].type", "one of air_velocity, gnss_horizontal, gnss_position"),
    (lambda s: s.replace("noise: {imu: p3_imu}", "noise: {imu: p3_gps}"), "estimators[1].noise.imu", "not an IMU"),
    (lambda s: s.replace("- {label: free SINS, type: sins}", "- {label: KF, type: sins}"), "estimators[1].label", "used twice"),
    (lambda s: s.replace("montecarlo: {runs: 6, seed: 4}", "montecarlo: {runs: 0, seed: 4}"), "montecarlo.runs", ">= 1"),
    (lambda s: s.replace("montecarlo: {runs: 6, seed: 4}", "montecarlo: {runs: 6, sed: 4}"), "montecarlo.sed", "did you mean 'seed'"),
    (lambda s: s.replace("end_s: 30}]", "end_s: 3000}]"), "metrics.windows[0].end_s", "after the end of the flight"),
    (lambda s: s.replace("settle_s: 10", "settle_s: -1"), "metrics.settle_s", ">= 0.0"),
    (lambda s: s + "reference:\n  source: x\n  kind: population\n  values:\n    KFF: {rms.pos_m: 1}\n", "reference.values.KFF", "did you mean 'KF'"),
    (lambda s: s + "reference:\n  source: x\n  kind: population\n  values:\n    KF: {rmse.pos_m: 1}\n", "reference.values.KF.rmse.pos_m", "not a metric"),
    (lambda s: s.replace("initial_errors: {pos_m: [5, 5, 3]", "initial_errors: {pos_m: [5, 5, -3]"), "initial_errors.pos_m", "non-negative"),
    (lambda s: s.replace("sensors:\n  imu: {model: p3_imu}\n", "sensors:\n"), "sensors", "exactly one sensor of kind imu"),
    (lambda s: s.replace("environment", "x") + "environment: {wind: {force: 13}}\n", "environment.wind.force", "one of 0"),
    (lambda s: s.replace("{type: velocity, sensor: gps, sigma_mps: 0.05}",
                         "{type: mag_heading, sensor: gps, sigma_deg: 1, noise_uT: 0.2}"),
     "estimators[1].measurements[1].sensor", "is a gnss (expected a magnetometer sensor)"),
    (lambda s: s.replace("{type: velocity, sensor: gps, sigma_mps: 0.05}",
                         "{type: mag_heading, sensor: mag, sigma_deg: 1, noise_uT: 0.2, forgetting: 1.5}")
     .replace("sensors:\n  imu: {model: p3_imu}\n", "sensors:\n  imu: {model: p3_imu}\n  mag: {model: p1_magnetometer}\n"),
     "estimators[1].measurements[1].forgetting", "<= 1.0"),
    (lambda s: s.replace("{type: velocity, sensor: gps, sigma_mps: 0.05}", "{type: mag_heading, sensor: mag, sigma_deg: 1}")
     .replace("sensors:\n  imu: {model: p3_imu}\n", "sensors:\n  imu: {model: p3_imu}\n  mag: {model: p1_magnetometer}\n"),
     "estimators[1].measurements[1].noise_uT", "is missing"),
]


@pytest.mark.parametrize("i", range(len(CORPUS)))
def test_malformed_scenario_corpus(i, tmp_path, capsys):
    change, key, words = CORPUS[i]
    text = change(BASE)
    assert text != BASE, "the corpus entry must change the scenario"
    path = tmp_path / f"bad{i}.yaml"
    path.write_text(text)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: {key}:" in err, err
    assert words in err, err


def test_malformed_scenario_exits_2_from_run_without_traceback(tmp_path, monkeypatch, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(BASE.replace("type: eskf", "type: ekf"))
    monkeypatch.chdir(tmp_path)                  # its default output folder, reports/, under tmp_path
    assert main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "estimators[1].type" in err and "hint: did you mean 'eskf'?" in err
    assert not (tmp_path / "reports").exists()


def test_a_sweep_point_that_cannot_be_flown_is_reported_and_the_others_run(short, tmp_path, capsys):
    """A wind above the airspeed at one point (issue 35): that point 'not flown' with the
    flight's reason, the other run and written; exit 1."""
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"scenario: {short.name}\nruns: 2\ngrid:\n  environment.wind.speed_mps: [3, 20]\n"
                     "metric: rms.pos_m\n")
    out = tmp_path / "out"
    assert main(["sweep", str(sweep), "--out", str(out)]) == 1
    data = json.loads((out / "sweep.json").read_text())
    fine, unflown = data["points"]
    assert fine["metrics"]["runs_done"] == 2 and fine["values"]["KF"] > 0
    assert unflown["metrics"] is None and unflown["values"] == {"free SINS": None, "KF": None}
    assert "above the airspeed" in data["failed_points"]["1"]
    text = capsys.readouterr()
    assert "point 2/2 (wind.speed_mps=20): the flight cannot be flown" in text.out
    assert "error: point 2/2 (wind.speed_mps=20): the flight cannot be flown" in text.err and (out / "sweep.png").stat().st_size > 0


def test_sweep_grid(short, tmp_path, capsys):
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"""
scenario: {short.name}
runs: 2
grid:
  sensors.gps.override.position_sigma: ["[2, 2, 1] m", "[20, 20, 10] m"]
  estimators[1].measurements[0].sigma_m: [[2, 2, 1], [20, 20, 10]]
metric: rms.pos_m
""")
    out = tmp_path / "out"
    assert main(["sweep", str(sweep), "--out", str(out)]) == 0
    data = json.loads((out / "sweep.json").read_text())
    assert len(data["points"]) == 4 and (out / "sweep.png").stat().st_size > 0
    kf = [p["values"]["KF"] for p in data["points"]]
    # a noisier GPS gives a larger position error, whatever the filter assumes
    assert kf[2] > kf[0] and kf[3] > kf[1]
    # every point's whole metrics, its norm the value compared
    assert all(p["metrics"]["runs_done"] == 2 for p in data["points"])
    assert kf[0] == pytest.approx(np.linalg.norm(data["points"][0]["metrics"]["estimators"]["KF"]["rms"]["pos_m"]))
    rows = (out / "sweep.csv").read_text().splitlines()
    assert rows[0] == "point,sensors.gps.override.position_sigma,estimators[1].measurements[0].sigma_m," \
                      "free SINS: rms.pos_m,free SINS: rms.pos_m ci95_lo,free SINS: rms.pos_m ci95_hi," \
                      "KF: rms.pos_m,KF: rms.pos_m ci95_lo,KF: rms.pos_m ci95_hi" and len(rows) == 5
    value, lo, hi = map(float, rows[3].split(",")[-3:])
    # the norm's interval: the 3-D RMS's over the 2 runs, around the value
    assert value == kf[2] and lo < value < hi and data["points"][2]["ci95"]["KF"] == [lo, hi]
    out_text = capsys.readouterr().out
    assert "KF: rms.pos_m" in out_text
    # a line per point as it finishes
    assert [ln.split(" (")[0] for ln in out_text.splitlines() if re.match(r"point \d+/", ln)] == \
        [f"point {n}/4" for n in range(1, 5)]
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"scenario: {short.name}\ngrid:\n  estimators[5].type: [sins]\n")
    assert main(["sweep", str(bad), "--out", str(tmp_path / "bad_out")]) == 2
    assert "estimators[5]" in capsys.readouterr().err


def test_a_lent_pool_serves_many_monte_carlos_with_the_same_numbers(short):
    """Inside lend_pool (what budget, sweep and tune open) one pool of workers runs every Monte
    Carlo of the thread: the same worker processes, and results bit for bit those of a pool
    started for each; a pool broken by a dead worker is replaced; leaving shuts the workers down."""
    import os
    import signal

    from navsim.experiment import executors
    alone = navsim.run(short, runs=4, seed=3, workers=2).to_dict()
    with executors.lend_pool():
        first = navsim.run(short, runs=4, seed=3, workers=2)
        pool = executors._THREAD.lent[1]
        pids = set(pool._processes)
        second = navsim.run(short, runs=4, seed=3, workers=2)
        assert executors._THREAD.lent[1] is pool and set(pool._processes) == pids
        os.kill(next(iter(pids)), signal.SIGKILL)                 # a worker dies: the pool is broken
        navsim.run(short, runs=4, seed=3, workers=2)              # (its chunks may fail; it must not hang)
        third = navsim.run(short, runs=4, seed=3, workers=2)
        replacement = executors._THREAD.lent[1]
        assert replacement is not pool
        workers = list(replacement._processes.values())
    assert executors._THREAD.lent is None and workers and not any(p.is_alive() for p in workers)
    timeless = lambda d: {label: {k: v for k, v in m.items() if k != "cost"} for label, m in d["estimators"].items()}
    for r in (first, second, third):
        got = r.to_dict()
        assert timeless(got) == timeless(alone) and got["paper_checks"] == alone["paper_checks"]


def test_ctrl_c_inside_a_lent_pool_stops_its_workers_and_the_next_monte_carlo_gets_a_new_one(short, monkeypatch):
    """A Ctrl-C while a lent pool runs chunks: the Monte Carlo keeps what finished (interrupted),
    the pool is shut down (its running chunks waited for, its workers gone, none left computing
    behind the caller), and the next Monte Carlo inside the same lend gets a fresh pool."""
    from navsim.experiment import executors, runner
    real = runner.as_completed

    def interrupted(futures):
        yield from []
        raise KeyboardInterrupt
    with executors.lend_pool():
        navsim.run(short, runs=4, seed=3, workers=2)
        pool = executors._THREAD.lent[1]
        workers = list(pool._processes.values())
        monkeypatch.setattr(runner, "as_completed", interrupted)
        r = navsim.run(short, runs=4, seed=3, workers=2)
        assert r.interrupted and executors._THREAD.lent[1] is None
        for w in workers:
            w.join(timeout=10)
        assert not any(w.is_alive() for w in workers)
        monkeypatch.setattr(runner, "as_completed", real)
        again = navsim.run(short, runs=4, seed=3, workers=2)
        assert not again.interrupted and executors._THREAD.lent[1] not in (None, pool)
