"""The verb *budget*: :func:`budget` gives each error source's contribution to every RMS metric
of every estimator (:mod:`navsim.scoring.budget`), from Monte Carlos with each source alone, a
covariance analysis along the flight, or both, with "what if" predictions of a source scaled;
:func:`write_budget` writes ``budget.json``, ``budget.csv`` and the pages."""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navsim import report
from navsim.api.arguments import load_scenario
from navsim.api.runs import run
from navsim.experiment.executors import lend_pool
from navsim.experiment.budget import GROUPS as BUDGET_GROUPS, SCALE_RANGE, alone, budget_sources, find_source
from navsim.experiment.budget import check_method, covariance_contributions, left_out_reasons, linear_sources
from navsim.experiment.budget import scale_ok, scaled
from navsim.experiment.options import RunOptions, shown
from navsim.experiment.runner import cached_flight, scenario_hash
from navsim.experiment.scenario import REPORT_FORMATS, Scenario
from navsim.foundations.errors import UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.provenance import provenance
from navsim.records.samples import load_samples, save_samples
from navsim.report.budget import CSV_HEADERS as BUDGET_CSV_HEADERS, budget_csv_rows, budget_pages
from navsim.report.figures import pyplot
from navsim.report.render import render
from navsim.scoring.budget import METHODS as BUDGET_METHODS, Budget, WhatIf, covariance_budgets, metric_budgets
from navsim.scoring.budget import epoch_mean_squares, monte_carlo_curves, predict, with_covariance

#: the files a budget keeps of each finished Monte Carlo (:func:`budget`'s ``store``)
BUDGET_PARTS = "budget_part_*.npz"


def budget(scenario, runs: int | None = None, seed: int | None = None, workers: int | None = None, *,
           group: str = "source", method: str = "montecarlo", **options) -> Budget:
    """The error budget of every estimator of ``scenario``: each error source's contribution to
    every RMS metric (:mod:`navsim.scoring.budget`); nothing is written.

    Parameters
    ----------
    scenario, runs, seed, workers
        As :func:`run` (each of the Monte Carlos runs so).
    group : {"source", "sensor", "kind"}
        The budget's lines: each source, each sensor (and the initial errors), each sensor's
        kind of term (``imu gyro``).
    method : {"montecarlo", "covariance", "both"}
        ``montecarlo``: the runs with every error source on, with none, and with each source
        alone (the same seeds: each source's realisation is the one it has with all on);
        ``covariance``: one covariance analysis along the flight
        (:mod:`navsim.navigation.covariance`; the sources without a linear form are listed in
        ``monte_carlo_only``, the filters it does not take in ``not_analysed``); ``both``: the
        Monte Carlo budget with each line's covariance figure beside it.
    **options
        ``scales``, a sequence of ``(source, factor)``: "what if", each source scaled by the
        factor; the metric predicted from the budget, then a Monte Carlo with it scaled
        (:class:`~navsim.scoring.budget.WhatIf`). ``store``, an
        :class:`~navsim.foundations.outputs.OutputFolder` opened for a budget: where each
        finished Monte Carlo's per-run samples go (``budget_part_<key>.npz``, keyed by the
        scenario, the source, the runs, the seed and navsim's version), so that an interrupted
        budget keeps them. And how the Monte Carlos run, as :func:`run`'s
        (:class:`~navsim.experiment.options.RunOptions`: ``executor``, ``scheduler``,
        ``chunk_runs``, ``options=``), but ``resume``: read the Monte Carlos ``store``
        already holds instead of running them again, and ``progress``: called
        ``progress(done, total, what)`` after each Monte Carlo (and the covariance analysis).

    Raises
    ------
    UsageError
        No error source in the scenario, an unknown source, group or method, a factor below 0;
        a covariance analysis of a closed loop or of sources none of which has a linear form.
    """
    t0 = time.perf_counter()
    with lend_pool():                 # one pool of workers for the K + 1 Monte Carlos
        return _run_budget(_budgeting(scenario, (runs, seed, workers), group, method, options), t0)


@dataclass(frozen=True)
class _Budgeting:
    """A budget's arguments, checked: what :func:`_run_budget` runs."""

    scenario: Scenario
    sources: list                   #: the scenario's error sources
    group: str
    method: str
    scaled_runs: list               #: ``(source, factor)`` of each "what if"
    how: RunOptions                 #: ``runs`` and ``seed`` filled from the scenario
    store: OutputFolder | None


def _budgeting(scenario, numbers: tuple, group, method, options: dict) -> _Budgeting:
    """:func:`budget`'s arguments checked (``numbers``: its runs, seed and workers), in the
    order it always has: the run options, the scales, the store, the scenario, the group, the
    method."""
    scales, store = options.pop("scales", ()), options.pop("store", None)
    how = RunOptions.of(*numbers, **options)
    scales = _scales(scales)
    _check_store(store)
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    sources = budget_sources(sc)
    if group not in BUDGET_GROUPS:
        raise UsageError(f"group: {group!r} is not a budget's grouping (expected one of {', '.join(BUDGET_GROUPS)})")
    check_method(sc, method, BUDGET_METHODS, sources)
    scaled_runs = [(find_source(name, sources), float(k)) for name, k in scales]
    how = dataclasses.replace(how, runs=sc.runs if how.runs is None else how.runs,
                              seed=sc.seed if how.seed is None else how.seed)
    return _Budgeting(sc, sources, group, method, scaled_runs, how, store)


