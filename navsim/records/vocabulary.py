"""The metric vocabulary: the dotted paths of an estimator's ``metrics.json`` entry that a
scenario's ``reference:`` and a sweep's ``metric`` may name (``rms.pos_m``,
``windows.<name>.height_m.rms``, ``nis.<measurement>.fraction_inside``, ``diverged_runs``),
derived from the fields of :class:`~navsim.records.metrics.EstimatorMetrics` and checked by
:func:`check_metric_path`."""

from __future__ import annotations

import dataclasses
import types
import typing

from navsim.foundations.config import close_match
from navsim.foundations.errors import ScenarioError
from navsim.records.metrics import EstimatorMetrics


def plain_type(tp):
    """``X`` of ``X | None``."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return args[0] if len(args) == 1 else tp
    return tp


def _field_types(cls) -> dict:
    """Field name -> its type (``None`` removed) of the dataclass ``cls``."""
    hints = typing.get_type_hints(cls)
    return {f.name: plain_type(hints[f.name]) for f in dataclasses.fields(cls)}


#: the fields of an estimator's metrics (its intervals, ``ci95``, are not a metric of their own)
_ESTIMATOR = {k: t for k, t in _field_types(EstimatorMetrics).items() if k != "ci95"}
#: the first part of a metric path with a rest (``rms.pos_m``, ``windows.<name>.height_m.rms``):
#: the sections of :class:`EstimatorMetrics`
METRIC_HEADS = tuple(k for k, t in _ESTIMATOR.items() if dataclasses.is_dataclass(t) or typing.get_origin(t) is dict)
#: the metrics of an estimator that are one number (no dotted rest)
SCALAR_METRICS = tuple(k for k, t in _ESTIMATOR.items() if t in (int, float))
#: a section's fields, which the second part of its paths must name (sections keyed by a name,
#: ``windows`` and ``nis``, are checked by the name: a window of the scenario, any measurement)
SECTION_FIELDS = {k: tuple(_field_types(t)) for k, t in _ESTIMATOR.items() if dataclasses.is_dataclass(t)}
#: the error statistics, each per quantity (:class:`~navsim.records.metrics.ErrorStats`)
ERROR_QUANTITIES = SECTION_FIELDS["rms"]


def check_metric_path(path: str, windows, *, file: str | None, key: str) -> None:
    """Raise :class:`ScenarioError` unless ``path`` names a metric of an estimator's
    metrics.json (:data:`METRIC_HEADS`, :data:`SECTION_FIELDS`; ``windows.<name>`` a window of
    ``windows``, each ``(name, start_s, end_s)``)."""
    head, _, rest = path.partition(".")
    if head in SCALAR_METRICS and not rest:
        return
    if head not in METRIC_HEADS or not rest:
        raise ScenarioError(f"'{path}' is not a metric", file=file, key=key,
                            expected=" or ".join([f"{h}.*" for h in METRIC_HEADS] + list(SCALAR_METRICS)),
                            hint=close_match(head, METRIC_HEADS + SCALAR_METRICS))
    part = rest.split(".")[0]
    if head in SECTION_FIELDS and part not in SECTION_FIELDS[head]:
        raise ScenarioError(f"'{path}' is not a metric", file=file, key=key,
                            expected=" or ".join(f"{head}.{q}" for q in SECTION_FIELDS[head]),
                            hint=close_match(part, SECTION_FIELDS[head]))
    if head == "windows" and part not in [w[0] for w in windows]:
        raise ScenarioError(f"window '{part}' is not defined under metrics.windows", file=file, key=key,
                            hint=close_match(part, [w[0] for w in windows]))
