"""Datasheet units -> SI, in one place.

A datasheet value is a number with its unit in a string, ``"0.2 deg/h"``, ``"150 ug/rtHz"``,
``"25 m"``, or a list of three numbers with one unit, ``"[0.1, 0.1, 0.2] deg/h"``, or a mapping
``{value: 0.2, unit: deg/h}``. Each datasheet field has a *dimension*; its unit must be one of
that dimension's units, otherwise :func:`to_si` raises :class:`UnitError` naming the
acceptable ones.
"""

from __future__ import annotations

import math
import re

import numpy as np

from navsim.foundations.config import check_number

G0_MPS2 = 9.80665          #: standard gravity, m/s^2 (for g, mg, ug)
DEG = math.pi / 180.0
HOUR_S = 3600.0

#: dimension -> {unit: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "angular_rate": {"rad/s": 1.0, "deg/s": DEG, "deg/h": DEG / HOUR_S, "rad/h": 1.0 / HOUR_S,
                     "dps": DEG, "dph": DEG / HOUR_S},
    # angle random walk, rad/sqrt(s): deg/sqrt(h) = deg/h/sqrt(Hz) / 60
    "angle_random_walk": {"rad/s/rtHz": 1.0, "rad/rts": 1.0, "deg/rth": DEG / 60.0,
                          "deg/s/rtHz": DEG, "deg/h/rtHz": DEG / HOUR_S, "dps/rtHz": DEG},
    # rate random walk, rad/s/sqrt(s)
    "rate_random_walk": {"rad/s/rts": 1.0, "deg/h/rth": DEG / HOUR_S / 60.0, "deg/s/rts": DEG},
    "acceleration": {"m/s2": 1.0, "m/s^2": 1.0, "g": G0_MPS2, "mg": 1e-3 * G0_MPS2,
                     "ug": 1e-6 * G0_MPS2},
    # velocity random walk, m/s/sqrt(s) = m/s^2/sqrt(Hz)
    "velocity_random_walk": {"m/s2/rtHz": 1.0, "m/s/rts": 1.0, "ug/rtHz": 1e-6 * G0_MPS2,
                             "mg/rtHz": 1e-3 * G0_MPS2, "m/s/rth": 1.0 / 60.0, "ft/s/rth": 0.3048 / 60.0},
    # acceleration random walk, m/s^2/sqrt(s)
    "acceleration_random_walk": {"m/s2/rts": 1.0, "m/s3/rtHz": 1.0, "ug/rts": 1e-6 * G0_MPS2,
                                 "ug/rth": 1e-6 * G0_MPS2 / 60.0, "m/s/h/rth": 1.0 / HOUR_S / 60.0},
    "ratio": {"1": 1.0, "ppm": 1e-6, "%": 1e-2, "percent": 1e-2},
    "angle": {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": DEG, "arcmin": DEG / 60.0,
              "arcsec": DEG / 3600.0},
    "length": {"m": 1.0, "cm": 0.01, "mm": 1e-3, "km": 1e3, "ft": 0.3048},
    "speed": {"m/s": 1.0, "mps": 1.0, "km/h": 1.0 / 3.6, "kt": 1852.0 / 3600.0, "ft/s": 0.3048},
    "time": {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": HOUR_S},
    "frequency": {"Hz": 1.0, "kHz": 1e3},
    "pressure": {"Pa": 1.0, "hPa": 100.0, "mbar": 100.0, "kPa": 1e3, "inHg": 3386.389},
    "temperature": {"K": 1.0, "degC": 1.0},     # differences only (noise, offsets)
    "magnetic_field": {"T": 1.0, "uT": 1e-6, "nT": 1e-9, "G": 1e-4, "mG": 1e-7},
    "dimensionless": {"1": 1.0},
}

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_SCALAR = re.compile(rf"^\s*({_NUMBER})\s*(\S*)\s*$")
_VECTOR = re.compile(r"^\s*\[([^\]]*)\]\s*(\S*)\s*$")


class UnitError(ValueError):
    """A value whose unit is missing or not one of its dimension's units."""


def units_of(dimension: str) -> list[str]:
    return list(UNITS[dimension])


def to_si(value, dimension: str):
    """Convert a datasheet value to SI: a float, or a (3,) array for a three-axis value.

    Numbers without a unit are accepted only for the ``dimensionless`` dimension; NaN and
    infinite values (``.nan``, ``1e400 m``) are refused.
    """
    out = _to_si(value, dimension)
    if not np.all(np.isfinite(out)):
        raise UnitError(f"is {value!r}, expected finite numbers")
    return out


def _to_si(value, dimension: str):
    if isinstance(value, dict):
        if set(value) != {"value", "unit"}:
            raise UnitError("a mapping value needs exactly 'value' and 'unit'")
        given, unit = value["value"], str(value["unit"])
        if isinstance(given, list):
            if len(given) != 3:
                raise UnitError(f"a list of {len(given)} values, expected three (x, y, z)")
            return np.array([number(v) for v in given], float) * _factor(unit, dimension)
        return number(given) * _factor(unit, dimension)
    if isinstance(value, bool):
        raise UnitError(f"is a boolean, expected a number with a unit ({_hint(dimension)})")
    if isinstance(value, (int, float)):
        if dimension == "dimensionless":
            return number(value)
        if value == 0:
            return 0.0          # zero needs no unit
        raise UnitError(f"{number(value):g} has no unit; write it with one of: {_hint(dimension)}")
    if isinstance(value, list):
        if len(value) != 3:
            raise UnitError(f"a list of {len(value)} values, expected three (x, y, z)")
        if dimension == "dimensionless" or all(v == 0 for v in value):
            return np.array([number(v) for v in value], float)
        raise UnitError(f"a list needs its unit after it, e.g. '[1, 1, 2] {units_of(dimension)[0]}'")
    if not isinstance(value, str):
        raise UnitError(f"expected a number with a unit ({_hint(dimension)})")
    m = _VECTOR.match(value)
    if m:
        parts = [p for p in m.group(1).split(",") if p.strip()]
        if len(parts) != 3:
            raise UnitError(f"'{value}': a vector needs three values (x, y, z)")
        unit = m.group(2) or "1"
        return np.array([number(p) for p in parts], float) * _factor(unit, dimension)
    m = _SCALAR.match(value)
    if not m:
        raise UnitError(f"'{value}' is not a number with a unit ({_hint(dimension)})")
    unit = m.group(2) or "1"
    return number(float(m.group(1))) * _factor(unit, dimension)


def number(v) -> float:
    """A datasheet number (a number or its text) within the global bounds of
    :func:`navsim.foundations.config.check_number` (no NaN, infinity, boolean, 1e308 or 1e-308)."""
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            raise UnitError(f"'{v}' is not a number") from None
    def refuse(message, expected):
        raise UnitError(f"{message}, expected {expected}")
    return check_number(v, float, error=refuse)


def _factor(unit: str, dimension: str) -> float:
    table = UNITS[dimension]
    if unit in table:
        return table[unit]
    if unit == "1" and dimension != "dimensionless":
        raise UnitError(f"has no unit; use one of: {_hint(dimension)}")
    raise UnitError(f"unit '{unit}' is not a unit of {dimension.replace('_', ' ')}; "
                    f"use one of: {_hint(dimension)}")


def _hint(dimension: str) -> str:
    return ", ".join(units_of(dimension))
