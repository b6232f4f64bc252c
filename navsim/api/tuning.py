"""The verb *tune*: :func:`tune` searches an estimator's parameters (Optuna's TPE sampler) for
the lowest objective over Monte Carlo runs against the truth, every trial on the same seed
(common random numbers: trials differ by their parameters, not by their noise), then checks the
best parameters against the original ones, paired, on the tuning seed and on a seed the tuning
never saw (the gap between the two shows over-fitting).

>>> import navsim
>>> t = navsim.tune("scenarios/p0_two_step.yaml", "ES-KF 16, R/10", objective="nees", trials=30, runs=40)
>>> t.record.tuned_entry                 # the estimator's entry with the best values
>>> t.record.checks["held_out"].differences

Objectives: :mod:`navsim.scoring.tuning`; parameters: :mod:`navsim.experiment.tuning`. A tuning
written to a folder (``tune.json``, ``tune.csv``, ``tuned.yaml``, ``tune.journal``: Optuna's
storage) resumes from it (``resume=True``) to the same trials.
"""

from __future__ import annotations

import copy
import csv
import hashlib
import io
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from navsim import report
from navsim.api.arguments import checked_path, overrides_of
from navsim.api.comparisons import compare
from navsim.api.runs import run
from navsim.experiment.executors import lend_pool
from navsim.experiment.runner import cached_flight, default_chunk_runs
from navsim.experiment.scenario import MAX_SEED, REPORT_FORMATS, parse_changed, parse_scenario
from navsim.experiment.tuning import TRUTH_PREFIX, TuneParam, default_params, entry_index, parse_param
from navsim.foundations.config import load_yaml
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.overrides import apply_overrides, make_override, value_at
from navsim.records.tuning import TuneCheck, TuneRecord, TuneTrial
from navsim.records.vocabulary import check_metric_path
from navsim.report.tuning import write_tune_report
from navsim.replay import ReplayOptions, load_ulog, replay, replay_metrics
from navsim.scoring.tuning import (
    DEFAULT_METRIC,
    NEEDS_TRUTH,
    OBJECTIVES,
    band_record,
    nis_objective,
    objective,
    paper_checks_of,
    paper_distance,
    shape_distance,
)

log = logging.getLogger(__name__)
#: the seed the held-out check flies: the tuning seed plus this (runs the tuning never saw)
HELD_OUT_OFFSET = 1_000_003
#: the metrics the checks compare, tuned minus original
CHECKED = ("rms.pos_m", "rms.vel_mps", "rms.att_deg", "nees.average")
STUDY = "navsim-tune"
#: the trials drawn at random before the sampler models the objective (after the original)
STARTUP_TRIALS = 10
JOURNAL = "tune.journal"


@dataclass(frozen=True)
class TuneOptions:
    """How a tuning searches: the objective (:data:`~navsim.scoring.tuning.OBJECTIVES`) and its
    metric, the trials, the runs per trial, the seed (default the scenario's), the worker
    processes, the runs of each check (default ``runs``), the ``--param`` texts (none: each
    noise term scaled), the scenario's ``--set`` changes, and where the runs go (``executor``
    ``local`` or ``dask``, a Dask ``scheduler``: :class:`~navsim.experiment.options.RunOptions`),
    and the weight of the chi-square shape term (:func:`~navsim.scoring.tuning.shape_distance`, 0: none)."""

    objective: str = "nees"
    metric: str = DEFAULT_METRIC
    trials: int = 40
    runs: int = 50
    seed: int | None = None
    workers: int | None = None
    check_runs: int | None = None
    params: tuple = ()
    set: tuple = ()
    executor: str = "local"
    scheduler: str | None = None
    shape: float = 0.0


