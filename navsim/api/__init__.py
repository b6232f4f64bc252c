"""navsim's Python API: load a scenario, run its Monte Carlo, read a finished run back, write
its report; sweep, compare and budget. ``navsim run`` is this API with a progress bar and a
summary table.

>>> import navsim
>>> scenario = navsim.load_scenario("scenarios/p0_bd_sins_ads.yaml")
>>> result = navsim.run(scenario, runs=20, workers=2)          # out=None: nothing is written
>>> result.metrics.estimators["BD/SINS/ADS ES-KF 16"].rms.pos_m   # typed (navsim.records.metrics)
>>> ds = result.to_xarray()                                    # run x epoch x axis, with units
>>> navsim.write_report(result, "reports/p0")                 # report.html, .pdf, PNGs, metrics.json
>>> again = navsim.open_result("reports/p0")                   # read-only

A run written to a folder holds ``metrics.json`` (:attr:`Result.metrics`), ``run.json``
(:attr:`Result.record`: seed, runs, versions, git revision), ``scenario.resolved.yaml`` and
the per-run histories once: in ``chunks/``, or in ``runs.npz`` for a run held in memory and
written with :func:`write_report`.

One module per verb: :mod:`~navsim.api.runs` (:func:`run`), :mod:`~navsim.api.results` (the
:class:`Result`, :func:`open_result`, :func:`write_report`, :func:`report_figures`),
:mod:`~navsim.api.sweeps` (:func:`sweep`), :mod:`~navsim.api.replays` (:func:`read_log`,
:func:`replay_log`: an INS/GNSS log through a scenario's estimators, scored as one run),
:mod:`~navsim.api.tuning` (:func:`tune`: an estimator's noise searched over Monte Carlo runs), :mod:`~navsim.api.comparisons` (:func:`compare`,
:func:`write_comparison`), :mod:`~navsim.api.budgets` (:func:`budget`, :func:`write_budget`);
:mod:`~navsim.api.arguments` checks what they are given (:func:`load_scenario`). How the runs are
made is one :class:`~navsim.experiment.options.RunOptions` (``options=``, or its fields as
keywords), whose checks the command line shares (:data:`RUNS`, :data:`SEED`, :data:`WORKERS`,
:data:`CHUNK_RUNS`, :data:`EXECUTORS`, :func:`check_scheduler`).
"""

from navsim.api.arguments import load_scenario
from navsim.api.budgets import BUDGET_PARTS, budget, write_budget
from navsim.api.comparisons import compare, write_comparison
from navsim.api.results import (
    NPZ_KEYS,
    XARRAY_METRICS,
    Result,
    npz_key,
    open_result,
    report_figures,
    resolved_scenario,
    write_report,
)
from navsim.api.replays import read_log, replay_log
from navsim.api.runs import run
from navsim.api.sweeps import sweep
from navsim.api.tuning import TuneOptions, TuneResult, tune, tune_log
from navsim.experiment.options import (
    CHUNK_RUNS,
    EXECUTORS,
    RUNS,
    SCHEDULER_SCHEMES,
    SEED,
    WORKERS,
    RunOptions,
    check_scheduler,
)
from navsim.foundations.errors import UsageError
from navsim.records.chunk import ChunkPart

__all__ = ["BUDGET_PARTS", "CHUNK_RUNS", "ChunkPart", "EXECUTORS", "NPZ_KEYS", "RUNS", "Result", "RunOptions",
           "SCHEDULER_SCHEMES", "SEED", "UsageError", "WORKERS", "XARRAY_METRICS", "budget", "check_scheduler",
           "compare", "load_scenario", "npz_key", "open_result", "read_log", "replay_log", "report_figures",
           "resolved_scenario", "run", "sweep", "TuneOptions", "TuneResult", "tune", "tune_log", "write_budget", "write_comparison", "write_report"]
