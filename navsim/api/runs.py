"""The verb *run*: :func:`run` flies a scenario's track (cached), emulates its sensors, runs
every estimator over the Monte Carlo runs (:func:`~navsim.experiment.runner.run_monte_carlo`, or
:func:`~navsim.experiment.runner.run_closed_loop` with navigation in the loop) and scores them
into a :class:`~navsim.api.results.Result`, written to a folder or held in memory. How the runs
are made is one :class:`~navsim.experiment.options.RunOptions`, passed down to the runner.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from navsim.api.arguments import checked_path, load_scenario
from navsim.api.results import Result, write_run
from navsim.experiment import resources, runner
from navsim.experiment.chunkstore import ChunkStore
from navsim.experiment.executors import children_die_with_parent, lend_client
from navsim.experiment.options import RunOptions, check_flags
from navsim.experiment.runner import (
    cached_flight,
    chunk_ranges,
    flight_key,
    run_closed_loop,
    run_monte_carlo,
    scenario_hash,
)
from navsim.experiment.scenario import Scenario, check_scenario
from navsim.foundations.errors import UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.provenance import provenance
from navsim.records.chunk import ChunkPart
from navsim.records.metrics import RunMetrics
from navsim.records.run import RunRecord
from navsim.scoring.closed_loop import closed_loop_metrics
from navsim.scoring.scorer import score_run
from navsim.scoring.verdicts import judge
from navsim.sensors.camera import flight_sightings


def run(scenario, runs: int | None = None, seed: int | None = None, workers: int | None = None, *,
        out=None, force: bool = False, **options) -> Result:
    """Fly the scenario's track (cached), emulate its sensors and run every estimator over the
    Monte Carlo runs; score them.

    Parameters
    ----------
    scenario : Scenario, path or mapping
        What :func:`load_scenario` accepts.
    runs, seed, workers : int, optional
        Default: the scenario's ``montecarlo`` settings.
    out : path, optional
        Write the run there (chunks streamed as they finish, ``metrics.json``, ``run.json``,
        ``scenario.resolved.yaml``); None: nothing is written.
    force : bool
        Write into ``out`` even when it is a non-empty folder that is not navsim's (else a
        :class:`UsageError` naming its files). ``out`` is locked while the run writes it
        (another writer is refused, :class:`~navsim.foundations.outputs.OutputFolder`).
    **options
        How the runs are made, the other fields of
        :class:`~navsim.experiment.options.RunOptions` as keywords (``executor``,
        ``scheduler``, ``chunk_runs``, ``resume``, which needs ``out``, and ``progress``,
        called ``progress(runs_finished)`` as chunks complete), or ``options=RunOptions(...)``
        (whose ``runs``, ``seed`` and ``workers`` the explicit ones replace); and ``flight``:
        the scenario's flight already at hand, ``(truth, cached_path, from_cache)`` as
        :func:`navsim.experiment.runner.cached_flight` returns it (default: that call). An
        unknown keyword is a :class:`UsageError`.

    Returns
    -------
    Result
    """
    flight = options.pop("flight", None)
    how = RunOptions.of(runs, seed, workers, **options)
    check_flags(dict(force=force))
    out = None if out is None else checked_path("out", out, "output folder")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    how = how.for_scenario(scenario)
    resources.check_run(scenario, how.runs, how.chunk_runs, out, how.workers)   # estimators, memory, disk: before flying
    if how.resume and out is None:
        raise UsageError("resume needs the folder of the interrupted run (out=...)")
    if out is None:
        return _run(scenario, how, None, flight)
    with OutputFolder(Path(out), command="run", force=force) as folder:
        return _run(scenario, how, folder, flight)


def _run(scenario, how: RunOptions, folder, flight) -> Result:
    """:func:`run` once its arguments are read (``how`` filled from the scenario), into
    ``folder`` (held) or none, on ``flight`` (None: the cached flight)."""
    t0 = time.perf_counter()
    result = (_closed_loop(scenario, how, folder) if scenario.closed_loop is not None
              else _open_loop(scenario, how, folder, flight))
    result.record = dataclasses.replace(result.record, scenario=None if scenario.path is None else str(scenario.path),
                                        runs=how.runs, runs_done=int(len(result.runs)), seed=how.seed,
                                        workers=how.workers, data_key=runner.data_key(scenario, how.seed))
    score_result(result, time.perf_counter() - t0)
    if folder is not None:
        write_run(result, folder)
        result.folder = folder.path
    return result


def _closed_loop(scenario, how: RunOptions, folder) -> Result:
    if how.executor != "local" or how.resume:
        raise UsageError("closed-loop scenarios run on the local executor only, without --resume "
                         "(drop --executor dask and --resume)")
    if folder is not None:
        folder.clear_earlier()
    with children_die_with_parent():
        rr, loop, reference = run_closed_loop(scenario, how.runs, how.seed, how.workers, progress=how.progress)
    record = RunRecord(flight_cached=False, flight_key=flight_key(scenario.flight), executor=how.executor)
    return Result.from_run(scenario, rr, record, truth=reference.truth, loop=loop, reference=reference)


def _open_loop(scenario, how: RunOptions, folder, flight) -> Result:
    truth, truth_path, cached = flight if flight is not None else cached_flight(scenario.flight)
    check_scenario(scenario, truth.duration_s)     # the duration flown, before any sensor
    # the executor first: an unreachable scheduler must find the earlier run in the folder untouched
    early = how.executor == "dask" and folder is not None
    with lend_client(how.workers, how.scheduler) if early else children_die_with_parent():
        store = None
        if folder is not None:
            store = _open_store(folder.path, scenario, how)
            folder.clear_earlier()               # the earlier run's metrics, report, runs.npz
        size = store.key["chunk_runs"] if store is not None else (how.chunk_runs
                                                                   or runner.default_chunk_runs(how.runs, how.workers))
        rr = run_monte_carlo(scenario, truth, truth_path, dataclasses.replace(how, chunk_runs=size), store=store,
                             keep_runs=runner.REPORT_RUNS if store is not None else None)
    record = RunRecord(flight_cached=cached, flight_key=flight_key(scenario.flight), executor=how.executor,
                       scheduler=how.scheduler, resumed=bool(how.resume), chunk_runs=size)
    if store is not None:
        record = dataclasses.replace(record, failed_chunks=store.failed, per_run_data="chunks/")
    return Result.from_run(scenario, rr, record, truth=truth)


def _open_store(out: Path, scenario, how: RunOptions) -> ChunkStore:
    """The chunk store of a run in ``out/chunks``; resuming, the chunk size defaults to the
    stored run's."""
    folder = out / "chunks"
    chunk_runs = how.chunk_runs
    if chunk_runs is None:
        index = ChunkStore.read_index(folder) if how.resume else None
        chunk_runs = ((index or {}).get("chunk_runs")                        # typed by read_index
                      or runner.default_chunk_runs(how.runs, how.workers))
    chunk_ranges(how.runs, chunk_runs)              # a bad chunk size stops before anything is cleared
    key = {"scenario_hash": scenario_hash(scenario), "seed": how.seed, "runs": how.runs, "chunk_runs": chunk_runs}
    return ChunkStore(folder, key, mode="resume" if how.resume else "new")