@dataclass
class TuneResult:
    """A finished tuning: its record (``tune.json``), the check runs, the folder written."""

    record: TuneRecord
    params: list = field(default_factory=list)          #: TuneParam
    folder: Path | None = None

    def to_xarray(self):
        """The trials as an ``xarray.Dataset`` over ``trial``: the objective, each parameter's
        value, the position RMS and the NEES average."""
        import xarray as xr
        trials = self.record.trials
        nan = lambda v: math.nan if v is None else v
        data = {"objective": ("trial", [nan(t.objective) for t in trials]),
                "nees_average": ("trial", [nan(t.nees_average) for t in trials])}
        for p in self.params:
            data[p.what] = ("trial", [t.values.get(p.name, math.nan) for t in trials])
        ds = xr.Dataset(data, coords={"trial": [t.number for t in trials]})
        ds.attrs.update(objective=self.record.objective, estimator=self.record.estimator,
                        best=-1 if self.record.best is None else self.record.best)
        return ds


def _check_options(o: TuneOptions) -> None:
    if o.objective not in OBJECTIVES:
        raise UsageError(f"--objective {o.objective!r}: one of {', '.join(OBJECTIVES)}")
    if not (isinstance(o.shape, (int, float)) and math.isfinite(o.shape) and o.shape >= 0):
        raise UsageError(f"--shape {o.shape!r}: a weight of at least 0")
    for name, v, low in (("trials", o.trials, 1), ("runs", o.runs, 2), ("check-runs", o.check_runs, 2)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < low):
            raise UsageError(f"--{name} {v!r}: a whole number of at least {low}")


class _Trials:
    """The scenario mappings of a tuning: a trial's (the tuned estimator alone, its parameters
    set), the check's (the original and the tuned entries side by side)."""

    def __init__(self, path: Path, label: str, options: TuneOptions):
        self.path, self.label = path, label
        self.base, _ = apply_overrides(load_yaml(path), overrides_of(list(options.set)))
        parsed = parse_changed(self.base, str(path))        # the scenario as changed is valid
        if parsed.closed_loop is not None:
            raise UsageError(f"{path}: a closed-loop scenario (each run flies on an estimator's solution) is not "
                             "tuned: tune its open-loop twin, then fly the tuned entry")
        if options.objective in ("rms", "rms+consistent"):
            check_metric_path(options.metric, parsed.windows, file=str(path), key="--metric")
        self.entry_index = entry_index(self.base, label)
        self.params = ([parse_param(t, label, self.base) for t in options.params] if options.params
                       else default_params(self.base, label))
        self.truth = any(p.truth for p in self.params)
        if self.truth and options.objective != "paper":
            name = next(p.name for p in self.params if p.truth)
            raise UsageError(f"--param {name}: a truth parameter (the sensors' errors) is calibrated against a "
                             f"paper's numbers, --objective paper; {options.objective} would only make the sensors "
                             "as good as the range allows")
        self.paper = paper_checks_of(parsed.reference, label)
        if options.objective == "paper" and not self.paper:
            raise UsageError(f"--objective paper: {path} publishes no single-flight number of '{label}' to fit "
                             "(reference values of kind single_run)")
        self.digest = hashlib.sha256(path.read_bytes()).hexdigest()

    def changed(self, values: dict | None) -> dict:
        """The scenario mapping with ``values`` (name -> trial value) set (None: the original)."""
        changes = [make_override(p.path, p.value(values[p.name]), f"--param {p.name}") for p in self.params
                   if values is not None]
        return apply_overrides(self.base, changes)[0]

    def entry(self, values: dict | None) -> dict:
        """The tuned estimator's entry with ``values`` set (None: the original)."""
        return self.changed(values)["estimators"][self.entry_index]

    def scenario(self, entries: list[dict], values: dict | None = None):
        """The scenario flying ``entries`` only, its sensors with ``values`` set (the truth
        parameters), without its published results (of its estimators)."""
        raw = {k: copy.deepcopy(v) for k, v in self.changed(values).items() if k != "reference"}
        raw["estimators"] = entries
        return parse_scenario(raw, str(self.path))

    def whole(self, values: dict | None):
        """The whole scenario (every estimator, its published results) with ``values`` set."""
        return parse_scenario(self.changed(values), str(self.path))

    def objective(self, o: TuneOptions, result, label: str) -> float | None:
        """The objective of the estimator ``label`` of ``result`` (``paper``: of its runs' values)."""
        m = result.metrics.estimators.get(label)
        if o.objective != "paper":
            return objective(o.objective, m, o.metric)
        if m is None or m.diverged_runs or not m.runs_counted:
            return None
        return paper_distance(self.paper, result.samples.get(label))


