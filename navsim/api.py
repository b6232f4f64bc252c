"""navsim's Python API: load a scenario, run its Monte Carlo, read a finished run back, write
its report. ``navsim run`` is this API with a progress bar and a summary table.

>>> import navsim
>>> scenario = navsim.load_scenario("scenarios/p0_bd_sins_ads.yaml")
>>> result = navsim.run(scenario, runs=20, workers=2)          # out=None: nothing is written
>>> result.metrics.estimators["BD/SINS/ADS ES-KF 16"].rms.pos_m   # typed (navsim.records.metrics)
>>> ds = result.to_xarray()                                    # run x epoch x axis, with units
>>> navsim.write_report(result, "reports/p0")                 # report.pdf, PNGs, metrics.json
>>> again = navsim.open_result("reports/p0")                   # read-only

A run written to a folder holds ``metrics.json`` (:attr:`Result.metrics`), ``run.json``
(:attr:`Result.record`: seed, runs, versions, git revision), ``scenario.resolved.yaml`` and
the per-run histories once: in ``chunks/``, or in ``runs.npz`` for a run held in memory and
written with :func:`write_report`.

Over 600 lines (run, result I/O, sweep, compare and budget in one file): issue 51 splits it into a package, one
module per verb, its long keyword chains into options objects.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import logging
import os
import time
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import yaml

from navsim.experiment import runner
from navsim.experiment.chunkstore import ChunkStore
from navsim.experiment.executors import children_die_with_parent, lend_client
from navsim.experiment.runner import (
    cached_flight,
    chunk_ranges,
    flight_key,
    run_closed_loop,
    run_monte_carlo,
    scenario_hash,
)
from navsim.experiment import resources
from navsim.experiment.budget import GROUPS as BUDGET_GROUPS, SCALE_RANGE, alone, budget_sources, find_source
from navsim.experiment.budget import check_method, covariance_contributions, left_out_reasons, linear_sources
from navsim.experiment.budget import scale_ok, scaled
from navsim.experiment.results import ResultFiles, check_comparable, check_not_being_written, pairing, read_files
from navsim.experiment.results import read_result
from navsim.experiment.scenario import MAX_SEED, MAX_WORKERS, Scenario, check_scenario, parse_scenario
from navsim.experiment.scenario import load_scenario as _load_file
from navsim.experiment.sweep import SweepResult, plan_sweep, point_values
from navsim.foundations.config import MAX_RUNS, Argument
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.provenance import provenance
from navsim.records.chunk import ChunkPart
from navsim.records.history import ARRAYS, ARRAY_FIELDS, EPOCH_ARRAYS, EstimatorHistory
from navsim.records.run import RunRecord
from navsim.records.samples import SAMPLES_FILE, EstimatorSamples, load_samples, save_samples
from navsim.records.states import SIGMA_STATES
from navsim.records.truth import CalibrationHistory, TruthBias
from navsim.report.budget import CSV_HEADERS as BUDGET_CSV_HEADERS, budget_csv_rows, budget_pages
from navsim.report.compare import CSV_HEADERS, compare_page, csv_rows
from navsim.report.figures import pyplot
from navsim.report.pages import report_pages as _report_pages, write_report as _write_report
from navsim.report.render import render
from navsim.scoring.budget import METHODS as BUDGET_METHODS, Budget, WhatIf, covariance_budgets, metric_budgets
from navsim.scoring.budget import epoch_mean_squares, monte_carlo_curves, predict, with_covariance
from navsim.scoring.closed_loop import closed_loop_metrics
from navsim.scoring.compare import DEFAULT_MARGIN_PCT, Comparison, Side, check_margin, check_margin_paths
from navsim.scoring.compare import compare_samples
from navsim.scoring.intervals import MIN_RUNS
from navsim.scoring.landmarks import sighting_spans
from navsim.records.metrics import RunMetrics
from navsim.scoring.samples import value_interval
from navsim.scoring.scorer import score_run
from navsim.scoring.verdicts import judge


@dataclass
class Result:
    """A finished (or interrupted) Monte Carlo run of one scenario.

    Attributes
    ----------
    scenario : Scenario
        The scenario as parsed.
    runs : (R,) int array
        The indices of the runs that completed.
    histories : dict
        Estimator label -> :class:`~navsim.records.history.EstimatorHistory` (``(R, E, ...)`` arrays;
        above :data:`navsim.experiment.runner.REPORT_RUNS` runs read from a folder, the first chunks only).
    metrics : RunMetrics
        The scores (:mod:`navsim.records.metrics`); ``metrics.to_dict()`` is ``metrics.json``.
    record : RunRecord
        How the run was made (seed, runs, workers, versions, git):
        :class:`~navsim.records.run.RunRecord`, ``record.to_dict()`` is ``run.json``.
    folder : Path or None
        Where it was written (None: held in memory only).
    truth_bias : TruthBias or None
        The IMU's true biases at the first estimator's epochs over the runs ``histories`` hold
        (:class:`~navsim.records.truth.TruthBias`); None: none recorded.
    calibration : dict
        Magnetometer name -> its online calibration over those runs
        (:class:`~navsim.records.truth.CalibrationHistory`); empty: none calibrated online.

    Every field of :class:`~navsim.experiment.runner.RunResult` (``runs``, ``histories``,
    ``failed``, ...) is one of its own, of the same name: :meth:`from_run` copies them all.
    """

    scenario: Scenario
    runs: np.ndarray
    histories: dict
    metrics: RunMetrics | None
    record: RunRecord
    folder: Path | None = None
    truth: object = None
    truth_bias: TruthBias | None = None
    calibration: dict[str, CalibrationHistory] = field(default_factory=dict)
    failed: dict = field(default_factory=dict)
    interrupted: bool = False
    loop: runner.LoopRuns | None = None
    reference: object = None
    sightings: list = field(default_factory=list)
    #: the chunk store every finished run is in (a run written to a folder), or None
    store: object = None
    #: the runs ``histories`` hold when fewer than ``runs`` (the first chunks); None: all
    history_runs: np.ndarray | None = None
    #: estimator label -> its runs' samples (:mod:`navsim.records.samples`, ``samples.npz``:
    #: what :func:`compare` pairs); empty until scored or read
    samples: dict[str, EstimatorSamples] = field(default_factory=dict)

    @classmethod
    def from_run(cls, scenario: Scenario, rr: runner.RunResult, record: RunRecord, **rest) -> "Result":
        """The (unscored) result of the runner's ``rr``: every field of
        :class:`~navsim.experiment.runner.RunResult`, by name, and ``rest`` (``truth``, ``loop``,
        ``reference``, ...)."""
        return cls(scenario=scenario, metrics=None, record=record,
                   **{f.name: getattr(rr, f.name) for f in fields(rr)}, **rest)

    def to_dict(self) -> dict:
        """The scores as ``metrics.json`` holds them."""
        return self.metrics.to_dict()

    def to_xarray(self, label: str | None = None):
        """The histories as an :class:`xarray.Dataset` with named dimensions ``run``, ``epoch``
        (coordinate ``t_s``), ``axis`` (N, E, D or x, y, z) and ``state``, units in each
        variable's attributes; savable with ``to_netcdf``.

        Every estimator's variables are named ``<field>`` with an ``estimator`` dimension when
        all estimators share their epochs; otherwise pass ``label`` for one estimator."""
        import xarray as xr  # heavy to import (pandas): only when asked
        hists = self._histories(label)
        t = {k: tuple(h.t_s) for k, h in hists.items()}
        if len(set(t.values())) > 1:
            raise UsageError(f"the estimators have different epochs ({', '.join(hists)}): "
                             "pass label= for one of them")
        first = next(iter(hists.values()))
        data = {}
        for name in EPOCH_ARRAYS:
            dims, unit = ARRAYS[name]
            arrays = [getattr(h, name) for h in hists.values()]
            if all(a is None for a in arrays):
                continue
            like = next(a for a in arrays if a is not None)       # NaN for an estimator without it
            arrays = [np.full(like.shape, np.nan) if a is None else a for a in arrays]
            data[name] = xr.Variable(("estimator", *dims), np.stack(arrays), attrs={"units": unit})
        runs = self.runs if self.history_runs is None else self.history_runs
        coords = {"estimator": list(hists), "run": np.asarray(runs),
                  "t_s": ("epoch", np.asarray(first.t_s), {"units": "s"}), "axis": ["N", "E", "D"],
                  "state": list(SIGMA_STATES)}
        ds = xr.Dataset(data, coords={k: v for k, v in coords.items()
                                      if k in ("estimator", "run", "t_s") or any(k in v.dims for v in data.values())})
        ds["diverged"] = (("estimator", "run"), np.stack([h.diverged for h in hists.values()]))
        if self.metrics is not None:
            ds = ds.assign(_metric_variables(self.metrics, list(hists))).assign_coords(
                axis=["N", "E", "D"], bound=["lo", "hi"])
        ds.attrs.update({"scenario": self.scenario.name, "seed": int(self.record.seed),
                         "navsim": str(self.record.versions.get("navsim", "")),
                         "git_revision": str(self.record.git_revision or "")})
        return ds

    def _histories(self, label: str | None) -> dict:
        """The histories :meth:`to_xarray` takes (``label``'s, or all); :class:`UsageError` for
        an unknown label, or a result without per-run histories (its ``chunks/`` or
        ``runs.npz`` gone)."""
        where = self.folder if self.folder is not None else f"result of '{self.scenario.name}'"
        if not self.histories:
            stored = self.record.per_run_data or "runs.npz"
            raise UsageError(f"{where}: no per-run histories to read (its {stored} is missing: removed, or the run "
                             "was not written there); hint: run the scenario again to have them, the metrics "
                             "are in result.metrics")
        if label is None:
            return self.histories
        if label not in self.histories:
            raise UsageError(f"{where}: no estimator {label!r}; it has: " + ", ".join(self.histories))
        return {label: self.histories[label]}


#: the per-axis metrics :meth:`Result.to_xarray` carries with their intervals
XARRAY_METRICS = tuple(f"{section}.{q}" for section in ("rms", "final", "p99") for q in ("pos_m", "vel_mps", "att_deg"))


def _metric_variables(metrics, labels) -> dict:
    """``rms_pos_m`` ``(estimator, axis)`` and ``rms_pos_m_ci95`` ``(estimator, axis, bound)``
    for each of :data:`XARRAY_METRICS` (NaN where an estimator has none)."""
    out = {}
    for path in XARRAY_METRICS:
        name, unit = path.replace(".", "_"), path.rsplit("_", 1)[1].replace("mps", "m/s")
        value = np.full((len(labels), 3), np.nan)
        ci = np.full((len(labels), 3, 2), np.nan)
        for i, label in enumerate(labels):
            m = metrics.estimators.get(label)
            if m is None or m.get(path) is None:
                continue
            value[i] = m.get(path)
            if m.interval(path) is not None:
                ci[i] = np.asarray(m.interval(path), float)
        out[name] = (("estimator", "axis"), value, {"units": unit, "metric": path})
        out[name + "_ci95"] = (("estimator", "axis", "bound"), ci,
                               {"units": unit, "metric": path, "description": "95 % interval, the runs as the samples"})
    return out


# --- the arguments: each declared once; navsim.cli reads its options with the same ------------------
RUNS = Argument("runs", int, minimum=1, maximum=MAX_RUNS)
SEED = Argument("seed", int, minimum=0, maximum=MAX_SEED)
WORKERS = Argument("workers", int, minimum=1, maximum=MAX_WORKERS)
CHUNK_RUNS = Argument("chunk_runs", int, minimum=1, maximum=MAX_RUNS)
#: where the chunks of runs go (``executor=``, ``--executor``)
EXECUTORS = ("local", "dask")
#: the Dask schemes a scheduler address may use
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "inproc", "ucx")


def _shown(value) -> str:
    """``value`` for a message, at most 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def check_scheduler(address, name: str = "scheduler") -> str:
    """``address`` if it is a Dask scheduler address, ``scheme://host:port`` or ``host:port``
    for TCP as Dask reads it; else a :class:`UsageError` (naming ``name``, when given)."""
    url = None
    if isinstance(address, str) and address:
        try:
            url = urllib.parse.urlsplit(address if "://" in address else f"tcp://{address}")
            port = url.port
        except ValueError:
            url = None
    if url is None or url.scheme not in SCHEDULER_SCHEMES or not url.hostname or (
            url.scheme != "inproc" and port is None):
        raise UsageError(f"{name + ': ' if name else ''}{_shown(address)} is not a scheduler address (expected "
                         f"scheme://host:port, scheme one of {', '.join(SCHEDULER_SCHEMES)}, e.g. tcp://10.0.0.5:8786)")
    return address


def _numbers(runs, seed, workers, chunk_runs=None) -> tuple:
    """The numbers of a call checked (:data:`RUNS`, :data:`SEED`, :data:`WORKERS`,
    :data:`CHUNK_RUNS`; None: the default)."""
    return tuple(None if v is None else a.check(v)
                 for a, v in ((RUNS, runs), (SEED, seed), (WORKERS, workers), (CHUNK_RUNS, chunk_runs)))


def _check_how(executor, scheduler, flags: dict, functions: dict) -> None:
    """:class:`UsageError` for an executor not in :data:`EXECUTORS`, a scheduler that is not
    an address, and as :func:`_check_flags`."""
    if not isinstance(executor, str) or executor not in EXECUTORS:
        raise UsageError(f"executor: {_shown(executor)} is not an executor (expected one of {', '.join(EXECUTORS)})")
    if scheduler is not None:
        check_scheduler(scheduler)
    _check_flags(flags, functions)


def _check_flags(flags: dict, functions: dict | None = None) -> None:
    """:class:`UsageError` for a flag (name -> value) that is not a bool, or a function
    (``progress=``) that is neither None nor callable."""
    for name, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):
            raise UsageError(f"{name}: {_shown(value)} is not true or false (expected a bool)")
    for name, value in (functions or {}).items():
        if value is not None and not callable(value):
            raise UsageError(f"{name}: {_shown(value)} is not callable (expected a function or None)")


