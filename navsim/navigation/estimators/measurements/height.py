"""The height measurement (``height``: a barometer, the ADS's pressure altitude, a radar
altimeter, a fused height; the baro's Markov error as a state) and its compiled form
(:func:`height`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations.compiled import njit
from navsim.foundations.config import Node
from navsim.foundations.jsonschema import NUM, VEC3
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.measurements.model import CompiledModel, Linearised, _compiled, _valid
from navsim.navigation.estimators.measurements.registry import measurement
from navsim.navigation.strapdown import NavState
from navsim.sensors import registry


def _height_output(kind: str) -> str:
    """The output a ``height`` measurement of a sensor of ``kind`` reads without a ``field``: the
    first the kind declares with the role ``height`` (:mod:`navsim.sensors.registry`), else ``h_m``."""
    return registry.default_output(kind, "height") or "h_m"


@measurement("height")
@dataclass
class Height:
    """INS height minus a measured height (barometer, ADS pressure altitude, a fused height),
    m. With a ``baro`` state in the filter, the sensor's Markov error is modelled:
    ``z = dh - dh_b``. ``offset_m`` is added to the sensor value (e.g. the surface height under
    a radar altimeter)."""

    sensor: str
    sigma_m: float
    field: str = "h_m"
    use_baro_state: bool = False
    offset_m: float = 0.0
    SCHEMA = {"sigma_m": VEC3, "field": {"type": "string"}, "baro_state": {"type": "boolean"}, "offset_m": NUM}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_m": node.get("sigma_m", float, exclusive_minimum=0.0),
                "field": node.get("field", str, _height_output(sensors[node.data["sensor"]])),
                "baro_state": node.get("baro_state", bool, False), "offset_m": node.get("offset_m", float, 0.0)}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], entry["sigma_m"], field=entry["field"], use_baro_state=entry["baro_state"],
                   offset_m=entry["offset_m"])

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ()                        # its field alone

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        z = (nav.h_m - (data.values[self.field][:, j] + self.offset_m))[:, None]
        H = np.zeros((B, 1, layout.n))
        H[:, 0, layout.slice("pos").start + 2] = 1.0
        if self.use_baro_state and layout.has("baro"):
            H[:, 0, layout.slice("baro").start] = -1.0
        return Linearised(z, H, np.full((B, 1, 1), float(self.sigma_m) ** 2), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        baro = layout.slice("baro").start if self.use_baro_state and layout.has("baro") else -1
        return _compiled(height, 1, [float(self.sigma_m) ** 2], [layout.slice("pos").start + 2, baro],
                         lambda nav, data, j: ((data.values[self.field][:, j] + self.offset_m)[:, None],
                                               _valid(data, j)))


@njit(cache=True, error_model="numpy")
def height(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS height minus ``inp[:, 0]``, m (``par[0]`` its variance; ``cols`` the height's column
    and the baro state's, or -1)."""
    for b in range(lat.shape[0]):
        z[b, r0] = h[b] - inp[b, 0]
        H[b, r0, cols[0]] = 1.0
        if cols[1] >= 0:
            H[b, r0, cols[1]] = -1.0
        R[b, r0, r0] = par[0]
