"""Estimators behind one contract (:mod:`navsim.navigation.estimators.base`), one file each.

Built in: ``sins`` (free inertial, :mod:`.sins`), ``eskf`` (error-state Kalman filter,
:mod:`.eskf`), ``two_stage_adaptive`` (P0), ``p2_dynamic_height`` (P2), ``sage_husa`` and
``fuzzy_adaptive``, ``federated`` (P1), ``cpf`` and ``cpf_ekf`` (P4's complementary filter and
its 20-state quaternion EKF with the CPF divergence monitor). Third-party estimators register through the ``navsim.estimators``
entry points.
"""

from navsim.navigation.estimators import (  # noqa: F401
    cpf,
    cpf_ekf,
    eskf,
    federated,
    fuzzy_adaptive,
    p2_height,
    sage_husa,
    sins,
    two_stage,
)

BUILT_IN = (eskf.ErrorStateKF, sins.FreeInertial, p2_height.DynamicHeightKF,
            two_stage.TwoStageAdaptiveKF, sage_husa.SageHusaKF, fuzzy_adaptive.FuzzyAdaptiveKF,
            federated.FederatedKF, cpf.ComplementaryFilter, cpf_ekf.CpfEkf)
from navsim.navigation.estimators.base import Innovation, Solution, available, get, register

__all__ = ["Innovation", "Solution", "available", "get", "register"]
