"""A run's result and its files: :class:`Result` (what :func:`~navsim.api.runs.run` returns and
:func:`open_result` reads back), :func:`write_report` and :func:`report_figures` (the report of
a result), and how a result is written to its folder (:func:`write_run`: ``metrics.json``,
``run.json``, ``scenario.resolved.yaml``, the per-run data once, in ``chunks/`` or ``runs.npz``).

>>> result = navsim.run(scenario, runs=20, workers=2)          # out=None: nothing is written
>>> ds = result.to_xarray()                                    # run x epoch x axis, with units
>>> navsim.write_report(result, "reports/p0")                 # report.pdf, PNGs, metrics.json
>>> again = navsim.open_result("reports/p0")                   # read-only
"""

from __future__ import annotations

import dataclasses
import json
import logging
import zipfile
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import yaml

from navsim.api.arguments import checked_path
from navsim.experiment import runner
from navsim.experiment.chunkstore import ChunkStore
from navsim.experiment.options import check_flags, shown
from navsim.experiment.reference import stored_kind
from navsim.experiment.results import check_not_being_written, read_files
from navsim.experiment.runner import cached_flight
from navsim.experiment.scenario import Scenario, parse_scenario
from navsim.flight.truth import Truth
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.overrides import set_comments
from navsim.navigation.estimators.base import plugin_sources
from navsim.records.history import ARRAYS, ARRAY_FIELDS, EPOCH_ARRAYS, EstimatorHistory
from navsim.records.metrics import RunMetrics
from navsim.records.run import RunRecord
from navsim.records.samples import SAMPLES_FILE, EstimatorSamples, load_samples, save_samples
from navsim.records.states import SIGMA_STATES
from navsim.records.truth import CalibrationHistory, TruthBias
from navsim.report.figures import ReportInput
from navsim.report.pages import report_pages as _report_pages, write_report as _write_report


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
        if scenario.overrides:
            record = dataclasses.replace(record, overrides=list(scenario.overrides))
        sources = plugin_sources(e.type for e in scenario.estimators)
        if sources:
            record = dataclasses.replace(record, plugins=sources)
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



def check_result(name: str, value) -> None:
    """A :class:`UsageError` naming ``name`` unless ``value`` is a :class:`Result`."""
    if not isinstance(value, Result):
        raise UsageError(f"{name}: {shown(value)} is not a navsim Result (expected what navsim.run or "
                         "navsim.open_result returns)")


def write_run(result: Result, folder: OutputFolder, record: RunRecord | None = None) -> None:
    """``metrics.json``, ``scenario.resolved.yaml``, ``run.json`` (``record``, default the
    result's), ``samples.npz`` and, for a run without a chunk store whose every history is in
    memory, ``runs.npz`` into ``folder``: per-run data is kept once, in ``chunks/`` or there.

    Parameters
    ----------
    result : Result
        A scored run.
    folder : navsim.foundations.outputs.OutputFolder
        The open output folder written into.
    record : RunRecord, optional
        The ``run.json`` written (default ``result.record``).
    """
    record = result.record if record is None else record
    folder.json("metrics.json", result.metrics.to_dict())
    changed = set_comments(result.scenario.overrides)
    folder.text("scenario.resolved.yaml",
                f"# resolved by navsim {result.record.versions['navsim']} at git {result.record.git_revision}\n"
                + changed + yaml.safe_dump(resolved_scenario(result), sort_keys=False))
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


