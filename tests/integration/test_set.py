"""``--set PATH=VALUE`` on the commands and ``set=`` in the API: a change on the command line is
the same change made in a copied file, recorded where the run is; a misspelt path is refused
naming the ``--set`` and the closest path, nothing written."""

import json

import pytest
import yaml
from test_run import run, short, short_pdf  # noqa: F401 (fixtures)

import navsim
from navsim.cli import main

CHANGES = ["sensors.gps.override.position_sigma=4 m", "montecarlo.runs=3", "estimators[KF].period_s=0.5"]


def _changed_copy(short, tmp_path):
    data = yaml.safe_load(short.read_text())
    data["sensors"]["gps"]["override"] = {"position_sigma": "4 m"}
    data["montecarlo"]["runs"] = 3
    data["estimators"][1]["period_s"] = 0.5
    copy = tmp_path / "copied" / short.name
    copy.parent.mkdir()
    copy.write_text(yaml.safe_dump(data, sort_keys=False))
    return copy


def _without_wall_times(metrics: dict) -> dict:
    out = {k: v for k, v in metrics.items() if k != "wall_s"}
    out["estimators"] = {label: {k: v for k, v in m.items() if k != "cost"} for label, m in metrics["estimators"].items()}
    return out


def test_a_set_run_equals_the_same_change_made_in_a_copied_file(short_pdf, tmp_path):
    assert run(short_pdf, tmp_path / "set", *[a for c in CHANGES for a in ("--set", c)]) == 0
    assert run(_changed_copy(short_pdf, tmp_path), tmp_path / "copy") == 0
    by_set, by_copy = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in ("set", "copy"))
    assert by_set["runs"] == 3 and by_set["estimators"]["KF"]["rms"]["pos_m"]
    assert _without_wall_times(by_set) == _without_wall_times(by_copy)
    record = json.loads((tmp_path / "set" / "run.json").read_text())
    assert record["overrides"] == CHANGES and "overrides" not in json.loads((tmp_path / "copy" / "run.json").read_text())
    resolved = (tmp_path / "set" / "scenario.resolved.yaml").read_text()
    assert [ln for ln in resolved.splitlines() if ln.startswith("# --set ")] == [f"# --set {c}" for c in CHANGES]
    assert yaml.safe_load(resolved) == yaml.safe_load((tmp_path / "copy" / "scenario.resolved.yaml").read_text())


@pytest.mark.parametrize("change, words", [
    ("sensors.gps.overide.position_sigma=4 m", ["sensors.gps.overide", "is not a known key", "override"]),
    ("sensors.gsp.override.position_sigma=4 m", ["sensors.gsp", "the closest existing path: sensors.gps"]),
    ("estimators[KF].perod_s=0.5", ["estimators[1].perod_s", "period_s"]),
    ("estimators[K F].period_s=0.5", ["no entry labelled 'K F'", "KF"]),
    ("montecarlo.runs=many", ["montecarlo.runs", "many"]),
])
def test_a_misspelt_or_bad_set_exits_2_naming_it_and_the_closest_path(short, tmp_path, capsys, change, words):
    out = tmp_path / "out"
    assert run(short, out, "--set", change) == 2
    err = capsys.readouterr().err
    assert f"{short} (--set {change}): " in err and all(w in err for w in words), err
    assert "Traceback" not in err and not out.exists()
    assert main(["validate", str(short), "--set", change]) == 2


def test_the_api_takes_a_mapping_or_strings_and_fly_records_the_change(short, tmp_path):
    by_map = navsim.load_scenario(short, set={"montecarlo.runs": 3, "estimators[KF].period_s": 0.5,
                                              "track.segments[0].time_s": 10})
    by_text = navsim.load_scenario(short, set=["montecarlo.runs=3", "estimators[KF].period_s=0.5",
                                               "track.segments[0].time_s=10"])
    assert by_map.raw == by_text.raw and by_map.overrides == by_text.overrides
    assert by_map.runs == 3 and by_map.estimators[1].params["period_s"] == 0.5 and navsim.load_scenario(short).runs == 6
    with pytest.raises(navsim.api.UsageError, match="not a mapping of paths to values"):
        navsim.load_scenario(short, set=3)
    out = tmp_path / "fly"
    assert main(["fly", str(short), "--set", "track.segments[0].time_s=10", "--out", str(out)]) == 0
    assert yaml.safe_load((out / "scenario.yaml").read_text())["track"]["segments"][0]["time_s"] == 10
    record = json.loads((out / "run.json").read_text())
    assert record["overrides"] == ["track.segments[0].time_s=10"] and record["duration_s"] < 50


def test_sweep_takes_set_runs_and_seed(short, tmp_path):
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"scenario: {short.name}\nruns: 4\ngrid:\n  sensors.gps.override.position_sigma: [2 m, 8 m]\n"
                     "metric: rms.pos_m\n")
    out = tmp_path / "out"
    assert main(["sweep", str(sweep), "--runs", "2", "--seed", "9", "--set", "estimators[KF].period_s=0.5",
                 "--out", str(out)]) == 0
    points = json.loads((out / "sweep.json").read_text())["points"]
    assert [(p["metrics"]["runs_done"], p["metrics"]["seed"]) for p in points] == [(2, 9), (2, 9)]
    assert main(["sweep", str(sweep), "--set", "estimators[KF].perod_s=0.5", "--out", str(tmp_path / "bad")]) == 2
