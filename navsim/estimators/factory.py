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

``p2_dynamic_height`` takes the same keys plus P2's height channel (see
:mod:`navsim.estimators.p2_height`)::

      height: {gps: gps, radar: radar, baro: baro, gps_sigma_m: 30, baro_sigma_m: 25,
               radar_noise_m: 0.3, radar_ratio: 0.03, threshold_m: 500, hysteresis_m: 20,
               window_s: 10, surface_m: 0, gating_sigma: 3, average_radar: true}

``two_stage_adaptive`` (P0) takes the ES-KF keys plus
``adaptive: {enabled: true, window: 30, floor: 1.0}`` (see :mod:`navsim.estimators.two_stage`).

Other registered types (third-party) get their parameters as keyword arguments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.config import Node, close_match
from navsim.errors import ScenarioError
from navsim.estimators import base
from navsim.estimators.error_model import BLOCK_SIZES, PRESETS, Layout
from navsim.estimators.measurements import GnssPosition, Height, Velocity


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
        elif kind == "sins":
            params = {"period_s": node.get("period_s", float, 1.0, exclusive_minimum=0.0)}
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
    from navsim.sensors.catalog import load_spec
    spec = load_spec(imu, override.data if override else None, (), node.file, noise.path)
    from navsim.sensors.specs import ImuSpec
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
    node._seen.add("measurements")
    raw = node.data.get("measurements")
    if not isinstance(raw, list) or not raw:
        raise node.error("is missing or empty", "measurements",
                         expected="a list of measurement models",
                         hint="e.g. [{type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}]")
    meas = []
    for j, item in enumerate(raw):
        m = Node(item, node.key(f"measurements[{j}]"), node.file)
        mtype = m.get("type", str, choices=("gnss_position", "gnss_horizontal", "velocity", "height"))
        sensor = m.get("sensor", str)
        if sensor not in sensors:
            raise m.error(f"'{sensor}' is not a sensor of this scenario", "sensor",
                          expected="one of " + ", ".join(sensors) if sensors else "a sensor under 'sensors'",
                          hint=close_match(sensor, sensors))
        entry = {"type": mtype, "sensor": sensor}
        if mtype == "gnss_position":
            entry["sigma_m"] = _vec(m, "sigma_m")
        elif mtype == "gnss_horizontal":
            entry["sigma_m"] = _vec(m, "sigma_m")[:2]
        elif mtype == "velocity":
            entry["sigma_mps"] = _vec(m, "sigma_mps")
            entry["field"] = m.get("field", str, "vel_n_mps")
        else:
            entry["sigma_m"] = m.get("sigma_m", float, exclusive_minimum=0.0)
            entry["field"] = m.get("field", str, {"radar_altimeter": "h_agl_m", "baro": "h_baro_m",
                                                  "ads": "h_pressure_m"}.get(sensors[sensor], "h_m"))
            entry["baro_state"] = m.get("baro_state", bool, False)
            entry["offset_m"] = m.get("offset_m", float, 0.0)
        m.done()
        meas.append(entry)
    params["measurements"] = meas
    return params


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


def build(config: EstimatorConfig):
    """A fresh estimator object from its configuration."""
    if config.type == "sins":
        from navsim.estimators.sins import FreeInertial
        return FreeInertial(**config.params)
    if config.type in ("eskf", "p2_dynamic_height", "two_stage_adaptive"):
        from navsim.estimators.eskf import ErrorStateKF
        from navsim.estimators.measurements import GnssHorizontal
        from navsim.estimators.p2_height import DynamicHeightKF, HeightFusion
        from navsim.sensors.catalog import load_spec
        p = config.params
        spec = load_spec(p["noise"]["imu"], p["noise"]["override"])
        models = []
        for m in p["measurements"]:
            if m["type"] == "gnss_position":
                models.append(GnssPosition(m["sensor"], np.array(m["sigma_m"])))
            elif m["type"] == "gnss_horizontal":
                models.append(GnssHorizontal(m["sensor"], np.array(m["sigma_m"])))
            elif m["type"] == "velocity":
                models.append(Velocity(m["sensor"], np.array(m["sigma_mps"]), field=m["field"]))
            else:
                models.append(Height(m["sensor"], m["sigma_m"], field=m["field"],
                                     use_baro_state=m["baro_state"], offset_m=m["offset_m"]))
        kw = dict(baro_sigma_m=p["baro"]["sigma_m"], baro_tau_s=p["baro"]["tau_s"], period_s=p["period_s"],
                  discretization=p["discretization"], series_order=p["series_order"])
        if config.type == "two_stage_adaptive":
            from navsim.estimators.two_stage import TwoStageAdaptiveKF
            return TwoStageAdaptiveKF.from_imu_spec(Layout(tuple(p["states"])), spec, models,
                                                    **p["adaptive"], **kw)
        if config.type == "p2_dynamic_height":
            return DynamicHeightKF.from_imu_spec(Layout(tuple(p["states"])), spec, models,
                                                 fusion=HeightFusion(**p["height"]), **kw)
        return ErrorStateKF.from_imu_spec(Layout(tuple(p["states"])), spec, models, **kw)
    return base.get(config.type)(**config.params)
