"""Estimators from scenario configuration (``estimators:`` list entries).

Each entry: ``label``, ``type`` (a registered estimator) and its parameters. For ``eskf``::

    - label: BD/SINS/ADS ES-KF
      type: eskf
      states: p0_16                      # a preset (p3_15, p0_16, p2_18) or a list of blocks
      period_s: 1.0
      discretization: series             # or van_loan
      series_order: 6                    # P3 uses 3
      noise: {imu: p0_imu}               # the filter's own IMU noise model: a catalog entry,
                                         # with override: {...} like a sensor
      baro: {sigma_m: 3, tau_s: 600}     # the baro Markov state's model (p0_16)
      measurements:
        - {type: gnss_position, sensor: bd, sigma_m: [8, 8, 8]}
        - {type: velocity, sensor: ads, sigma_mps: 1.0}
        - {type: height, sensor: ads, field: h_pressure_m, sigma_m: 3, baro_state: true}
        - {type: landmark, sensor: camera, sigma_m: 3, ratio: 0.01}   # P1: std 3 m + 1 % of range
        - {type: mag_heading, sensor: mag, sigma_deg: 1.0, noise_uT: 0.2,   # P1: heading from the
           forgetting: 1.0, min_turns: 2}         # magnetometer calibrated online (measurements.py)

``p2_dynamic_height`` takes the same keys plus P2's height channel (see
:mod:`navsim.navigation.estimators.p2_height`)::

      height: {gps: gps, radar: radar, baro: baro, gps_sigma_m: 30, baro_sigma_m: 25,
               radar_noise_m: 0.3, radar_ratio: 0.03, threshold_m: 500, hysteresis_m: 20,
               window_s: 10, surface_m: 0, gating_sigma: 3, average_radar: true}

``two_stage_adaptive`` (P0) takes the ES-KF keys plus
``adaptive: {enabled: true, window: 30, floor: 1.0}`` (see :mod:`navsim.navigation.estimators.two_stage`).

``federated`` (P1) takes the ES-KF keys with ``locals`` instead of ``measurements``:
``locals: [{name: SINS/GPS, beta: 0.5, measurements: [...]}, ...]``, ``master_beta: 0``,
``reset: true`` and ``isolation: {window: 5, p: 0.999}`` (see :mod:`navsim.navigation.estimators.federated`).

``sage_husa`` (P1) takes the ES-KF keys plus ``sage_husa: {forgetting: 0.95, floor: 1.0,
sensors: [gps]}`` and ``fuzzy_adaptive`` (P1) ``fuzzy: {window: 3, sensors: [gps],
rules: [[1, 1], [2, 4], [3, 9], [5, 25], [10, 100]]}`` (see their modules); ``sensors`` lists
the sensors whose R is adapted (default: all).

``cpf_ekf`` and ``cpf`` (P4) take their sensors by name and the filter's own IMU model from the
catalog (see :mod:`navsim.navigation.estimators.attitude_config`)::

    - label: CPF-EKF
      type: cpf_ekf
      mag: mag                 # magnetometer; gnss: GNSS (velocity + position); baro: barometer
      gnss: gps
      baro: baro
      imu: mpu6050             # the filter's IMU noise model (vibration as white noise)
      period_s: 0.1
      sigma: {mag_uT: 0.5, gnss_pos_m: 2, gnss_vel_mps: 0.1, baro_m: 1}
      initial: {mag_bias_uT: 5, field_uT: 0.5}
      monitor: cpf             # cpf (P4), innovation (nu^T nu > r tr(S)) or none
      threshold_rad2: 0.27416  # P4's N; cycles: 3; innovation_ratio: 3
      cpf: {kp_acc: 0.2, kp_mag: 0.2, ki: 0.002, mag_gate: 0.15}

Other registered types (third-party) get their parameters as keyword arguments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations.config import Node, close_match
from navsim.foundations.errors import ScenarioError
from navsim.navigation.estimators import base
from navsim.navigation.estimators.attitude_config import attitude_params, build_attitude
from navsim.navigation.estimators.error_model import BLOCK_SIZES, PRESETS, Layout
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.federated import FederatedKF
from navsim.navigation.estimators.fuzzy_adaptive import FuzzyAdaptiveKF
from navsim.navigation.estimators.measurements import (
    GnssHorizontal,
    GnssPosition,
    Height,
    LandmarkFix,
    MagneticHeading,
    Velocity,
)
from navsim.navigation.estimators.p2_height import DynamicHeightKF, HeightFusion
from navsim.navigation.estimators.sage_husa import SageHusaKF
from navsim.navigation.estimators.sins import FreeInertial
from navsim.navigation.estimators.two_stage import TwoStageAdaptiveKF
from navsim.sensors.catalog import load_spec
from navsim.sensors.specs import ImuSpec


@dataclass(frozen=True)
class EstimatorConfig:
    label: str
    type: str
    params: dict             #: validated parameters (plain data, picklable)


def parse_estimators(data, sensors: dict, file: str | None = None, path: str = "estimators") -> tuple:
    """Validate the ``estimators`` list. ``sensors``: sensor name -> kind."""
    if not isinstance(data, list) or not data:
        raise ScenarioError("is missing or empty", file=file, key=path,
                            expected="a list of estimators, each with label and type",
                            hint="e.g. estimators: [{label: free SINS, type: sins}]")
    out, labels = [], set()
    for i, item in enumerate(data):
        node = Node(item, f"{path}[{i}]", file)
        label = node.get("label", str)
        if label in labels:
            raise node.error(f"'{label}' is used twice", "label", expected="a unique label")
        labels.add(label)
        kind = node.get("type", str)
        if kind not in base.available():
            raise node.error(f"'{kind}' is not a registered estimator", "type",
                             expected="one of " + ", ".join(base.available()),
                             hint=close_match(kind, base.available()))
        if kind == "eskf":
            params = _eskf_params(node, sensors)
        elif kind == "two_stage_adaptive":
            params = _eskf_params(node, sensors)
            for block in ("gyro_bias", "accel_bias"):
                if block not in params["states"]:
                    raise node.error(f"the two-stage filter needs the '{block}' block", "states")
            ad = node.child("adaptive", None)
            params["adaptive"] = {"adaptive": True, "window": 30, "floor": 1.0}
            if ad is not None:
                params["adaptive"] = {"adaptive": ad.get("enabled", bool, True),
                                      "window": ad.get("window", int, 30, minimum=1),
                                      "floor": ad.get("floor", float, 1.0, exclusive_minimum=0.0)}
                ad.done()
        elif kind == "p2_dynamic_height":
            params = _eskf_params(node, sensors)
            params["height"] = _height_params(node.child("height"), sensors)
        elif kind == "federated":
            params = _eskf_params(node, sensors)
            params["federated"] = _federated_params(node, sensors)
        elif kind in ("sage_husa", "fuzzy_adaptive"):
            params = _eskf_params(node, sensors)
            params["adaptive"] = _adaptive_params(node, kind, sensors)
        elif kind == "sins":
            params = {"period_s": node.get("period_s", float, 1.0, exclusive_minimum=0.0)}
        elif kind in ("cpf", "cpf_ekf"):
            params = attitude_params(node, kind, sensors)
        else:
            params = {k: v for k, v in node.data.items() if k not in ("label", "type")}
            node._seen.update(params)
        node.done()
        out.append(EstimatorConfig(label, kind, params))
    return tuple(out)


def _vec(node: Node, key: str, default=None, minimum=0.0):
    node._seen.add(key)
    v = node.data.get(key, default)
    if v is None:
        raise node.error("is missing", key, expected="a number or [x, y, z]")
    arr = None
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        arr = np.full(3, float(v))
    elif isinstance(v, list) and len(v) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
        arr = np.asarray(v, float)
    if arr is None or not np.all(np.isfinite(arr)) or np.any(arr <= minimum):
        raise node.error(f"is {v!r}", key, expected="a positive number or a list of three")
    return [float(x) for x in arr]


def _eskf_params(node: Node, sensors: dict) -> dict:
    states = node.data.get("states", "p3_15")
    node._seen.add("states")
    if isinstance(states, str):
        if states not in PRESETS:
            raise node.error(f"is '{states}'", "states", expected="a preset (" + ", ".join(PRESETS)
                             + ") or a list of blocks", hint=close_match(states, PRESETS))
        blocks = list(PRESETS[states])
    elif isinstance(states, list) and all(isinstance(b, str) for b in states):
        blocks = states
        twice = sorted({b for b in blocks if blocks.count(b) > 1})
        if twice:
            raise node.error(f"names the block '{twice[0]}' twice", "states", expected="each state block once")
        for b in blocks:
            if b not in BLOCK_SIZES:
                raise node.error(f"block '{b}' is unknown", "states", expected=", ".join(BLOCK_SIZES),
                                 hint=close_match(b, BLOCK_SIZES))
        try:
            Layout(tuple(blocks))
        except ValueError as exc:
            raise node.error(str(exc), "states") from None
    else:
        raise node.error("is malformed", "states", expected="a preset name or a list of blocks")
    params = {"states": blocks,
              "period_s": node.get("period_s", float, 1.0, exclusive_minimum=0.0),
              "discretization": node.get("discretization", str, "series", choices=("series", "van_loan")),
              "series_order": node.get("series_order", int, 6, minimum=1, maximum=12)}
    noise = node.child("noise")
    imu = noise.get("imu", str)
    override = noise.child("override", None)
    spec = load_spec(imu, override.data if override else None, (), node.file, noise.path)
    if not isinstance(spec, ImuSpec):
        raise noise.error(f"'{imu}' is not an IMU", "imu", expected="an imu catalog entry")
    noise.done()
    params["noise"] = {"imu": imu, "override": override.data if override else None}
    baro = node.child("baro", None)
    params["baro"] = {"sigma_m": 0.0, "tau_s": 300.0}
    if baro is not None:
        params["baro"] = {"sigma_m": baro.get("sigma_m", float, exclusive_minimum=0.0),
                          "tau_s": baro.get("tau_s", float, 300.0, exclusive_minimum=0.0)}
        baro.done()
    if "baro" in blocks and params["baro"]["sigma_m"] == 0.0:
        raise node.error("the 'baro' state needs its model", "baro", expected="{sigma_m: ..., tau_s: ...}")
    if node.data.get("type") == "federated":
        params["measurements"] = []
        return params
    params["measurements"] = _measurements(node, sensors)
    return params


def _list(node: Node, key: str, minimum: int, expected: str, hint: str) -> list:
    node._seen.add(key)
    raw = node.data.get(key)
    if not isinstance(raw, list) or len(raw) < minimum:
        raise node.error("is missing or too short", key, expected=expected, hint=hint)
    return raw


def _measurements(node: Node, sensors: dict) -> list:
    """The ``measurements`` list of an estimator (or of a federated filter's local filter)."""
    raw = _list(node, "measurements", 1, "a list of measurement models",
                "e.g. [{type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}]")
    meas = []
    for j, item in enumerate(raw):
        m = Node(item, node.key(f"measurements[{j}]"), node.file)
        mtype = m.get("type", str, choices=("gnss_position", "gnss_horizontal", "velocity", "height",
                                            "landmark", "mag_heading"))
        sensor = m.get("sensor", str)
        if sensor not in sensors:
            raise m.error(f"'{sensor}' is not a sensor of this scenario", "sensor",
                          expected="one of " + ", ".join(sensors) if sensors else "a sensor under 'sensors'",
                          hint=close_match(sensor, sensors))
        entry = {"type": mtype, "sensor": sensor}
        if mtype == "landmark":
            if sensors[sensor] != "camera":
                raise m.error(f"'{sensor}' is a {sensors[sensor]}", "sensor", expected="a camera sensor",
                              hint=close_match(sensor, [k for k, v in sensors.items() if v == "camera"]))
            entry["sigma_m"] = m.get("sigma_m", float, exclusive_minimum=0.0)
            entry["ratio"] = m.get("ratio", float, 0.0, minimum=0.0)
        elif mtype == "gnss_position":
            entry["sigma_m"] = _vec(m, "sigma_m")
        elif mtype == "gnss_horizontal":
            entry["sigma_m"] = _vec(m, "sigma_m")[:2]
        elif mtype == "velocity":
            entry["sigma_mps"] = _vec(m, "sigma_mps")
            entry["field"] = m.get("field", str, "vel_n_mps")
        elif mtype == "mag_heading":
            entry.update(_mag_heading_params(m, sensors))
        else:
            entry["sigma_m"] = m.get("sigma_m", float, exclusive_minimum=0.0)
            entry["field"] = m.get("field", str, {"radar_altimeter": "h_agl_m", "baro": "h_baro_m",
                                                  "ads": "h_pressure_m"}.get(sensors[sensor], "h_m"))
            entry["baro_state"] = m.get("baro_state", bool, False)
            entry["offset_m"] = m.get("offset_m", float, 0.0)
        m.done()
        meas.append(entry)
    return meas


def _mag_heading_params(m: Node, sensors: dict) -> dict:
    """``mag_heading``: the heading's ``sigma_deg``, the filter's model of the magnetometer
    noise ``noise_uT`` (per axis), the calibration's ``forgetting`` and ``min_turns``."""
    if sensors[m.data["sensor"]] != "magnetometer":
        raise m.error(f"'{m.data['sensor']}' is not a magnetometer", "sensor",
                      expected="a sensor of kind magnetometer",
                      hint=close_match(m.data["sensor"], [k for k, v in sensors.items() if v == "magnetometer"]))
    return {"sigma_deg": m.get("sigma_deg", float, exclusive_minimum=0.0),
            "noise_uT": m.get("noise_uT", float, minimum=0.0),
            "forgetting": m.get("forgetting", float, 1.0, exclusive_minimum=0.0, maximum=1.0),
            "min_turns": m.get("min_turns", float, 2.0, minimum=0.0)}


def _federated_params(node: Node, sensors: dict) -> dict:
    """``locals: [{name, beta, measurements}]``, ``master_beta``, ``reset``, ``isolation``."""
    raw = _list(node, "locals", 2, "a list of at least two {name, beta, measurements}",
                "e.g. [{name: SINS/GPS, beta: 0.5, measurements: [...]}, ...]")
    out = []
    for i, item in enumerate(raw):
        loc = Node(item, node.key(f"locals[{i}]"), node.file)
        out.append({"name": loc.get("name", str), "beta": loc.get("beta", float, exclusive_minimum=0.0),
                    "measurements": _measurements(loc, sensors)})
        loc.done()
    master = node.get("master_beta", float, 0.0, minimum=0.0)
    total = sum(o["beta"] for o in out) + master
    if abs(total - 1.0) > 1e-6:
        raise node.error(f"the information-sharing factors add up to {total:g}", "locals",
                         expected="sum of the locals' beta + master_beta = 1")
    iso = node.child("isolation", None)
    isolation = None
    if iso is not None:
        isolation = {"window": iso.get("window", float, 5.0, minimum=1.0),
                     "p": iso.get("p", float, 0.999, exclusive_minimum=0.5, maximum=0.999999)}
        iso.done()
    return {"locals": out, "master_beta": master, "reset": node.get("reset", bool, True),
            "isolation": isolation}


def _adaptive_params(node: Node, kind: str, sensors: dict) -> dict:
    """``sage_husa:`` / ``fuzzy:`` blocks (both optional)."""
    key = "sage_husa" if kind == "sage_husa" else "fuzzy"
    sub = node.child(key, None)
    if sub is None:
        return {}
    out = {}
    if kind == "sage_husa":
        out["forgetting"] = sub.get("forgetting", float, 0.95, exclusive_minimum=0.0, maximum=0.9999)
        out["floor"] = sub.get("floor", float, 1.0, exclusive_minimum=0.0)
    else:
        out["window"] = sub.get("window", float, 3.0, minimum=1.0)
        sub._seen.add("rules")
        rules = sub.data.get("rules")
        if rules is not None:
            ok = (isinstance(rules, list) and rules and all(
                isinstance(r, list) and len(r) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                         for x in r) for r in rules))
            arr = np.asarray(rules, float) if ok else None
            if not ok or np.any(np.diff(arr[:, 0]) <= 0) or np.any(arr[:, 1] <= 0):
                raise sub.error(f"is {rules!r}", "rules",
                                expected="a list of [r, s] pairs with r increasing and s > 0",
                                hint="e.g. [[1, 1], [2, 4], [3, 9], [5, 25], [10, 100]]")
            out["rules"] = [[float(a), float(b)] for a, b in rules]
    sub._seen.add("sensors")
    names = sub.data.get("sensors")
    if names is not None:
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise sub.error(f"is {names!r}", "sensors", expected="a list of sensor names")
        for n in names:
            if n not in sensors:
                raise sub.error(f"'{n}' is not a sensor of this scenario", "sensors",
                                expected="one of " + ", ".join(sensors), hint=close_match(n, sensors))
        out["sensors"] = list(names)
    sub.done()
    return out


