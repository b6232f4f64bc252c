"""The verb *sweep*: :func:`sweep` runs every point of a sweep file (:mod:`navsim.experiment.sweep`)
through :func:`~navsim.api.runs.run`, held in memory, and gathers each point's metric with its
95 % interval into a :class:`~navsim.experiment.sweep.SweepResult`."""

from __future__ import annotations

import dataclasses

from navsim.api.arguments import checked_path, overrides_of
from navsim.api.runs import run
from navsim.experiment.executors import lend_pool
from navsim.experiment.options import RunOptions, check_flags
from navsim.experiment.sweep import SweepResult, plan_sweep, point_values
from navsim.foundations.errors import UsageError
from navsim.scoring.samples import value_interval


def sweep(path, workers: int | None = None, *, on_point=None, set=None, **options) -> SweepResult:  # noqa: A002
    """Every point of a sweep file (``navsim sweep``) through :func:`run`, held in memory, so
    every scenario feature works at every point (closed loop, landmarks, magnetometer
    calibration). All points are parsed and checked before the first runs.

    Parameters
    ----------
    path : path
        The sweep file (:mod:`navsim.experiment.sweep`).
    workers : int, optional
        Default: each point's scenario's.
    on_point : callable, optional
        ``on_point(index, point, values, result)`` after each point (its :class:`Result`;
        None for a point whose flight cannot be flown).
    set : mapping or sequence of str, optional
        Changes to the sweep's scenario before each point's, as :func:`load_scenario`'s.
    **options
        How each point's runs are made, as :func:`run`'s (``executor``, ``scheduler``,
        ``chunk_runs``, or ``options=RunOptions(...)``); ``runs`` and ``seed``, when given,
        replace the sweep file's runs and each point's seed. ``progress``: called
        ``progress(1)`` after each point. ``resume`` is refused (a sweep is held in memory).

    Returns
    -------
    SweepResult
        The rows ``(point, {label: value})`` and each value's 95 % interval
        (``intervals``); the points none of whose runs succeeded, or whose flight cannot be
        flown (their values None, their metrics None; the other points go on); whether it was
        interrupted (the points after it are not run).
    """
    how = RunOptions.of(workers=workers, **options)
    check_flags({}, dict(on_point=on_point))
    if how.resume:
        raise UsageError("resume: a sweep is held in memory, there is nothing to resume (expected False)")
    overrides = overrides_of(set)
    plan = plan_sweep(checked_path("path", path, "sweep file"), overrides)
    result = SweepResult([], plan.metric, overrides=tuple(o.as_text() for o in overrides))
    with lend_pool():                  # one pool of workers for every point
        for i, (point, sc) in enumerate(zip(plan.points, plan.scenarios)):
            res = None
            if i in plan.unflown:
                _unflown(result, i, point, sc, plan.unflown[i])
            else:
                res = run(sc, options=dataclasses.replace(how, runs=how.runs or plan.runs or sc.runs, progress=None,
                                                          seed=sc.seed if how.seed is None else how.seed,
                                                          workers=how.workers or sc.workers))
                if res.interrupted:
                    result.interrupted = True
                    break
                _scored(result, i, point, res, plan)
            if on_point:
                on_point(i, point, result.rows[-1][1], res)
            if how.progress:
                how.progress(1)
    return result


def _unflown(result: SweepResult, i: int, point: dict, sc, why: str) -> None:
    """The row of the point ``i`` whose flight cannot be flown (``why``): no values, no metrics."""
    result.failed_points[i] = f"the flight cannot be flown: {why}"
    result.unflown.add(i)
    result.rows.append((point, {e.label: None for e in sc.estimators}))
    result.metrics.append(None)
    result.intervals.append({})


def _scored(result: SweepResult, i: int, point: dict, res, plan) -> None:
    """The row of the point ``i`` run as ``res``: its values, metrics and intervals (a failed
    point when none of its runs succeeded)."""
    if not len(res.runs):
        result.failed_points[i] = min(res.failed.items())[1] if res.failed else "no run"
    result.rows.append((point, point_values(plan, res.metrics.estimators)))
    result.metrics.append(res.metrics)
    result.intervals.append({label: value_interval(m, res.samples.get(label), plan.metric)
                             for label, m in res.metrics.estimators.items()})
