"""Sage–Husa adaptive error-state Kalman filter: the measurement noise of chosen sensors is
re-estimated online from the innovations with a fading memory (P1, Tang & Wu's related work;
Sage & Husa, "Adaptive filtering with unknown prior statistics", JACC 1969).

For each adapted measurement model and each run, with the innovation ``y = z - H x-`` and the
predicted ``H P- H^T``::

    R^_k = (1 - d_k) R^_k-1 + d_k (y y^T - H P- H^T),   d_k = (1 - b) / (1 - b^(k+2))

``b`` is the forgetting factor (memory of about ``1 / (1 - b)`` epochs). The weight counts the
model's own R as the first sample (``k + 2`` where the textbook has ``k + 1``), so that one
innovation does not replace it. The difference ``y y^T - H P H^T`` can make ``R^`` indefinite:
it is kept positive definite by clipping its eigenvalues at ``floor`` times the smallest
eigenvalue of the model's R (default 1: never trust the sensor more than its model says, the
choice of :mod:`navsim.navigation.estimators.two_stage`). The full matrix is adapted, so a correlated
error (interference on all axes) is learnt as such.
"""

from __future__ import annotations

import numpy as np

from navsim.foundations.config import Node
from navsim.foundations.jsonschema import POS, obj
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import register
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.measurements.air_data import reject_rotating_R
from navsim.navigation.estimators.measurements.registry import sensor_names


@register("sage_husa")
class SageHusaKF(ErrorStateKF):
    """Parameters as :class:`ErrorStateKF`, plus ``forgetting`` (b, 0 < b < 1), ``floor`` and
    ``sensors`` (the sensor names whose measurement models are adapted; None: all)."""

    SCHEMA = {**ErrorStateKF.SCHEMA, "sage_husa": obj({
        "forgetting": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1}, "floor": POS,
        "sensors": {"type": "array", "items": {"type": "string"}}})}
    OPTIONS = "adaptive"                 #: its constructor arguments: parse's "adaptive"

    def __init__(self, layout, noise, measurements, forgetting: float = 0.95, floor: float = 1.0,
                 sensors=None, **kw):
        super().__init__(layout, noise, measurements, **kw)
        if not 0.0 < forgetting < 1.0:
            raise ValueError(f"forgetting factor {forgetting}: expected 0 < b < 1")
        self.forgetting, self.floor = forgetting, floor
        self.sensors = None if sensors is None else set(sensors)

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The ES-KF's keys plus ``sage_husa: {forgetting: 0.95, floor: 1.0, sensors: [...]}``
        (optional; ``sensors``: the sensors whose R is adapted, default all)."""
        read = lambda sub: {"forgetting": sub.get("forgetting", float, 0.95, exclusive_minimum=0.0, maximum=0.9999),
                            "floor": sub.get("floor", float, 1.0, exclusive_minimum=0.0),
                            "sensors": sensor_names(sub, "sensors", sensors)}
        params = {**super().parse(node, sensors), "adaptive": node.section("sage_husa", read)}
        reject_rotating_R(node, params["measurements"], params["adaptive"].get("sensors"), "the Sage-Husa filter")
        return params

    def initialize(self, nav0, sigma0):
        super().initialize(nav0, sigma0)
        self.R_hat: dict = {}
        self.count: dict = {}

    def adapts(self, model) -> bool:
        return self.sensors is None or model.sensor in self.sensors

    def measurement_noise(self, model, z, H, R, valid):
        if not self.adapts(model):
            return R
        key = f"{model.name}:{model.sensor}"
        B = z.shape[0]
        est = self.R_hat.get(key, R)
        k = self.count.get(key, np.zeros(B))
        y = z - (H @ self.x[..., None])[..., 0]
        HPH = H @ self.P @ np.swapaxes(H, -1, -2)
        b = self.forgetting
        d = ((1.0 - b) / (1.0 - b ** (k + 2)))[:, None, None]
        new = kalman.symmetrize((1.0 - d) * est + d * (y[..., :, None] * y[..., None, :] - HPH))
        w, V = np.linalg.eigh(new)
        w = np.maximum(w, self.floor * np.linalg.eigvalsh(R)[:, :1])
        new = kalman.symmetrize(V @ (w[..., None] * np.swapaxes(V, -1, -2)))
        v = np.asarray(valid, bool)
        est = np.where(v[:, None, None], new, est)
        self.R_hat[key] = est
        self.count[key] = k + v
        return est
