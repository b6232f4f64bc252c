"""Free-inertial navigation: the strapdown mechanization alone (no aiding)."""

from __future__ import annotations

import numpy as np

from navsim.foundations.config import MAX_DURATION_S, Node
from navsim.foundations.jsonschema import POS
from navsim.navigation.estimators.base import Innovation, Solution, register
from navsim.navigation.strapdown import BlockStrapdown, NavState


@register("sins")
class FreeInertial:
    """Integrates the IMU; its epochs do nothing. ``solution().P_nav`` is None: free inertial
    carries no covariance."""

    period_s = 1.0
    SCHEMA = {"period_s": POS}

    def __init__(self, period_s: float = 1.0):
        self.period_s = period_s

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """``period_s`` (1 s): how often its solution is recorded."""
        return {"period_s": node.get("period_s", float, 1.0, exclusive_minimum=0.0, maximum=MAX_DURATION_S)}

    def initialize(self, nav0: NavState, sigma0: dict | None = None) -> None:
        self.sd = BlockStrapdown(nav0.copy())
        self.diverged = np.zeros(nav0.lat_rad.shape[0], bool)

    def propagate(self, dtheta_b, dv_b, dt: float) -> None:
        """Mechanize the increments ``(B, K, 3)``."""
        self.sd.block(dtheta_b, dv_b, dt)

    def epoch(self, t: float, sensors: dict) -> list[Innovation]:
        return []

    def solution(self) -> Solution:
        return Solution(nav=self.sd.state, extra={"diverged": self.diverged})