def _path(name: str, value, what: str) -> Path:
    """``value`` as the path of a ``what``; :class:`UsageError` naming ``name`` for anything else."""
    text = os.fspath(value) if isinstance(value, (str, os.PathLike)) else None
    if not isinstance(text, str) or not text or "\0" in text:
        why = "has a NUL character" if isinstance(text, str) and text else "is not a path"
        raise UsageError(f"{name}: {_shown(value)} {why} (expected the {what}'s path: a non-empty str or "
                         "os.PathLike without NUL characters)")
    return Path(text)


def _scales(scales) -> list[tuple[str, float]]:
    """A budget's ``scales`` checked: ``(source, factor)`` pairs, each factor :data:`SCALE_RANGE`."""
    expected = f"expected a sequence of (source, factor) pairs, {SCALE_RANGE}"
    if isinstance(scales, (str, bytes, Mapping)) or not hasattr(scales, "__iter__"):
        raise UsageError(f"scales: {_shown(scales)}: {expected}")
    out = []
    for item in scales:
        ok = isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str) and item[0]
        number = ok and isinstance(item[1], (int, float, np.integer, np.floating)) and not isinstance(item[1], bool)
        if not (number and scale_ok(float(item[1]))):
            raise UsageError(f"scales: {_shown(item)}: {expected} (imu.gyro.noise_density, 0.5)")
        out.append((item[0], float(item[1])))
    return out


