"""``navsim sweep``: a grid (or list) of changes to a scenario, each point a Monte Carlo run.

A sweep file::

    scenario: p3_sins_gps.yaml        # relative to the sweep file
    runs: 10                          # per point (default: the scenario's)
    grid:                             # Cartesian product over dotted key paths
      sensors.imu.override.gyro.bias_sigma: [0.01 deg/h, 0.1 deg/h]
      estimators[1].series_order: [3, 6]
    # or points: [{key: value, ...}, ...]
    metric: rms.pos_m                 # a metrics.json path; vectors are shown by their norm
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navsim.experiment.resources import check_held
from navsim.experiment.runner import cached_flight
from navsim.experiment.scenario import check_scenario, parse_changed, parse_scenario
from navsim.foundations.config import MAX_RUNS, Node, close_match, load_yaml
from navsim.foundations.errors import FlightError, ScenarioError, UsageError
from navsim.foundations.overrides import make_override, set_in
from navsim.records.metrics import EstimatorMetrics, Window
from navsim.records.vocabulary import check_metric_path, plain_type

#: the most points a sweep may have (each is a Monte Carlo of its own)
MAX_POINTS = 10_000


def set_path(data, path: str, value, file=None, where="grid"):
    """Set ``value`` at ``path`` (``a.b[2].c``, ``estimators[ES-KF 16].period_s``: the grammar of
    :mod:`navsim.foundations.overrides`) in ``data``, in place; an error names ``file`` and
    ``where.path``."""
    try:
        set_in(data, make_override(path, value))
    except ScenarioError as exc:
        raise ScenarioError(exc.detail, file=file, key=f"{where}.{path}", hint=exc.hint) from None


def parse_sweep(path: str | Path, overrides=()):
    """The sweep file's ``(scenario path, runs, metric, points)``, checked; ``overrides`` (the
    ``--set``) are checked on the scenario first, and its metrics windows are the changed
    scenario's."""
    path = Path(path)
    node = Node(load_yaml(path), "", str(path))
    scenario = node.get("scenario", str)
    base_path = (path.parent / scenario)
    relative = "a scenario YAML path relative to the sweep file"
    if Path(scenario).is_absolute():
        raise node.error(f"'{scenario}' is an absolute path", "scenario", expected=relative,
                         hint="a sweep file names its scenario relative to itself, so that the two move "
                         "together (a copied or shared folder of both still runs): put them side by side")
    if Path(scenario).suffix.lower() not in (".yaml", ".yml") or not base_path.is_file():
        raise node.error(f"'{scenario}' not found next to the sweep file", "scenario", expected=relative)
    runs = node.get("runs", int, None, minimum=1, maximum=MAX_RUNS)
    metric = node.get("metric", str, "rms.pos_m")
    base = load_yaml(base_path)
    if overrides:                             # a bad --set named before anything runs
        base = parse_changed(base, str(base_path), overrides).raw
    check_metric_path(metric, [(w, 0, 0) for w in _window_names(base)], file=str(path), key="metric")
    check_number_path(metric, file=str(path), key="metric")
    grid = node.child("grid", None)
    node._seen.add("points")
    points = node.data.get("points")
    if (grid is None) == (points is None):
        raise node.error("needs exactly one of 'grid' or 'points'")
    if grid is not None:
        keys = list(grid.data)
        for k in keys:
            grid._seen.add(k)
            if not isinstance(grid.data[k], list) or not grid.data[k]:
                raise grid.error("is not a non-empty list of values", str(k))
        size = math.prod(len(grid.data[k]) for k in keys)
        if size > MAX_POINTS:             # counted before the product is built
            raise grid.error(f"has {size:g} points", expected=f"at most {MAX_POINTS} points (the product of "
                             "the lists' lengths)", hint="sweep fewer values, or split the sweep")
        points = [dict(zip(keys, combo)) for combo in itertools.product(*(grid.data[k] for k in keys))]
        grid.done()
    elif not (isinstance(points, list) and points and all(isinstance(p, dict) for p in points)):
        raise node.error("is not a list of mappings", "points")
    elif len(points) > MAX_POINTS:
        raise node.error(f"has {len(points)} points", "points", expected=f"at most {MAX_POINTS} points")
    node.done()
    return base_path, runs, metric, points


