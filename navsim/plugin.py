"""Everything a plug-in needs, from one module: ``from navsim.plugin import ...``.

A filter in one file is a class registered with :func:`register`, run by ``navsim run
scenario.yaml --plugin my_filter.py`` (also ``budget``, ``sweep``, ``validate``, ``fly``,
``sensors``, ``replay``)
and named in the scenario by ``type: <its name>``. It follows one of two contracts:

- **one vehicle** (filterpy-style, for prototyping): ``initialize(nav0, P0)``,
  ``predict(imu)``, ``update(t_s, samples)``, ``solution()`` on numpy arrays of one run
  (:class:`VehicleFilter`, :class:`ImuBlock`, :class:`Sample`, :class:`VehicleInnovation`,
  :class:`VehicleSolution`; :class:`VehicleStrapdown` mechanizes, :func:`remove_errors` feeds
  back); navsim runs one object per Monte Carlo run;
- **a batch** of ``B`` runs at once (for speed): ``initialize``, ``propagate``, ``epoch``,
  ``solution`` (:class:`Estimator`, :class:`Innovation`, :class:`Solution`).

``docs/plugins.md`` walks through both; the notation (frames, units, ``C_nb``, the error
states) is the package's (:mod:`navsim`).
"""

from __future__ import annotations

from navsim.foundations.config import Node, load_yaml
from navsim.foundations.earth import OMEGA_IE_RPS, gravity_n, radii
from navsim.foundations.jsonschema import NUM, POS, VEC3, obj
from navsim.foundations.plugins import load_file
from navsim.foundations.transform import dcm_from_euler, euler_from_dcm, rotation, skew
from navsim.navigation.estimators.base import ESTIMATORS, Estimator, Innovation, Solution, sample
from navsim.navigation.estimators.measurements import Linearised, build_measurements, measurement, parse_measurements
from navsim.navigation.estimators.measurements.registry import MEASUREMENTS
from navsim.navigation.estimators.vehicle import (ImuBlock, Sample, VehicleFilter, VehicleInnovation, VehicleSolution,
                                                  VehicleStrapdown, batch_class, is_vehicle_filter, remove_errors)
from navsim.navigation.strapdown import BlockStrapdown, NavState
from navsim.sensors.base import Measurements
from navsim.sensors.catalog import load_spec


def register(name: str):
    """Class decorator: make a filter available to scenarios as ``type: name``. A class of the
    one-vehicle contract is run for every run by a batch class made for it; the decorated
    class itself is returned unchanged."""
    def deco(cls: type) -> type:
        ESTIMATORS.register(name, batch_class(cls) if is_vehicle_filter(cls) else cls)
        return cls
    return deco


#: what a plug-in file may register into (:func:`load`, ``--plugin``)
REGISTRIES = {"estimator": ESTIMATORS, "measurement type": MEASUREMENTS}


def load(path) -> list[str]:
    """Import the plug-in file ``path`` as ``--plugin`` does (once per process); returns what it
    registered (``["estimator 'my_filter'"]``); a :class:`~navsim.foundations.errors.UsageError`
    names the file for one that raises on import, registers nothing or takes a registered name."""
    return load_file(path, REGISTRIES)


def imu_spec(name: str, override: dict | None = None):
    """An IMU catalog entry (``sensors/<name>.yaml``, or a file) in SI: ``.gyro`` and ``.accel``
    with ``noise_density`` (rad/s/√Hz, m/s²/√Hz), ``random_walk``, ``bias_sigma``, ``bias``
    (rad/s, m/s²), each ``(3,)``; ``override`` as a scenario's."""
    return load_spec(name, override or {})


__all__ = ["BlockStrapdown", "Estimator", "ImuBlock", "Innovation", "Linearised", "Measurements", "NUM", "NavState",
           "Node", "OMEGA_IE_RPS", "POS", "Sample", "Solution", "VEC3", "VehicleFilter", "VehicleInnovation",
           "VehicleSolution", "VehicleStrapdown", "build_measurements", "dcm_from_euler", "euler_from_dcm",
           "gravity_n", "imu_spec", "load", "load_yaml", "measurement", "obj", "parse_measurements", "radii", "register",
           "remove_errors", "rotation", "sample", "skew"]
