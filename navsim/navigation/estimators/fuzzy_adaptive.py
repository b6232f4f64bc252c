"""Fuzzy adaptive error-state Kalman filter: the credibility of a sensor (GNSS near a faulty
power line, P1's Tang & Wu) is judged from the size of its innovation by fuzzy rules that
scale its measurement noise R.

Input, per run and adapted measurement model: the normalised innovation magnitude
``r = sqrt(m_k)``, where ``m_k`` is the exponentially smoothed NIS per degree of freedom computed
with the model's own R, ``m_k = (1 - a) m_k-1 + a (y^T S^-1 y) / dim``, ``a = 1 / window``
(a consistent sensor gives ``r ~ 1``; one whose noise is c times larger gives ``r ~ c`` once R
dominates S).

Membership functions: one fuzzy set per rule, triangles centred on the rule's input ``r_i``
reaching zero at the neighbouring centres, with shoulders (membership 1) below the first centre
and above the last, so that the memberships sum to 1 everywhere.

Rules (zero-order Sugeno): ``IF r is R_i THEN s = s_i``; the output is the membership-weighted
average of the ``s_i`` and ``R_used = s R``. The default table::

    r:  1 (normal)   2 (suspect)   3 (poor)   5 (jammed)   10 (unusable)
    s:  1            4             9          25           100

follows ``s = r^2`` at the centres (the scale that makes the NIS consistent again) and
interpolates between them; a table with ``s < r^2`` trusts the sensor more. Both rows are
parameters (``rules: [[r, s], ...]``). The measurement noise only is scaled (the Q scaling of
some fuzzy filters is not implemented).
"""

from __future__ import annotations

import numpy as np

from navsim.foundations.config import MAX_RULES, MAX_WINDOW, Node, check_numbers
from navsim.foundations.jsonschema import POS, obj
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import register
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.measurements.registry import sensor_names

DEFAULT_RULES = ((1.0, 1.0), (2.0, 4.0), (3.0, 9.0), (5.0, 25.0), (10.0, 100.0))


def memberships(r: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Degrees of membership ``(..., K)`` of ``r`` in the K shouldered triangular sets."""
    r = np.asarray(r, float)[..., None]
    c = np.asarray(centres, float)
    if c.size == 1:
        return np.ones(r.shape[:-1] + (1,))
    left = np.r_[c[0] - 1.0, c[:-1]]
    right = np.r_[c[1:], c[-1] + 1.0]
    rising = (r - left) / (c - left)
    rising[..., 0] = 1.0                        # left shoulder
    falling = (right - r) / (right - c)
    falling[..., -1] = 1.0                      # right shoulder
    return np.clip(np.where(r <= c, rising, falling), 0.0, 1.0)


def infer(r: np.ndarray, rules) -> np.ndarray:
    """The R scale of the rule table ``[(r_i, s_i), ...]`` at ``r`` (weighted average)."""
    rules = np.asarray(rules, float)
    mu = memberships(r, rules[:, 0])
    return (mu @ rules[:, 1]) / mu.sum(-1)


@register("fuzzy_adaptive")
class FuzzyAdaptiveKF(ErrorStateKF):
    """Parameters as :class:`ErrorStateKF`, plus ``rules`` (``[[r, s], ...]``, r increasing,
    s >= 0), ``window`` (epochs of the NIS smoothing) and ``sensors`` (the sensor names whose
    models are adapted; None: all)."""

    SCHEMA = {**ErrorStateKF.SCHEMA, "fuzzy": obj({
        "window": {"type": "number", "minimum": 1},
        "rules": {"type": "array", "items": {"type": "array", "items": POS, "minItems": 2, "maxItems": 2}},
        "sensors": {"type": "array", "items": {"type": "string"}}})}
    OPTIONS = "adaptive"                 #: its constructor arguments: parse's "adaptive"

    def __init__(self, layout, noise, measurements, rules=DEFAULT_RULES, window: float = 3.0,
                 sensors=None, **kw):
        super().__init__(layout, noise, measurements, **kw)
        rules = np.asarray(rules, float)
        if rules.ndim != 2 or rules.shape[1] != 2 or np.any(np.diff(rules[:, 0]) <= 0) or np.any(rules[:, 1] <= 0):
            raise ValueError("rules: expected [[r, s], ...] with r increasing and s > 0")
        self.rules, self.window = rules, float(window)
        self.sensors = None if sensors is None else set(sensors)

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The ES-KF's keys plus ``fuzzy: {window: 3, rules: [[1, 1], [2, 4], ...], sensors: [...]}``
        (optional; ``sensors``: the sensors whose R is adapted, default all)."""
        def read(sub: Node) -> dict:
            out = {"window": sub.get("window", float, 3.0, minimum=1.0, maximum=MAX_WINDOW), "sensors": sensor_names(sub, "sensors", sensors)}
            rules = _rules(sub)
            return out if rules is None else {**out, "rules": rules}
        return {**super().parse(node, sensors), "adaptive": node.section("fuzzy", read)}

    def initialize(self, nav0, sigma0):
        super().initialize(nav0, sigma0)
        self.nis_smoothed: dict = {}
        self.scale: dict = {}

    def measurement_noise(self, model, z, H, R, valid):
        if not (self.sensors is None or model.sensor in self.sensors):
            return R
        key = f"{model.name}:{model.sensor}"
        B, dim = z.shape
        y = z - (H @ self.x[..., None])[..., 0]
        S = H @ self.P @ np.swapaxes(H, -1, -2) + R
        nis = np.einsum("bi,bi->b", y, kalman.solve_runs(S, y[..., None])[..., 0]) / dim
        a = 1.0 / self.window
        m = self.nis_smoothed.get(key, np.ones(B))
        v = np.asarray(valid, bool)
        m = np.where(v, (1.0 - a) * m + a * nis, m)
        self.nis_smoothed[key] = m
        s = infer(np.sqrt(m), self.rules)
        self.scale[key] = s
        return s[:, None, None] * R


def _rules(node: Node) -> list | None:
    """``rules``: ``[[r, s], ...]`` with r increasing and s > 0, or None."""
    node._seen.add("rules")
    rules = node.data.get("rules")
    if rules is None:
        return None
    ok = isinstance(rules, list) and 0 < len(rules) <= MAX_RULES and all(isinstance(r, list) for r in rules)
    err = lambda m, e: node.error(f"is {rules!r}", "rules", expected=f"a list of [r, s] pairs ({e})")
    arr = np.array([check_numbers(r, 2, error=err) for r in rules], float) if ok else None
    if not ok or np.any(np.diff(arr[:, 0]) <= 0) or np.any(arr[:, 1] <= 0):
        raise node.error(f"is {rules!r}", "rules", expected="a list of [r, s] pairs with r increasing and s > 0",
                         hint="e.g. [[1, 1], [2, 4], [3, 9], [5, 25], [10, 100]]")
    return [[float(a), float(b)] for a, b in rules]