def tune(scenario, estimator: str, options: TuneOptions = TuneOptions(), *, out=None, force: bool = False,
         resume: bool = False, progress=None) -> TuneResult:
    """Tune the estimator labelled ``estimator`` of the scenario file ``scenario``.

    Parameters
    ----------
    scenario : path
        The scenario file (its ``--set`` changes in ``options.set``).
    estimator : str
        The label of the estimator tuned.
    options : TuneOptions
        The objective, the trials, the runs per trial, the seed, the parameters.
    out : path, optional
        Write ``tune.json``, ``tune.csv``, ``tuned.yaml``, the report and Optuna's journal there.
    force : bool
        As :func:`navsim.run`'s: write into a non-empty folder that is not navsim's.
    resume : bool
        Continue the tuning in ``out`` (its journal) to ``options.trials`` trials.
    progress : callable, optional
        ``progress(trial)`` after each trial (a :class:`TuneTrial`).

    Returns
    -------
    TuneResult
    """
    _check_options(options)
    path = checked_path("scenario", scenario, "scenario file")
    trials = _Trials(path, estimator, options)
    if resume and out is None:
        raise UsageError("resume needs the folder of the interrupted tuning (out=...)")
    if out is None:
        with lend_pool():              # one pool of workers for every trial and check
            return _tune(trials, options, None, resume, progress)
    with OutputFolder(checked_path("out", out, "output folder"), command="tune", force=force) as folder, lend_pool():
        return _tune(trials, options, folder, resume, progress)


def _tune(trials: _Trials, o: TuneOptions, folder, resume: bool, progress) -> TuneResult:
    import optuna
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    t0 = time.perf_counter()
    first = trials.scenario([trials.entry(None)])
    seed = first.seed if o.seed is None else o.seed
    workers = first.workers if o.workers is None else o.workers
    flight = cached_flight(first.flight)
    for p in trials.params:                        # both ends of every range make a valid scenario
        for end in (p.lo, p.hi):
            ends = {q.name: (end if q is p else q.lo) for q in trials.params}
            trials.scenario([trials.entry(ends)], ends)
    if folder is not None and not resume:
        folder.clear_earlier()
    record = TuneRecord(str(trials.path), trials.label, o.objective, o.metric, [_param_dict(p) for p in trials.params],
                        seed, o.runs, sampler="optuna TPESampler (seeded per trial)", shape=o.shape)
    study = _study(optuna, folder, resume, _key(str(trials.path.resolve()), record)
                   | {"set": list(o.set), "sha256": trials.digest, "shape": o.shape})
    start = _original_values(trials)
    waiting = [t for t in study.get_trials(deepcopy=False) if t.state == optuna.trial.TrialState.WAITING]
    if start and not _finished(study, trials.params) and not waiting:     # trial 0: the original
        study.enqueue_trial(start)
    record.trials = _finished(study, trials.params)
    runs = dict(runs=o.runs, seed=seed, workers=workers, chunk_runs=default_chunk_runs(o.runs, workers),
                flight=flight, executor=o.executor, scheduler=o.scheduler)
    _search(study, record, trials.params, _scenario_trial(trials, o, runs), o.trials, folder, progress)
    best = _best(record)
    record.best, record.tuned_entry = best.number, trials.entry(best.values)
    if trials.truth:
        record.tuned_sensors = trials.changed(best.values)["sensors"]
    check_runs = o.check_runs or o.runs
    checked = _truth_check if trials.truth else _check
    record.checks = {name: checked(trials, best.values, s, check_runs, workers, flight, o)
                     for name, s in (("tuning", seed), ("held_out", (seed + HELD_OUT_OFFSET) % (MAX_SEED + 1)))}
    record.improved = None if start is None else best.number != 0
    record.wall_s = time.perf_counter() - t0
    result = TuneResult(record, trials.params, None if folder is None else folder.path)
    if folder is not None:
        _write(folder, result, first.report.get("formats", REPORT_FORMATS))
    return result


