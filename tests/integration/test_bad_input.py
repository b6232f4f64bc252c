"""Malformed input, as a careless or hostile user would give it: every case exits with its code
(2 bad input, 3 unflyable track, 4 the operating system refused), prints no traceback, names
the file and the key, and writes nothing outside the output folder.

Each case is a scenario (the small one below with a change, or a file of its own), a command
line and what must come back. The cases run in a fresh working folder each.
"""

from __future__ import annotations

import copy
import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from navsim.cli import main
from navsim.experiment.sweep import set_path

BASE = {
    "name": "tiny",
    "track": {"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 250, "speed_mps": 14, "heading_deg": 45},
              "segments": [{"type": "straight", "time_s": 20, "label": "leg"}]},
    "sensors": {"imu": {"model": "p0_imu"}, "bd": {"model": "p0_bd2"}, "ads": {"model": "p0_ads"}},
    "estimators": [
        {"label": "free SINS", "type": "sins"},
        {"label": "eskf", "type": "eskf", "states": "p0_16", "period_s": 1.0, "noise": {"imu": "p0_imu"},
         "baro": {"sigma_m": 3.0, "tau_s": 600},
         "measurements": [{"type": "gnss_position", "sensor": "bd", "sigma_m": [8, 8, 8]},
                          {"type": "velocity", "sensor": "ads", "sigma_mps": [1.0, 1.0, 1.5]}]}],
    "initial_errors": {"pos_m": [5, 5, 10], "vel_mps": 0.1, "att_arcsec": [20, 20, 50]},
    "montecarlo": {"runs": 2, "seed": 1, "workers": 1},
    # these tests read the numbers and the files navsim writes, not the pages: a PDF only (the
    # PNGs, every page drawn a second time, cost seconds a run)
    "report": {"formats": ["pdf"]},
}
SECRET = "top-secret-token-123"


def scenario(**changes) -> str:
    """The base scenario as YAML with ``changes`` (dotted key path -> value; ``None`` deletes)."""
    data = copy.deepcopy(BASE)
    for path, value in changes.items():
        path = path.replace("__", ".")
        if value is None:
            head, _, last = path.rpartition(".")
            node = data
            for part in head.split(".") if head else []:
                node = node[part]
            del node[last]
        else:
            set_path(data, path, value)
    return yaml.safe_dump(data, sort_keys=False)


S = "s.yaml"            # the scenario file of a case, in the case's folder "case/"
RUN = ["run", "case/" + S]
VALIDATE = ["validate", "case/" + S]

