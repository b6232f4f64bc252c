"""The memory and disk a run needs, estimated before anything is flown.

A flight records every truth sample (the raw JSBSim properties, then the truth's arrays); a
chunk of Monte Carlo runs records each estimator's history at its epochs; the chunks go to
disk. :func:`check_run`, :func:`check_flight` and :func:`check_sensors` refuse, with the figure and the limit, a run
that cannot fit, instead of a ``MemoryError`` after minutes of flying.
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navsim.experiment.runner import CHUNK_RUNS, CLOSED_CHUNK_RUNS
from navsim.flight import properties as P
from navsim.flight.track import nominal_duration_s
from navsim.flight.truth import ARRAY_FIELDS as TRUTH_ARRAYS, Truth
from navsim.foundations.config import MAX_RUNS
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.records.history import ARRAYS
from navsim.sensors import output_fields

#: the values of one truth sample: the widths of the truth's arrays (those of a one-sample record)
#: besides the raw properties recorded while flying
TRUTH_FLOATS = sum(int(np.prod(np.shape(getattr(Truth.static(0.0, 1.0), f))[1:])) for f in TRUTH_ARRAYS)
#: the share of the available memory a run may plan to use
MEMORY_SHARE = 0.8
_SIZES = {"axis": 3, "state": 9}


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
    duration = nominal_duration_s(scenario.flight.track) if duration_s is None else duration_s
    samples = duration * scenario.flight.rate_hz + 1
    return int(samples * (len(P.RAW_PROPERTIES) + TRUTH_FLOATS) * 8)


def _recorded_per_epoch() -> int:
    """The float64 values an estimator history records per run and epoch (its epoch arrays)."""
    n = 0
    for dims, _ in ARRAYS.values():
        if dims[:2] == ("run", "epoch"):
            n += math.prod(_SIZES.get(d, 1) for d in dims[2:])
    return n


def _chunk_size(scenario, chunk_runs: int | None) -> int:
    """The runs of one chunk: ``chunk_runs``, or the default of open or closed loop."""
    return chunk_runs or (CLOSED_CHUNK_RUNS if scenario.closed_loop is not None else CHUNK_RUNS)


def _duration_s(scenario) -> float:
    """The longest the scenario flies: its track, or a closed loop's time limit."""
    nominal = nominal_duration_s(scenario.flight.track)
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
    chunk = min(runs, _chunk_size(scenario, chunk_runs))
    busy = min(max(workers, 1), math.ceil(runs / chunk)) if workers > 1 else 0
    flight = flight_bytes(scenario, duration)
    return Needs(flight * (1 + busy), int(chunk * per_run) * max(busy, 1), int(runs * per_run))


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
                            f"({nominal_duration_s(scenario.flight.track):.6g} s at {scenario.flight.rate_hz:g} Hz), "
                            f"more than {MEMORY_SHARE:.0%} of the {_gib(have)} available",
                            file=scenario.path, key="track", expected="a shorter track or a lower flight.rate_hz")


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
    if out is None and n.flight + n.disk > MEMORY_SHARE * have:     # every run held in memory
        raise UsageError(f"the {runs} runs held in memory need about {_gib(n.disk)} beside the flight's "
                         f"{_gib(n.flight)}, more than {MEMORY_SHARE:.0%} of the {_gib(have)} available; "
                         "write them to a folder (out=...), where they stream chunk by chunk, or run fewer")
    if n.flight + n.chunk > MEMORY_SHARE * have:
        raise UsageError(f"the chunks in work ({min(runs, _chunk_size(scenario, chunk_runs))} runs each, on {workers} "
                         f"worker(s)) need about {_gib(n.chunk)} of memory beside the flights' {_gib(n.flight)}, "
                         f"more than {MEMORY_SHARE:.0%} of the {_gib(have)} available; use a smaller --chunk-runs "
                         "or fewer --workers")
    free = _free_disk(out) if out is not None else None
    if free is not None and n.disk > free:
        raise UsageError(f"the {runs} runs' chunks need about {_gib(n.disk)} on disk, more than the "
                         f"{_gib(free)} free under {out}; use fewer --runs or write elsewhere with --out")


def sensor_bytes(scenario, runs: int) -> int:
    """The memory of ``runs`` runs of every sensor of the scenario, emulated at once (``navsim
    sensors``): samples x (outputs + validity) x 8 per run."""
    duration = nominal_duration_s(scenario.flight.track)
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