def npz_histories(path: Path, labels) -> tuple:
    """``(runs, histories)`` from a ``runs.npz`` (the NIS are not stored there); an older file
    is read with its keys, and labels that clash there get no history (with a warning).

    Parameters
    ----------
    path : Path
        The ``runs.npz``.
    labels : iterable of str
        The estimators' labels (``metrics.json``'s).

    Returns
    -------
    tuple
        ``(runs, histories)``: the run indices, label -> EstimatorHistory.
    """
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
    """``report.html``, ``report.pdf`` and its PNGs for ``result`` (those of its scenario's
    ``report.formats``); also writes the run's ``metrics.json``,
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
    check_result("result", result)
    check_flags(dict(force=force))
    out = None if out is None else checked_path("out", out, "output folder")
    if out is None and result.folder is None:
        raise UsageError("write_report needs a folder: out=... (the run was held in memory)")
    command = "run" if result.record.log is None else "replay"      # a replayed log's folder is replay's
    with OutputFolder(Path(out) if out is not None else result.folder, command=command, force=force) as folder:
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
        write_run(result, folder, record)
    return _write_report(folder, _report_input(result))


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
    check_result("result", result)
    return _report_pages(_report_input(result))


def _report_input(result: Result) -> ReportInput:
    """What the report's page sources read of ``result``."""
    return ReportInput(result.scenario, _truth(result), result, result.metrics, result.record, result.loop,
                       result.reference, tuple(result.sightings))


def _truth(result: Result):
    """The flight the report draws: the run's, or the cached flight of an open-loop scenario."""
    if result.truth is None and result.scenario.closed_loop is None:
        return cached_flight(result.scenario.flight)[0]
    return result.truth


def open_result(folder) -> Result:
    """The run written to ``folder`` (by ``navsim run`` or :func:`run`), read-only: nothing in
    the folder is written or removed. The histories of up to :data:`navsim.experiment.runner.REPORT_RUNS`
    runs are loaded (from ``runs.npz`` or the first stored chunks); the store
    (:attr:`Result.store`) reads every chunk, one at a time.

    Parameters
    ----------
    folder : path
        The result folder.

    Returns
    -------
    Result

    Raises
    ------
    UsageError
        Not a finished navsim run (a file missing or damaged, named with its key), one being
        written, or its scenario no longer parses.
    """
    folder = checked_path("folder", folder, "result folder")
    check_not_being_written(folder)
    try:
        metrics, record, raw = read_files(folder)
    except OSError as exc:
        raise UsageError(f"{folder}: not a finished navsim run ({exc.strerror or exc})") from None
    except UsageError as exc:
        raise UsageError(f"not a finished navsim run: {exc}") from None
    try:
        scenario = parse_scenario(stored_kind(raw), record.scenario)
    except ScenarioError as exc:
        raise UsageError(f"{folder}: its scenario.resolved.yaml does not parse any more ({exc})") from None
    scenario.overrides = tuple(record.overrides or ())      # already in the resolved mapping
    store = ChunkStore.open(folder / "chunks") if (folder / "chunks" / "index.json").is_file() else None
    histories, runs, bias, calib = {}, np.array([], int), None, {}
    merged = store.merged(runner.REPORT_RUNS) if store is not None else None
    if merged is not None:
        runs, histories, bias, calib = np.asarray(merged.runs, int), merged.histories, merged.truth_bias, merged.calibration
    elif (folder / "runs.npz").is_file():
        runs, histories = npz_histories(folder / "runs.npz", metrics.estimators)
    every = np.asarray(store.runs(), int) if store is not None else runs
    try:
        samples = load_samples(folder / SAMPLES_FILE) if (folder / SAMPLES_FILE).is_file() else {}
    except (OSError, UsageError) as exc:
        logging.getLogger(__name__).warning("%s; the rest of the result is read (compare refuses it)", exc)
        samples = {}
    return Result(scenario, every, histories, metrics, record, folder=folder, truth_bias=bias, calibration=calib,
                  failed=dict(record.failed_runs), interrupted=bool(record.interrupted), store=store,
                  history_runs=None if len(runs) == len(every) else runs, samples=samples,
                  truth=_log_reference(folder, record))


#: a replayed log's reference, as a truth, in its folder (``navsim replay``): the report's flight
LOG_REFERENCE_FILE = "reference.npz"


def _log_reference(folder: Path, record: RunRecord):
    """The reference a replayed log was scored against (None for a scenario's run: its flight
    is the cached one)."""
    if record.log is None:
        return None
    try:
        return Truth.load(folder / LOG_REFERENCE_FILE)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise UsageError(f"{folder}: a replayed log's {LOG_REFERENCE_FILE} cannot be read ({exc})") from None