def _search(study, record: TuneRecord, params: list, evaluate, trials: int, folder, progress) -> None:
    """Trials until ``record`` holds ``trials``, each saved to ``tune.json`` as it ends."""
    while len(record.trials) < trials:
        trial = _one_trial(study, params, evaluate, len(record.trials), record.seed, trials)
        record.trials.append(trial)
        if folder is not None:
            folder.json("tune.json", record.to_dict())
        if progress is not None:
            progress(trial)


def _best(record: TuneRecord) -> TuneTrial:
    done = [t for t in record.trials if t.objective is not None]
    if not done:
        raise UsageError(f"no trial of '{record.estimator}' gave an objective (every one diverged or failed)")
    return min(done, key=lambda t: t.objective)


def tune_log(log, estimator: str, options: TuneOptions = TuneOptions(objective="nis"), *, out=None,
             force: bool = False, resume: bool = False, progress=None) -> TuneResult:
    """Tune the registered estimator ``estimator`` on a PX4 log (:func:`navsim.replay.replay`),
    by its innovations alone (a log has no truth), and compare its attitude with PX4's before
    and after.

    Parameters
    ----------
    log : path
        A PX4 ULog (the attitude replay's; the shipped ``tests/data/px4_quad_real_69s.ulg.gz``).
    estimator : str
        A registered estimator name (``cpf_ekf``), built as ``navsim replay`` builds it.
    options : TuneOptions
        ``objective`` ``nis`` or ``nis-band`` (those needing the truth are refused); ``params``
        the ``--param`` texts, paths into the estimator's parameters (``sigma.mag_uT=0.5:20:log``,
        required); ``trials``.
    out, force, resume, progress
        As :func:`tune`'s.

    Returns
    -------
    TuneResult
        Its ``checks["log"]``: the attitude's RMS difference from PX4's and each NIS, original
        against tuned.
    """
    if options.objective in NEEDS_TRUTH:
        raise UsageError(f"--objective {options.objective}: it needs the truth, and a log has none "
                         "(tune a log by its innovations: --objective nis or nis-band)")
    if not options.params:
        raise UsageError("tuning a log needs --param PATH=LO:HI: paths into the estimator's parameters "
                         "(sigma.mag_uT=0.5:20:log)")
    _check_options(options)
    if resume and out is None:
        raise UsageError("resume needs the folder of the interrupted tuning (out=...)")
    params = [parse_log_param(t) for t in options.params]
    replay_log = load_ulog(checked_path("log", log, "PX4 log"))
    # the parameters build the estimator and replay (before a folder is written): the low ends
    replay_checked(replay_log, estimator, _log_params(params, {p.name: p.lo for p in params}))
    if out is None:
        return _tune_log(replay_log, estimator, params, options, None, resume, progress)
    with OutputFolder(checked_path("out", out, "output folder"), command="tune", force=force) as folder:
        return _tune_log(replay_log, estimator, params, options, folder, resume, progress)


def parse_log_param(text: str) -> TuneParam:
    """``PATH=LO:HI[:log]`` of a log's estimator: a path into its parameters (no entry to check,
    so no factor: its values are the estimator's own defaults)."""
    if text.strip().startswith(TRUTH_PREFIX):
        raise UsageError(f"--param {text!r}: a log's sensors are what they were: no truth parameter to set")
    if text.partition("=")[2].strip().startswith("x"):
        raise UsageError(f"--param {text!r}: a factor needs the entry's value, and a log's estimator has no entry: "
                         "give LO:HI")
    return parse_param(text, "log", {"estimators": [{"label": "log"}]}, check=False)


def _log_params(params: list, values: dict) -> dict:
    """The estimator's parameters (``--set`` of ``navsim replay``) with the trial's values."""
    out, _ = apply_overrides({}, [make_override(p.name, p.value(values[p.name]), f"--param {p.name}") for p in params])
    return out


def replay_checked(log, estimator: str, params: dict):
    """The replay of ``log`` through ``estimator`` with ``params`` and its metrics."""
    result = replay(log, estimator, params, ReplayOptions())
    return replay_metrics(result)