def _labels(estimators) -> list[str] | None:
    """:func:`compare`'s ``estimators``: None, one label or a sequence of one or two."""
    if estimators is None or isinstance(estimators, str):
        return None if estimators is None else [estimators]
    names = list(estimators) if isinstance(estimators, (list, tuple)) else None
    if names is None or not all(isinstance(x, str) for x in names) or len(names) > 2:
        raise UsageError(f"estimators: {_shown(estimators)}: expected one or two estimator labels (str)")
    return names


def _check_result(name: str, value) -> None:
    if not isinstance(value, Result):
        raise UsageError(f"{name}: {_shown(value)} is not a navsim Result (expected what navsim.run or "
                         "navsim.open_result returns)")


def load_scenario(source) -> Scenario:
    """A scenario from a YAML file (path) or from a mapping with the file's keys (relative
    paths then resolve from the working directory)."""
    if isinstance(source, Mapping):
        return parse_scenario(dict(source), None)
    return _load_file(_path("scenario", source, "scenario file"))


def run(scenario, runs: int | None = None, seed: int | None = None, workers: int | None = None, *,
        out=None, executor: str = "local", scheduler: str | None = None, chunk_runs: int | None = None,
        resume: bool = False, progress=None, flight=None, force: bool = False) -> Result:
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
    executor, scheduler, chunk_runs, resume
        As ``navsim run``'s options (``resume`` needs ``out``).
    progress : callable, optional
        ``progress(runs_finished)`` as chunks complete.
    flight : tuple, optional
        The scenario's flight already at hand, ``(truth, cached_path, from_cache)`` as
        :func:`navsim.experiment.runner.cached_flight` returns it (default: that call).
    force : bool
        Write into ``out`` even when it is a non-empty folder that is not navsim's (else a
        :class:`UsageError` naming its files). ``out`` is locked while the run writes it
        (another writer is refused, :class:`~navsim.foundations.outputs.OutputFolder`).

    Returns
    -------
    Result
    """
    runs, seed, workers, chunk_runs = _numbers(runs, seed, workers, chunk_runs)
    _check_how(executor, scheduler, dict(resume=resume, force=force), dict(progress=progress))
    out = None if out is None else _path("out", out, "output folder")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    runs = scenario.runs if runs is None else runs
    resources.check_run(scenario, runs, chunk_runs, out, workers)   # estimators, memory, disk: before flying
    seed = scenario.seed if seed is None else seed
    workers = scenario.workers if workers is None else workers
    if resume and out is None:
        raise UsageError("resume needs the folder of the interrupted run (out=...)")
    how = _How(runs, seed, workers, executor, scheduler, chunk_runs, resume, progress, flight)
    if out is None:
        return _run(scenario, how, None)
    with OutputFolder(Path(out), command="run", force=force) as folder:
        return _run(scenario, how, folder)


def _run(scenario, how: "_How", folder) -> Result:
    """:func:`run` once its arguments are read, into ``folder`` (held) or none."""
    runs, seed, workers = how.runs, how.seed, how.workers
    t0 = time.perf_counter()
    result = (_closed_loop if scenario.closed_loop is not None else _open_loop)(scenario, how, folder)
    result.record = dataclasses.replace(result.record, scenario=None if scenario.path is None else str(scenario.path),
                                        runs=runs, runs_done=int(len(result.runs)), seed=seed, workers=workers,
                                        data_key=runner.data_key(scenario, seed))
    _score(result, time.perf_counter() - t0)
    if folder is not None:
        _write_run(result, folder)
        result.folder = folder.path
    return result


@dataclass(frozen=True)
class _How:
    """How :func:`run` runs a scenario (its arguments but the scenario and the folder)."""

    runs: int
    seed: int
    workers: int
    executor: str
    scheduler: str | None
    chunk_runs: int | None
    resume: bool
    progress: object
    flight: tuple | None = None


def _closed_loop(scenario, how: _How, folder) -> Result:
    if how.executor != "local" or how.resume:
        raise UsageError("closed-loop scenarios run on the local executor only, without --resume "
                         "(drop --executor dask and --resume)")
    if folder is not None:
        folder.clear_earlier()
    with children_die_with_parent():
        rr, loop, reference = run_closed_loop(scenario, how.runs, how.seed, how.workers, progress=how.progress)
    record = RunRecord(flight_cached=False, flight_key=flight_key(scenario.flight), executor=how.executor)
    return Result.from_run(scenario, rr, record, truth=reference.truth, loop=loop, reference=reference)


def _open_loop(scenario, how: _How, folder) -> Result:
    truth, truth_path, cached = how.flight if how.flight is not None else cached_flight(scenario.flight)
    check_scenario(scenario, truth.duration_s)     # the duration flown, before any sensor
    # the executor first: an unreachable scheduler must find the earlier run in the folder untouched
    early = how.executor == "dask" and folder is not None
    with lend_client(how.workers, how.scheduler) if early else children_die_with_parent():
        store = None
        if folder is not None:
            store = _open_store(folder.path, scenario, how)
            folder.clear_earlier()               # the earlier run's metrics, report, runs.npz
        size = store.key["chunk_runs"] if store is not None else (how.chunk_runs or runner.CHUNK_RUNS)
        rr = run_monte_carlo(scenario, truth, truth_path, how.runs, how.seed, how.workers, progress=how.progress,
                             chunk_runs=size, store=store, executor=how.executor, scheduler=how.scheduler,
                             keep_runs=runner.REPORT_RUNS if store is not None else None)
    record = RunRecord(flight_cached=cached, flight_key=flight_key(scenario.flight), executor=how.executor,
                       scheduler=how.scheduler, resumed=bool(how.resume), chunk_runs=size)
    if store is not None:
        record = dataclasses.replace(record, failed_chunks=store.failed, per_run_data="chunks/")
    return Result.from_run(scenario, rr, record, truth=truth)


def _open_store(out: Path, scenario, how: _How) -> ChunkStore:
    """The chunk store of a run in ``out/chunks``; resuming, the chunk size defaults to the
    stored run's."""
    folder = out / "chunks"
    chunk_runs = how.chunk_runs
    if chunk_runs is None:
        index = ChunkStore.read_index(folder) if how.resume else None
        chunk_runs = (index or {}).get("chunk_runs") or runner.CHUNK_RUNS    # typed by read_index
    chunk_ranges(how.runs, chunk_runs)              # a bad chunk size stops before anything is cleared
    key = {"scenario_hash": scenario_hash(scenario), "seed": how.seed, "runs": how.runs, "chunk_runs": chunk_runs}
    return ChunkStore(folder, key, mode="resume" if how.resume else "new")