# (id, files (name under case/ -> text or bytes), argv, exit code, words the message must hold)
CASES = [
    # 1. the output folder comes from the scenario's name: a plain name only
    ("name-absolute", {S: scenario(name="/tmp/navsim-escape")}, RUN, 2, ["name", "plain name"]),
    ("name-dotdot", {S: scenario(name="../../x")}, RUN, 2, ["name", "plain name"]),
    ("name-separator", {S: scenario(name="a/b")}, VALIDATE, 2, ["name"]),
    ("name-dots", {S: scenario(name="..")}, VALIDATE, 2, ["name"]),
    ("name-fly", {S: scenario(name="../fly-out")}, ["fly", "case/" + S], 2, ["name"]),
    ("name-sensors", {S: scenario(name="../sensors-out")}, ["sensors", "case/" + S], 2, ["name"]),
    # 2. accepted by validate, failing every run: now refused before anything is flown
    ("fault-after-end", {S: scenario(**{"sensors.bd.faults": [{"type": "outage", "start_s": 900, "end_s": 950}]})},
     RUN, 2, ["sensors.bd.faults[0].start_s", "after the flight ends"]),
    ("fault-after-end-validate", {S: scenario(**{"sensors.bd.faults": [{"type": "outage", "start_s": 900}]})},
     VALIDATE, 2, ["sensors.bd.faults[0]"]),
    ("field-not-produced", {S: scenario(**{"estimators[1].measurements[1].field": "vel_body"})},
     VALIDATE, 2, ["estimators[1].measurements[1].field", "vel_n_mps"]),
    ("height-field-not-produced", {S: scenario(**{"estimators[1].measurements[1]":
                                                  {"type": "height", "sensor": "bd", "field": "h_baro_m",
                                                   "sigma_m": 3.0}})},
     VALIDATE, 2, ["estimators[1].measurements[1].field", "h_m"]),
    # the filter's ADS model has vanes, the sensor none; an ADS model without vanes and no sigma
    # for the angles it leaves out; a model that is not an ADS
    ("air-velocity-no-vanes", {S: scenario(**{"estimators[1].measurements[1]":
                                              {"type": "air_velocity", "sensor": "ads", "model": "p0_ads",
                                               "override": {"velocity_axis": "air", "vane_noise": "0.5 deg"}}})},
     VALIDATE, 2, ["estimators[1].measurements[1]", "alpha_rad", "vanes"]),
    ("air-velocity-angle-sigma", {S: scenario(**{"estimators[1].measurements[1]":
                                                 {"type": "air_velocity", "sensor": "ads", "model": "p0_ads"}})},
     VALIDATE, 2, ["estimators[1].measurements[1].angle_sigma_deg", "no vanes"]),
    ("air-velocity-not-ads", {S: scenario(**{"estimators[1].measurements[1]":
                                             {"type": "air_velocity", "sensor": "ads", "model": "p0_imu"}})},
     VALIDATE, 2, ["estimators[1].measurements[1].model", "not an ADS"]),
    ("air-velocity-angle-with-vanes", {S: scenario(**{
        "sensors.ads.override": {"velocity_axis": "air"},
        "estimators[1].measurements[1]": {"type": "air_velocity", "sensor": "ads", "model": "p0_ads",
                                          "override": {"velocity_axis": "air"}, "angle_sigma_deg": 4}})},
     VALIDATE, 2, ["estimators[1].measurements[1].angle_sigma_deg", "vane_noise"]),
    ("pitot-bias-unobserved", {S: scenario(**{"estimators[1].states": ["att", "vel", "pos", "pitot_bias"]})},
     VALIDATE, 2, ["estimators[1].states", "pitot_bias", "0 air_velocity"]),
    ("sage-husa-air-velocity", {S: scenario(**{"estimators[1].type": "sage_husa",
                                               "estimators[1].measurements[1]": {"type": "air_velocity", "sensor": "ads", "model": "p0_ads", "angle_sigma_deg": 4}})},
     VALIDATE, 2, ["estimators[1].measurements", "air_velocity", "Sage-Husa"]),
    ("zero-velocity-axes", {S: scenario(**{"estimators[1].measurements[1]":
                                           {"type": "zero_velocity", "sensor": "ads", "sigma_mps": 1.0, "axes": "up"}})},
     VALIDATE, 2, ["estimators[1].measurements[1].axes", "horizontal, ned"]),
    ("zero-velocity-sigma", {S: scenario(**{"estimators[1].measurements[1]":
                                            {"type": "zero_velocity", "sensor": "ads", "sigma_mps": [1, 0, 1]}})},
     VALIDATE, 2, ["estimators[1].measurements[1].sigma_mps", "a positive number"]),
    ("seed-negative", {S: scenario()}, RUN + ["--seed", "-1"], 2, ["--seed", "below 0"]),
    ("rate-nan", {S: scenario(flight={"rate_hz": float("nan")})}, VALIDATE, 2, ["flight.rate_hz", "finite"]),
    ("period-tiny", {S: scenario(**{"estimators[1].period_s": 1e-9})}, VALIDATE, 2,
     ["estimators[1].period_s", "IMU"]),
    ("period-not-multiple", {S: scenario(**{"estimators[1].period_s": 0.015})}, VALIDATE, 2,
     ["estimators[1].period_s", "whole number"]),
    # 3. tracks and sensor models: the catalog, or files beside or below the scenario
    ("track-absolute", {S: scenario(track="/etc/passwd")}, VALIDATE, 2, ["track", "not allowed"]),
    ("track-outside", {S: scenario(track="../outside.yaml"), "../outside.yaml": "start: {}\n"}, VALIDATE, 2,
     ["track", "leaves the scenario's folder"]),
    ("track-secret-file", {S: scenario(track="notes.yaml"), "notes.yaml": f"{SECRET}\n"}, VALIDATE, 2,
     ["notes.yaml", "is not a track"]),
    ("track-names-itself", {S: scenario(track="self.yaml"), "self.yaml": "self.yaml\n"}, VALIDATE, 2,
     ["self.yaml", "is not a track"]),
    ("track-not-yaml", {S: scenario(track="notes.txt"), "notes.txt": f"{SECRET}\n"}, VALIDATE, 2,
     ["track", "not a shipped track"]),
    ("track-not-yaml-path", {S: scenario(track="sub/notes.txt"), "sub/notes.txt": f"{SECRET}\n"}, VALIDATE, 2,
     ["track", "not allowed"]),
    ("track-unknown-name", {S: scenario(track="p9")}, VALIDATE, 2, ["track", "not a shipped track"]),
    ("model-absolute", {S: scenario(**{"sensors.imu.model": "/etc/hostname"})}, VALIDATE, 2,
     ["sensors.imu.model", "not allowed"]),
    ("model-dotdot", {S: scenario(**{"sensors.imu.model": "../../sensors/p0_imu"})}, VALIDATE, 2,
     ["sensors.imu.model"]),
    ("model-outside-yaml", {S: scenario(**{"sensors.imu.model": "../imu.yaml"}), "../imu.yaml": "kind: imu\n"},
     VALIDATE, 2, ["sensors.imu.model", "leaves the scenario's folder"]),
    # 5. NaN and infinity
    ("initial-nan", {S: scenario(**{"initial_errors.pos_m": [5, float("nan"), 10]})}, VALIDATE, 2,
     ["initial_errors.pos_m"]),
    ("initial-inf", {S: scenario(**{"initial_errors.vel_mps": float("inf")})}, VALIDATE, 2,
     ["initial_errors.vel_mps"]),
    ("datasheet-nan-mapping", {S: scenario(**{"sensors.bd.override": {"position_sigma": {"value": float("nan"),
                                                                                           "unit": "m"}}})},
     VALIDATE, 2, ["sensors.bd.override.position_sigma", "finite"]),
    ("datasheet-nan-vector", {S: scenario(**{"sensors.bd.override": {"position_sigma": "[nan, nan, nan] m"}})},
     VALIDATE, 2, ["sensors.bd.override.position_sigma", "finite"]),
    ("datasheet-overflow", {S: scenario(**{"sensors.bd.override": {"position_sigma": "1e400 m"}})},
     VALIDATE, 2, ["sensors.bd.override.position_sigma", "finite"]),
    ("sensor-rate-nan", {S: scenario(**{"sensors.bd.override": {"rate_hz": float("nan")}})}, VALIDATE, 2,
     ["sensors.bd.override.rate_hz", "finite"]),
    ("sensor-rate-inf", {S: scenario(**{"sensors.bd.override": {"rate_hz": float("inf")}})}, VALIDATE, 2,
     ["sensors.bd.override.rate_hz"]),
    # 8. reference values
    ("reference-strings", {S: scenario(reference={"source": "P0", "kind": "population", "values": {"eskf": {"rms.pos_m": ["a", "b", "c"]}}})},
     VALIDATE, 2, ["reference.values.eskf.rms.pos_m", "finite"]),
    ("reference-nan", {S: scenario(reference={"source": "P0", "kind": "population", "values": {"eskf": {"rms.pos_m": float("nan")}}})},
     VALIDATE, 2, ["reference.values.eskf.rms.pos_m"]),
    ("reference-unknown-metric", {S: scenario(reference={"source": "P0", "kind": "population", "values": {"eskf": {"rmse.pos_m": 1}}})},
     VALIDATE, 2, ["reference.values.eskf.rmse.pos_m", "not a metric"]),
    ("reference-alias-bomb", {S: scenario() + "reference:\n  source: P0\n  note: &a [x, x, x, x, x, x, x, x, x, x]\n"
                              + "".join(f"  n{i}: &{c} [{', '.join([f'*{p}'] * 10)}]\n"
                                        for i, (p, c) in enumerate(zip("abcdefgh", "bcdefghi")))},
     VALIDATE, 2, ["expands to more than"]),
    # 9. command-line numbers
    ("runs-zero", {S: scenario()}, RUN + ["--runs", "0"], 2, ["--runs", "below 1"]),
    ("runs-negative", {S: scenario()}, RUN + ["--runs", "-3"], 2, ["--runs"]),
    ("runs-text", {S: scenario()}, RUN + ["--runs", "many"], 2, ["--runs", "not an integer"]),
    ("workers-zero", {S: scenario()}, RUN + ["--workers", "0"], 2, ["--workers"]),
    ("workers-negative", {S: scenario()}, RUN + ["--workers", "-1"], 2, ["--workers"]),
    ("workers-huge", {S: scenario()}, RUN + ["--workers", "100000"], 2, ["--workers", "above 256"]),
    ("chunk-runs-zero", {S: scenario()}, RUN + ["--chunk-runs", "0"], 2, ["--chunk-runs"]),
    ("sensors-runs-zero", {S: scenario()}, ["sensors", "case/" + S, "--runs", "0"], 2, ["--runs"]),
    ("fly-rate-negative", {S: scenario()}, ["fly", "case/" + S, "--rate-hz", "-5"], 2, ["--rate-hz"]),
    ("fly-rate-zero", {S: scenario()}, ["fly", "case/" + S, "--rate-hz", "0"], 2, ["--rate-hz"]),
    ("fly-rate-nan", {S: scenario()}, ["fly", "case/" + S, "--rate-hz", "nan"], 2, ["--rate-hz", "finite"]),
    ("scheduler-not-url", {S: scenario()}, RUN + ["--executor", "dask", "--scheduler", "not a url"], 2,
     ["--scheduler", "scheduler address"]),
    ("scheduler-no-port", {S: scenario()}, RUN + ["--executor", "dask", "--scheduler", "tcp://host"], 2,
     ["--scheduler"]),
    ("replay-imu-rate", {}, ["replay", "tests/data/px4_quad_real_69s.ulg.gz", "--imu-rate", "-5"], 2,
     ["--imu-rate"]),
    ("replay-settle", {}, ["replay", "tests/data/px4_quad_real_69s.ulg.gz", "--settle", "-1"], 2, ["--settle"]),
    ("replay-align", {}, ["replay", "tests/data/px4_quad_real_69s.ulg.gz", "--align", "0"], 2, ["--align"]),
    ("replay-not-a-log", {"log.ulg": f"{SECRET}\n"}, ["replay", "case/log.ulg"], 2, ["case/log.ulg"]),
    ("replay-missing-log", {}, ["replay", "case/nothing.ulg"], 2, ["case/nothing.ulg"]),
    # 10. what used to end in a traceback
    ("landmarks-malformed", {S: scenario(**{"sensors.cam": {"model": "p1_camera", "override": {
        "landmarks": [[37.0, 118.0, 0.0], ["north", 118.0, 0.0]]}}})}, VALIDATE, 2,
     ["sensors.cam.override.landmarks", "landmark [1]"]),
    ("landmarks-not-list", {S: scenario(**{"sensors.cam": {"model": "p1_camera", "override": {"landmarks": 5}}})},
     VALIDATE, 2, ["sensors.cam.override.landmarks"]),
    ("nesting-500", {S: "name: deep\ntrack: " + "[" * 500 + "]" * 500 + "\n"}, VALIDATE, 2, ["nested more than"]),
    ("binary-file", {S: bytes(range(256)) * 4}, VALIDATE, 2, ["not UTF-8"]),
    ("scenario-is-folder", {"dir.yaml/x": "x"}, ["validate", "case/dir.yaml"], 2, ["is a folder"]),
    ("scenario-missing", {}, ["validate", "case/none.yaml"], 2, ["cannot read"]),
    ("scenario-a-list", {S: "- track: p0\n"}, VALIDATE, 2, ["a mapping"]),
    ("scenario-empty", {S: ""}, VALIDATE, 2, ["is empty"]),
    ("sweep-unknown-metric", {S: scenario(), "w.yaml": "scenario: s.yaml\ngrid: {montecarlo.seed: [1, 2]}\n"
                              "metric: rms.position\n"}, ["sweep", "case/w.yaml"], 2, ["case/w.yaml: metric"]) ,
    ("sweep-unknown-metric-head", {S: scenario(), "w.yaml": "scenario: s.yaml\ngrid: {montecarlo.seed: [1, 2]}\n"
                                   "metric: rmse.pos_m\n"}, ["sweep", "case/w.yaml"], 2, ["metric", "rms"]),
    ("sweep-bad-fault-point", {S: scenario(), "w.yaml": "scenario: s.yaml\npoints:\n"
                               "  - {sensors.bd.faults: [{type: outage, start_s: 900}]}\n"},
     ["sweep", "case/w.yaml"], 2, ["case/w.yaml: point 1/1", "sensors.bd.faults[0]"]),
    ("sweep-scenario-not-yaml", {"w.yaml": "scenario: notes.txt\ngrid: {montecarlo.seed: [1]}\n",
                                 "notes.txt": SECRET}, ["sweep", "case/w.yaml"], 2, ["scenario"]),
    # 11. duplicate keys
    ("duplicate-top-key", {S: scenario() + "name: again\n"}, VALIDATE, 2, ["duplicate key 'name'"]),
    ("duplicate-nested-key", {S: scenario().replace("  seed: 1\n", "  seed: 1\n  seed: 2\n")}, VALIDATE, 2,
     ["duplicate key 'seed'"]),
    ("duplicate-state-block", {S: scenario(**{"estimators[1].states": ["att", "vel", "pos", "att"]})},
     VALIDATE, 2, ["estimators[1].states", "twice"]),
    # 12. settle beyond the flight
    ("settle-after-end", {S: scenario(metrics={"settle_s": 5000})}, VALIDATE, 2,
     ["metrics.settle_s", "end of the flight"]),
    ("window-after-end", {S: scenario(metrics={"windows": [{"name": "w", "start_s": 5, "end_s": 500}]})},
     VALIDATE, 2, ["metrics.windows[0].end_s"]),
    # 13. inputs that used to be reported as "state became NaN at t = 0"
    ("start-500-mps", {S: scenario(**{"track.start.speed_mps": 500})}, RUN, 2, ["track.start.speed_mps", "<= 40"]),
    ("start-below-surface", {S: scenario(**{"track.start.alt_m": 50}, environment={"surface_m": 100})}, RUN, 2,
     ["track.start.alt_m", "below the surface"]),
    ("wind-1e6", {S: scenario(environment={"wind": {"speed_mps": 1e6, "from_deg": 0}})}, RUN, 2,
     ["environment.wind.speed_mps", "<= 40"]),
    ("wind-component", {S: scenario(environment={"wind": {"north_mps": -1e6}})}, VALIDATE, 2,
     ["environment.wind.north_mps"]),
    ("segment-speed", {S: scenario(**{"track.segments[0].speed_mps": 300})}, VALIDATE, 2,
     ["track.segments[0].speed_mps"]),
    # 7. the operating system
    ("out-is-a-file", {S: scenario(), "taken": "a file"}, RUN + ["--out", "case/taken"], 4,
     ["case/taken", "not a folder"]),
    ("out-under-a-file", {S: scenario(), "taken": "a file"}, RUN + ["--out", "case/taken/sub"], 4, ["case/taken"]),
    ("out-not-creatable", {S: scenario()}, RUN + ["--out", "/proc/navsim-out"], 4, ["/proc/navsim-out"]),
    ("fly-out-is-a-file", {S: scenario(), "taken": "a file"}, ["fly", "case/" + S, "--out", "case/taken"], 4,
     ["not a folder"]),
    ("sweep-scenario-absolute", {"w.yaml": "scenario: /etc/hostname.yaml\ngrid: {montecarlo.seed: [1]}\n"},
     ["sweep", "case/w.yaml"], 2, ["case/w.yaml: scenario"]),
    ("sweep-metric-group", {S: scenario(metrics={"windows": [{"name": "w", "start_s": 1, "end_s": 5}]}),
                            "w.yaml": "scenario: s.yaml\ngrid: {montecarlo.seed: [1]}\nmetric: windows.x.height_m\n"},
     ["sweep", "case/w.yaml"], 2, ["case/w.yaml: metric", "window 'x'"]),
    ("sensor-name-path", {S: scenario(**{"sensors": {"imu": {"model": "p0_imu"}, "../../x": {"model": "p0_bd2"}}})},
     VALIDATE, 2, ["sensors.../../x", "not a sensor name"]),
    ("name-trailing-newline", {S: scenario(name="tiny\n")}, VALIDATE, 2, ["name"]),
    ("yaml-list-as-key", {S: scenario() + "? [a, b]\n: 1\n"}, VALIDATE, 2, ["a list or mapping used as a key"]),
    ("yaml-deep-through-aliases", {S: "name: x\n" + "".join(
        f"a{i}: &a{i} " + "[" * 30 + (f"*a{i - 1}" if i else "0") + "]" * 30 + "\n" for i in range(4))},
     VALIDATE, 2, ["nested more than"]),
    ("attitude-sigma-zero", {S: (Path(__file__).parents[2] / "scenarios" / "p4_static.yaml").read_text()
                             .replace("mag_uT: 0.5", "mag_uT: 0")}, VALIDATE, 2, ["sigma.mag_uT", "> 0.0"]),
    ("resume-index-not-object", {S: scenario(), "out/.navsim-files.json": "[]", "out/chunks/index.json": "[1, 2]"},
     RUN + ["--out", "case/out", "--resume"], 2, ["not a chunk index"]),
    ("resume-nothing", {S: scenario()}, RUN + ["--out", "case/empty", "--resume"], 2, ["nothing to resume"]),
]


