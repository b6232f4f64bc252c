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
           forgetting: 1.0, min_turns: 2}         # magnetometer calibrated online (measurements/magnetometer.py)

The other built-in types' keys are in their classes' ``parse`` docstrings
(:meth:`~navsim.navigation.estimators.eskf.ErrorStateKF.parse` and its subclasses,
:meth:`~navsim.navigation.estimators.cpf_ekf.CpfEkf.parse`); ``navsim schema`` lists them all.

Each estimator class reads its own entry (its ``parse`` classmethod, the defaults declared there
once) and builds itself from what it read (``from_params``); a type without them (a simple
third-party one) gets the entry's keys as keyword arguments (:func:`navsim.navigation.estimators.base.parse_params`).
Measurement types come from the registry of :mod:`navsim.navigation.estimators.measurements`.
"""

from __future__ import annotations

from dataclasses import dataclass

from navsim.foundations.config import Node, close_match
from navsim.foundations.errors import ScenarioError
from navsim.navigation.estimators import base


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
        if not base.known(kind):
            raise node.error(f"'{kind}' is not a registered estimator", "type",
                             expected="one of " + ", ".join(base.available()),
                             hint=close_match(kind, base.available()))
        params = base.parse_params(base.get(kind), node, sensors)
        node.done()
        out.append(EstimatorConfig(label, kind, params))
    return tuple(out)


def build(config: EstimatorConfig):
    """A fresh estimator object from its configuration."""
    return base.build(base.get(config.type), config.params)