def score_result(result: Result, wall_s: float) -> None:
    """``result.metrics`` and the rest of ``result.record``: scored chunk by chunk from the
    store when there is one (flat memory), else the histories in memory as one chunk."""
    sc = result.scenario
    result.sightings = flight_sightings(result.truth, sc.sensors) if result.truth is not None else []
    if result.store is not None:
        parts = result.store.parts
    else:
        held = ChunkPart(list(result.runs), result.histories, calibration=result.calibration)
        parts = lambda: iter([held] if result.histories else [])
    scores = score_run(parts, sc.settle_s, sc.windows, result.sightings)
    estimators, calibration, result.samples = scores.estimators, scores.calibration, scores.samples
    closed = None
    if sc.closed_loop is not None:
        closed = closed_loop_metrics(result.loop, result.reference, sc.closed_loop, result.histories)
    result.metrics = RunMetrics(sc.name, result.record.runs, int(len(result.runs)), result.record.seed,
                                {str(k): v for k, v in result.failed.items()}, result.interrupted, estimators,
                                calibration or None, closed, wall_s, judge(sc.reference, estimators, result.samples))
    plotted = len(result.runs) if result.history_runs is None else len(result.history_runs)
    result.record = dataclasses.replace(result.record, failed_runs=dict(result.failed), interrupted=result.interrupted,
                                        wall_s=wall_s, **provenance(), runs_plotted=plotted)
