"""Estimators behind one contract (:class:`~navsim.navigation.estimators.base.Estimator`), one
file each, and the measurement models they share (:mod:`.measurements`, registered by name).

Built in: ``sins`` (free inertial, :mod:`.sins`), ``eskf`` (error-state Kalman filter,
:mod:`.eskf`), ``two_stage_adaptive`` (P0), ``p2_dynamic_height`` (P2), ``sage_husa`` and
``fuzzy_adaptive``, ``federated`` (P1), ``cpf`` and ``cpf_ekf`` (P4's complementary filter and
its 20-state quaternion EKF with the CPF divergence monitor). Every module of this package is
imported here, so a new built-in estimator is a new file whose class is decorated with
:func:`register`. Third-party estimators register through the ``navsim.estimators`` entry
points.
"""

import importlib
import pkgutil

from navsim.navigation.estimators.base import Estimator, Innovation, Solution, available, get, register
from navsim.navigation.estimators.measurements import (
    Linearised,
    build_measurements,
    measurement,
    measurement_types,
    parse_measurements,
)

for _module in pkgutil.iter_modules(__path__):       # every built-in registers itself on import
    importlib.import_module(f"{__name__}.{_module.name}")

__all__ = ["Estimator", "Innovation", "Linearised", "Solution", "available", "build_measurements", "get", "measurement",
           "measurement_types", "parse_measurements", "register"]
