"""The landmark camera's position fix (``landmark``, P1 GNSS-denied) and its compiled form
(:func:`landmark_fix`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations import earth
from navsim.foundations.compiled import njit
from navsim.foundations.config import Node
from navsim.foundations.jsonschema import VEC3
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.measurements.gnss import POSITION_VALUES, GnssPosition, position_fix
from navsim.navigation.estimators.measurements.model import CompiledModel, Linearised, _columns, _compiled, _valid
from navsim.navigation.estimators.measurements.registry import measurement, sensor_of_kind
from navsim.navigation.kernels.earth import radii
from navsim.navigation.strapdown import NavState


@measurement("landmark")
@dataclass
class LandmarkFix:
    """INS minus the aircraft position the landmark camera fixes from a recognised anchor point
    (P1, GNSS-denied), NED metres: the GNSS position model on the camera's fix, with the
    filter's own noise model, std ``sigma_m + ratio * range`` per axis, the range taken from the
    INS position to the anchor the camera reports (``values['landmark']``; the anchors'
    coordinates are known on board, ``meta['landmarks']``: that is the method)."""

    sensor: str
    sigma_m: float
    ratio: float = 0.0
    SCHEMA = {"sigma_m": VEC3, "ratio": {"type": "number", "minimum": 0}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        sensor_of_kind(node, sensors, "camera")
        return {"sigma_m": node.get("sigma_m", float, exclusive_minimum=0.0),
                "ratio": node.get("ratio", float, 0.0, minimum=0.0)}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], entry["sigma_m"], entry["ratio"])

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return POSITION_VALUES + ("landmark",)

    def model(self, nav: NavState, layout: Layout, data, j: int):
        fix = GnssPosition(self.sensor, np.ones(3)).model(nav, layout, data, j)
        idx = data.values["landmark"][:, j]
        anchors = np.asarray(data.meta.get("landmarks") or [(0.0, 0.0, 0.0)], float)
        a = anchors[np.clip(idx, 0, len(anchors) - 1)]
        r_m, r_n = earth.radii(nav.lat_rad)
        d = np.stack([(np.radians(a[:, 0]) - nav.lat_rad) * (r_m + nav.h_m),
                      (np.radians(a[:, 1]) - nav.lon_rad) * (r_n + nav.h_m) * np.cos(nav.lat_rad),
                      nav.h_m - a[:, 2]], -1)
        sigma = self.sigma_m + self.ratio * np.linalg.norm(d, axis=-1)
        R = sigma[:, None, None] ** 2 * np.eye(3)
        return Linearised(fix.z, fix.H, R, fix.valid & (idx >= 0))

    def compiled(self, layout: Layout) -> CompiledModel:
        def inputs(nav, data, j):
            idx = data.values["landmark"][:, j]
            anchors = np.asarray(data.meta.get("landmarks") or [(0.0, 0.0, 0.0)], float)
            fix = _columns(data, j, POSITION_VALUES)
            return np.concatenate([fix, anchors[np.clip(idx, 0, len(anchors) - 1)]], 1), _valid(data, j) & (idx >= 0)
        return _compiled(landmark_fix, 3, [self.sigma_m, self.ratio, 1.0, 1.0, 1.0],
                         [layout.slice("pos").start], inputs)


@njit(cache=True, error_model="numpy")
def landmark_fix(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus the camera's position fix ``inp[:, :3]`` ``(lat, lon, h)``, NED metres, with
    the std ``par[0] + par[1] * range`` to the anchor ``inp[:, 3:6]`` ``(lat, lon in degrees,
    h)``; ``cols[0]`` the position block."""
    position_fix(lat, lon, h, vel, C, inp, par[2:5], cols, r0, z, H, R, valid)
    for b in range(lat.shape[0]):
        r_m, r_n = radii(lat[b])
        dn = (math.radians(inp[b, 3]) - lat[b]) * (r_m + h[b])
        de = (math.radians(inp[b, 4]) - lon[b]) * (r_n + h[b]) * math.cos(lat[b])
        dd = h[b] - inp[b, 5]
        sigma = par[0] + par[1] * math.sqrt(dn * dn + de * de + dd * dd)
        for i in range(3):
            R[b, r0 + i, r0 + i] = sigma * sigma