@pytest.fixture
def workdir(tmp_path, monkeypatch, repo_root, tmp_path_factory):
    """A fresh working folder with the shipped PX4 log under tests/data, a shared flight cache."""
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path_factory.getbasetemp() / "bad-input-cache"))
    work = tmp_path / "work"
    (work / "tests" / "data").mkdir(parents=True)
    (work / "tests" / "data" / "px4_quad_real_69s.ulg.gz").symlink_to(
        repo_root / "tests" / "data" / "px4_quad_real_69s.ulg.gz")
    monkeypatch.chdir(work)
    return work


def call(argv) -> int:
    try:
        return main(list(argv))
    except SystemExit as exc:        # argparse's usage errors
        return exc.code


def files_under(folder: Path) -> set:
    return {p.relative_to(folder) for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("case, files, argv, code, words", CASES, ids=[c[0] for c in CASES])
def test_malformed_input(workdir, capsys, case, files, argv, code, words):
    for name, content in files.items():
        path = workdir / "case" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
    before = files_under(workdir.parent)
    assert call(argv) == code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    for word in words:
        assert word in err, (word, err)
    assert SECRET not in out + err
    if code == 2 and argv[1].startswith("case/") and "usage:" not in err and "--out" not in argv:
        assert argv[1] in err, err                 # the message names the input file
    new = files_under(workdir.parent) - before
    out = Path("work", argv[argv.index("--out") + 1]) if "--out" in argv else Path("work", "reports")
    assert all(p.is_relative_to(out) for p in new), new    # nothing outside the output folder
    assert not Path("/tmp/navsim-escape").exists()


def test_corpus_covers_every_class():
    """At least 60 cases, and each defect class of issue 17 in them."""
    assert len(CASES) >= 60
    ids = " ".join(c[0] for c in CASES)
    for word in ("name", "fault", "field", "seed", "track", "model", "nan", "reference", "runs", "workers",
                 "scheduler", "replay", "landmarks", "nesting", "binary", "sweep", "duplicate", "settle",
                 "start", "wind", "out-"):
        assert word in ids, word


def test_full_disk_leaves_no_partial_file(workdir, capsys, monkeypatch):
    """A disk that fills up while the report of a resumed run is written: exit 4 naming the
    file, no temporary file left, no truncated report.pdf (the earlier run's was removed as
    the rerun started, the new one is never renamed into place)."""
    import matplotlib.figure

    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario())
    assert call(RUN + ["--out", "out"]) == 0
    real = matplotlib.figure.Figure.savefig
    calls = {"n": 0}

    def full(self, fname, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] > 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(fname))
        return real(self, fname, *args, **kwargs)
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", full)
    capsys.readouterr()
    assert call(RUN + ["--out", "out", "--resume"]) == 4
    err = capsys.readouterr().err
    assert "No space left on device" in err and "Traceback" not in err
    assert not [p for p in (workdir / "out").rglob("*") if ".tmp" in p.name]
    assert not (workdir / "out" / "report.pdf").exists()
    assert json.loads((workdir / "out" / "metrics.json").read_text())["runs_done"] == 2   # written before


