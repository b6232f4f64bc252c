"""The sensor catalog: ``sensors/*.yaml`` datasheets in datasheet units, read into SI specs.

A datasheet names its ``kind`` (imu, gnss, baro, ads, radar_altimeter, magnetometer, camera),
says where its numbers come from (``source``) and gives its fields with units (see
:mod:`navsim.sensors.units`). A scenario names an entry and may override any field::

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
from navsim.sensors import specs as S
from navsim.sensors.units import UnitError, number, to_si

#: the catalog's datasheets: the package ``navsim.data.sensors`` (edited in the repository's
#: ``sensors/`` folder), read through importlib.resources
CATALOG_DIR = data_folder("sensors")

# field tables: yaml key -> (spec attribute, dimension, shape); shape "3" broadcasts a scalar
# to three axes, "1" is a scalar, "33" a 3x3 matrix, "plain" a unit-less number, "str" a string
_GYRO = {
    "bias": ("bias", "angular_rate", "3"),
    "bias_sigma": ("bias_sigma", "angular_rate", "3"),
    "bias_instability": ("bias_instability", "angular_rate", "3"),
    "bias_instability_tau": ("bias_instability_tau_s", "time", "1"),
    "markov_sigma": ("markov_sigma", "angular_rate", "3"),
    "markov_tau": ("markov_tau_s", "time", "1"),
    "noise_density": ("noise_density", "angle_random_walk", "3"),
    "random_walk": ("random_walk", "rate_random_walk", "3"),
    "scale_factor": ("scale_factor", "ratio", "3"),
    "scale_factor_sigma": ("scale_factor_sigma", "ratio", "3"),
    "misalignment_sigma": ("misalignment_sigma", "angle", "1"),
    "quantization": ("quantization", "angular_rate", "1"),
    "range": ("range", "angular_rate", "1"),
}
_ACCEL = {k: (a, {"angular_rate": "acceleration", "angle_random_walk": "velocity_random_walk",
                  "rate_random_walk": "acceleration_random_walk"}.get(d, d), s)
          for k, (a, d, s) in _GYRO.items()}
_VIBRATION = {
    "type": ("type", None, "str"),
    "amplitude": ("amplitude", "acceleration", "3"),
    "gyro_amplitude": ("gyro_amplitude", "angular_rate", "3"),
    "frequency_hz": ("frequency_hz", None, "plain"),
    "band_hz": ("band_hz", None, "pair"),
}
FIELDS: dict[str, dict] = {
    "imu": {"rate_hz": ("rate_hz", None, "plain"), "gyro": ("gyro", _GYRO, "group"),
            "accel": ("accel", _ACCEL, "group"), "vibration": ("vibration", _VIBRATION, "list")},
    "gnss": {"rate_hz": ("rate_hz", None, "plain"),
             "position_sigma": ("position_sigma", "length", "3"),
             "horizontal_sigma": ("position_sigma", "length", "h"),
             "vertical_sigma": ("position_sigma", "length", "v"),
             "velocity_sigma": ("velocity_sigma", "speed", "3"),
             "markov_sigma": ("markov_sigma", "length", "3"),
             "markov_tau": ("markov_tau_s", "time", "1"),
             "latency": ("latency_s", "time", "1"),
             "lever_arm": ("lever_arm_b", "length", "3"),
             "velocity_output": ("velocity_output", None, "bool")},
    "baro": {"rate_hz": ("rate_hz", None, "plain"), "offset": ("offset", "length", "1"),
             "offset_sigma": ("offset_sigma", "length", "1"),
             "markov_sigma": ("markov_sigma", "length", "1"),
             "markov_tau": ("markov_tau_s", "time", "1"), "noise": ("noise", "length", "1")},
    "ads": {"rate_hz": ("rate_hz", None, "plain"),
            "static_noise": ("static_noise", "pressure", "1"),
            "static_bias_sigma": ("static_bias_sigma", "pressure", "1"),
            "total_noise": ("total_noise", "pressure", "1"),
            "total_bias_sigma": ("total_bias_sigma", "pressure", "1"),
            "temperature_noise": ("temperature_noise", "temperature", "1"),
            "formula": ("formula", None, "str"), "pitot": ("pitot", None, "str"),
            "velocity_axis": ("velocity_axis", None, "str"),
            "vane_noise": ("vane_noise", "angle", "1")},
    "radar_altimeter": {"rate_hz": ("rate_hz", None, "plain"), "noise": ("noise", "length", "1"),
                        "noise_ratio": ("noise_ratio", "ratio", "1"),
                        "min_range": ("min_range", "length", "1"),
                        "max_range": ("max_range", "length", "1"),
                        "beam_half_width": ("beam_half_width", "angle", "1"),
                        "tilt_noise_gain": ("tilt_noise_gain", "dimensionless", "1"),
                        "wave_height": ("wave_height", "length", "1")},
    "magnetometer": {"rate_hz": ("rate_hz", None, "plain"),
                     "hard_iron": ("hard_iron", "magnetic_field", "3"),
                     "hard_iron_sigma": ("hard_iron_sigma", "magnetic_field", "3"),
                     "soft_iron": ("soft_iron", "dimensionless", "33"),
                     "soft_iron_sigma": ("soft_iron_sigma", "dimensionless", "1"),
                     "noise": ("noise", "magnetic_field", "3"), "date": ("date", None, "str")},
    "camera": {"rate_hz": ("rate_hz", None, "plain"), "half_fov": ("half_fov", "angle", "1"),
               "max_range": ("max_range", "length", "1"), "noise": ("noise", "length", "1"),
               "noise_ratio": ("noise_ratio", "ratio", "1"),
               "landmarks": ("landmarks", None, "landmarks")},
}
_CHOICES = {"type": ("sine", "random"), "formula": ("isa", "p0"),
            "pitot": ("absolute", "differential"), "velocity_axis": ("body_x", "air")}
_NON_NEGATIVE_EXCEPT = {"bias", "offset", "scale_factor", "hard_iron", "lever_arm", "soft_iron"}
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
    if not isinstance(data, dict) or data.get("kind") not in FIELDS:
        raise ScenarioError("needs 'kind'", file=str(path), key="kind",
                            expected="one of " + ", ".join(FIELDS))
    return data, path


def spec_from_datasheet(data: dict, file: str | None = None, path: str = ""):
    """Build the SI spec of a datasheet mapping (catalog entry, possibly with overrides)."""
    kind = data.get("kind")
    if kind not in FIELDS:
        raise ScenarioError(f"is '{kind}'", file=file, key=_join(path, "kind"),
                            expected="one of " + ", ".join(FIELDS), hint=close_match(str(kind), FIELDS))
    values = _read_fields({k: v for k, v in data.items() if k not in META_KEYS}, FIELDS[kind],
                          file, path, S.SPEC_TYPES[kind])
    return S.SPEC_TYPES[kind](**values)


def load_spec(name: str, override: dict | None = None, off=(), file: str | None = None,
              key: str = ""):
    """The spec of catalog entry ``name`` with ``override`` merged and ``off`` error sources
    switched off (``off: all`` gives the ideal sensor)."""
    sheet, sheet_path = load_datasheet(name, _join(key, "model"), file)
    data = merge(sheet, override or {})
    spec = spec_from_datasheet(data, file if override else str(sheet_path),
                               _join(key, "override") if override else "")
    if off == "all":
        return S.ideal(spec)
    known = S.ERROR_FIELDS[data["kind"]]
    for item in off:
        if item not in known:
            raise ScenarioError(f"'{item}' is not an error source of a {data['kind']}", file=file,
                                key=_join(key, "off"), expected="one of " + ", ".join(known),
                                hint=close_match(item, known))
    return S.disable(spec, list(off))


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _read_fields(data: dict, table: dict, file, path, typ) -> dict:
    if not isinstance(data, dict):
        raise ScenarioError("is not a mapping", file=file, key=path or None, expected="a mapping")
    out: dict = {}
    for key, value in data.items():
        where = _join(path, str(key))
        if key not in table:
            raise ScenarioError("is not a known field", file=file, key=where,
                                hint=close_match(str(key), table))
        attr, dim, shape = table[key]
        try:
            if shape == "group":
                out[attr] = S.AxisErrors(**_read_fields(value, dim, file, where, S.AxisErrors))
            elif shape == "list":
                if not isinstance(value, list):
                    raise UnitError("expected a list")
                out[attr] = tuple(S.Vibration(**_read_fields(v, dim, file, f"{where}[{i}]", S.Vibration))
                                  for i, v in enumerate(value))
            elif shape == "plain":            # a rate or a frequency, Hz
                out[attr] = _plain(value, MAX_RATE_HZ)
            elif shape == "str":
                if not isinstance(value, str):
                    raise UnitError(f"is {value!r}, expected a string")
                if key in _CHOICES and value not in _CHOICES[key]:
                    raise UnitError(f"is '{value}', expected one of {', '.join(_CHOICES[key])}")
                out[attr] = value
            elif shape == "bool":
                if not isinstance(value, bool):
                    raise UnitError(f"is {value!r}, expected true or false")
                out[attr] = value
            elif shape == "pair":
                if not (isinstance(value, list) and len(value) == 2):
                    raise UnitError(f"is {value!r}, expected [low, high] with 0 < low < high")
                low, high = (_plain(x, MAX_RATE_HZ) for x in value)
                if not low < high:
                    raise UnitError(f"is {value!r}, expected [low, high] with 0 < low < high")
                out[attr] = (low, high)
            elif shape == "landmarks":
                out[attr] = _landmarks(value)
            else:
                out[attr] = _value(value, dim, shape, key, out.get(attr))
        except UnitError as exc:
            raise ScenarioError(str(exc), file=file, key=where) from None
    return out


def _value(value, dim, shape, key, previous):
    if shape == "33":                # a dimensionless matrix: plain numbers, no unit
        if not (isinstance(value, list) and len(value) == 3 and all(
                isinstance(row, list) and len(row) == 3 for row in value)):
            raise UnitError("expected a 3x3 matrix (list of three rows)")
        return np.array([[to_si(x, "dimensionless") for x in row] for row in value], float)
    v = to_si(value, dim)
    if shape == "1":
        if isinstance(v, np.ndarray):
            raise UnitError("expected one value, not three")
        _check_sign(key, v)
        if key.endswith("tau") and not v > 0:
            raise UnitError(f"is {v:g} s, expected a time constant > 0")
        return float(v)
    arr = np.broadcast_to(np.asarray(v, float), (3,)).copy()
    _check_sign(key, arr)
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


def _check_sign(key, v):
    if key not in _NON_NEGATIVE_EXCEPT and np.any(np.asarray(v) < 0):
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
