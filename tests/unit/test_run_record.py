"""``run.json`` as a typed record (:class:`navsim.records.run.RunRecord`): the keys and their order
as navsim has always written them, optional keys only when set, a JSON round trip back to the
same record, and the files of older or newer navsim versions read without losing a key."""

import json
import math

import pytest

from navsim.experiment import runner
from navsim.experiment.scenario import load_scenario
from navsim.foundations.outputs import strict_json
from navsim.records.run import RunRecord

#: run.json's keys, in order, of a run streamed to a chunk store (as written before the record was typed)
STREAMED_KEYS = ["scenario", "runs", "runs_done", "seed", "workers", "flight_cached", "flight_key", "data_key", "executor",
                 "scheduler", "resumed", "chunk_runs", "failed_chunks", "per_run_data", "failed_runs",
                 "interrupted", "wall_s", "versions", "git_revision", "utc", "command", "platform", "runs_plotted"]


def streamed() -> RunRecord:
    return RunRecord(scenario="s.yaml", runs=6, runs_done=4, seed=3, workers=2, flight_cached=True,
                     flight_key="k", executor="dask", scheduler="tcp://h:1", resumed=True, chunk_runs=2,
                     failed_chunks={"2-3": "worker killed"}, per_run_data="chunks/",
                     failed_runs={2: "worker killed", 3: "worker killed"}, interrupted=False, wall_s=math.nan,
                     versions={"navsim": "0"}, git_revision=None, utc="2026-12-02T00:00:00+00:00",
                     command="navsim run", platform="Linux", runs_plotted=2)


def test_keys_in_run_json_order_and_optional_ones_only_when_set():
    assert list(streamed().to_dict()) == STREAMED_KEYS
    closed_loop = RunRecord(runs=2, runs_done=2, runs_plotted=2)
    assert list(closed_loop.to_dict()) == [k for k in STREAMED_KEYS
                                           if k not in ("chunk_runs", "failed_chunks", "per_run_data")]


def test_json_round_trip_gives_the_same_record():
    back = RunRecord.from_dict(json.loads(strict_json(streamed().to_dict())))
    assert math.isnan(back.wall_s) and set(back.failed_runs) == {2, 3}       # NaN written as null
    assert back.to_dict().keys() == streamed().to_dict().keys()
    assert {k: v for k, v in back.to_dict().items() if k != "wall_s"} == \
        {k: v for k, v in streamed().to_dict().items() if k != "wall_s"}


def test_an_older_file_reads_and_keeps_its_unknown_keys():
    old = {"scenario": "s.yaml", "runs": 3, "runs_done": 3, "seed": 1, "workers": 1, "wall_s": 2.5,
           "note": "from a newer navsim"}                    # no runs_plotted, no provenance
    record = RunRecord.from_dict(old)
    assert record.plotted == 3 and record.failed_runs == {} and record.versions == {}
    assert record.to_dict()["note"] == "from a newer navsim" and record.to_dict()["wall_s"] == 2.5


@pytest.mark.parametrize("raw", [[], "run", None])
def test_not_a_mapping_is_refused(raw):
    with pytest.raises(TypeError, match="not a mapping"):
        RunRecord.from_dict(raw)


def test_results_of_other_random_streams_are_not_the_same_data(repo_root, monkeypatch):
    """A result or chunk store made with the former random streams (one per sensor) is not
    paired run by run with one of the streams per error process, nor resumed by it: the data key
    and the scenario hash name the streams' version."""
    scenario = load_scenario(repo_root / "scenarios" / "p3_sins_gps.yaml")
    now = runner.data_key(scenario, 1), runner.scenario_hash(scenario)
    monkeypatch.setattr(runner, "RANDOM_STREAMS", runner.RANDOM_STREAMS - 1)
    before = runner.data_key(scenario, 1), runner.scenario_hash(scenario)
    assert now[0] != before[0] and now[1] != before[1]
