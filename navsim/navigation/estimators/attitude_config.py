"""Scenario parameters of P4's attitude estimators (``cpf``, ``cpf_ekf``): validation with clear
errors, and the filter's own noise model from an IMU catalog entry.

The IMU entry gives the white noise densities. Its vibration (P4: +/-0.488 g x/y, +/-0.732 g z
peak, 8-22 Hz) is zero-mean and far above the filter's bandwidth: it does not make the velocity
wander, it makes it jitter, by ``sigma_v^2 = sigma_a^2 / ((f2 - f1) 4 pi^2) (1/f1 - 1/f2)`` for
random vibration of peak ``A = 3 sigma_a`` over ``[f1, f2]`` (``A / (sqrt(2) 2 pi f)`` for a
sine). The filter takes it as the white accelerometer noise that spreads the same velocity
variance over the GNSS interval ``VIBRATION_INTERVAL_S`` (P4: 5 Hz), added to the datasheet
density: for P4's vibration 0.051 m/s^2/rt Hz. (The white noise of equal *power*,
``sigma_a / sqrt(f2 - f1)`` = 0.47, would make the filter ten times too slow; the datasheet
density alone, 0.004, too confident.) The bias-instability Gauss-Markov process becomes the
random walk of the same short-term growth, ``sigma sqrt(2 / tau)``.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.config import MAX_DURATION_S, Node, check_numbers, close_match
from navsim.foundations.jsonschema import POS, obj
from navsim.sensors.catalog import load_spec
from navsim.sensors.specs import ImuSpec

SENSOR_KINDS = {"mag": ("magnetometer",), "gnss": ("gnss",), "baro": ("baro",)}
CPF_GAINS = ("kp_acc", "kp_mag", "ki", "accel_tau_s", "acc_gate", "mag_gate", "dip_gate_deg", "accel_ref_tau_s",
             "course_min_speed_mps")
SIGMA_KEYS = {"mag_uT": "mag_sigma_uT", "gnss_pos_m": "gnss_pos_sigma_m", "gnss_vel_mps": "gnss_vel_sigma_mps",
              "baro_m": "baro_sigma_m", "no_gnss_mps": "no_gnss_sigma_mps"}
INITIAL_KEYS = ("gyro_bias_dps", "accel_z_bias_mps2", "mag_bias_uT", "field_uT")
VIBRATION_INTERVAL_S = 0.2
#: the divergence monitor's settings of an entry, their types and bounds (defaults: the CPF-EKF's
#: constructor's, P4's numbers)
MONITOR = (("monitor", str, {"choices": ("cpf", "innovation", "none")}),
           ("threshold_rad2", float, {"exclusive_minimum": 0.0}), ("cycles", int, {"minimum": 1}),
           ("innovation_ratio", float, {"minimum": 1.0}), ("cpf_trust_s", float, {"exclusive_minimum": 0.0}))
MONITOR_KEYS = tuple(k for k, _, _ in MONITOR)


def attitude_schema(kind: str) -> dict:
    """The JSON Schema of a ``cpf`` / ``cpf_ekf`` entry's keys."""
    nonneg = {"type": "number", "minimum": 0}
    out = {"mag": {"type": "string"}, "gnss": {"type": "string"}, "baro": {"type": "string"}, "period_s": POS,
           "field_uT": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
           "cpf": obj({k: nonneg for k in CPF_GAINS})}
    if kind == "cpf":
        return out
    return {**out, "imu": {"type": "string"}, "sigma": obj({k: nonneg for k in SIGMA_KEYS}),
            "initial": obj({k: nonneg for k in INITIAL_KEYS}), "reset_sigma": obj({k: nonneg for k in INITIAL_KEYS}),
            "noise": obj({k: nonneg for k in ("gyro_rad_s_rthz", "accel_mps2_rthz", "gyro_bias_walk", "accel_bias_walk",
                                              "mag_bias_walk_uT", "field_walk_uT", "quat_stab")}),
            "monitor": {"enum": ["cpf", "innovation", "none"]}, "threshold_rad2": POS,
            "cycles": {"type": "integer", "minimum": 1}, "innovation_ratio": {"type": "number", "minimum": 1},
            "cpf_trust_s": POS}


def _sensor(node: Node, role: str, sensors: dict, required: bool):
    name = node.get(role, str, None)
    if name is None:
        if required:
            raise node.error("is missing", role, expected=f"the name of a {SENSOR_KINDS[role][0]} sensor")
        return None
    kinds = SENSOR_KINDS[role]
    if sensors.get(name) not in kinds:
        options = [k for k, v in sensors.items() if v in kinds]
        what = f"a {sensors[name]}" if name in sensors else "not a sensor of this scenario"
        raise node.error(f"'{name}' is {what}", role, expected=f"a sensor of kind {kinds[0]}"
                         + (f" ({', '.join(options)})" if options else ""), hint=close_match(name, options))
    return name


def _floats(node: Node, key: str, keys, positive: bool = False) -> dict:
    """The numbers ``keys`` of the block ``key`` (>= 0, or > 0 with ``positive``)."""
    sub = node.child(key, None)
    if sub is None:
        return {}
    out = {}
    bound = {"exclusive_minimum": 0.0} if positive else {"minimum": 0.0}
    for k in keys:
        v = sub.get(k, float, None, **bound)
        if v is not None:
            out[k] = v
    sub.done()
    return out