def test_a_rerun_removes_only_what_navsim_wrote(workdir, capsys):
    """An earlier run's metrics.json never stands beside a new run's results; a user's own file
    in the output folder, and chunk-like files the index does not list, are left alone."""
    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario())
    assert call(RUN + ["--out", "out"]) == 0
    out = workdir / "out"
    (out / "my_notes.txt").write_text("mine")
    (out / "chunks" / "chunk_99-100.npz").write_text("not navsim's")
    # a rerun refused after the folder is opened (another seed to resume) keeps everything
    assert call(RUN + ["--out", "out", "--resume", "--seed", "7"]) == 2
    assert "holds another run" in capsys.readouterr().err
    assert json.loads((out / "metrics.json").read_text())["runs"] == 2
    assert (out / "chunks" / "chunk_0-1.npz").exists()
    # a new run replaces navsim's own files only
    assert call(RUN + ["--out", "out", "--runs", "1"]) == 0
    assert json.loads((out / "metrics.json").read_text())["runs"] == 1
    assert (out / "my_notes.txt").read_text() == "mine"
    assert (out / "chunks" / "chunk_99-100.npz").read_text() == "not navsim's"
    assert not (out / "chunks" / "chunk_0-1.npz").exists() and (out / "chunks" / "chunk_0-0.npz").exists()