def _score(result: Result, wall_s: float) -> None:
    """``result.metrics`` and the rest of ``result.record``: scored chunk by chunk from the
    store when there is one (flat memory), else the histories in memory as one chunk."""
    sc = result.scenario
    result.sightings = sighting_spans(result.truth, sc) if result.truth is not None else []
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
                                calibration or None, closed, wall_s, judge(sc.reference, estimators))
    plotted = len(result.runs) if result.history_runs is None else len(result.history_runs)
    result.record = dataclasses.replace(result.record, failed_runs=dict(result.failed), interrupted=result.interrupted,
                                        wall_s=wall_s, **provenance(), runs_plotted=plotted)


def _write_run(result: Result, folder: OutputFolder, record: RunRecord | None = None) -> None:
    """``metrics.json``, ``scenario.resolved.yaml``, ``run.json`` (``record``, default the
    result's) and, for a run without a chunk store whose every history is in memory, ``runs.npz``
    into ``folder``: per-run data is kept once, in ``chunks/`` or there."""
    record = result.record if record is None else record
    folder.json("metrics.json", result.metrics.to_dict())
    folder.text("scenario.resolved.yaml",
                f"# resolved by navsim {result.record.versions['navsim']} at git {result.record.git_revision}\n"
                + yaml.safe_dump(resolved_scenario(result), sort_keys=False))
    folder.json("run.json", record.to_dict())
    if result.samples:
        folder.write(SAMPLES_FILE, lambda p: save_samples(p, result.samples))
    if result.store is None and result.histories and result.record.plotted == len(result.runs):
        arrays = {"runs": result.runs, NPZ_KEYS: np.array(NPZ_KEYS_VERSION)}
        for label, h in result.histories.items():
            key = npz_key(label)
            arrays.update({f"{key}.{name}": getattr(h, name) for name in ARRAY_FIELDS
                           if getattr(h, name) is not None})
        if result.loop is not None:
            arrays.update({f"closed_loop.{f.name}": np.asarray(getattr(result.loop, f.name))
                           for f in fields(result.loop)})
        # uncompressed: deflate saved 8 % of 1000 P0 runs (160 MB) and cost 7.6 of the 30 s
        folder.write("runs.npz", lambda p: np.savez(p, **arrays))


#: the entry of a ``runs.npz`` naming how its keys are made (absent: the older, clashing keys)
NPZ_KEYS, NPZ_KEYS_VERSION = "npz_keys", "percent-1"
_NPZ_SAFE = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


def npz_key(label: str) -> str:
    """An estimator label as the prefix of its arrays in ``runs.npz``: every character outside
    ``[A-Za-z0-9_-]`` percent-encoded (its UTF-8 bytes), so two labels never share a key."""
    return "".join(c if c in _NPZ_SAFE else "".join(f"%{b:02X}" for b in c.encode()) for c in label)


def _old_npz_key(label: str) -> str:
    """The key of runs.npz written before :data:`NPZ_KEYS` (``"a b"`` and ``"a_b"`` clash)."""
    return label.replace(" ", "_").replace("/", "-")


def _npz_histories(path: Path, labels) -> tuple:
    """``(runs, histories)`` from a ``runs.npz`` (the NIS are not stored there); an older file
    is read with its keys, and labels that clash there get no history (with a warning)."""
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    key = npz_key if NPZ_KEYS in arrays else _old_npz_key
    labels = list(labels)
    keys = [key(label) for label in labels]
    hist = {}
    for label, k in zip(labels, keys):
        if keys.count(k) > 1:
            logging.getLogger(__name__).warning("%s: estimators %s share the key %r in this older file; "
                                                "%r is not read", path, [la for la, o in zip(labels, keys) if o == k],
                                                k, label)
            continue
        got = {name: arrays.get(f"{k}.{name}") for name in ARRAY_FIELDS}
        if got["t_s"] is not None:
            hist[label] = EstimatorHistory(label=label, nis={}, nis_dim={}, **got)
    return np.asarray(arrays.get("runs", []), int), hist