def _run_budget(b: _Budgeting, t0: float) -> Budget:
    """The budget ``b`` asks for: the covariance analysis and the Monte Carlos (each reported
    to ``b.how.progress``), their budgets and "what if" predictions; ``t0`` when it began."""
    sc, sources, method, progress = b.scenario, b.sources, b.method, b.how.progress
    plan = _budget_plan(sc, sources, b.scaled_runs, method)
    flight = cached_flight(sc.flight) if sc.closed_loop is None else None
    steps = len(plan) + (method != "montecarlo")
    cov = None
    if method != "montecarlo":
        cov = _covariance_budget(sc, sources, flight[0], b.group)
        if progress:
            progress(1, steps, "covariance analysis")
    samples, squares = {}, {}
    for i, (what, variant) in enumerate(plan):
        samples[what], squares[what] = _budget_monte_carlo(variant, b.how, b.store, flight)
        if progress:
            progress(i + 1 + (cov is not None), steps, what)
    metrics, by_source = (cov.metrics, cov.by_source) if method == "covariance" else _monte_carlo_budgets(
        samples, sources, b.group)
    if method == "both":
        metrics = with_covariance(metrics, cov.metrics)
    what_if = _what_ifs(samples, by_source, b.scaled_runs)
    extra = {} if cov is None else dict(monte_carlo_only=cov.left, left_out=left_out_reasons(sc, sources, cov.left),
                                        not_analysed=cov.skipped, covariance_s=cov.wall_s,
                                        covariance_curves=cov.curves)
    if method != "covariance":
        extra["curves"] = monte_carlo_curves(squares, [s.name for s in sources])
    return Budget(sc.name, b.how.runs if method != "covariance" or plan else 0, b.how.seed, [s.name for s in sources],
                  b.group, metrics, what_if, time.perf_counter() - t0, method, **extra, overrides=list(sc.overrides))


def _budget_plan(sc: Scenario, sources, scaled_runs, method: str) -> list:
    """The Monte Carlos of a budget, ``(what, scenario)``: all on, none and each source alone
    (not for a covariance analysis alone), then each scaled source."""
    plan = [(f"{s.name} x{k:g}", scaled(sc, s, k)) for s, k in scaled_runs]
    if method == "covariance":
        return plan
    return [("all on", sc), ("none", alone(sc, None, sources))] + [(s.name, alone(sc, s, sources))
                                                                   for s in sources] + plan


def _budget_part(variant: Scenario, runs: int, seed: int) -> str:
    """The file of one Monte Carlo of a budget, named by a digest of what makes its numbers:
    the variant's content as resolved (its sensor and estimator models, initial errors and
    flight, navsim's version: :func:`~navsim.experiment.runner.scenario_hash`), its metric
    settings, the runs and the seed."""
    key = json.dumps([scenario_hash(variant), variant.raw.get("metrics"), runs, seed], sort_keys=True, default=str)
    return BUDGET_PARTS.replace("*", hashlib.sha256(key.encode()).hexdigest()[:16])


def _budget_monte_carlo(variant: Scenario, how: RunOptions, store: OutputFolder | None, flight):
    """One Monte Carlo of a budget, ``variant`` run as ``how`` says on ``flight``: its per-run
    samples and epoch mean squares (:func:`~navsim.scoring.budget.epoch_mean_squares`), run (and
    kept in ``store``, both in one file) or, with ``how.resume``, read back from ``store``."""
    name = _budget_part(variant, how.runs, how.seed)
    if how.resume and store is not None and (store.path / name).is_file():
        with np.load(store.path / name, allow_pickle=False) as z:
            squares = {str(label): (z[f"squares_t{i}"], z[f"squares_ms{i}"])
                       for i, label in enumerate(z["squares_labels"].tolist())} if "squares_labels" in z.files else None
        if squares is not None:
            store.record([store.path / name])             # this budget's: kept when the folder is cleared
            return load_samples(store.path / name), squares
    res = run(variant, options=dataclasses.replace(how, resume=False, progress=None), flight=flight)
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
        raise UsageError(f"store: {shown(store)} is not an OutputFolder opened for a budget "
                         "(OutputFolder(path, command='budget'), or None)")


def _scales(scales) -> list[tuple[str, float]]:
    """A budget's ``scales`` checked: ``(source, factor)`` pairs, each factor :data:`SCALE_RANGE`."""
    expected = f"expected a sequence of (source, factor) pairs, {SCALE_RANGE}"
    if isinstance(scales, (str, bytes, Mapping)) or not hasattr(scales, "__iter__"):
        raise UsageError(f"scales: {shown(scales)}: {expected}")
    out = []
    for item in scales:
        ok = isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str) and item[0]
        number = ok and isinstance(item[1], (int, float, np.integer, np.floating)) and not isinstance(item[1], bool)
        if not (number and scale_ok(float(item[1]))):
            raise UsageError(f"scales: {shown(item)}: {expected} (imu.gyro.noise_density, 0.5)")
        out.append((item[0], float(item[1])))
    return out



def write_budget(result: Budget, folder: OutputFolder, metrics=None, fmts=REPORT_FORMATS) -> list[Path]:
    """``budget.json``, ``budget.csv`` (one row per estimator, metric and line) and the budget's
    pages (``budget.pdf``, a PNG each: a sorted bar chart per estimator and metric) and
    ``budget.html`` (the tables, sortable, and each source's share with its interval).

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
    if "html" in fmts:                          # Bokeh imported here, on first use
        files.append(folder.write("budget.html", lambda p: p.write_text(report.html.budget_html(result, metrics),
                                                                         encoding="utf-8")))
    return [folder.path / "budget.json", folder.path / "budget.csv", *files]
