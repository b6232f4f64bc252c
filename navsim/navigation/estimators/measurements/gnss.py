"""The GNSS position fixes: ``gnss_position`` (N, E, D) and ``gnss_horizontal`` (N, E), and
their compiled form (:func:`position_fix`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations import earth
from navsim.foundations.compiled import njit
from navsim.foundations.config import Node
from navsim.foundations.jsonschema import VEC3
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.measurements.model import (
    CompiledModel,
    Linearised,
    _columns,
    _compiled,
    _diag,
    _valid,
)
from navsim.navigation.estimators.measurements.registry import measurement
from navsim.navigation.kernels.earth import radii
from navsim.navigation.strapdown import NavState


#: the values a position fix reads of its sensor
POSITION_VALUES = ("lat_rad", "lon_rad", "h_m")


@measurement("gnss_position")
@dataclass
class GnssPosition:
    """INS minus GNSS position, NED metres: ``[dL (R_M+h), dlambda (R_N+h) cos L, -dh]``."""

    sensor: str
    sigma_m: np.ndarray                  #: (3,) NED
    SCHEMA = {"sigma_m": VEC3}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_m": node.vector("sigma_m")}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_m"]))

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return POSITION_VALUES

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        v = data.values
        r_m, r_n = earth.radii(nav.lat_rad)
        k_n, k_e = r_m + nav.h_m, (r_n + nav.h_m) * np.cos(nav.lat_rad)
        z = np.stack([(nav.lat_rad - v["lat_rad"][:, j]) * k_n,
                      (nav.lon_rad - v["lon_rad"][:, j]) * k_e,
                      -(nav.h_m - v["h_m"][:, j])], -1)
        H = np.zeros((B, 3, layout.n))
        p = layout.slice("pos").start
        H[:, 0, p], H[:, 1, p + 1], H[:, 2, p + 2] = k_n, k_e, -1.0
        return Linearised(z, H, _diag(np.asarray(self.sigma_m, float) ** 2, B), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        return _position_fix(np.asarray(self.sigma_m, float)[:3] ** 2, layout)


def _position_fix(var, layout: Layout) -> CompiledModel:
    """The compiled position fix of ``len(var)`` rows (N, E, D)."""
    return _compiled(position_fix, len(var), var, [layout.slice("pos").start],
                     lambda nav, data, j: (_columns(data, j, POSITION_VALUES), _valid(data, j)))


@measurement("gnss_horizontal")
@dataclass
class GnssHorizontal(GnssPosition):
    """INS minus GNSS horizontal position, NED metres: ``[dL (R_M+h), dlambda (R_N+h) cos L]``
    (the height is left to a separate height channel, as in P2): the first two rows of
    :class:`GnssPosition`, whose entry it reads but for the height's sigma."""

    sensor: str
    sigma_m: np.ndarray                  #: (2,) north, east

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_m": node.vector("sigma_m")[:2]}

    def model(self, nav: NavState, layout: Layout, data, j: int):
        full = GnssPosition(self.sensor, np.r_[self.sigma_m, 1.0]).model(nav, layout, data, j)
        return Linearised(full.z[:, :2], full.H[:, :2], full.R[:, :2, :2], full.valid)

    def compiled(self, layout: Layout) -> CompiledModel:
        return _position_fix(np.asarray(self.sigma_m, float)[:2] ** 2, layout)

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        """The position fix's values (its own: a type that changes ``model`` declares them)."""
        return super().reads(entry)


@njit(cache=True, error_model="numpy")
def position_fix(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus a position ``inp`` ``(lat, lon, h)``, NED metres, the first ``len(par)`` rows
    (``par`` the variances, ``cols[0]`` the position block): ``gnss_position``, ``gnss_horizontal``."""
    m, p = par.shape[0], cols[0]
    for b in range(lat.shape[0]):
        r_m, r_n = radii(lat[b])
        k_n, k_e = r_m + h[b], (r_n + h[b]) * math.cos(lat[b])
        row = ((lat[b] - inp[b, 0]) * k_n, (lon[b] - inp[b, 1]) * k_e, -(h[b] - inp[b, 2]))
        gain = (k_n, k_e, -1.0)
        for i in range(m):
            z[b, r0 + i] = row[i]
            H[b, r0 + i, p + i] = gain[i]
            R[b, r0 + i, r0 + i] = par[i]