def test_resume_runs_a_truncated_chunk_again(workdir, capsys):
    """A chunk file cut short (a disk failure) is run again on --resume, and the metrics equal
    the uninterrupted run's."""
    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario(montecarlo={"runs": 4, "seed": 3, "workers": 1}))
    assert call(RUN + ["--out", "out", "--chunk-runs", "2"]) == 0
    first = json.loads((workdir / "out" / "metrics.json").read_text())
    chunk = workdir / "out" / "chunks" / "chunk_2-3.npz"
    chunk.write_bytes(chunk.read_bytes()[: chunk.stat().st_size // 2])
    assert call(RUN + ["--out", "out", "--resume"]) == 0
    again = json.loads((workdir / "out" / "metrics.json").read_text())
    assert again["runs_done"] == 4
    assert again["estimators"]["eskf"]["rms"] == first["estimators"]["eskf"]["rms"]


def test_run_on_an_unflyable_track_saves_the_part_flown(workdir, capsys):
    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario(track={
        "start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 60, "speed_mps": 14},
        "segments": [{"type": "straight", "time_s": 5},
                     {"type": "descend", "to_m": -20, "rate_mps": 4, "label": "into the sea"}]}))
    assert call(RUN + ["--out", "out"]) == 3
    err = capsys.readouterr().err
    assert "segment 1 (into the sea)" in err and "Traceback" not in err
    flight = workdir / "out" / "flight"
    assert (flight / "truth.npz").stat().st_size > 0 and (flight / "flight_time.png").stat().st_size > 0
    assert json.loads((flight / "run.json").read_text())["failure"]


def test_a_wind_above_the_airspeed_fails_the_flight_and_saves_it(workdir, capsys):
    """A 20 m/s wind against a 14 m/s aircraft (issue 35): the flight cannot be flown, exit 3, the
    part flown (10 s of it) saved with its steady wind recorded."""
    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario(
        track={"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 300, "speed_mps": 14},
               "segments": [{"type": "straight", "time_s": 60}]},
        environment={"wind": {"speed_mps": 20, "from_deg": 90}}))
    assert call(RUN + ["--out", "out"]) == 3
    err = capsys.readouterr().err
    assert "steady wind (20.0 m/s) is above the airspeed" in err and "Traceback" not in err
    with np.load(workdir / "out" / "flight" / "truth.npz") as truth:
        assert 9.0 < truth["t_s"][-1] < 11.0
        np.testing.assert_allclose(truth["wind_steady_n_mps"][-1], [0.0, -20.0, 0.0], atol=1e-9)


