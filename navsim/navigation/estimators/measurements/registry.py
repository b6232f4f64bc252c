"""The registry of measurement model types (:data:`MEASUREMENTS`, a
:class:`~navsim.foundations.registry.Registry`, filled by :func:`measurement`) and the
scenario's ``measurements:`` entries read through it: :func:`parse_measurements`,
:func:`build_measurements`, :func:`measurements_schema`, :func:`values_read`, and the checks a
type's ``parse`` shares (:func:`sensor_of_kind`, :func:`sensor_names`)."""

from __future__ import annotations

import functools
import warnings

from navsim.foundations.config import Node, close_match
from navsim.foundations.jsonschema import merge_properties
from navsim.foundations.registry import Registry
from navsim.navigation.estimators.measurements.model import LINEARISED_FIELDS, Linearised, _own


def _returns_linearised(name: str, model):
    """``model`` whose result is a :class:`Linearised`: a plug-in's model that returns the former
    ``(z, H, R, valid)`` tuple gets it wrapped (with a ``DeprecationWarning``), anything else is a
    ``TypeError`` naming the type."""
    @functools.wraps(model)
    def wrapped(self, nav, layout, data, j):
        out = model(self, nav, layout, data, j)
        if isinstance(out, Linearised):
            return out
        if isinstance(out, tuple) and len(out) == len(LINEARISED_FIELDS):
            warnings.warn(f"measurement '{name}': model() returns a tuple; return a Linearised(z, H, R, valid) "
                          "(navsim.navigation.estimators.Linearised)", DeprecationWarning, stacklevel=2)
            return Linearised(*out)
        raise TypeError(f"measurement '{name}': model() returned {type(out).__name__}, expected a Linearised")
    wrapped.returns_linearised = True
    return wrapped


def _checked(name: str, cls: type) -> type:
    """The :data:`MEASUREMENTS` registry's check: ``cls`` has ``parse``, ``from_entry`` and
    ``model`` (a :class:`TypeError` naming what it lacks); its ``model`` returns a
    :class:`Linearised` (a former tuple is wrapped, deprecated) and its ``name`` is ``name``."""
    for attr in ("parse", "from_entry", "model"):
        if not callable(getattr(cls, attr, None)):
            raise TypeError(f"measurement '{name}': {cls.__name__} has no {attr}()")
    if not getattr(cls.model, "returns_linearised", False):
        cls.model = _returns_linearised(name, cls.model)
    cls.name = name
    return cls


#: the measurement model types by name (built in: registered when their family's module is
#: imported; a plug-in's: when its module is)
MEASUREMENTS: Registry[type] = Registry("measurement type", check=_checked)


def measurement(name: str):
    """Class decorator: register a measurement model type as ``name`` (the ``type`` of its
    scenario entries; also the model's ``name``, the first part of its NIS key). Its ``model``
    returns a :class:`Linearised` (a former tuple is wrapped, deprecated)."""
    return MEASUREMENTS.decorator(name)


def measurement_types() -> list[str]:
    """The registered measurement types, sorted."""
    return MEASUREMENTS.names()


def measurement_class(name: str) -> type:
    """The measurement model type registered as ``name`` (a :class:`KeyError` naming the
    closest one)."""
    return MEASUREMENTS.get(name)


def sensor_of_kind(node: Node, sensors: dict, kind: str) -> str:
    """The entry's ``sensor``, checked to be a sensor of ``kind`` (``sensors``: name -> kind)."""
    name = node.data["sensor"]
    if sensors[name] != kind:
        raise node.error(f"'{name}' is a {sensors[name]}", "sensor", expected=f"a {kind} sensor",
                         hint=close_match(name, [k for k, v in sensors.items() if v == kind]))
    return name


def sensor_names(node: Node, key: str, sensors: dict) -> list | None:
    """The optional list of sensor names under ``key``, each a sensor of the scenario."""
    node._seen.add(key)
    names = node.data.get(key)
    if names is None:
        return None
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise node.error(f"is {names!r}", key, expected="a list of sensor names")
    for n in names:
        if n not in sensors:
            raise node.error(f"'{n}' is not a sensor of this scenario", key, expected="one of " + ", ".join(sensors),
                             hint=close_match(n, sensors))
    return list(names)


def parse_measurements(node: Node, sensors: dict, key: str = "measurements") -> list:
    """The list under ``key`` of an estimator's entry, each checked by its type's ``parse``:
    ``{"type", "sensor", **its values}``. ``sensors``: the scenario's sensor name -> kind."""
    raw = node.items(key, 1, "a list of measurement models", "e.g. [{type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}]")
    out = []
    for j, item in enumerate(raw):
        m = Node(item, node.key(f"{key}[{j}]"), node.file)
        mtype = m.get("type", str, choices=measurement_types())
        sensor = m.get("sensor", str)
        if sensor not in sensors:
            raise m.error(f"'{sensor}' is not a sensor of this scenario", "sensor",
                          expected="one of " + ", ".join(sensors) if sensors else "a sensor under 'sensors'",
                          hint=close_match(sensor, sensors))
        entry = {"type": mtype, "sensor": sensor, **measurement_class(mtype).parse(m, sensors)}
        m.done()
        out.append(entry)
    return out


def build_measurements(entries: list) -> list:
    """The measurement models of entries read by :func:`parse_measurements`."""
    return [measurement_class(e["type"]).from_entry(e) for e in entries]


def measurements_schema(built_in: bool = False) -> dict:
    """The JSON Schema of a ``measurements`` entry: every registered type's keys (``built_in``:
    navsim's own types only)."""
    names = [n for n in measurement_types() if not built_in or measurement_class(n).__module__.startswith("navsim.")]
    props = {"type": {"enum": names}, "sensor": {"type": "string"}}
    for name in names:
        merge_properties(props, measurement_class(name).SCHEMA)
    return {"type": "object", "properties": props, "additionalProperties": False, "required": ["type", "sensor"]}


def values_read(entry: dict) -> tuple | None:
    """The sensor values the model of ``entry`` reads (its ``field`` and its type's
    ``reads(entry)``), or None when its type does not say (a plug-in without ``reads``)."""
    reads = _own(measurement_class(entry["type"]), "reads")
    if reads is None:
        return None
    return tuple(reads(entry)) + ((entry["field"],) if "field" in entry else ())