def _height_params(node: Node, sensors: dict) -> dict:
    """P2's height fusion: ``gps``, ``radar``, ``baro`` sensor names and the model numbers."""
    out = {}
    for role, kind in (("gps", "gnss"), ("radar", "radar_altimeter"), ("baro", "baro")):
        name = node.get(role, str)
        if sensors.get(name) != kind:
            raise node.error(f"'{name}' is not a {kind} of this scenario", role,
                             expected=f"a sensor of kind {kind}",
                             hint=close_match(name, [k for k, v in sensors.items() if v == kind]))
        out[role] = name
    for key, default in (("gps_sigma_m", 30.0), ("baro_sigma_m", 25.0), ("radar_noise_m", 0.3),
                         ("radar_ratio", 0.03), ("hysteresis_m", 20.0), ("window_s", 10.0)):
        out[key] = node.get(key, float, default, minimum=0.0)
    out["threshold_m"] = node.get("threshold_m", float, 500.0)
    out["surface_m"] = node.get("surface_m", float, 0.0)
    out["gating_sigma"] = node.get("gating_sigma", float, None, exclusive_minimum=0.0)
    out["average_radar"] = node.get("average_radar", bool, False)
    node.done()
    return out


def _models(entries: list) -> list:
    models = []
    for m in entries:
        if m["type"] == "gnss_position":
            models.append(GnssPosition(m["sensor"], np.array(m["sigma_m"])))
        elif m["type"] == "gnss_horizontal":
            models.append(GnssHorizontal(m["sensor"], np.array(m["sigma_m"])))
        elif m["type"] == "velocity":
            models.append(Velocity(m["sensor"], np.array(m["sigma_mps"]), field=m["field"]))
        elif m["type"] == "landmark":
            models.append(LandmarkFix(m["sensor"], m["sigma_m"], m["ratio"]))
        elif m["type"] == "mag_heading":
            models.append(MagneticHeading(m["sensor"], np.radians(m["sigma_deg"]), m["noise_uT"] * 1e-6,
                                          forgetting=m["forgetting"], min_turns=m["min_turns"]))
        else:
            models.append(Height(m["sensor"], m["sigma_m"], field=m["field"],
                                 use_baro_state=m["baro_state"], offset_m=m["offset_m"]))
    return models