def _tune_log(log, estimator: str, params: list, o: TuneOptions, folder, resume: bool, progress) -> TuneResult:
    import optuna
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    t0 = time.perf_counter()
    if folder is not None and not resume:
        folder.clear_earlier()
    record = TuneRecord(str(log.path), estimator, o.objective, "", [_param_dict(p) for p in params],
                        o.seed or 0, 1, sampler="optuna TPESampler (seeded per trial)")
    study = _study(optuna, folder, resume, _key(str(Path(log.path).resolve()), record))
    record.trials = _finished(study, params)

    def evaluate(values: dict):
        m = replay_checked(log, estimator, _log_params(params, values))
        return nis_objective(o.objective, m.nis), None, None
    _search(study, record, params, evaluate, o.trials, folder, progress)
    best = _best(record)
    record.best = best.number
    record.tuned_entry = _log_params(params, best.values)
    before, after = replay_checked(log, estimator, {}), replay_checked(log, estimator, record.tuned_entry)
    record.checks = {"log": _log_check(o, before, after)}
    record.wall_s = time.perf_counter() - t0
    result = TuneResult(record, params, None if folder is None else folder.path)
    if folder is not None:
        _write(folder, result)
    return result


def _log_check(o: TuneOptions, before, after) -> TuneCheck:
    """The attitude's difference from PX4's (RMS per axis) and each NIS, original against tuned."""
    diffs = []
    for axis in ("roll", "pitch", "yaw"):
        a, b = before.attitude_diff_deg.axis(axis), after.attitude_diff_deg.axis(axis)
        if a is not None and b is not None:
            diffs.append({"metric": "attitude - PX4, RMS deg", "component": axis, "a": a.rms, "b": b.rms,
                          "diff": b.rms - a.rms, "ci95": [math.nan, math.nan], "verdict": "one log: no interval"})
    pick = lambda m: {"nees": None, "nis": {k: band_record(n) for k, n in (m.nis or {}).items()}}
    return TuneCheck(0, 1, nis_objective(o.objective, before.nis), nis_objective(o.objective, after.nis), diffs,
                     {"original": pick(before), "tuned": pick(after)})


def _param_dict(p: TuneParam) -> dict:
    return {"name": p.name, "path": p.path, "lo": p.lo, "hi": p.hi, "log": p.log, "base": p.base,
            **({"unit": p.unit} if p.unit else {})}


def _study(optuna, folder, resume: bool, key: dict):
    """The Optuna study: in the folder's journal (resumed: loaded) or in memory. A trial left
    running by an interruption is marked failed (no record: not counted). ``key`` (what the
    trials depend on: the scenario or log, the estimator, the objective, the parameters, the runs
    and seed) is kept with the study; a resumed study of another key is refused."""
    storage = None
    if folder is not None:
        from optuna.storages import JournalStorage
        from optuna.storages.journal import JournalFileBackend
        journal = folder.path / JOURNAL
        folder.record([journal])
        storage = JournalStorage(JournalFileBackend(str(journal)))
    if resume and folder is not None and not (folder.path / JOURNAL).is_file():
        raise UsageError(f"--resume: {folder.path} holds no tuning ({JOURNAL}) to resume")
    try:
        study = optuna.create_study(study_name=STUDY, storage=storage, direction="minimize", load_if_exists=resume)
    except optuna.exceptions.DuplicatedStudyError:
        raise UsageError(f"{folder.path} holds a tuning already: --resume it, or choose another --out") from None
    stored = study.user_attrs.get("navsim_key")
    if stored is None:
        study.set_user_attr("navsim_key", key)
    elif stored != key:
        changed = sorted(k for k in set(stored) | set(key) if stored.get(k) != key.get(k))
        raise UsageError(f"--resume: {folder.path} holds another tuning (its {', '.join(changed)} differ); "
                         "resume it with its own arguments, or choose another --out")
    for t in study.get_trials(deepcopy=False):
        if t.state != optuna.trial.TrialState.RUNNING:
            continue
        done = t.user_attrs.get("navsim")                   # scored, then stopped before it was told
        if done is not None and done["objective"] is not None:
            study.tell(t.number, done["objective"])
        else:                                                # interrupted: no record, not counted
            study.tell(t.number, state=optuna.trial.TrialState.FAIL)
    return study