def resolved_scenario(result: Result) -> dict:
    """The scenario's mapping with the ``montecarlo`` settings the run used."""
    resolved = dict(result.scenario.raw)
    resolved["montecarlo"] = {**(resolved.get("montecarlo") or {}), **result.record.montecarlo()}
    return resolved


def write_report(result: Result, out=None, *, force: bool = False) -> list[Path]:
    """``report.pdf`` and its PNGs for ``result``; also writes the run's ``metrics.json``,
    ``run.json`` and ``scenario.resolved.yaml`` there when it is another folder than the run's.

    Parameters
    ----------
    result : Result
        A run (:func:`run`, :func:`open_result`).
    out : path, optional
        The folder (default: the one the run was written to); locked meanwhile.
    force : bool
        As :func:`run`'s: write into a non-empty folder that is not navsim's.

    Returns
    -------
    list of Path
        The report's files.
    """
    _check_result("result", result)
    _check_flags(dict(force=force))
    out = None if out is None else _path("out", out, "output folder")
    if out is None and result.folder is None:
        raise UsageError("write_report needs a folder: out=... (the run was held in memory)")
    with OutputFolder(Path(out) if out is not None else result.folder, command="run", force=force) as folder:
        return _write_report_into(folder, result)


def _check_same_run(folder: OutputFolder, result: Result) -> None:
    """A :class:`UsageError` when ``folder`` (not the run's own) holds another run's result
    (its ``run.json`` of other flights and sensor data, seed or runs), which the report of
    ``result`` would overwrite in part."""
    try:
        earlier = json.loads((folder.path / "run.json").read_text())
    except (OSError, ValueError):
        return
    if not isinstance(earlier, dict) or "run.json" in folder.written():
        return
    ours = {"data_key": result.record.data_key, "seed": result.record.seed, "runs_done": result.record.runs_done}
    if {k: earlier.get(k) for k in ours} != ours:
        raise UsageError(f"{folder.path}: holds the result of another run ({earlier.get('scenario') or '?'}, seed "
                         f"{earlier.get('seed')}, {earlier.get('runs_done')} runs); write_report writes a run's "
                         "report into its own folder or a new one: choose another out=...")


def _write_report_into(folder: OutputFolder, result: Result) -> list[Path]:
    if result.folder is None or folder.path.resolve() != Path(result.folder).resolve():
        _check_same_run(folder, result)
        folder.clear_earlier()                  # the same run's earlier report: replaced whole
        record = result.record                  # the chunks stay where the run wrote them
        if result.store is not None:
            record = dataclasses.replace(record, per_run_data=str(Path(result.store.folder).resolve()))
        _write_run(result, folder, record)
    return _write_report(folder, result.scenario, _truth(result), result, result.metrics, result.record,
                         result.loop, result.reference, result.sightings)


def report_figures(result: Result) -> list:
    """The report's pages in order, for a notebook; nothing is written.

    Parameters
    ----------
    result : Result
        A run (:func:`run`, :func:`open_result`).

    Returns
    -------
    list of navsim.report.figures.Page
        ``name``: the PNG's stem, ``title``: its line in the contents, ``figure``: the
        matplotlib figure. Close them with ``matplotlib.pyplot.close(page.figure)``.
    """
    _check_result("result", result)
    return _report_pages(result.scenario, _truth(result), result, result.metrics, result.record, result.loop,
                         result.reference, result.sightings)


def _truth(result: Result):
    """The flight the report draws: the run's, or the cached flight of an open-loop scenario."""
    if result.truth is None and result.scenario.closed_loop is None:
        return cached_flight(result.scenario.flight)[0]
    return result.truth


def open_result(folder) -> Result:
    """The run written to ``folder`` (by ``navsim run`` or :func:`run`), read-only: nothing in
    the folder is written or removed. The histories of up to :data:`navsim.experiment.runner.REPORT_RUNS`
    runs are loaded (from ``runs.npz`` or the first stored chunks); the store
    (:attr:`Result.store`) reads every chunk, one at a time."""
    folder = _path("folder", folder, "result folder")
    check_not_being_written(folder)
    try:
        metrics, record, raw = read_files(folder)
    except OSError as exc:
        raise UsageError(f"{folder}: not a finished navsim run ({exc.strerror or exc})") from None
    except UsageError as exc:
        raise UsageError(f"not a finished navsim run: {exc}") from None
    try:
        scenario = parse_scenario(raw, record.scenario)
    except ScenarioError as exc:
        raise UsageError(f"{folder}: its scenario.resolved.yaml does not parse any more ({exc})") from None
    store = ChunkStore.open(folder / "chunks") if (folder / "chunks" / "index.json").is_file() else None
    histories, runs, bias, calib = {}, np.array([], int), None, {}
    merged = store.merged(runner.REPORT_RUNS) if store is not None else None
    if merged is not None:
        runs, histories, bias, calib = np.asarray(merged.runs, int), merged.histories, merged.truth_bias, merged.calibration
    elif (folder / "runs.npz").is_file():
        runs, histories = _npz_histories(folder / "runs.npz", metrics.estimators)
    every = np.asarray(store.runs(), int) if store is not None else runs
    try:
        samples = load_samples(folder / SAMPLES_FILE) if (folder / SAMPLES_FILE).is_file() else {}
    except (OSError, UsageError) as exc:
        logging.getLogger(__name__).warning("%s; the rest of the result is read (compare refuses it)", exc)
        samples = {}
    return Result(scenario, every, histories, metrics, record, folder=folder, truth_bias=bias, calibration=calib,
                  failed=dict(record.failed_runs), interrupted=bool(record.interrupted), store=store,
                  history_runs=None if len(runs) == len(every) else runs, samples=samples)


