"""The closed loop's per-run outcome is one typed :class:`LoopRuns` (its fields those of the same
names of :class:`LoopBatch`), joined over chunks in run order and scored by attribute."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from navsim.experiment.closed_loop import LoopBatch
from navsim.experiment.runner import LoopRuns
from navsim.scoring.closed_loop import closed_loop_metrics


def batch(B: int, E: int, offset: float):
    """A LoopBatch's per-run values for ``B`` runs on ``E`` path epochs, distinct per chunk."""
    f = lambda *shape: offset + np.arange(np.prod(shape), dtype=float).reshape(shape)
    return SimpleNamespace(outcome=["landed"] * (B - 1) + ["failed"], abort_t_s=f(B), land_t_s=f(B),
                           fail_t_s=f(B), end_t_s=f(B), miss_m=f(B), miss_est_m=f(B), landing_n_m=f(B, 2),
                           path_n_m=f(B, E, 3), path_t_s=np.arange(E, dtype=float))


def test_its_fields_are_the_loop_batch_ones_of_the_same_names_and_the_runs():
    names = [f.name for f in dataclasses.fields(LoopRuns)]
    batch_fields = {f.name for f in dataclasses.fields(LoopBatch)}
    assert [n for n in names if n not in batch_fields] == ["runs"]


def test_chunks_are_joined_in_run_order_and_the_paths_kept_once():
    a = LoopRuns.of_batch(batch(2, 4, 0.0), [0, 1])
    b = LoopRuns.of_batch(batch(3, 4, 100.0), [2, 3, 4])
    assert a.outcome.tolist() == ["landed", "failed"] and a.runs.tolist() == [0, 1]
    joined = LoopRuns.concatenate([a, b], a.path_t_s, np.arange(5))
    assert joined.outcome.tolist() == ["landed", "failed", "landed", "landed", "failed"]
    np.testing.assert_array_equal(joined.miss_m, [0.0, 1.0, 100.0, 101.0, 102.0])
    assert joined.landing_n_m.shape == (5, 2) and joined.path_n_m.shape == (5, 4, 3)
    np.testing.assert_array_equal(joined.path_t_s, np.arange(4.0))
    np.testing.assert_array_equal(joined.runs, np.arange(5))


def test_it_is_scored_by_attribute_and_no_finished_run_is_none():
    loop = LoopRuns.of_batch(batch(3, 2, 0.0), [0, 1, 2])
    rtl = SimpleNamespace(area_m=1.5)
    config = SimpleNamespace(fly_on="KF", time_limit_s=100.0, return_to_land=rtl)
    reference = SimpleNamespace(miss_m=np.array([0.2]), land_t_s=np.array([50.0]), outcome=["landed"])
    out = closed_loop_metrics(loop, reference, config)
    assert out["outcomes"] == {"failed": 1, "landed": 2}
    r = out["return_to_land"]
    assert r["landed"] == 3 and r["reached_area"] == 2 and r["abort_t_s"]["max"] == 2.0
    assert closed_loop_metrics(None, reference, config) == {"fly_on": "KF", "time_limit_s": 100.0}


@pytest.mark.parametrize("threaded", [True, False])
def test_the_truth_guided_flight_beside_the_runs_hands_over_its_result_or_its_error(monkeypatch, threaded):
    """The truth-guided flight flies in a thread while the workers fly the runs: its batch, or
    what it raised (a FlightError of the reference), reaches the caller as if flown first."""
    import threading

    from navsim.experiment import runner
    from navsim.foundations.errors import FlightError
    seen = []

    def fake_fly_batch(scenario, seed, runs, on_truth=False, keep_truth=False):
        seen.append((threading.current_thread().name, list(runs), on_truth, keep_truth))
        if scenario == "bad":
            raise FlightError("stall", time_s=3.0)
        return "batch"

    monkeypatch.setattr(runner, "fly_batch", fake_fly_batch)
    monkeypatch.setattr(runner, "end_records", lambda batch, dt: None)

    class Flight:
        rate_hz = 100.0

    class Good:
        flight = Flight()

    side = runner._TruthGuided(Good(), 3)
    if threaded:
        side.start()
    assert side.result() == "batch"
    assert seen == [("navsim-truth-guided" if threaded else threading.current_thread().name, [0], True, True)]
    bad = runner._TruthGuided("bad", 3)
    if threaded:
        bad.start()
    with pytest.raises(FlightError, match="stall"):
        bad.result()
