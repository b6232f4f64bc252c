"""``navsim run``: fly (cached), emulate, estimate and score a scenario's Monte Carlo runs.

The flight is flown once per distinct flight configuration and cached on disk
(``$NAVSIM_CACHE``, default ``~/.cache/navsim``), keyed by a hash of everything that determines
it (track, environment, aircraft model files, rate, navsim version). Runs are cut into chunks
(:func:`default_chunk_runs`; the numbers do not depend on their size nor on the number of
workers); chunks go to a process pool. A chunk that fails marks its runs as failed and the others complete; Ctrl-C keeps the
chunks that finished.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import threading
import uuid
import zipfile
from concurrent.futures import as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path

import jsbsim
import numpy as np

from navsim.experiment.chunkstore import chunk_name, job_chunks
from navsim.experiment.closed_loop import end_records, fly_batch
from navsim.experiment.driver import Batch, run_batch
from navsim.experiment.executors import local_pool, run_chunks_dask
from navsim.experiment.options import RunOptions
from navsim.experiment.scenario import values_read
from navsim.flight.airframe import model_digest
from navsim.flight.simulator import fly
from navsim.flight.truth import Truth
from navsim.foundations.config import cache_dir
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.navigation.estimators import factory
from navsim.navigation.estimators.base import plugin_sources
from navsim.navigation.magcal import calibration_history
from navsim.records.chunk import ChunkPart, merge_parts
from navsim.records.history import EPOCH_ARRAYS
from navsim.records.truth import CalibrationHistory, TruthBias
from navsim.sensors import emulate
from navsim.sensors.base import RANDOM_STREAMS, SensorData
from navsim.sensors.imu import ImuStream, emulate_imu, seen_bias
from navsim.sensors.registry import INERTIAL
from navsim.version import __version__

log = logging.getLogger(__name__)

#: runs per chunk, by measurement (benchmarks/chunk_size.py, P0, 1000 runs, 2 workers): 125 runs
#: 21.0 s, 250 runs 19.0 s, 500 runs 18.8 s with a worker's peak memory 505 -> 813 MB
CHUNK_RUNS = 250

#: streamed to a chunk store, the first chunks holding this many runs are loaded for the report's
#: plots; the metrics are computed from every stored chunk (navsim.scoring.scorer)
REPORT_RUNS = 1000


def default_chunk_runs(runs: int, workers: int) -> int:
    """The runs of a chunk where none is asked for: :data:`CHUNK_RUNS`, or, for a Monte Carlo of
    at most :data:`REPORT_RUNS` runs (the report draws them all, however chunked) that would not
    keep every worker busy, ``runs / workers`` rounded up (40 runs on 2 workers are 2 chunks of
    20, not one of 40 on one worker). The numbers do not depend on it."""
    if runs > REPORT_RUNS:
        return CHUNK_RUNS
    return max(1, min(CHUNK_RUNS, -(-runs // max(workers, 1))))


def plain(x):
    """Dataclasses, containers and arrays as plain JSON-able values (for content hashes)."""
    if dataclasses.is_dataclass(x):
        return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def scenario_hash(scenario) -> str:
    """Hash of what a scenario's chunks depend on: its content without the ``montecarlo``,
    ``metrics`` and ``report`` settings (the chunks do not depend on them: a resumed run may
    be scored with other windows), the sensor and estimator models as resolved from the
    catalog, navsim's version and the flight.

    Parameters
    ----------
    scenario : navsim.experiment.scenario.Scenario
        A parsed scenario.

    Returns
    -------
    str
        20 hex digits.
    """
    raw = {k: v for k, v in scenario.raw.items() if k not in ("montecarlo", "metrics", "report")}
    h = hashlib.sha256(json.dumps(raw, sort_keys=True, default=str).encode())
    h.update(json.dumps(plain([scenario.sensors, scenario.estimators, scenario.initial]), sort_keys=True,
                        default=str).encode())
    h.update(__version__.encode())
    h.update(f"streams {RANDOM_STREAMS}".encode())
    h.update(flight_key(scenario.flight).encode())
    for source in plugin_sources(e.type for e in scenario.estimators):    # a --plugin file's text
        h.update(source["sha256"].encode())
    return h.hexdigest()[:20]


def data_key(scenario, seed: int) -> str:
    """Hash of what makes a run's flights and sensor data: the sensors and initial errors as
    resolved (catalog and model files read), the seed, the flight and how the random streams are
    drawn (:data:`~navsim.sensors.base.RANDOM_STREAMS`); in a closed loop also the estimators and
    the loop (the flight follows the estimator it flies on). Two results with one
    data key have the same run ``j`` whatever their estimators: :func:`navsim.compare` pairs them.

    Returns
    -------
    str
        20 hex digits.
    """
    parts = [scenario.sensors, scenario.initial, int(seed), flight_key(scenario.flight), RANDOM_STREAMS]
    if scenario.closed_loop is not None:
        parts += [scenario.estimators, scenario.closed_loop]
    return hashlib.sha256(json.dumps(plain(parts), sort_keys=True, default=str).encode()).hexdigest()[:20]


def flight_key(config) -> str:
    """Hash of everything that determines a flight: the configuration, navsim's and JSBSim's
    versions (JSBSim's own models, such as one an airframe's ``jsbsim_model`` names, ship with it)
    and the aircraft folder's files. A folder outside ``aircraft/`` (beside a scenario) enters by its
    model's identity (:func:`~navsim.flight.airframe.model_digest`: every file, sub-folders too,
    by name and content) in place of its path: an edited model flies again, a copy elsewhere
    shares the flight."""
    h = hashlib.sha256()
    described = plain(config)
    if config.aircraft_dir:
        described["aircraft_dir"] = f"model {model_digest(config.folder)}"
    h.update(json.dumps({"config": described, "version": __version__, "jsbsim": jsbsim.__version__},
                        sort_keys=True, default=str).encode())
    for path in sorted(config.folder.glob("*")):
        if path.is_file():
            h.update(path.read_bytes())
    return h.hexdigest()[:20]


def cached_flight(config, progress=None) -> tuple[Truth, Path | None, bool]:
    """The truth of ``config``, flown or read from the cache; returns (truth, path, was_cached),
    ``path`` None where the cache folder is unusable (:func:`cache_dir` warned; flown each time).

    A cached flight carries its key and a SHA-256 of its contents (:meth:`Truth.save`); one
    that is damaged (truncated), foreign (another flight's under this key) or of an older
    navsim is flown again and replaced, with a warning. It is written under a name of its own
    (two runs flying the same flight at once never share a file) and renamed into place."""
    key = flight_key(config)
    folder = cache_dir("flights")
    if folder is None:                   # an unusable cache (warned): flown, not cached
        return fly(config, progress=progress), None, False
    path = folder / f"{key}.npz"
    truth = _read_cached(path, key)
    if truth is not None:
        return truth, path, True
    truth = fly(config, progress=progress)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{key}.{os.getpid()}.{uuid.uuid4().hex}.tmp.npz")
    try:
        truth.save(tmp, key=key)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return truth, path, False


def _read_cached(path: Path, key: str) -> Truth | None:
    """The cached flight ``key`` at ``path`` if it is there and checks (:meth:`Truth.load`), else
    None (a warning when it was there but unusable)."""
    if not path.is_file():
        return None
    try:
        return Truth.load(path, key=key)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        log.warning("%s: the cached flight is unusable (%s); flying it again", path, exc)
        return None


@dataclass
class RunResult:
    """What the runner returns of a scenario's runs (open loop or closed): every field is also
    one of :class:`navsim.api.Result`'s, of the same name, copied by ``Result.from_run``."""

    histories: dict                      #: label -> EstimatorHistory over the finished runs
    runs: np.ndarray                     #: run indices finished
    failed: dict = field(default_factory=dict)   #: run -> error message
    interrupted: bool = False
    truth_bias: TruthBias | None = None   #: gyro/accel true bias at epochs (B, E, 3); None: none
    #: magnetometer name -> its online calibration scored against the truth (navsim.navigation.magcal)
    calibration: dict[str, CalibrationHistory] = field(default_factory=dict)
    #: the chunk store every finished run is in (streamed runs), or None (all runs in memory)
    store: object = None
    #: the runs ``histories``, ``truth_bias`` and ``calibration`` hold (streamed: the first
    #: :data:`REPORT_RUNS`); None: all of ``runs``
    history_runs: np.ndarray | None = None


def _chunk(args):
    """Worker: sensors and estimators of one chunk of runs; a :class:`ScenarioError` raised
    there names the scenario's file."""
    try:
        return _chunk_work(*args)
    except ScenarioError as exc:
        raise (exc.with_file(str(args[1].path)) if exc.file is None and args[1].path else exc) from None


def _chunk_work(truth_or_path, scenario, seed, runs):
    """The sensors and estimators of the runs ``runs``, as a :class:`ChunkPart`."""
    truth = Truth.load(truth_or_path) if isinstance(truth_or_path, (str, Path)) else truth_or_path
    imu_cfg = next(c for c in scenario.sensors if c.role == INERTIAL)
    if imu_cfg.spec.vibration:       # normalised over the whole record: emulated whole
        imu = emulate_imu(truth, imu_cfg.spec, seed, runs, name=imu_cfg.name, keep_rates=False)
    else:                            # generated block by block inside the loop
        imu = ImuStream(truth, imu_cfg.spec, seed, runs, name=imu_cfg.name)
        imu.record_bias()
    # the true errors the emulators also return are dropped (air data: 50 of its 140 MB for 250
    # runs) but for the magnetometers whose online calibration is scored against them
    calibrated = mag_calibrations(scenario)
    read = values_read(scenario)
    others = {c.name: emulate(truth, c, seed, runs) if c.name in calibrated
              else emulated(truth, c, seed, runs, None if read is None else read[c.name])
              for c in scenario.sensors if c.role != INERTIAL}
    estimators = {e.label: factory.build(e) for e in scenario.estimators}   # looked up at the call
    hist = run_batch(truth, imu, others, estimators, Batch(scenario.initial, seed, runs))
    # true IMU biases at the epochs of the first estimator, for the bias plots
    first = next(iter(hist.values()))
    idx = np.searchsorted(imu.t_s, first.t_s - 1e-9)
    if isinstance(imu, ImuStream):
        bias = TruthBias(**imu.bias(idx))
    else:
        bias = {k: np.broadcast_to(imu.errors[k], (len(runs), max(imu.errors[k].shape[1], 1), 3))
                for k in ("gyro_bias", "accel_bias")}
        bias = {k: (v[:, idx] if v.shape[1] > 1 else np.repeat(v, len(idx), axis=1)) for k, v in bias.items()}
        at = np.searchsorted(truth.t_s, imu.t_s[np.minimum(idx, len(imu.t_s) - 1)] - 1e-9)
        for key, x in (("gyro", truth.omega_ib_b_rps), ("accel", truth.f_b_mps2)):
            if f"{key}_matrix" in imu.errors:
                bias[f"{key}_bias_seen"] = seen_bias(bias[f"{key}_bias"], imu.errors[f"{key}_matrix"], x[at])
        bias = TruthBias(**bias)
    calib = {name: CalibrationHistory(**calibration_history(truth, others[name], s["noise_uT"] * 1e-6, s["forgetting"]))
             for name, s in calibrated.items()}
    return ChunkPart(list(runs), hist, bias, calib)


#: the runs a chunk emulates a sensor for at a time (:func:`emulated`)
EMULATE_RUNS = 50


def emulated(truth, config, seed: int, runs, read: set | None) -> SensorData:
    """``config`` emulated for ``runs`` as a chunk holds it: :data:`EMULATE_RUNS` runs at a
    time (a batch equals its runs bit for bit), without the true errors, and the float values
    no estimator reads (``read``: :func:`~navsim.experiment.scenario.values_read`'s set for
    this sensor; None: all are read) in single precision. A chunk of 250 P0 runs so holds the
    air data once (65 MB, its pressures, temperature and airspeeds at 10 Hz in single
    precision), not beside their true errors and the emulator's temporaries of every run (150 MB)."""
    runs = list(runs)
    if not runs:
        return replace(emulate(truth, config, seed, runs), errors={})
    out, valid, first = {}, None, None
    for i in range(0, len(runs), EMULATE_RUNS):
        d = emulate(truth, config, seed, runs[i:i + EMULATE_RUNS])
        if first is None:
            first = replace(d, values={}, errors={})         # its name, kind, times, meta
            valid = np.empty((len(runs), *d.valid.shape[1:]), d.valid.dtype)
            single = lambda k, v: read is not None and k not in read and v.dtype == np.float64
            out = {k: np.empty((len(runs), *v.shape[1:]), np.float32 if single(k, v) else v.dtype)
                   for k, v in d.values.items()}
        rows = slice(i, i + d.runs)
        valid[rows] = d.valid
        for k, v in d.values.items():
            out[k][rows] = v
        del d
    return replace(first, values=out, valid=valid, errors={}, meta={**first.meta, "runs": runs})


def mag_calibrations(scenario) -> dict:
    """Magnetometer name -> the settings of the first ``mag_heading`` measurement that calibrates
    it online (its fit is scored against the sensor's true iron)."""
    out = {}
    for e in scenario.estimators:
        groups = [e.params.get("measurements", [])] + [loc["measurements"] for loc in
                                                      e.params.get("federated", {}).get("locals", [])]
        for m in (m for g in groups for m in g):
            if m["type"] == "mag_heading" and m.get("calibration", "online") == "online":
                out.setdefault(m["sensor"], m)
    return out


def run_chunks(fn, chunks, make_args, workers: int, progress=None, on_part=None, after_submit=None):
    """Run ``fn(make_args(chunk, in_worker))`` for each chunk of run indices, in this process or
    a pool of ``workers``; a chunk that raises marks its runs as failed and the others complete;
    Ctrl-C keeps what finished. Returns ``(parts, failed, interrupted)``; with ``on_part``, each
    finished part is handed to ``on_part(part)`` as it arrives instead of being kept in ``parts``;
    ``after_submit()``, in a pool, is called once every chunk is queued (the workers forked):
    this process's own work that overlaps the chunks' may start there."""
    parts, failed, interrupted = [], {}, False
    keep = on_part or parts.append
    try:
        if workers <= 1:
            for ch in chunks:
                try:
                    part = fn(make_args(ch, False))
                except Exception as exc:  # a failing chunk must not lose the others
                    failed.update({r: f"{type(exc).__name__}: {exc}" for r in ch})
                else:
                    keep(part)
                if progress:
                    progress(len(ch))
        else:
            with local_pool(workers) as pool:
                futures = {}
                try:
                    for ch in chunks:
                        futures[pool.submit(fn, make_args(ch, True))] = ch
                except BrokenProcessPool as exc:       # a lent pool whose worker died while idle
                    failed.update({r: f"{type(exc).__name__}: {exc}" for ch in chunks for r in ch
                                   if ch not in futures.values()})
                if after_submit is not None:
                    after_submit()
                try:
                    for fut in as_completed(futures):
                        ch = futures.pop(fut)          # a finished future keeps its part: drop it
                        part = None
                        try:
                            part = fut.result()
                        except Exception as exc:
                            failed.update({r: f"{type(exc).__name__}: {exc}" for r in ch})
                        else:
                            keep(part)
                        del fut, part
                        if progress:
                            progress(len(ch))
                except Exception:                      # an error: nothing left queued behind it
                    for fut in futures:
                        fut.cancel()
                    raise
    except KeyboardInterrupt:
        interrupted = True
    return parts, failed, interrupted


def chunk_ranges(runs: int, size: int) -> list[range]:
    """Runs ``0 .. runs-1`` cut into chunks of ``size``."""
    if size < 1:
        raise UsageError(f"chunk size must be at least 1, not {size}")
    return job_chunks(runs, size)


def _chunk_failures(chunks, failed: dict) -> dict:
    """Chunk name -> error message of the chunks whose runs failed."""
    return {chunk_name(ch): failed[ch[0]] for ch in chunks if ch[0] in failed}


def run_monte_carlo(scenario, truth: Truth, truth_path: Path | None, options: RunOptions, *, store=None,
                    keep_runs: int | None = None) -> RunResult:
    """All runs of ``scenario`` on ``truth``, in chunks of ``options.chunk_runs`` (default
    :func:`default_chunk_runs`).

    Parameters
    ----------
    scenario, truth, truth_path
        The scenario and its flight (in memory, and its cached ``.npz`` or None).
    options : navsim.experiment.options.RunOptions
        How the runs are made, ``runs``, ``seed`` and ``workers`` given
        (:meth:`~navsim.experiment.options.RunOptions.for_scenario`): the number of runs, the
        seed, the worker processes, the runs per chunk (the numbers do not depend on it), the
        executor (``local``: a process pool on this machine; ``dask``: Dask distributed,
        :mod:`navsim.experiment.executors`, on ``scheduler`` or a ``LocalCluster`` of
        ``workers`` processes) and a callback ``progress(runs_finished)``; its ``resume`` is
        not read (a ``store`` opened to resume is).
    store : navsim.experiment.chunkstore.ChunkStore, optional
        Streams each finished chunk to disk; only the chunks it lacks are run (resume) and the
        result is rebuilt from the stored chunks.
    keep_runs : int, optional
        With ``store``: load the histories of the first chunks holding this many runs only
        (memory independent of ``runs``; the whole result stays in ``result.store``).

    Returns
    -------
    RunResult
    """
    chunks = chunk_ranges(options.runs, options.chunk_runs or default_chunk_runs(options.runs, options.workers))
    pending = store.missing(chunks) if store is not None else chunks
    on_part = store.add if store is not None else None
    seed = options.seed
    if options.executor == "dask":
        parts, failed, interrupted = run_chunks_dask(_chunk, pending, truth, truth_path, (scenario, seed), options,
                                                     on_part)
    else:
        parts, failed, interrupted = run_chunks(
            _chunk, pending, lambda ch, remote: (str(truth_path) if remote and truth_path else truth, scenario, seed, ch),
            options.workers, options.progress, on_part)
    if store is not None:
        store.flag(_chunk_failures(pending, failed))
        merged = store.merged(keep_runs)
    else:
        merged = merge_parts(parts) if parts else None
    merged = merged if merged is not None else ChunkPart([], {})
    done = np.asarray(merged.runs, int)
    every = np.asarray(store.runs(), int) if store is not None else done
    return RunResult(merged.histories, every, failed, interrupted, merged.truth_bias, merged.calibration,
                     store=store, history_runs=done)


# --- navigation in the loop ---------------------------------------------------------------------
CLOSED_CHUNK_RUNS = 25


@dataclass(frozen=True, eq=False)
class LoopRuns:
    """The per-run outcome of closed-loop runs, ``R`` runs in order (their indices ``runs``, and
    the fields of the same names of :class:`~navsim.experiment.closed_loop.LoopBatch` over every
    chunk): what
    :func:`run_closed_loop` returns, ``Result.loop``, scored by
    :func:`navsim.scoring.closed_loop.closed_loop_metrics`, ``closed_loop.<field>`` in ``runs.npz``."""

    outcome: np.ndarray          #: (R,) str: landed, completed, failed, time limit
    abort_t_s: np.ndarray        #: (R,) time the mission was abandoned (NaN: never)
    land_t_s: np.ndarray         #: (R,) time the parachute opened (NaN: never)
    fail_t_s: np.ndarray         #: (R,) time the flight failed (NaN: never)
    end_t_s: np.ndarray          #: (R,) time the run ended (NaN: time limit)
    miss_m: np.ndarray           #: (R,) true horizontal distance of the landing to the point
    miss_est_m: np.ndarray       #: (R,) the same, of the navigation solution
    landing_n_m: np.ndarray      #: (R, 2) true north, east of the landing from the track start
    path_n_m: np.ndarray         #: (R, E, 3) true north, east, height from the track start
    path_t_s: np.ndarray         #: (E,) times of the paths (the estimators' epochs)
    runs: np.ndarray             #: (R,) int: the run indices

    @classmethod
    def of_batch(cls, b, runs) -> "LoopRuns":
        """The outcome of the runs ``runs`` flown as the LoopBatch ``b``."""
        kept = {f.name: getattr(b, f.name) for f in dataclasses.fields(cls) if f.name not in ("outcome", "runs")}
        return cls(outcome=np.array(b.outcome), runs=np.asarray(runs, int), **kept)

    @classmethod
    def concatenate(cls, parts: list, path_t_s: np.ndarray, runs: np.ndarray) -> "LoopRuns":
        """The chunks ``parts`` (in run order, their paths on ``path_t_s``) of the runs ``runs``
        as one: every other field concatenated."""
        joined = {f.name: np.concatenate([getattr(p, f.name) for p in parts])
                  for f in dataclasses.fields(cls) if f.name not in ("path_t_s", "runs")}
        return cls(**joined, path_t_s=path_t_s, runs=runs)


@dataclass
class LoopChunk:
    """What a chunk of closed-loop runs returns: its records, the per-run outcomes (miss
    distances, abort and landing times, true paths) and the runs that failed (run -> error)."""

    part: ChunkPart
    loop: LoopRuns
    failed: dict


class _TruthGuided:
    """The truth-guided flight of a closed loop (one run flown on the truth, the reference of the
    miss distances and the report's flight), flown in a thread of this process while the pool's
    workers fly the runs (:meth:`start`, after they are forked), or here when asked for."""

    def __init__(self, scenario, seed: int):
        self.scenario, self.seed = scenario, seed
        self.thread, self.batch, self.error = None, None, None

    def fly(self) -> None:
        try:
            batch = fly_batch(self.scenario, self.seed, [0], on_truth=True, keep_truth=True)
            end_records(batch, 1.0 / self.scenario.flight.rate_hz)
            self.batch = batch
        except BaseException as exc:                 # handed to the caller by result()
            self.error = exc

    def start(self) -> None:
        self.thread = threading.Thread(target=self.fly, name="navsim-truth-guided", daemon=True)
        self.thread.start()

    def result(self):
        """The flight's LoopBatch (flown here if it was not started); what it raised, raised."""
        if self.thread is not None:
            self.thread.join()
        elif self.batch is None and self.error is None:
            self.fly()
        if self.error is not None:
            raise self.error
        return self.batch


def _closed_chunk(args) -> LoopChunk:
    """Worker: one chunk of closed-loop runs (each run flies its own aircraft)."""
    scenario, seed, runs = args
    b = fly_batch(scenario, seed, runs)
    end_records(b, 1.0 / scenario.flight.rate_hz)
    return LoopChunk(ChunkPart(list(runs), b.histories, b.truth_bias), LoopRuns.of_batch(b, runs), b.failed)


def _pad(a, E: int, axis: int = 1):
    if a is None or a.shape[axis] == E:
        return a
    width = [(0, 0)] * a.ndim
    width[axis] = (0, E - a.shape[axis])
    return np.pad(a.astype(float) if a.dtype.kind != "f" else a, width, constant_values=np.nan)


def _pad_part(chunk: LoopChunk, t_full, path_t_full) -> LoopChunk:
    """Extend a chunk's records (which end when its last run landed) to the longest chunk."""
    E = len(t_full)
    for h in chunk.part.histories.values():
        for name in EPOCH_ARRAYS:
            setattr(h, name, _pad(getattr(h, name), E))
        h.nis = {k: _pad(v, E) for k, v in h.nis.items()}
        h.t_s = t_full
    bias = chunk.part.truth_bias
    bias = bias if bias is None else TruthBias.from_arrays({k: _pad(v, E) for k, v in bias.arrays().items()})
    loop = replace(chunk.loop, path_n_m=_pad(chunk.loop.path_n_m, len(path_t_full)), path_t_s=path_t_full)
    return LoopChunk(replace(chunk.part, truth_bias=bias), loop, chunk.failed)


def run_closed_loop(scenario, runs: int, seed: int, workers: int, progress=None):
    """All runs of a closed-loop scenario in chunks of :data:`CLOSED_CHUNK_RUNS`, and the same
    flight guided on the truth (in a thread of this process while a pool's workers fly the runs:
    :class:`_TruthGuided`); returns ``(RunResult, loop, reference)``: ``loop`` the
    :class:`LoopRuns` (per-run outcome, abort and landing times, miss distances and true paths,
    runs in order; None when no run finished), ``reference`` the
    :class:`~navsim.experiment.closed_loop.LoopBatch` of the truth-guided flight."""
    side = _TruthGuided(scenario, seed)
    if workers <= 1:
        side.fly()                                   # first, in this process
    chunks = chunk_ranges(runs, CLOSED_CHUNK_RUNS)
    parts, failed, interrupted = run_chunks(_closed_chunk, chunks, lambda ch, remote: (scenario, seed, ch),
                                            workers, progress, after_submit=side.start)
    reference = side.result()
    if not parts:
        return RunResult({}, np.array([], int), failed, interrupted), None, reference
    t_of = lambda c: next(iter(c.part.histories.values())).t_s
    longest = max(parts, key=lambda c: len(t_of(c)))
    path_t_s = longest.loop.path_t_s
    parts = [_pad_part(c, t_of(longest), path_t_s) for c in parts]
    for c in parts:
        failed.update(c.failed)
    merged = merge_parts([c.part for c in parts])
    order = sorted(parts, key=lambda c: c.part.runs[0])
    done = np.asarray(merged.runs, int)
    loop = LoopRuns.concatenate([c.loop for c in order], path_t_s, done)
    return RunResult(merged.histories, done, failed, interrupted, merged.truth_bias), loop, reference