ESKF_FAMILY = ("eskf", "p2_dynamic_height", "two_stage_adaptive", "sage_husa", "fuzzy_adaptive", "federated")


def build(config: EstimatorConfig):
    """A fresh estimator object from its configuration."""
    if config.type == "sins":
        return FreeInertial(**config.params)
    if config.type in ("cpf", "cpf_ekf"):
        return build_attitude(config.type, config.params)
    if config.type not in ESKF_FAMILY:
        return base.get(config.type)(**config.params)
    p = config.params
    spec = load_spec(p["noise"]["imu"], p["noise"]["override"])
    layout = Layout(tuple(p["states"]))
    models = _models(p["measurements"])
    kw = dict(baro_sigma_m=p["baro"]["sigma_m"], baro_tau_s=p["baro"]["tau_s"], period_s=p["period_s"],
              discretization=p["discretization"], series_order=p["series_order"])
    if config.type == "federated":
        f = p["federated"]
        locals_ = [{**loc, "measurements": _models(loc["measurements"])} for loc in f["locals"]]
        return FederatedKF.from_imu_spec(layout, spec, locals_, master_beta=f["master_beta"],
                                         reset=f["reset"], isolation=f["isolation"], **kw)
    if config.type == "two_stage_adaptive":
        return TwoStageAdaptiveKF.from_imu_spec(layout, spec, models, **p["adaptive"], **kw)
    if config.type == "sage_husa":
        return SageHusaKF.from_imu_spec(layout, spec, models, **p["adaptive"], **kw)
    if config.type == "fuzzy_adaptive":
        return FuzzyAdaptiveKF.from_imu_spec(layout, spec, models, **p["adaptive"], **kw)
    if config.type == "p2_dynamic_height":
        return DynamicHeightKF.from_imu_spec(layout, spec, models, fusion=HeightFusion(**p["height"]), **kw)
    return ErrorStateKF.from_imu_spec(layout, spec, models, **kw)