def _key(source: str, record: TuneRecord) -> dict:
    """What a tuning's trials depend on (a resumed one must match)."""
    return {"source": source, "estimator": record.estimator, "objective": record.objective, "metric": record.metric,
            "params": [{k: v for k, v in p.items()} for p in record.params], "runs": record.runs, "seed": record.seed}


def _original_values(trials: _Trials) -> dict | None:
    """The parameters' values of the original entry (a scaled term: 1), or None where one is
    not a number inside its range (a --param on a list of unequal values, or outside the range)."""
    out = {}
    for p in trials.params:
        if p.truth:                         # a datasheet value with its unit (often the catalog's): no trial 0
            return None
        if p.base is not None:
            out[p.name] = 1.0
            continue
        v = value_at(trials.base, p.path, p.name)
        v = v[0] if isinstance(v, list) and v and all(x == v[0] for x in v) else v
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not p.lo <= v <= p.hi:
            return None
        out[p.name] = float(v)
    return out


def _finished(study, params: list) -> list:
    """The trials of a resumed study (those interrupted left out)."""
    out = []
    for t in study.get_trials(deepcopy=False):
        if t.user_attrs.get("navsim") is None:
            continue
        a = t.user_attrs["navsim"]
        out.append(TuneTrial(len(out), {p.name: t.params[p.name] for p in params}, a["objective"], a["rms_pos_m"],
                             a["nees_average"], a["wall_s"]))
    return out


def _one_trial(study, params: list, evaluate, n: int, seed: int, trials: int) -> TuneTrial:
    """Trial ``n``: the original values first (enqueued), then suggested by a TPE sampler seeded
    for the trial (so a resumed tuning suggests what the uninterrupted one would), scored by
    ``evaluate(values) -> (objective, rms_pos_m, nees_average)``, told its objective."""
    import optuna
    from optuna.distributions import FloatDistribution, IntDistribution
    study.sampler = optuna.samplers.TPESampler(seed=(seed * 7919 + n) % 2**32, n_startup_trials=STARTUP_TRIALS)
    trial = study.ask({p.name: IntDistribution(int(p.lo), int(p.hi), log=p.log) if p.integer
                       else FloatDistribution(p.lo, p.hi, log=p.log) for p in params})
    t0 = time.perf_counter()
    value, rms, nees = evaluate(dict(trial.params))
    record = {"objective": value, "rms_pos_m": rms, "nees_average": nees, "wall_s": time.perf_counter() - t0}
    trial.set_user_attr("navsim", record)
    study.tell(trial, value) if value is not None else study.tell(trial, state=optuna.trial.TrialState.FAIL)
    return TuneTrial(n, dict(trial.params), value, rms, nees, record["wall_s"])


def _scenario_trial(trials: _Trials, o: TuneOptions, runs: dict):
    """A trial's evaluation: the tuned estimator alone over the runs, its objective."""
    def evaluate(values: dict):
        try:
            scenario = trials.scenario([trials.entry(values)], values)
        except ScenarioError as exc:                  # a mix of values the file's checks refuse
            log.warning("trial %s: %s", values, exc)
            return None, None, None
        result = run(scenario, **runs)
        if result.interrupted:                        # Ctrl-C: the trial is not scored
            raise KeyboardInterrupt
        if result.failed:
            return None, None, None
        m = result.metrics.estimators.get(trials.label)
        value = trials.objective(o, result, trials.label) if m is not None else None
        if value is not None and o.shape:
            shape = shape_distance(result.histories[trials.label], m.settle_s, o.objective.startswith("nis"))
            value = value + o.shape * shape if math.isfinite(shape) else None
        rms = None if m is None or m.rms is None else [float(x) for x in m.rms.pos_m]
        return value, rms, None if m is None or m.nees is None else float(m.nees.average)
    return evaluate