def test_no_run_succeeding_is_an_error_that_shows_why(workdir, capsys, monkeypatch):
    import navsim.experiment.runner

    def broken(args):
        raise RuntimeError("emulator exploded")
    monkeypatch.setattr(navsim.experiment.runner, "_chunk", broken)
    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario())
    assert call(RUN + ["--out", "out"]) == 1
    out, err = capsys.readouterr()
    assert "0/2 runs" in out and "emulator exploded" in out and "no run succeeded" in err


def test_a_track_file_beside_the_scenario_is_found_from_any_folder(workdir, capsys):
    """Relative track and sensor files resolve against the scenario's folder, not the working one."""
    (workdir / "case" / "tracks").mkdir(parents=True)
    (workdir / "case" / "tracks" / "leg.yaml").write_text(yaml.safe_dump(BASE["track"]))
    (workdir / "case" / "my_gnss.yaml").write_text((Path(__file__).parents[2] / "sensors" / "p0_bd2.yaml").read_text())
    (workdir / "case" / S).write_text(scenario(track="tracks/leg.yaml", **{"sensors.bd.model": "my_gnss.yaml"}))
    assert call(VALIDATE) == 0
    assert "ok" in capsys.readouterr().out


AUDIT = r'''
import os, sys
events = []
def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        mode = args[1] or "r"
        flags = args[2] if len(args) > 2 and isinstance(args[2], int) else 0
        write = any(c in str(mode) for c in "wax+") or flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT)
        events.append(("write" if write else "read", os.fsdecode(args[0])))
    elif event in ("os.remove", "os.rename", "os.replace", "os.rmdir", "shutil.rmtree", "os.mkdir"):
        events.append(("write", os.fsdecode(args[0])))
        if event in ("os.rename", "os.replace"):
            events.append(("write", os.fsdecode(args[1])))
sys.addaudithook(hook)
from navsim.cli import main
code = main(sys.argv[1:])
seen = list(events)
with open(os.environ["AUDIT_OUT"], "w") as f:
    for kind, path in seen:
        f.write(f"{kind}\t{os.path.abspath(path)}\n")
sys.exit(code)
'''


