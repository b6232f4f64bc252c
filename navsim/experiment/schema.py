"""The JSON Schema of scenario files (``docs/scenario.schema.json``), for editors.

navsim's own validation (:mod:`navsim.experiment.scenario`) is stricter (units, cross references such as
a measurement's sensor); the schema catches structure and names while typing.
"""

from __future__ import annotations

import json

from navsim.experiment.scenario import MAX_INITIAL, MAX_SEED, MAX_WORKERS, RATE_HZ, REPORT_FORMATS
from navsim.flight.environment import MAX_TURBULENCE_SEED
from navsim.flight.track import MAX_AIRSPEED_MPS, SEGMENT_KEYS, START_CLASSES
from navsim.foundations.config import MAX_DURATION_S, MAX_RUNS, MAX_WIND_MPS, PLAIN_NAME_PATTERN
from navsim.foundations.jsonschema import NUM, POS, merge_properties, obj
from navsim.navigation.estimators import available as available_estimators, get as get_estimator
from navsim.navigation.estimators.measurements import measurements_schema
from navsim.records.reference import KINDS, RULES
from navsim.sensors.base import FAULT_TYPES
from navsim.sensors.catalog import available

TIME = {"type": "number", "minimum": 0, "maximum": MAX_DURATION_S}


def _vec3(minimum: float, maximum: float) -> dict:
    """A number or three, each within ``[minimum, maximum]``."""
    one = {"type": "number", "minimum": minimum, "maximum": maximum}
    return {"oneOf": [one, {"type": "array", "items": one, "minItems": 3, "maxItems": 3}]}


AIRSPEED = {"type": "number", "exclusiveMinimum": 0, "maximum": MAX_AIRSPEED_MPS}
WIND = {"type": "number", "minimum": -MAX_WIND_MPS, "maximum": MAX_WIND_MPS}
QUANTITY = {"description": "a number with its unit, e.g. '0.2 deg/h' or '[1, 1, 2] m'",
            "oneOf": [{"type": "string"}, {"type": "number"}, {"type": "array"},
                      {"type": "object", "properties": {"value": {}, "unit": {"type": "string"}},
                       "required": ["value", "unit"], "additionalProperties": False}]}


#: the parser's bounds (navsim.foundations.config.Node.get) by their JSON Schema names
_JSON_BOUND = {"minimum": "minimum", "maximum": "maximum", "exclusive_minimum": "exclusiveMinimum"}


def _segment(kind: str) -> dict:
    props = {"type": {"const": kind}, "label": {"type": "string"}, "speed_mps": AIRSPEED}
    for key, (typ, _default, cons) in SEGMENT_KEYS[kind].items():
        props[key] = ({"type": "string", "enum": list(cons["choices"])} if "choices" in cons
                      else {"type": "number", **{_JSON_BOUND[k]: v for k, v in cons.items()}})
    return obj(props, ["type"])