def sweep(path, workers: int | None = None, *, executor: str = "local", scheduler: str | None = None,
          progress=None, on_point=None) -> SweepResult:
    """Every point of a sweep file (``navsim sweep``) through :func:`run`, held in memory, so
    every scenario feature works at every point (closed loop, landmarks, magnetometer
    calibration). All points are parsed and checked before the first runs.

    Parameters
    ----------
    path : path
        The sweep file (:mod:`navsim.experiment.sweep`).
    workers : int, optional
        Default: each point's scenario's.
    executor, scheduler
        As :func:`run`.
    progress : callable, optional
        ``progress(1)`` after each point.
    on_point : callable, optional
        ``on_point(index, point, values, result)`` after each point (its :class:`Result`;
        None for a point whose flight cannot be flown).

    Returns
    -------
    SweepResult
        The rows ``(point, {label: value})`` and each value's 95 % interval
        (``intervals``); the points none of whose runs succeeded, or whose flight cannot be
        flown (their values None, their metrics None; the other points go on); whether it was
        interrupted (the points after it are not run).
    """
    workers = None if workers is None else WORKERS.check(workers)
    _check_how(executor, scheduler, {}, dict(progress=progress, on_point=on_point))
    plan = plan_sweep(_path("path", path, "sweep file"))
    result = SweepResult([], plan.metric)
    for i, (point, sc) in enumerate(zip(plan.points, plan.scenarios)):
        if i in plan.unflown:
            result.failed_points[i] = f"the flight cannot be flown: {plan.unflown[i]}"
            result.unflown.add(i)
            result.rows.append((point, {e.label: None for e in sc.estimators}))
            result.metrics.append(None)
            result.intervals.append({})
            if on_point:
                on_point(i, point, result.rows[-1][1], None)
            if progress:
                progress(1)
            continue
        res = run(sc, plan.runs or sc.runs, sc.seed, workers or sc.workers, executor=executor, scheduler=scheduler)
        if res.interrupted:
            result.interrupted = True
            break
        if not len(res.runs):
            result.failed_points[i] = min(res.failed.items())[1] if res.failed else "no run"
        result.rows.append((point, point_values(plan, res.metrics.estimators)))
        result.metrics.append(res.metrics)
        result.intervals.append({label: value_interval(m, res.samples.get(label), plan.metric)
                                 for label, m in res.metrics.estimators.items()})
        if on_point:
            on_point(i, point, result.rows[-1][1], res)
        if progress:
            progress(1)
    return result


def compare(a, b=None, estimators=None, *, partial: bool = False, unpaired: bool = False,
            margin=DEFAULT_MARGIN_PCT) -> list[Comparison]:
    """Compare two estimators over the runs as the samples: ``B - A`` per metric with its 95 %
    interval and a verdict (:mod:`navsim.scoring.compare`); nothing is written.

    Parameters
    ----------
    a, b : path or Result
        Result folders (``navsim run``'s ``--out``) or :class:`Result` objects (:func:`run`,
        :func:`open_result`); ``b`` None: two estimators of ``a``.
    estimators : sequence of str, optional
        ``(A, B)``: the estimator of ``a`` and of ``b``; one label: the same on both sides.
        Default: every label the two results share (one comparison each), or each one's only
        estimator; required for two estimators of one result.
    partial : bool
        Compare an interrupted result as it is (its finished runs), else refuse it.
    unpaired : bool
        Compare side against side even where the runs pair (what pairing gains).
    margin : float or mapping, optional
        The practical-equivalence margin, per cent of the larger of the two values: a
        difference whose 95 % interval lies within it is ``negligible``, and none within it is
        offered a run count (:mod:`navsim.scoring.compare`). A mapping gives it per metric path
        (``{"rms.pos_m": 5, "": 1}``: the longest matching start; ``""`` the others).
        Default :data:`navsim.scoring.compare.DEFAULT_MARGIN_PCT`.

    Returns
    -------
    list of Comparison
        One per estimator pair. Paired run by run when both results flew the same flights and
        sensor data (:func:`navsim.experiment.results.pairing`), else unpaired.

    Raises
    ------
    UsageError
        A folder that is not a result, a damaged file of one (named with its key or array), a
        result an older or a newer navsim wrote, two different tracks or
        metric settings, an interrupted result without ``partial``, an unknown estimator.
    """
    for name, x in (("a", a), ("b", b)):
        if not isinstance(x, Result) and (x is not None or name == "a"):
            _path(name, x, "result folder")
    estimators = _labels(estimators)
    _check_flags(dict(partial=partial, unpaired=unpaired))
    margin = check_margin(margin)
    ra = _result_files(a)
    rb = ra if b is None or b is a else _result_files(b)
    check_comparable(ra, rb)
    for r in {id(ra): ra, id(rb): rb}.values():
        if r.record.interrupted and not partial:
            raise UsageError(f"{r.folder}: interrupted after {r.record.runs_done} of {r.record.runs} runs; hint: "
                             "complete it with navsim run --resume, or compare what finished with --partial")
    paired, why = pairing(ra, rb)
    if unpaired:
        paired, why = False, "unpaired (asked): side against side"
    out = [_compare_pair(ra, rb, pair, (paired, why), margin)
           for pair in _estimator_pairs(ra, rb, b is None, estimators)]
    check_margin_paths(margin, {d.metric for c in out for d in c.differences})
    return out


def _compare_pair(ra: ResultFiles, rb: ResultFiles, pair: tuple, pairing_: tuple, margin) -> Comparison:
    """The comparison of the estimators ``pair`` = ``(A's, B's)``, ``pairing_`` = ``(paired, why)``;
    a :class:`UsageError` where they share no metric or too few runs."""
    (la, lb), (paired, why) = pair, pairing_
    side = lambda r, label: Side(str(r.folder), label, len(r.samples[label].runs), r.record.runs_done,
                                 r.record.runs, bool(r.record.interrupted), r.record.seed)
    c = compare_samples(side(ra, la), ra.samples[la], side(rb, lb), rb.samples[lb], paired, why, margin)
    if not c.differences:
        raise UsageError(f"{ra.folder} '{la}' and {rb.folder} '{lb}' share no metric to compare")
    if c.runs_compared < MIN_RUNS:
        raise UsageError(f"'{la}' ({c.a.runs} counted runs) against '{lb}' ({c.b.runs}): "
                         f"{c.runs_compared} runs to compare{' in common' if paired else ''}, at least "
                         f"{MIN_RUNS} needed (a diverged run is not counted)")
    return c


def _result_files(x) -> ResultFiles:
    """A result folder's files (:func:`~navsim.experiment.results.read_result`), or the same
    of a :class:`Result` at hand (its scenario resolved as a folder would hold it)."""
    if not isinstance(x, Result):
        return read_result(x)
    if x.metrics is None or not x.samples:
        raise UsageError(f"result of '{x.scenario.name}': not scored, or scored by an older navsim (no per-run samples)")
    resolved = yaml.safe_load(yaml.safe_dump(resolved_scenario(x), sort_keys=False))
    return ResultFiles(x.folder or f"{x.scenario.name} (in memory)", x.metrics, x.record, resolved, x.samples)