def audited(tmp_path, *argv):
    """Run ``navsim argv`` in a fresh process under an audit hook: ``(process, reads, writes)``,
    the files it opened for reading and the paths it wrote, renamed, created or deleted."""
    import os
    import subprocess
    import sys

    (tmp_path / "script.py").write_text(AUDIT)
    env = dict(os.environ, NAVSIM_CACHE=str(tmp_path / "cache"), MPLCONFIGDIR=str(tmp_path / "mpl"),
               PYTHONDONTWRITEBYTECODE="1", AUDIT_OUT=str(tmp_path / "audit.tsv"))
    proc = subprocess.run([sys.executable, str(tmp_path / "script.py"), *map(str, argv)], cwd=tmp_path, env=env,
                          capture_output=True, text=True)
    events = [line.split("\t") for line in (tmp_path / "audit.tsv").read_text().splitlines()]
    reads = {Path(p) for kind, p in events if kind == "read" and Path(p).is_file()}
    return proc, reads, {Path(p) for kind, p in events if kind == "write"}


def plugin_folders() -> list:
    """The folders of the installed estimator plug-ins' modules (``navsim.estimators`` entry points)."""
    import importlib.util
    from importlib.metadata import entry_points
    specs = []
    for ep in entry_points(group="navsim.estimators"):
        try:
            specs.append(importlib.util.find_spec(ep.module))
        except ModuleNotFoundError:          # a broken plug-in: navsim leaves it out, and so does this
            pass
    return [Path(s.origin).resolve().parent for s in specs if s is not None and s.origin]


