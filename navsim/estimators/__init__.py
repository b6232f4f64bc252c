"""Estimators behind one contract (:mod:`navsim.estimators.base`), one file each.

Built in: ``sins`` (free inertial, :mod:`.sins`) and ``eskf`` (error-state Kalman filter,
:mod:`.eskf`). Third-party estimators register through the ``navsim.estimators`` entry points.
"""

from navsim.estimators import eskf, p2_height, sins, two_stage  # noqa: F401  (registers the built-ins)

BUILT_IN = (eskf.ErrorStateKF, sins.FreeInertial, p2_height.DynamicHeightKF,
            two_stage.TwoStageAdaptiveKF)
from navsim.estimators.base import Innovation, Solution, available, get, register

__all__ = ["Innovation", "Solution", "available", "get", "register"]
