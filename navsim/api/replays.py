"""The verb *replay* for INS/GNSS logs: :func:`read_log` reads one (KF-GINS text or CSV,
:mod:`navsim.replay.kfgins`, :mod:`navsim.replay.csvlog`; a PX4 ULog with GNSS,
:mod:`navsim.replay.ulog_nav`), :func:`replay_log` runs a scenario's
estimators over it as one Monte Carlo run (:func:`navsim.replay.logrun.run_log`), scored by the
same scorer into a :class:`~navsim.api.results.Result`: every metric, interval and report page a
run has, against the log's reference (or the difference from the log's own solution).

>>> import navsim
>>> log = navsim.read_log("data/kf-gins.yaml")                  # or imu.csv, gnss=..., reference=...
>>> result = navsim.replay_log(log, "scenarios/p3_sins_gps.yaml", out="reports/my_log")
>>> result.metrics.estimators["SINS/GPS 15-state"].rms.pos_m
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from navsim.api.arguments import checked_path, load_scenario
from navsim.api.results import LOG_REFERENCE_FILE, Result, write_run
from navsim.api.runs import score_result
from navsim.experiment.scenario import Scenario
from navsim.foundations.errors import UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.resources import data_folder
from navsim.records.run import RunRecord
from navsim.replay.csvlog import read_csv_log
from navsim.replay.kfgins import read_kfgins
from navsim.replay.logrun import run_log, without_gnss_velocity
from navsim.replay.navlog import NavLog
from navsim.replay.ulog_nav import ulog_navlog

#: the scenario whose estimators a log is replayed through unless another is named: P3's
#: 15-state loosely coupled ES-KF (GNSS position and velocity) beside free inertial
DEFAULT_LOG_SCENARIO = "p3_sins_gps"
#: the formats :func:`read_log` reads
LOG_FORMATS = ("kfgins", "csv", "ulog")


def log_format(path) -> str:
    """The format a log file's name says: ``.ulg`` (``.ulg.gz``) a PX4 ULog, ``.csv`` CSV,
    anything else (``.txt``, a ``.yaml`` configuration, ``.nav``) KF-GINS text."""
    name = Path(path).name.lower()
    return "ulog" if name.endswith((".ulg", ".ulg.gz")) else "csv" if name.endswith(".csv") else "kfgins"


def read_log(log, gnss=None, reference=None, start=None, *, format: str | None = None,  # noqa: A002
             solution: bool = False) -> NavLog:
    """Read an INS/GNSS log.

    Parameters
    ----------
    log : path
        The IMU file, or for KF-GINS its configuration (``.yaml``, naming the other files), or a
        PX4 ULog with GNSS (:func:`navsim.replay.ulog_nav.ulog_navlog`: EKF2's solution as the
        ``solution``).
    gnss, reference : path, optional
        The GNSS fixes and the reference trajectory (KF-GINS: default the configuration's).
    start : path, optional
        A YAML file with KF-GINS's start keys (``starttime``, ``initpos``, ..., ``initattstd``);
        for KF-GINS the configuration is one.
    format : {"kfgins", "csv", "ulog"}, optional
        Default: :func:`log_format` of ``log``'s name.
    solution : bool
        ``reference`` is the log's own navigation solution (a KF-GINS result, a flight computer's
        estimate), not a truth: the scores are differences from it.

    Raises
    ------
    LogError
        A file or line that cannot be read (exit 2 on the command line), naming it.
    """
    fmt = format or log_format(log)
    if fmt not in LOG_FORMATS:
        raise UsageError(f"format '{fmt}': the logs navsim reads are {', '.join(LOG_FORMATS)}")
    if fmt == "ulog":
        if gnss or reference or start or solution:
            raise UsageError("a PX4 log holds its GNSS and its solution (EKF2's): no gnss, reference, start")
        return ulog_navlog(log)
    if fmt == "kfgins":
        is_config = Path(log).suffix.lower() in (".yaml", ".yml")
        if is_config and start is not None:
            raise UsageError(f"{log} is a KF-GINS configuration, the log's start: no start file besides")
        config = log if is_config else start
        nav = read_kfgins(None if is_config else log, gnss, reference, config)
    else:
        nav = read_csv_log(log, gnss, reference, start)
    if solution and nav.reference is not None:
        nav.files["solution"] = nav.files.pop("reference")
    return nav


def replay_log(log: NavLog, scenario=None, *, set=None, out=None, force: bool = False,  # noqa: A002
               progress=None) -> Result:
    """Run the estimators of ``scenario`` over ``log`` and score them as one run.

    Parameters
    ----------
    log : NavLog
        What :func:`read_log` returns (or a log built in Python).
    scenario : Scenario, path or mapping, optional
        Whose estimators, initial 1-sigma (where the log gives none) and metrics settings are
        used; its sensors name the log's streams (its IMU, its first GNSS receiver); its flight
        is not flown. Default: the shipped :data:`DEFAULT_LOG_SCENARIO` (its GNSS velocity
        measurement left out, with a note, for fixes without velocity).
    set : mapping or sequence of str, optional
        ``--set`` changes to the scenario (:func:`navsim.load_scenario`).
    out : path, optional
        Write ``metrics.json``, ``run.json``, ``scenario.resolved.yaml``, ``runs.npz``, the
        reference (``reference.npz``) there; :func:`navsim.write_report` then writes the report.
    force : bool
        As :func:`navsim.run`'s: write into a non-empty folder that is not navsim's.
    progress : callable, optional
        ``progress(i, n)`` over the IMU samples.

    Returns
    -------
    Result
        Scored; ``record.log`` names the log's files and what it is scored against.
    """
    log = dataclasses.replace(log, notes=list(log.notes))      # the replay's notes, not the log's
    default = scenario is None
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(data_folder("scenarios") / f"{DEFAULT_LOG_SCENARIO}.yaml" if default
                                 else scenario, set=set)
    elif set:
        raise UsageError("set= changes a scenario read from a file or a mapping, not a parsed Scenario")
    if default and log.gnss.vel_n_mps is None:
        scenario = without_gnss_velocity(scenario, log.notes)
    scenario = for_log(scenario, log)
    out = None if out is None else checked_path("out", out, "output folder")
    if out is None:
        return _replay(log, scenario, None, progress)
    with OutputFolder(Path(out), command="replay", force=force) as folder:
        return _replay(log, scenario, folder, progress)


def for_log(scenario: Scenario, log: NavLog) -> Scenario:
    """The scenario as a log's replay runs it: one run, named for the log, without the published
    results it checks (they are of its own flight); a :class:`UsageError` where its settling time
    or a metrics window ends after the log."""
    late = [f"metrics.settle_s {scenario.settle_s:g} s"] if scenario.settle_s >= log.duration_s else []
    late += [f"the window '{name}' ({a:g}-{b:g} s)" for name, a, b in scenario.windows if b > log.duration_s]
    if late:
        raise UsageError(f"{' and '.join(late)} of {scenario.path or 'the scenario'} end(s) after the log "
                         f"({log.duration_s:.1f} s): --set metrics.settle_s=... or metrics.windows=[]")
    raw = {k: v for k, v in scenario.raw.items() if k != "reference"}
    raw["montecarlo"] = {**(raw.get("montecarlo") or {}), "runs": 1, "workers": 1}
    estimators = scenario.estimators
    if log.format == "ulog":          # a receiver's fixes fall between the filter epochs
        late = [e.label for e in estimators if e.params.get("latest_sample") is False]
        estimators = tuple(dataclasses.replace(e, params={**e.params, "latest_sample": True}) if e.label in late
                           else e for e in estimators)
        if late:
            log.notes.append(f"latest_sample set for {', '.join(late)}: each takes the latest fix since its last "
                             "epoch (the receiver's fixes fall between the epochs)")
    return dataclasses.replace(scenario, name=f"{log.name} ({scenario.name})", raw=raw, runs=1, workers=1,
                               reference=None, estimators=estimators)


def _replay(log: NavLog, scenario: Scenario, folder, progress) -> Result:
    t0 = time.perf_counter()
    rr, truth = run_log(log, scenario, progress)
    against = "solution" if "solution" in log.files else "reference"
    record = RunRecord(scenario=None if scenario.path is None else str(scenario.path), runs=1, runs_done=1,
                       seed=scenario.seed, log={"format": log.format, "files": dict(log.files),
                                                "scored_against": against, "notes": list(log.notes)})
    result = Result.from_run(scenario, rr, record, truth=truth)
    score_result(result, time.perf_counter() - t0)
    if folder is not None:
        folder.clear_earlier()
        write_run(result, folder)
        folder.write(LOG_REFERENCE_FILE, truth.save)
        result.folder = folder.path
    return result