def test_a_run_touches_only_its_output_folder_the_cache_and_its_inputs(tmp_path, repo_root):
    """Every file navsim writes, renames or deletes in a whole ``navsim run`` is in the output
    folder or the caches (flights, compiled kernels); every file it reads is navsim's own (package, catalog,
    aircraft), the scenario's folder, the cache, the Python installation, the fonts or the CPU
    description numba reads; a track
    file that is a link to a file outside the scenario's folder is refused without being read."""
    import sys
    import sysconfig

    case = tmp_path / "case"
    (case / "tracks").mkdir(parents=True)
    (case / "tracks" / "leg.yaml").write_text(yaml.safe_dump(BASE["track"]))
    (case / "my_gnss.yaml").write_text((repo_root / "sensors" / "p0_bd2.yaml").read_text())
    (case / S).write_text(scenario(track="tracks/leg.yaml", **{"sensors.bd.model": "my_gnss.yaml"}))
    proc, reads, writes = audited(tmp_path, "run", case / S, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    numba_cache = [Path(os.environ["NUMBA_CACHE_DIR"])] if "NUMBA_CACHE_DIR" in os.environ else []
    allowed_writes = [tmp_path / "out", tmp_path / "cache", tmp_path / "mpl", *numba_cache]
    bad = [p for p in writes if not any(p.is_relative_to(a) for a in allowed_writes)
           and not str(p).startswith("/dev/")]
    assert not bad, bad
    assert any(p.is_relative_to(tmp_path / "out") for p in writes)
    installs = {Path(sysconfig.get_paths()[k]).resolve() for k in ("stdlib", "purelib", "platlib", "data")}
    allowed_reads = [case, tmp_path / "out", tmp_path / "cache", tmp_path / "mpl", *numba_cache, repo_root / "navsim",
                     repo_root / "sensors", repo_root / "aircraft", Path(sys.prefix), Path(sys.base_prefix),
                     *installs, Path("/usr/share/fonts"), Path("/proc/cpuinfo"), Path("/sys/devices/system/cpu"),
                     Path("/sys/fs/cgroup"),           # fonts for the plots; the CPU for numba
                     *plugin_folders()]                # the installed estimator plug-ins (entry points)
    strays = [p for p in reads if not any(p.resolve().is_relative_to(a) for a in allowed_reads)]
    assert not strays, strays
    assert (case / "tracks" / "leg.yaml") in reads and (case / "my_gnss.yaml") in reads

    (tmp_path / "secret.yaml").write_text(f"start: {{}}  # {SECRET}\n")
    (case / "tracks" / "link.yaml").symlink_to(tmp_path / "secret.yaml")
    (case / "linked.yaml").write_text(scenario(track="tracks/link.yaml"))
    proc, reads, writes = audited(tmp_path, "validate", case / "linked.yaml")
    assert proc.returncode == 2 and "leaves the scenario's folder" in proc.stderr, proc.stderr
    assert SECRET not in proc.stderr and not {tmp_path / "secret.yaml", case / "tracks" / "link.yaml"} & reads


def test_a_file_name_that_is_not_a_plain_name_gives_a_plain_default_name(tmp_path):
    from navsim.experiment.scenario import load_scenario
    path = tmp_path / "my copy (2).yaml"
    path.write_text(scenario(name=None))
    assert load_scenario(path).name == "my_copy__2_"


def test_a_sweep_point_without_a_successful_run_is_an_error(workdir, capsys, monkeypatch):
    import numpy as np

    import navsim.api
    import navsim.experiment.runner
    monkeypatch.setattr(navsim.api.runs, "run_monte_carlo", lambda *a, **k: navsim.experiment.runner.RunResult(
        {}, np.array([], int), failed={0: "RuntimeError: filter exploded", 1: "RuntimeError: filter exploded"}))
    (workdir / "case").mkdir()
    (workdir / "case" / S).write_text(scenario())
    (workdir / "case" / "w.yaml").write_text("scenario: s.yaml\ngrid: {montecarlo.seed: [1, 2]}\n")
    assert call(["sweep", "case/w.yaml", "--out", "out"]) == 1
    err = capsys.readouterr().err
    assert "no run of point 1/2 (montecarlo.seed=1) succeeded: RuntimeError: filter exploded" in err and "Traceback" not in err
    assert json.loads((workdir / "out" / "sweep.json").read_text())["failed_points"]