def scenario_schema(built_in: bool = False) -> dict:
    """The scenario schema: with every registered estimator and measurement type, plug-ins'
    included, or (``built_in``) navsim's own only (the published ``docs/scenario.schema.json``)."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "navsim scenario",
        "$defs": {"measurement": measurements_schema(built_in)},
        "description": "One experiment: flight, sensors, estimators, Monte Carlo, metrics, report.",
        **obj({
            "name": {"type": "string", "pattern": PLAIN_NAME_PATTERN,
                     "description": "a plain name: it names the output folder reports/<name>"},
            "description": {"type": "string"}, "aircraft": {"type": "string"},
            "track": _track(), "environment": _environment(),
            "flight": obj({"rate_hz": {"type": "number", "minimum": RATE_HZ[0], "maximum": RATE_HZ[1]}}),
            "sensors": {"type": "object", "additionalProperties": _sensor()},
            "estimators": {"type": "array", "minItems": 1, "items": _estimator(built_in)},
            "initial_errors": obj({**{k: _vec3(0.0, m) for k, m in MAX_INITIAL.items()}, "fixed": {"type": "boolean"}}),
            "montecarlo": obj({"runs": {"type": "integer", "minimum": 1, "maximum": MAX_RUNS},
                               "seed": {"type": "integer", "minimum": 0, "maximum": MAX_SEED},
                                "workers": {"type": "integer", "minimum": 1, "maximum": MAX_WORKERS}}),
            "metrics": obj({"settle_s": TIME,
                             "windows": {"type": "array", "items": obj(
                                 {"name": {"type": "string"}, "start_s": TIME, "end_s": TIME},
                                 ["name", "start_s", "end_s"])}}),
            "reference": _reference(),
            "report": obj({"formats": {"type": "array", "items": {"enum": list(REPORT_FORMATS)}},
                            "runs_plotted": {"type": "integer", "minimum": 0}}),
            "closed_loop": _closed_loop(),
        }, ["track"]),
    }


def _reference() -> dict:
    """``reference``: published numbers (``values``) and claims, each judged by a rule."""
    rule = {"check": {"enum": list(RULES)}, "tolerance": POS, "kind": {"enum": list(KINDS)}}
    number = {"oneOf": [NUM, {"type": "array", "items": NUM, "minItems": 3, "maxItems": 3}]}
    value = {"oneOf": [number, obj({"paper": number, **rule}, ["paper"])]}
    threshold = {"oneOf": [number, obj({"times": POS, "of": {"type": "string"}}, ["times", "of"])]}
    claim = obj({"claim": {"type": "string"}, "estimator": {"type": "string"}, "metric": {"type": "string"},
                 "at_most": threshold, "at_least": threshold, "kind": rule["kind"]}, ["claim", "estimator", "metric"])
    return obj({"source": {"type": "string"}, "note": {"type": "string"}, "kind_note": {"type": "string"}, **rule,
                "values": {"type": "object", "additionalProperties": {"type": "object", "additionalProperties": value}},
                "claims": {"type": "array", "items": claim}}, ["source", "kind"])


def _start() -> dict:
    """``track.start``: air, launch, ground or (a multirotor's) hover."""
    start = obj({"type": {"enum": list(START_CLASSES)}, "lat_deg": NUM, "lon_deg": NUM, "alt_m": NUM,
                  "speed_mps": AIRSPEED, "heading_deg": NUM, "pitch_deg": NUM, "roll_deg": NUM, "launcher_height_m": POS,
                  "booster_thrust_n": NUM, "booster_time_s": NUM},
                 ["lat_deg", "lon_deg", "alt_m"])
    # a parked (ground) start has no speed, a hover's has a default; the others need one
    start["if"] = {"properties": {"type": {"enum": ["ground", "hover"]}}, "required": ["type"]}
    start["else"] = {"required": ["speed_mps"]}
    return start


def _track() -> dict:
    """``track``: a shipped track's name or a start and segments."""
    return {"oneOf": [{"type": "string", "description": "a shipped track: p0, p3, p2_sea"},
                      obj({"name": {"type": "string"}, "description": {"type": "string"}, "start": _start(),
                            "segments": {"type": "array", "minItems": 1,
                                         "items": {"oneOf": [_segment(k) for k in SEGMENT_KEYS]}}},
                           ["start", "segments"])]}


def _environment() -> dict:
    """``environment``: wind (and its changes), turbulence, surface height."""
    wind = {"speed_mps": {**WIND, "minimum": 0}, "from_deg": NUM, "force": {"type": "integer", "minimum": 0, "maximum": 6},
            "north_mps": WIND, "east_mps": WIND, "down_mps": WIND}
    return obj({
        "wind": obj(wind),
        "wind_changes": {"type": "array", "minItems": 1, "items": obj({**wind, "at_s": TIME}, ["at_s"])},
        "turbulence": obj({"type": {"enum": ["none", "milspec", "tustin"]}, "wind20_mps": NUM,
                            "severity": {"type": "integer", "minimum": 0, "maximum": 7},
                            "seed": {"type": "integer", "minimum": 0, "maximum": MAX_TURBULENCE_SEED}}),
        "surface_m": NUM})


def _sensor() -> dict:
    """One entry of ``sensors``: catalog model, overrides, error sources off, faults."""
    fault = obj({"type": {"enum": list(FAULT_TYPES)}, "start_s": TIME, "end_s": TIME,
                  "value_m": {"oneOf": [NUM, {"type": "array", "items": NUM, "minItems": 3, "maxItems": 3}]},
                  "factor": NUM, "source": {"type": "array"}, "radius_m": POS, "lost_m": NUM,
                  "hard_iron_uT": {"type": "array", "items": NUM, "minItems": 3, "maxItems": 3},
                  "ramp_s": TIME}, ["type"])
    return obj({"model": {"enum": sorted(available())}, "override": {"type": "object"},
                 "off": {"oneOf": [{"const": "all"}, {"type": "array", "items": {"type": "string"}}]},
                 "faults": {"type": "array", "items": fault}}, ["model"])


def _estimator(built_in: bool = False) -> dict:
    """One entry of ``estimators``: the keys every registered type declares (its ``SCHEMA``;
    a key two types read differently takes either form); the type's own checks are navsim's."""
    names = [n for n in available_estimators() if not built_in or get_estimator(n).__module__.startswith("navsim.")]
    props = {"label": {"type": "string"}, "type": {"enum": names}}
    for name in names:
        merge_properties(props, getattr(get_estimator(name), "SCHEMA", {}))
    return {"type": "object", "required": ["label", "type"], "properties": props}


def _closed_loop() -> dict:
    """``closed_loop``: navigation in the loop, P1's return to land."""
    return obj({
        "fly_on": {"type": "string", "description": "estimator label the autopilot flies on, or truth"},
        "time_limit_s": {"type": "number", "exclusiveMinimum": 0},
        "return_to_land": obj({
            "gnss": {"type": "string"}, "lost_s": {"type": "number", "exclusiveMinimum": 0},
            "lat_deg": NUM, "lon_deg": NUM, "north_m": NUM, "east_m": NUM, "alt_m": NUM,
            "acceptance_m": {"type": "number", "minimum": 0},
            "area_m": {"type": "number", "exclusiveMinimum": 0}}, ["gnss"],
            "P1's safety strategy: on GNSS loss fly back to the recovery point")},
        ["fly_on"], "navigation in the loop: every run flies on an estimator's solution")


def schema_text(built_in: bool = False) -> str:
    return json.dumps(scenario_schema(built_in), indent=2) + "\n"