def attitude_params(node: Node, kind: str, sensors: dict) -> dict:
    """Validated parameters of a ``cpf`` / ``cpf_ekf`` entry (plain data)."""
    p = {"mag": _sensor(node, "mag", sensors, True), "gnss": _sensor(node, "gnss", sensors, False),
         "baro": _sensor(node, "baro", sensors, False),
         "period_s": node.get("period_s", float, 0.1, exclusive_minimum=0.0, maximum=MAX_DURATION_S)}
    field = node.data.get("field_uT")
    node._seen.add("field_uT")
    if field is not None:
        field = check_numbers(field, 3, error=lambda m, e: node.error(
            m, "field_uT", expected=f"[north, east, down] in microtesla ({e})"))
        if not any(field):
            raise node.error(f"is {field!r}", "field_uT", expected="a non-zero field [north, east, down] in microtesla")
        p["field_n_T"] = [float(v) * 1e-6 for v in field]
    p["cpf"] = _floats(node, "cpf", CPF_GAINS)
    for tau in ("accel_tau_s", "accel_ref_tau_s"):
        if p["cpf"].get(tau) == 0.0:
            raise node.error("is 0", f"cpf.{tau}", expected="a time constant > 0 s")
    if kind == "cpf":
        return p
    imu = node.get("imu", str, None)
    if imu is not None:
        spec = load_spec(imu, None, (), node.file, node.key("imu"))
        if not isinstance(spec, ImuSpec):
            raise node.error(f"'{imu}' is not an IMU", "imu", expected="an imu catalog entry")
        p["imu"] = imu
    p["sigma"] = _floats(node, "sigma", SIGMA_KEYS, positive=True)    # a zero sigma: a singular S
    p["initial"] = _floats(node, "initial", INITIAL_KEYS)
    p["reset_sigma"] = _floats(node, "reset_sigma", INITIAL_KEYS)
    p["noise"] = _floats(node, "noise", ("gyro_rad_s_rthz", "accel_mps2_rthz", "gyro_bias_walk",
                                         "accel_bias_walk", "mag_bias_walk_uT", "field_walk_uT", "quat_stab"))
    # the monitor's settings, when given (their defaults are the CPF-EKF's own: P4's)
    for key, typ, bounds in MONITOR:
        value = node.get(key, typ, None, **bounds)
        if value is not None:
            p[key] = value
    return p


def imu_noise(spec) -> tuple[dict, dict]:
    """The filter's noise densities and initial bias sigmas from an IMU spec."""
    g, a = spec.gyro, spec.accel
    vib2 = np.zeros(3)
    for v in spec.vibration:
        if v.type == "random":
            f1, f2 = v.band_hz
            var_v = (np.asarray(v.amplitude, float) / 3.0) ** 2 / ((f2 - f1) * 4 * math.pi ** 2) * (1 / f1 - 1 / f2)
        else:
            var_v = (np.asarray(v.amplitude, float) / (math.sqrt(2) * 2 * math.pi * v.frequency_hz)) ** 2
        vib2 += var_v / VIBRATION_INTERVAL_S
    gm = lambda e: float(np.mean(np.asarray(e.bias_instability, float))) * math.sqrt(2.0 / e.bias_instability_tau_s)
    noise = {"gyro_rad_s_rthz": float(np.mean(g.noise_density)),
             "accel_mps2_rthz": float(np.sqrt(np.mean(np.asarray(a.noise_density) ** 2 + vib2))),
             "gyro_bias_walk": max(gm(g), float(np.mean(g.random_walk)), 1e-7),
             "accel_bias_walk": max(gm(a), float(np.mean(a.random_walk)), 1e-6)}
    initial = {"gyro_bias_rad_s": float(np.mean(np.hypot(g.bias_sigma, g.bias))),
               "accel_z_bias_mps2": float(np.hypot(a.bias_sigma, a.bias)[2])}
    return noise, initial


def cpf_ekf_options(params: dict) -> dict:
    """The CPF-EKF's constructor arguments from :func:`attitude_params`' parameters (the IMU
    entry's noise model, overridden by ``noise`` and ``initial``)."""
    p = dict(params)
    noise, initial = {}, {}
    if p.get("imu"):
        noise, initial = imu_noise(load_spec(p["imu"]))
    noise.update(p.get("noise", {}))
    initial.update(p.get("initial", {}))          # gyro_bias_dps (if given) wins over the spec's
    sigma = {SIGMA_KEYS[k]: v for k, v in p.get("sigma", {}).items()}
    reset = dict(p.get("reset_sigma", {}))
    monitor = {k: p[k] for k in MONITOR_KEYS if k in p}
    return dict(mag=p["mag"], gnss=p.get("gnss"), baro=p.get("baro"), period_s=p["period_s"], noise=noise,
                initial=initial, cpf=p.get("cpf"), field_n_T=p.get("field_n_T"), reset_sigma=reset, **monitor, **sigma)