#: what a sweep's metric must name (its value is compared point by point)
NUMBER_EXPECTED = "the path of a number or of a list of numbers, a vector shown by its norm"


def _is_number(tp) -> bool:
    """Whether a field of type ``tp`` holds a number or a list of numbers (None allowed)."""
    tp = plain_type(tp)
    if typing.get_origin(tp) is list:
        item = typing.get_args(tp)[0]
        union = typing.get_origin(item) in (typing.Union, types.UnionType)
        return all(a in (int, float, type(None)) for a in (typing.get_args(item) if union else (item,)))
    return tp in (int, float)


def _members(tp) -> dict | None:
    """The names under a group of metrics of type ``tp`` -> their types (a mapping by name:
    ``{"*": type}``; a window's quantities beside its ``horizontal_m`` and ``nees``, as its
    mapping has them); None: not a group."""
    tp = plain_type(tp)
    if dataclasses.is_dataclass(tp):
        hints = typing.get_type_hints(tp)
        out = {f.name: hints[f.name] for f in dataclasses.fields(tp) if f.name != "ci95"}
        if tp is Window:
            out["*"] = typing.get_args(out.pop("quantities"))[1]
        return out
    if typing.get_origin(tp) is dict:
        return {"*": typing.get_args(tp)[1]}
    return None


def check_number_path(metric: str, *, file: str, key: str) -> None:
    """Raise :class:`ScenarioError` unless ``metric`` (a path that
    :func:`~navsim.records.vocabulary.check_metric_path` took) names a number or a list of
    numbers of an estimator's metrics: not a group of them, not a path past a number
    (``rms.pos_m.ci95``), nothing else (a list of lists, of records)."""
    tp, walked = EstimatorMetrics, []
    for part in metric.split("."):
        members = _members(tp)
        if members is None:
            raise ScenarioError(f"'{metric}': '{'.'.join(walked)}' is a number or a list of numbers, with nothing "
                                "under it", file=file, key=key, expected=NUMBER_EXPECTED,
                                hint=f"metric: {'.'.join(walked)} (its 95 % intervals are in sweep.json's ci95)")
        if part not in members and "*" not in members:
            raise ScenarioError(f"'{metric}' is not a metric", file=file, key=key, expected=NUMBER_EXPECTED,
                                hint=close_match(part, members))
        tp = members.get(part, members.get("*"))
        walked.append(part)
    members = _members(tp)
    if members is not None:
        names = [m for m in members if m != "*"] + ([f"<{'quantity' if plain_type(tp) is Window else 'name'}>"]
                                                   if "*" in members else [])
        raise ScenarioError(f"'{metric}' is a group of metrics ({', '.join(names)})", file=file, key=key,
                            expected=NUMBER_EXPECTED, hint=f"metric: {metric}.{'rms' if 'rms' in names else names[0]}")
    if not _is_number(tp):
        raise ScenarioError(f"'{metric}' is not a number nor a list of numbers", file=file, key=key,
                            expected=NUMBER_EXPECTED)


def _window_names(data) -> list[str]:
    """The names of the windows under the scenario mapping's ``metrics.windows`` (read loosely:
    the scenario itself is checked point by point)."""
    windows = ((data or {}).get("metrics") or {}).get("windows") if isinstance(data, dict) else None
    return [w.get("name") for w in windows if isinstance(w, dict)] if isinstance(windows, list) else []