def _check(trials: _Trials, values: dict, seed: int, runs: int, workers: int, flight, o: TuneOptions) -> TuneCheck:
    """The original and the tuned entries side by side on ``runs`` runs of ``seed``, paired."""
    original = {**trials.entry(None), "label": "original"}
    tuned = {**trials.entry(values), "label": "tuned"}
    result = run(trials.scenario([original, tuned]), runs=runs, seed=seed, workers=workers,
                 chunk_runs=default_chunk_runs(runs, workers), flight=flight, executor=o.executor,
                 scheduler=o.scheduler)
    if result.interrupted:
        raise KeyboardInterrupt
    (comparison,) = compare(result, None, estimators=("original", "tuned"))
    est = result.metrics.estimators
    diffs = [{"metric": d.metric, "component": d.component, "a": d.a, "b": d.b, "diff": d.diff,
              "ci95": list(d.ci95), "verdict": d.verdict} for d in comparison.differences if d.metric in CHECKED]
    return TuneCheck(seed, runs, trials.objective(o, result, "original"), trials.objective(o, result, "tuned"), diffs,
                     {side: _consistency(est.get(side)) for side in ("original", "tuned")})


def _truth_check(trials: _Trials, values: dict, seed: int, runs: int, workers: int, flight,
                 o: TuneOptions) -> TuneCheck:
    """The whole scenario (every estimator, its published results judged) flown with the
    original and with the fitted truth on ``runs`` runs of ``seed``: the objective of each, and
    the paper checks of each (a calibrated truth's prediction of the other estimators' numbers)."""
    out = {}
    for side, v in (("original", None), ("tuned", values)):
        result = run(trials.whole(v), runs=runs, seed=seed, workers=workers,
                     chunk_runs=default_chunk_runs(runs, workers), flight=flight, executor=o.executor,
                     scheduler=o.scheduler)
        if result.interrupted:
            raise KeyboardInterrupt
        out[side] = result
    est = {side: r.metrics.estimators.get(trials.label) for side, r in out.items()}
    return TuneCheck(seed, runs, trials.objective(o, out["original"], trials.label),
                     trials.objective(o, out["tuned"], trials.label), [],
                     {side: _consistency(m) for side, m in est.items()},
                     {side: [v.to_dict() for v in r.metrics.paper_checks or []] for side, r in out.items()})


def _consistency(m) -> dict:
    """The NEES and each NIS of ``m`` against its band (``average``, ``band``, ``fraction_inside``)."""
    if m is None:
        return {}
    return {"nees": band_record(m.nees) if m.nees else None, "nis": {k: band_record(v) for k, v in (m.nis or {}).items()}}


def _write(folder, result: TuneResult, formats=REPORT_FORMATS) -> None:
    r = result.record
    folder.json("tune.json", r.to_dict())
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["trial", "objective", *[p.what for p in result.params], "rms_pos_n_m", "rms_pos_e_m", "rms_pos_d_m",
                "nees_average", "wall_s"])
    for t in r.trials:
        w.writerow([t.number, t.objective, *[t.values[p.name] for p in result.params], *(t.rms_pos_m or [None] * 3),
                    t.nees_average, round(t.wall_s, 3)])
    folder.text("tune.csv", buf.getvalue())
    use = ("its parameters: give each to navsim replay as --set KEY=VALUE" if "log" in r.checks
           else "paste it into the scenario's estimators")
    text = (f"# '{r.estimator}' tuned by navsim tune ({r.objective}, best trial {r.best}); {use}\n"
            + yaml.safe_dump([r.tuned_entry], sort_keys=False))
    if r.tuned_sensors is not None:
        truth = (f"# the truth model fitted by navsim tune ({r.objective}, best trial {r.best}) on '{r.estimator}': "
                 "paste it over the scenario's sensors\n"
                 + yaml.safe_dump({"sensors": r.tuned_sensors}, sort_keys=False))
        text = truth + (text if any(not p.truth for p in result.params) else "")
    folder.text("tuned.yaml", text)
    folder.record(write_tune_report(folder, result.record, result.params, formats))
    if "html" in formats:                      # Bokeh imported here, on first use
        folder.write("tune.html", lambda p: p.write_text(report.html.tune_html(result.record, result.params),
                                                        encoding="utf-8"))


__all__ = ["TuneOptions", "TuneParam", "TuneResult", "tune", "tune_log"]
