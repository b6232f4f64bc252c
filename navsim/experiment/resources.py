"""The memory and disk a run needs, estimated before anything is flown.

A flight records every truth sample (the raw JSBSim properties, then the truth's arrays); a
chunk of Monte Carlo runs records each estimator's history at its epochs; the chunks go to
disk. :func:`check_run`, :func:`check_flight` and :func:`check_sensors` refuse, with the figure and the limit, a run
that cannot fit, instead of a ``MemoryError`` after minutes of flying.
"""

from __future__ import annotations

import logging
import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navsim.experiment.runner import CLOSED_CHUNK_RUNS, default_chunk_runs
from navsim.flight import properties as P
from navsim.flight.truth import ARRAY_FIELDS as TRUTH_ARRAYS, Truth
from navsim.foundations.config import MAX_RUNS
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.records.history import ARRAYS, EPOCH_ARRAYS, RECORD_DTYPES
from navsim.records.truth import TruthBias
from navsim.sensors import output_fields

#: the values of one truth sample: the widths of the truth's arrays (those of a one-sample record)
#: besides the raw properties recorded while flying
TRUTH_FLOATS = sum(int(np.prod(np.shape(getattr(Truth.static(0.0, 1.0), f))[1:])) for f in TRUTH_ARRAYS)
#: the share of the available memory a run may plan to use
MEMORY_SHARE = 0.8
_SIZES = {"axis": 3, "state": 9}
#: CPU seconds of a run per second flown and per estimator (the workers share them), and of
#: scoring it (the parent alone): P0's 1000 runs (two estimators over 500 s) on 2 workers, the
#: runs 6.6 s and scoring the stored chunks 1.6 s (``python benchmarks/run_speed.py``,
#: docs/performance.md)
RUN_CPU_S_PER_ESTIMATOR_S = 1.32e-5
SCORE_S_PER_ESTIMATOR_S = 1.6e-6
#: CPU seconds of a closed-loop run per second of its time limit: each run flies its own
#: flight with the navigation in the loop (P1's return to land, time limit 1400 s: 100 runs in
#: 154.4 s on 2 workers, docs/performance.md)
CLOSED_LOOP_CPU_S_PER_S = 2.2e-3
#: what an estimator without measurements (a free inertial solution) records: its errors
ERRORS_RECORDED = ("att_err_rad", "vel_err_mps", "pos_err_m", "euler_err_rad")
#: a chunk file's bytes besides its runs' (numpy's ``.npz``, measured on P0's chunks and on a
#: two-estimator test scenario's): per array entry (the zip's headers and the array's), the
#: file's JSON entries (UTF-32) and per estimator their description
CHUNK_FILE_BYTES = {"entry": 260, "file": 1600, "estimator": 1200}

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Needs:
    """Bytes a run needs: its flight in memory, one chunk in memory, all chunks on disk (or in
    memory, for a run without an output folder)."""

    flight: int
    chunk: int
    disk: int


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def available_memory() -> int:
    """Bytes of memory a run may count on: the free physical pages, at least half of the
    physical memory (the caches the system gives back); unknown: no limit."""
    try:
        page = os.sysconf("SC_PAGE_SIZE")
        return max(os.sysconf("SC_AVPHYS_PAGES") * page, os.sysconf("SC_PHYS_PAGES") * page // 2)
    except (ValueError, OSError, AttributeError):
        return 2**63


def flight_bytes(scenario, duration_s: float | None = None) -> int:
    """The memory of the scenario's flight: truth samples x (raw properties + truth arrays) x 8."""
    duration = scenario.nominal_duration_s if duration_s is None else duration_s
    samples = duration * scenario.flight.rate_hz + 1
    return int(samples * (len(P.RAW_PROPERTIES) + TRUTH_FLOATS) * 8)


def _recorded_per_epoch() -> int:
    """The float64 values an estimator history records per run and epoch (its epoch arrays)."""
    n = 0
    for dims, _ in ARRAYS.values():
        if dims[:2] == ("run", "epoch"):
            n += math.prod(_SIZES.get(d, 1) for d in dims[2:])
    return n


def _chunk_size(scenario, chunk_runs: int | None, runs: int, workers: int) -> int:
    """The runs of one chunk: ``chunk_runs``, or the default of open
    (:func:`~navsim.experiment.runner.default_chunk_runs`) or closed loop."""
    return chunk_runs or (CLOSED_CHUNK_RUNS if scenario.closed_loop is not None else default_chunk_runs(runs, workers))


def _duration_s(scenario) -> float:
    """The longest the scenario flies: its track, or a closed loop's time limit."""
    nominal = scenario.nominal_duration_s
    return max(nominal, scenario.closed_loop.time_limit_s) if scenario.closed_loop is not None else nominal


def needs(scenario, runs: int, chunk_runs: int | None = None, workers: int = 1) -> Needs:
    """The bytes a run of ``runs`` (in chunks of ``chunk_runs``, on ``workers`` processes) needs:
    in memory, the parent's flight and each busy worker's flight and chunk."""
    duration = _duration_s(scenario)
    per_run = 0.0
    for est in scenario.estimators:
        period = est.params.get("period_s") or 1.0 / scenario.flight.rate_hz
        nis = len(est.params.get("measurements", ()))
        per_run += (duration / period + 1) * (_recorded_per_epoch() + nis) * 8
    chunk = min(runs, _chunk_size(scenario, chunk_runs, runs, workers))
    busy = min(max(workers, 1), math.ceil(runs / chunk)) if workers > 1 else 0
    flight = flight_bytes(scenario, duration)
    return Needs(flight * (1 + busy), int(chunk * per_run) * max(busy, 1), int(runs * per_run))


def _epochs(scenario, est, duration_s: float) -> float:
    """The epochs an estimator records per run: one per ``period_s`` (default the flight's rate)."""
    return duration_s / (est.params.get("period_s") or 1.0 / scenario.flight.rate_hz) + 1


def _recorded(est) -> tuple:
    """The epoch arrays an estimator records, and its NIS streams (its measurements)."""
    nis = est.params.get("measurements") or ()
    return (EPOCH_ARRAYS if nis else ERRORS_RECORDED), len(nis)


def store_bytes_per_run(scenario) -> int:
    """The bytes one run adds to the chunk store (``chunks/``): each estimator's epoch arrays
    in the precision the driver records them in (:data:`~navsim.records.history.RECORD_DTYPES`;
    every array for an estimator with measurements, :data:`ERRORS_RECORDED` for one without) and
    its NIS, and the IMU's true biases at the first estimator's epochs."""
    if not scenario.estimators:
        return 0
    duration = _duration_s(scenario)
    width = lambda name: math.prod(_SIZES.get(d, 1) for d in ARRAYS[name][0][2:])
    total = 0.0
    for est in scenario.estimators:
        names, nis = _recorded(est)
        per_epoch = sum(width(n) * np.dtype(RECORD_DTYPES[n]).itemsize for n in names) + 8 * nis
        total += _epochs(scenario, est, duration) * per_epoch
    bias = len(TruthBias.__dataclass_fields__) * _SIZES["axis"] * 8
    return int(total + _epochs(scenario, scenario.estimators[0], duration) * bias)


def store_bytes(scenario, runs: int, chunk_runs: int | None = None, workers: int = 1) -> int:
    """The bytes of the chunk store of ``runs`` runs in chunks of ``chunk_runs`` (by default
    those of ``workers``): the runs'
    (:func:`store_bytes_per_run`) and each chunk file's own (:data:`CHUNK_FILE_BYTES`: its
    entries, its JSON description, the estimators' epoch times)."""
    duration = _duration_s(scenario)
    entries = 3 + len(TruthBias.__dataclass_fields__)          # runs, meta, ident, the biases
    own = CHUNK_FILE_BYTES["file"]
    for est in scenario.estimators:
        names, nis = _recorded(est)
        entries += 2 + len(names) + nis                          # t_s, diverged, the arrays, the NIS
        own += CHUNK_FILE_BYTES["estimator"] + 8 * _epochs(scenario, est, duration)
    chunks = math.ceil(runs / _chunk_size(scenario, chunk_runs, runs, workers))
    return runs * store_bytes_per_run(scenario) + chunks * int(own + entries * CHUNK_FILE_BYTES["entry"])


def run_seconds(scenario, runs: int, workers: int) -> float:
    """The seconds ``runs`` runs and their scoring take on ``workers`` processes, at the
    declared per-run costs (:data:`RUN_CPU_S_PER_ESTIMATOR_S`, :data:`SCORE_S_PER_ESTIMATOR_S`;
    a closed loop's flights at :data:`CLOSED_LOOP_CPU_S_PER_S`)."""
    duration_s = _duration_s(scenario)
    size = runs * duration_s * len(scenario.estimators)
    flights = runs * duration_s * CLOSED_LOOP_CPU_S_PER_S if scenario.closed_loop is not None else 0.0
    return (size * RUN_CPU_S_PER_ESTIMATOR_S + flights) / max(workers, 1) + size * SCORE_S_PER_ESTIMATOR_S


def _number(v: float) -> str:
    return f"{v:.2g}" if v < 100 else f"{v:.0f}"


def _clock(seconds: float) -> str:
    """``seconds`` as a reader counts them: s, min or h."""
    if seconds < 1:
        return "under 1 s"
    if seconds < 60:
        return f"{_number(seconds)} s"
    return f"{_number(seconds / 60)} min" if seconds < 3600 else f"{_number(seconds / 3600)} h"


def _bytes(n: float) -> str:
    for unit, size in (("GiB", 2**30), ("MiB", 2**20)):
        if n >= size:
            return f"{_number(n / size)} {unit}"
    return f"{_number(n / 2**10)} KiB"


def estimate_line(scenario, runs: int, out=None, workers: int | None = None, chunk_runs: int | None = None) -> str:
    """One line: the runs, the disk their chunks (of ``chunk_runs``) need under ``out`` (and what
    is free there; none without ``out``) and the time of the runs on ``workers`` (default the
    scenario's)."""
    workers = scenario.workers if workers is None else workers
    disk = ""
    if out is not None:
        free = _free_disk(out)
        disk = (f", about {_bytes(store_bytes(scenario, runs, chunk_runs, workers))} of chunks under {out} "
                f"({'free space unknown' if free is None else _bytes(free) + ' free'})")
    return (f"estimate: {runs} runs{disk}, the runs about {_clock(run_seconds(scenario, runs, workers))} "
            f"on {workers} worker{'s' if workers != 1 else ''}")


def _free_disk(out) -> int | None:
    """Free bytes where ``out`` is (its nearest existing folder), None if unknown."""
    path = Path(out).resolve()
    while not path.exists() and path != path.parent:
        path = path.parent
    try:
        usage = shutil.disk_usage(path)
    except OSError:
        return None
    return usage.free if usage.total else None      # a pseudo file system (/proc): the OS answers


def check_flight(scenario) -> None:
    """Refuse (:class:`ScenarioError`, exit 2) a flight whose truth cannot fit in memory."""
    need, have = flight_bytes(scenario), available_memory()
    if need > MEMORY_SHARE * have:
        raise ScenarioError(f"the flight needs about {_gib(need)} of memory for its truth "
                            f"({scenario.nominal_duration_s:.6g} s at {scenario.flight.rate_hz:g} Hz), "
                            f"more than {MEMORY_SHARE:.0%} of the {_gib(have)} available",
                            file=scenario.path, key="track", expected="a shorter track or a lower flight.rate_hz")


#: what to do about runs held in memory that do not fit, for each caller that holds them so:
#: ``navsim.run`` without ``out``, each Monte Carlo of ``navsim budget``, each point of ``navsim sweep``
HELD_HINTS = {"run": "write them to a folder (out=...), where they stream chunk by chunk, or run fewer",
              "budget": "a budget holds each Monte Carlo's runs in memory: use fewer --runs",
              "sweep": "a sweep holds each point's runs in memory: give the sweep file fewer 'runs'"}


def check_held(scenario, runs: int, chunk_runs: int | None = None, workers: int | None = None,
               held: str = "run") -> None:
    """Refuse (:class:`UsageError`) ``runs`` runs held in memory (no output folder) that do not
    fit, with the hint of the caller ``held`` (a key of :data:`HELD_HINTS`)."""
    workers = scenario.workers if workers is None else workers
    n, have = needs(scenario, runs, chunk_runs, workers), available_memory()
    if n.flight + n.disk > MEMORY_SHARE * have:
        raise UsageError(f"the {runs} runs held in memory need about {_gib(n.disk)} beside the flight's "
                         f"{_gib(n.flight)}, more than {MEMORY_SHARE:.0%} of the {_gib(have)} available; "
                         + HELD_HINTS[held])


def check_run(scenario, runs: int, chunk_runs: int | None = None, out=None, workers: int | None = None) -> None:
    """Refuse a Monte Carlo run that cannot be served before anything is flown: a scenario
    without estimators, more than :data:`~navsim.foundations.config.MAX_RUNS` runs, a flight or
    the chunks in work (one per worker, ``workers`` default the scenario's) too large for the
    memory available, chunks too large for the disk under ``out``."""
    if not scenario.estimators:
        raise ScenarioError("has no estimators to run", file=scenario.path, key="estimators",
                            expected="a list of estimators", hint="'navsim fly' flies a track alone")
    if not 1 <= runs <= MAX_RUNS:
        raise UsageError(f"{runs} runs: expected 1 to {MAX_RUNS}")
    check_flight(scenario)
    workers = scenario.workers if workers is None else workers
    n, have = needs(scenario, runs, chunk_runs, workers), available_memory()
    if out is None:                        # every run held in memory
        check_held(scenario, runs, chunk_runs, workers)
    if n.flight + n.chunk > MEMORY_SHARE * have:
        raise UsageError(f"the chunks in work ({min(runs, _chunk_size(scenario, chunk_runs, runs, workers))} runs each, on {workers} "
                         f"worker(s)) need about {_gib(n.chunk)} of memory beside the flights' {_gib(n.flight)}, "
                         f"more than {MEMORY_SHARE:.0%} of the {_gib(have)} available; use a smaller --chunk-runs "
                         "or fewer --workers")
    free = _free_disk(out) if out is not None else None
    disk = store_bytes(scenario, runs, chunk_runs, workers)
    if free is not None and disk > free:
        raise UsageError(f"the {runs} runs' chunks need about {_gib(disk)} on disk, more than the "
                         f"{_gib(free)} free under {out}; use fewer --runs or write elsewhere with --out")
    log.info(estimate_line(scenario, runs, out, workers, chunk_runs))


def sensor_bytes(scenario, runs: int) -> int:
    """The memory of ``runs`` runs of every sensor of the scenario, emulated at once (``navsim
    sensors``): samples x (outputs + validity) x 8 per run."""
    duration = scenario.nominal_duration_s
    per_run = sum((duration * min(c.spec.rate_hz, scenario.flight.rate_hz) + 1) * (3 * len(output_fields(c.spec)) + 1)
                  for c in scenario.sensors)
    return int(runs * per_run * 8)


def check_sensors(scenario, runs: int) -> None:
    """Refuse (:class:`UsageError`) ``navsim sensors`` runs whose emulated samples, with the
    flight, cannot fit in memory."""
    check_flight(scenario)
    need, have = sensor_bytes(scenario, runs) + flight_bytes(scenario), available_memory()
    if need > MEMORY_SHARE * have:
        raise UsageError(f"{runs} runs of the sensors need about {_gib(need)} of memory with the flight, more "
                         f"than {MEMORY_SHARE:.0%} of the {_gib(have)} available; use fewer --runs")
