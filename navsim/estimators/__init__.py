"""Estimators behind one contract (:mod:`navsim.estimators.base`), one file each.

Built in: ``sins`` (free inertial, :mod:`.sins`), ``eskf`` (error-state Kalman filter,
:mod:`.eskf`), ``two_stage_adaptive`` (P0), ``p2_dynamic_height`` (P2), ``sage_husa`` and
``fuzzy_adaptive``, ``federated`` (P1). Third-party estimators register through the ``navsim.estimators``
entry points.
"""

from navsim.estimators import (eskf, federated, fuzzy_adaptive, p2_height, sage_husa,  # noqa: F401
                               sins, two_stage)

BUILT_IN = (eskf.ErrorStateKF, sins.FreeInertial, p2_height.DynamicHeightKF,
            two_stage.TwoStageAdaptiveKF, sage_husa.SageHusaKF, fuzzy_adaptive.FuzzyAdaptiveKF,
            federated.FederatedKF)
from navsim.estimators.base import Innovation, Solution, available, get, register

__all__ = ["Innovation", "Solution", "available", "get", "register"]