@dataclass
class SweepResult:
    """The rows ``(point, {label: metric value})`` of the points run, the metric, the first
    error of each point none of whose runs succeeded (point index -> message), and whether the
    sweep was interrupted (the points after it are not run)."""

    rows: list
    metric: str
    failed_points: dict = field(default_factory=dict)
    interrupted: bool = False
    #: each point's whole :class:`~navsim.records.metrics.RunMetrics`, in the order of ``rows``
    metrics: list = field(default_factory=list)
    #: each point's label -> the 95 % interval ``[lo, hi]`` of its value (None: none), in the
    #: order of ``rows``
    intervals: list = field(default_factory=list)
    #: the indices of the points whose flight cannot be flown (a reason in ``failed_points``)
    unflown: set = field(default_factory=set)
    #: the ``--set`` changes made to the scenario before each point's (``PATH=VALUE``)
    overrides: tuple = ()

    def interval(self, row: int, label: str) -> list[float] | None:
        """The interval of point ``row``'s value of ``label`` (None: none)."""
        return self.intervals[row].get(label) if row < len(self.intervals) else None

    def axes(self) -> dict:
        """Parameter -> its values in the order the points take them (a grid's axes)."""
        out = {}
        for point, _ in self.rows:
            for k, v in point.items():
                values = out.setdefault(k, [])
                if v not in values:
                    values.append(v)
        return out


@dataclass(frozen=True)
class SweepPlan:
    """A parsed sweep: its points, each as a checked scenario, the runs per point (None: the
    scenario's) and the metric compared."""

    points: list
    scenarios: list
    runs: int | None
    metric: str
    path: Path
    #: point index -> why its flight cannot be flown (the sweep's other points go on)
    unflown: dict = field(default_factory=dict)


def plan_sweep(path, overrides=()) -> SweepPlan:
    """Every point of the sweep file ``path`` parsed, flown (or read from the flight cache) and
    checked against the duration flown, so a bad point stops the sweep before any Monte Carlo
    starts; a :class:`ScenarioError` names the sweep file and the point. A point whose flight
    cannot be flown (a wind the aircraft cannot make way against) is in ``unflown``.
    ``overrides`` (the ``--set``) change the scenario before each point's changes."""
    base_path, runs, metric, points = parse_sweep(path, overrides)
    base = load_yaml(base_path)
    if overrides:
        base = parse_changed(base, str(base_path), overrides).raw
    where = lambda i: f"{path}: point {i + 1}/{len(points)} ({points[i]}) of {base_path}"
    scenarios, unflown = [], {}
    for i, point in enumerate(points):
        data = copy.deepcopy(base)
        for key, value in point.items():
            set_path(data, key, value, str(path), f"points[{i}]")
        try:
            sc = parse_scenario(data, str(base_path))
            try:                                 # each point's runs are held in memory
                check_held(sc, runs or sc.runs, held="sweep")
            except UsageError as exc:
                raise UsageError(f"{where(i)}: {exc}") from None
            check_scenario(sc, cached_flight(sc.flight)[0].duration_s)
        except ScenarioError as exc:
            raise (exc.with_file(where(i)) if exc.file in (None, str(base_path)) else exc) from None
        except FlightError as exc:
            unflown[i] = str(exc)
        sc.overrides = tuple(o.as_text() for o in overrides)
        scenarios.append(sc)
    return SweepPlan(points, scenarios, runs, metric, Path(path), unflown)


def point_values(plan: SweepPlan, estimators: dict) -> dict:
    """Estimator label -> the sweep's metric of one point (vectors by their norm), from the
    point's :class:`~navsim.records.metrics.EstimatorMetrics`."""
    values = {}
    for label, scores in estimators.items():
        v = scores.get(plan.metric)
        if isinstance(v, dict):
            raise ScenarioError(f"'{plan.metric}' is a group of metrics ({', '.join(v)})", file=str(plan.path),
                                key="metric", expected="the path of a number or of a list of three")
        if isinstance(v, list):        # a vector by its norm, over the axes it has (None: not estimated)
            v = float(np.linalg.norm([x for x in v if x is not None]))
        values[label] = v
    return values
