"""``navsim.Result`` carries every field of the runner's ``RunResult`` under its own name, copied
in one place (``Result.from_run``), not field by field in each of the API's paths."""

import dataclasses
from pathlib import Path

import numpy as np

import navsim
from navsim.experiment.runner import RunResult
from navsim.records.run import RunRecord

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "p3_sins_gps.yaml"


def test_every_run_result_field_is_a_result_field():
    result_fields = {f.name for f in dataclasses.fields(navsim.Result)}
    missing = [f.name for f in dataclasses.fields(RunResult) if f.name not in result_fields]
    assert not missing, f"navsim.Result lacks RunResult's {missing}"


def test_from_run_copies_every_run_result_field_and_takes_the_rest():
    scenario = navsim.load_scenario(SCENARIO)
    # a distinct object in every field, whatever the fields are
    values = {f.name: object() for f in dataclasses.fields(RunResult)}
    rr = RunResult(**values)
    truth, record = object(), RunRecord(seed=5)
    result = navsim.Result.from_run(scenario, rr, record, truth=truth, loop={"t_s": np.zeros(1)})
    assert all(getattr(result, name) is value for name, value in values.items())
    assert result.scenario is scenario and result.record is record and result.truth is truth
    assert result.metrics is None and result.folder is None and set(result.loop) == {"t_s"}
