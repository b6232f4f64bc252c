"""The sensor catalog: ``sensors/*.yaml`` datasheets in datasheet units, read into SI specs.

A datasheet names its ``kind`` (a registered sensor kind: imu, gnss, baro, ads, radar_altimeter,
magnetometer, camera, or one a user's module registers), says where its numbers come from
(``source``) and gives its fields with units (see :mod:`navsim.sensors.units`); each kind's
fields are declared with the kind (:class:`navsim.sensors.registry.SensorKind`, ``fields``). A scenario names an entry and may override any field::

    imu: {model: p0_imu, override: {gyro: {bias_sigma: 0.5 deg/h}}, off: [accel.noise_density]}

An unknown field, a missing or wrong unit, a negative sigma: :class:`ScenarioError` naming the
file and the key path.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from navsim.foundations.config import MAX_RATE_HZ, check_number, close_match, load_yaml, resolve_file
from navsim.foundations.errors import ScenarioError
from navsim.foundations.resources import data_folder
from navsim.sensors import registry
from navsim.sensors.units import UnitError, number, to_si

#: the catalog's datasheets: the package ``navsim.data.sensors`` (edited in the repository's
#: ``sensors/`` folder), read through importlib.resources
CATALOG_DIR = data_folder("sensors")

META_KEYS = {"kind", "description", "source", "name"}


def available() -> dict[str, str]:
    """Catalog entries: name -> kind."""
    return {name: kind for name, (kind, _) in entries().items()}


def entries() -> dict[str, tuple[str, str]]:
    """Catalog entries: name -> (kind, description)."""
    out = {}
    for path in sorted(CATALOG_DIR.glob("*.yaml")):
        data = load_yaml(path)
        if isinstance(data, dict):
            out[path.stem] = (data.get("kind", "?"), str(data.get("description", "")).strip())
    return out


def merge(base: dict, override: dict) -> dict:
    """Deep merge of mappings (lists and scalars are replaced)."""
    out = copy.deepcopy(base)
    for key, value in (override or {}).items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_datasheet(name: str, key: str = "model", file: str | None = None) -> tuple[dict, Path]:
    """The datasheet ``name`` names (a catalog entry, or a ``.yaml`` file beside or below the
    scenario ``file``, see :func:`navsim.foundations.config.resolve_file`) and its path."""
    path = resolve_file(name, catalog=CATALOG_DIR, file=file, key=key, what="in the sensor catalog",
                        choices=available)
    data = load_yaml(path)
    if not isinstance(data, dict) or not isinstance(data.get("kind"), str) or not registry.known(data["kind"]):
        raise ScenarioError("needs 'kind'", file=str(path), key="kind",
                            expected="one of " + ", ".join(registry.available()),
                            hint=close_match(str(data.get("kind")), registry.available())
                            if isinstance(data, dict) and "kind" in data else None)
    return data, path


def spec_from_datasheet(data: dict, file: str | None = None, path: str = ""):
    """Build the SI spec of a datasheet mapping (catalog entry, possibly with overrides)."""
    kind = data.get("kind")
    if not isinstance(kind, str) or not registry.known(kind):
        raise ScenarioError(f"is '{kind}'", file=file, key=_join(path, "kind"),
                            expected="one of " + ", ".join(registry.available()),
                            hint=close_match(str(kind), registry.available()))
    declared = registry.get(kind)
    values = _read_fields({k: v for k, v in data.items() if k not in META_KEYS}, declared.fields, file, path)
    return declared.spec(**values)


def load_spec(name: str, override: dict | None = None, off=(), file: str | None = None,
              key: str = ""):
    """The spec of catalog entry ``name`` with ``override`` merged and ``off`` error sources
    switched off (``off: all`` gives the ideal sensor)."""
    sheet, sheet_path = load_datasheet(name, _join(key, "model"), file)
    data = merge(sheet, override or {})
    spec = spec_from_datasheet(data, file if override else str(sheet_path),
                               _join(key, "override") if override else "")
    kind = registry.get(data["kind"])
    if off == "all":
        return kind.ideal(spec)
    known = kind.error_names()
    for item in off:
        if item not in known:
            raise ScenarioError(f"'{item}' is not an error source of a {data['kind']}", file=file,
                                key=_join(key, "off"), expected="one of " + ", ".join(known),
                                hint=close_match(item, known))
    return kind.disable(spec, list(off))


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _read_fields(data: dict, table: dict, file, path) -> dict:
    """The spec attributes of a datasheet mapping ``data`` read by the field ``table``
    (:class:`~navsim.sensors.registry.Field` per key), in SI."""
    if not isinstance(data, dict):
        raise ScenarioError("is not a mapping", file=file, key=path or None, expected="a mapping")
    out: dict = {}
    for key, value in data.items():
        where = _join(path, str(key))
        if key not in table:
            raise ScenarioError("is not a known field", file=file, key=where,
                                hint=close_match(str(key), table))
        f = table[key]
        try:
            out[f.attr] = _field(f, value, key, file, where, out.get(f.attr))
        except UnitError as exc:
            raise ScenarioError(str(exc), file=file, key=where) from None
    return out


def _field(f, value, key: str, file, where: str, previous):
    """One datasheet value read as its :class:`~navsim.sensors.registry.Field` says."""
    if f.shape == "group":
        return f.dim.cls(**_read_fields(value, f.dim.table, file, where))
    if f.shape == "list":
        if not isinstance(value, list):
            raise UnitError("expected a list")
        return tuple(f.dim.cls(**_read_fields(v, f.dim.table, file, f"{where}[{i}]")) for i, v in enumerate(value))
    if f.shape == "plain":            # a rate or a frequency, Hz
        return _plain(value, MAX_RATE_HZ)
    if f.shape == "str":
        if not isinstance(value, str):
            raise UnitError(f"is {value!r}, expected a string")
        if f.dim and value not in f.dim:
            raise UnitError(f"is '{value}', expected one of {', '.join(f.dim)}")
        return value
    if f.shape == "bool":
        if not isinstance(value, bool):
            raise UnitError(f"is {value!r}, expected true or false")
        return value
    if f.shape == "pair":
        if not (isinstance(value, list) and len(value) == 2):
            raise UnitError(f"is {value!r}, expected [low, high] with 0 < low < high")
        low, high = (_plain(x, MAX_RATE_HZ) for x in value)
        if not low < high:
            raise UnitError(f"is {value!r}, expected [low, high] with 0 < low < high")
        return (low, high)
    if f.shape == "landmarks":
        return _landmarks(value)
    return _value(value, f, key, previous)


def _value(value, f, key, previous):
    """A value with a unit (``f.dim``) of shape ``1``, ``3``, ``h``, ``v`` or ``33``."""
    dim, shape = f.dim, f.shape
    if shape == "33":                # a dimensionless matrix: plain numbers, no unit
        if not (isinstance(value, list) and len(value) == 3 and all(
                isinstance(row, list) and len(row) == 3 for row in value)):
            raise UnitError("expected a 3x3 matrix (list of three rows)")
        return np.array([[to_si(x, "dimensionless") for x in row] for row in value], float)
    v = to_si(value, dim)
    if shape == "1":
        if isinstance(v, np.ndarray):
            raise UnitError("expected one value, not three")
        _check_sign(f, v)
        if key.endswith("tau") and not v > 0:
            raise UnitError(f"is {v:g} s, expected a time constant > 0")
        return float(v)
    arr = np.broadcast_to(np.asarray(v, float), (3,)).copy()
    _check_sign(f, arr)
    if shape in ("h", "v"):       # horizontal / vertical sigma into the NED triple
        base = np.zeros(3) if previous is None else previous.copy()
        if shape == "h":
            base[:2] = arr[:2]
        else:
            base[2] = arr[2]
        return base
    return arr


def _plain(value, maximum: float) -> float:
    """A positive unit-less number (a rate or a frequency, Hz) of at most ``maximum``."""
    def refuse(message, expected):
        raise UnitError(f"{message}, expected {expected}")
    return check_number(value, float, exclusive_minimum=0.0, maximum=maximum, error=refuse)


def _check_sign(f, v):
    if not f.signed and np.any(np.asarray(v) < 0):
        raise UnitError(f"is negative ({v}), expected a value >= 0")


def _landmarks(value):
    if not isinstance(value, list):
        raise UnitError("expected a list of [lat_deg, lon_deg, h_m]")
    out = []
    for i, item in enumerate(value):
        ok = isinstance(item, list) and len(item) == 3
        if ok:
            try:
                item = [number(x) for x in item]
            except UnitError:
                ok = False
        if not ok or not (-90 <= item[0] <= 90 and -180 <= item[1] <= 180):
            raise UnitError(f"landmark [{i}] is {item!r}, expected [lat_deg, lon_deg, h_m] "
                            "(finite numbers, latitude -90..90, longitude -180..180)")
        out.append(tuple(float(x) for x in item))
    return tuple(out)