def _estimator_pairs(ra: ResultFiles, rb: ResultFiles, one: bool, estimators) -> list[tuple[str, str]]:
    """The ``(A, B)`` labels compared (see :func:`compare`)."""
    la, lb = list(ra.samples), list(rb.samples)
    if estimators:
        names = list(estimators)
        if len(names) > 2:
            raise UsageError(f"--estimators takes one or two labels, not {len(names)}")
        pair = (names[0], names[-1])
        for r, label in zip((ra, rb), pair):
            if label not in r.samples:
                raise UsageError(f"{r.folder}: no estimator '{label}'; it has: " + ", ".join(r.samples))
        if one and pair[0] == pair[1]:
            raise UsageError(f"{ra.folder}: one estimator against itself; name two: --estimators A B")
        return [pair]
    if one:
        raise UsageError(f"{ra.folder}: one result: name the two estimators to compare, --estimators A B "
                         "(it has: " + ", ".join(la) + ")")
    common = [x for x in la if x in lb]
    if common:
        return [(x, x) for x in common]
    if len(la) == len(lb) == 1:
        return [(la[0], lb[0])]
    raise UsageError(f"{ra.folder} and {rb.folder} share no estimator label; name them: --estimators A B "
                     f"(A has: {', '.join(la)}; B has: {', '.join(lb)})")


def write_comparison(comparisons: list[Comparison], folder: OutputFolder, fmts=("pdf", "png")) -> list[Path]:
    """``compare.json``, ``compare.csv`` and the page of each comparison (``compare.pdf``, a PNG
    each, its runs' differences drawn).

    Parameters
    ----------
    comparisons : list of Comparison
        What :func:`compare` returned.
    folder : navsim.foundations.outputs.OutputFolder
        The open output folder written into.
    fmts : sequence of {"pdf", "png"}
        The page formats.

    Returns
    -------
    list of Path
        The files written.
    """
    folder.json("compare.json", {"comparisons": [c.to_dict() for c in comparisons], **provenance()})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_HEADERS)
    for c in comparisons:
        w.writerows(csv_rows(c))
    folder.text("compare.csv", buf.getvalue())
    pages = [compare_page(c, "compare" if j == 0 else f"compare_{j + 1}") for j, c in enumerate(comparisons)]
    try:
        files = render(folder, pages, fmts, "navsim compare", pdf="compare.pdf")
    finally:
        for p in pages:
            pyplot().close(p.figure)
    return [folder.path / "compare.json", folder.path / "compare.csv", *files]


def budget(scenario, runs: int | None = None, seed: int | None = None, workers: int | None = None, *,
           group: str = "source", scales=(), method: str = "montecarlo", executor: str = "local",
           scheduler: str | None = None, progress=None, store: OutputFolder | None = None,
           resume: bool = False) -> Budget:
    """The error budget of every estimator of ``scenario``: each error source's contribution to
    every RMS metric (:mod:`navsim.scoring.budget`); nothing is written.

    Parameters
    ----------
    scenario, runs, seed, workers, executor, scheduler
        As :func:`run` (each of the Monte Carlos runs so).
    group : {"source", "sensor", "kind"}
        The budget's lines: each source, each sensor (and the initial errors), each sensor's
        kind of term (``imu gyro``).
    scales : sequence of (str, float)
        "What if": each source scaled by the factor; the metric predicted from the budget, then
        a Monte Carlo with it scaled (:class:`~navsim.scoring.budget.WhatIf`).
    method : {"montecarlo", "covariance", "both"}
        ``montecarlo``: the runs with every error source on, with none, and with each source
        alone (the same seeds: each source's realisation is the one it has with all on);
        ``covariance``: one covariance analysis along the flight
        (:mod:`navsim.navigation.covariance`; the sources without a linear form are listed in
        ``monte_carlo_only``, the filters it does not take in ``not_analysed``); ``both``: the
        Monte Carlo budget with each line's covariance figure beside it.
    progress : callable, optional
        ``progress(done, total, what)`` after each Monte Carlo (and the covariance analysis).
    store : OutputFolder, optional
        Where each finished Monte Carlo's per-run samples go (``budget_part_<key>.npz``, keyed
        by the scenario, the source, the runs, the seed and navsim's version), so that an
        interrupted budget keeps them.
    resume : bool
        Read the Monte Carlos ``store`` already holds instead of running them again.

    Raises
    ------
    UsageError
        No error source in the scenario, an unknown source, group or method, a factor below 0;
        a covariance analysis of a closed loop or of sources none of which has a linear form.
    """
    t0 = time.perf_counter()
    runs, seed, workers, _ = _numbers(runs, seed, workers)
    _check_how(executor, scheduler, dict(resume=resume), dict(progress=progress))
    scales = _scales(scales)
    _check_store(store)
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    sources = budget_sources(sc)
    if group not in BUDGET_GROUPS:
        raise UsageError(f"group: {group!r} is not a budget's grouping (expected one of {', '.join(BUDGET_GROUPS)})")
    check_method(sc, method, BUDGET_METHODS, sources)
    scaled_runs = [(find_source(name, sources), float(k)) for name, k in scales]
    plan = _budget_plan(sc, sources, scaled_runs, method)
    runs = sc.runs if runs is None else runs
    seed = sc.seed if seed is None else seed
    flight = cached_flight(sc.flight) if sc.closed_loop is None else None
    steps = len(plan) + (method != "montecarlo")
    cov = None
    if method != "montecarlo":
        cov = _covariance_budget(sc, sources, flight[0], group)
        if progress:
            progress(1, steps, "covariance analysis")
    samples, squares = {}, {}
    for i, (what, variant) in enumerate(plan):
        samples[what], squares[what] = _budget_monte_carlo(
            (variant, runs, seed, workers), dict(executor=executor, scheduler=scheduler, flight=flight),
            store, _budget_part(variant, runs, seed), resume)
        if progress:
            progress(i + 1 + (cov is not None), steps, what)
    metrics, by_source = (cov.metrics, cov.by_source) if method == "covariance" else _monte_carlo_budgets(
        samples, sources, group)
    if method == "both":
        metrics = with_covariance(metrics, cov.metrics)
    what_if = _what_ifs(samples, by_source, scaled_runs)
    extra = {} if cov is None else dict(monte_carlo_only=cov.left, left_out=left_out_reasons(sc, sources, cov.left),
                                        not_analysed=cov.skipped, covariance_s=cov.wall_s,
                                        covariance_curves=cov.curves)
    if method != "covariance":
        extra["curves"] = monte_carlo_curves(squares, [s.name for s in sources])
    return Budget(sc.name, runs if method != "covariance" or plan else 0, seed, [s.name for s in sources], group,
                  metrics, what_if, time.perf_counter() - t0, method, **extra)


def _budget_plan(sc: Scenario, sources, scaled_runs, method: str) -> list:
    """The Monte Carlos of a budget, ``(what, scenario)``: all on, none and each source alone
    (not for a covariance analysis alone), then each scaled source."""
    plan = [(f"{s.name} x{k:g}", scaled(sc, s, k)) for s, k in scaled_runs]
    if method == "covariance":
        return plan
    return [("all on", sc), ("none", alone(sc, None, sources))] + [(s.name, alone(sc, s, sources))
                                                                   for s in sources] + plan


#: the files a budget keeps of each finished Monte Carlo (:func:`budget`'s ``store``)
BUDGET_PARTS = "budget_part_*.npz"


def _budget_part(variant: Scenario, runs: int, seed: int) -> str:
    """The file of one Monte Carlo of a budget, named by a digest of what makes its numbers:
    the variant's content as resolved (its sensor and estimator models, initial errors and
    flight, navsim's version: :func:`~navsim.experiment.runner.scenario_hash`), its metric
    settings, the runs and the seed."""
    key = json.dumps([scenario_hash(variant), variant.raw.get("metrics"), runs, seed], sort_keys=True, default=str)
    return BUDGET_PARTS.replace("*", hashlib.sha256(key.encode()).hexdigest()[:16])


def _budget_monte_carlo(args: tuple, how: dict, store: OutputFolder | None, name: str, resume: bool):
    """One Monte Carlo of a budget: its per-run samples and epoch mean squares
    (:func:`~navsim.scoring.budget.epoch_mean_squares`), run (and kept in ``store``, both in one
    file) or, with ``resume``, read back from ``store``."""
    if resume and store is not None and (store.path / name).is_file():
        with np.load(store.path / name, allow_pickle=False) as z:
            squares = {str(label): (z[f"squares_t{i}"], z[f"squares_ms{i}"])
                       for i, label in enumerate(z["squares_labels"].tolist())} if "squares_labels" in z.files else None
        if squares is not None:
            store.record([store.path / name])             # this budget's: kept when the folder is cleared
            return load_samples(store.path / name), squares
    res = run(*args, **how)
    if res.interrupted:
        raise KeyboardInterrupt
    squares = epoch_mean_squares(res.histories)
    if store is not None:
        extra = {"squares_labels": np.array(list(squares), dtype=str)}
        for i, (t, ms) in enumerate(squares.values()):
            extra.update({f"squares_t{i}": t, f"squares_ms{i}": ms})
        store.write(name, lambda path: save_samples(path, res.samples, extra))
    return res.samples, squares


@dataclass
class _CovarianceBudget:
    metrics: list                   #: grouped as asked
    by_source: dict                 #: estimator -> its budgets of each source alone
    left: list                      #: the sources without a linear form
    skipped: dict                   #: the estimators not analysed -> why
    curves: dict                    #: estimator -> Contributions
    wall_s: float


def _covariance_budget(sc, sources, truth, group: str) -> _CovarianceBudget:
    """The covariance analysis's budgets of ``sources`` (:func:`covariance_contributions`)."""
    t0 = time.perf_counter()
    models, left = linear_sources(sc, sources, truth)
    contributions, skipped = covariance_contributions(sc, truth, models)       # check_method: some of each
    groups = {s.name: s.group_of(group) for s in sources}
    metrics, by_source = [], {}
    for label, c in contributions.items():
        metrics += covariance_budgets(label, c, sc.settle_s, groups)
        by_source[label] = covariance_budgets(label, c, sc.settle_s, {s: s for s in c.sources})
    return _CovarianceBudget(metrics, by_source, left, skipped, contributions, time.perf_counter() - t0)


def _monte_carlo_budgets(samples: dict, sources, group: str) -> tuple[list, dict]:
    """The Monte Carlo budgets (grouped as asked) and each estimator's budgets per source."""
    metrics, by_source = [], {}
    for label in samples["all on"]:
        per = {s.name: samples[s.name][label] for s in sources}
        metrics += metric_budgets(label, samples["all on"][label], samples["none"][label], per,
                                  {s.name: s.group_of(group) for s in sources})
        by_source[label] = metric_budgets(label, samples["all on"][label], samples["none"][label], per,
                                          {s.name: s.name for s in sources})
    return metrics, by_source


def _what_ifs(samples: dict, by_source: dict, scaled_runs) -> list[WhatIf]:
    """Each scaled source's predictions (from the per-source budgets) beside its run."""
    out = []
    for s, k in scaled_runs:
        for label, budgets in by_source.items():
            run_samples = samples[f"{s.name} x{k:g}"][label]
            zero = samples["none"][label] if "none" in samples else None
            measured = metric_budgets(label, run_samples, zero if zero is not None else run_samples, {}, {})
            for mb in budgets:
                m = next((x for x in measured if (x.metric, x.component) == (mb.metric, mb.component)), None)
                if m is not None:
                    out.append(WhatIf(s.name, k, label, mb.metric, mb.component, mb.all_on, predict(mb, s.name, k),
                                      m.all_on))
    return out


def _check_store(store) -> None:
    """A :class:`UsageError` unless ``store`` is None or an output folder opened for a budget."""
    if store is not None and not (isinstance(store, OutputFolder) and store.command == "budget"):
        raise UsageError(f"store: {_shown(store)} is not an OutputFolder opened for a budget "
                         "(OutputFolder(path, command='budget'), or None)")


def write_budget(result: Budget, folder: OutputFolder, metrics=None, fmts=("pdf", "png")) -> list[Path]:
    """``budget.json``, ``budget.csv`` (one row per estimator, metric and line) and the budget's
    pages (``budget.pdf``, a PNG each: a sorted bar chart per estimator and metric).

    Parameters
    ----------
    result : Budget
        What :func:`budget` returned.
    metrics : sequence of str, optional
        The metrics drawn (default :data:`~navsim.scoring.budget.DEFAULT_METRICS`).
    folder, fmts
        As :func:`write_comparison`'s: the open output folder, the page formats.

    Returns
    -------
    list of Path
        ``budget.json``, ``budget.csv`` and the pages written.
    """
    folder.json("budget.json", {**result.to_dict(), **provenance()})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(BUDGET_CSV_HEADERS)
    w.writerows(budget_csv_rows(result))
    folder.text("budget.csv", buf.getvalue())
    pages = budget_pages(result, metrics)
    try:
        files = render(folder, pages, fmts, f"navsim budget {result.scenario}", pdf="budget.pdf")
    finally:
        for p in pages:
            pyplot().close(p.figure)
    return [folder.path / "budget.json", folder.path / "budget.csv", *files]
