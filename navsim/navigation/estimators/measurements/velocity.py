"""The velocity measurements: ``velocity`` (a NED velocity, GNSS or the ADS's ground velocity)
and ``zero_velocity`` (the pseudo-measurement of a vehicle that stays near one spot), and their
compiled form (:func:`velocity`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations.compiled import njit
from navsim.foundations.config import Node
from navsim.foundations.jsonschema import VEC3
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.measurements.model import CompiledModel, Linearised, _compiled, _diag, _valid
from navsim.navigation.estimators.measurements.registry import measurement
from navsim.navigation.strapdown import NavState


@measurement("velocity")
@dataclass
class Velocity:
    """INS minus a NED velocity (GNSS, or P0's ADS ground velocity), m/s."""

    sensor: str
    sigma_mps: np.ndarray                #: (3,)
    field: str = "vel_n_mps"
    SCHEMA = {"sigma_mps": VEC3, "field": {"type": "string"}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_mps": node.vector("sigma_mps"), "field": node.get("field", str, "vel_n_mps")}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_mps"]), field=entry["field"])

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ()                        # its field alone

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        z = nav.vel_n_mps - data.values[self.field][:, j]
        H = np.zeros((B, 3, layout.n))
        s = layout.slice("vel").start
        H[:, [0, 1, 2], [s, s + 1, s + 2]] = 1.0
        return Linearised(z, H, _diag(np.asarray(self.sigma_mps, float) ** 2, B), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        return _compiled(velocity, 3, np.asarray(self.sigma_mps, float) ** 2,
                         [layout.slice("vel").start],
                         lambda nav, data, j: (data.values[self.field][:, j], _valid(data, j)))


@measurement("zero_velocity")
@dataclass
class ZeroVelocity:
    """INS velocity against zero, m/s: a pseudo-measurement for a vehicle with no position or
    velocity aiding that stays near one spot (a replayed log without GNSS, a hover, a test
    stand). The horizontal velocity error grows as gravity times the tilt error, so holding it
    near zero keeps roll and pitch observable from the accelerometers, as PX4's EKF2 fuses a
    fake position when it has no aiding. ``sigma_mps`` (N, E, D) must cover the vehicle's true
    motion; ``axes: horizontal`` (the default) uses N and E only. ``sensor`` only times it: one
    update at each of its samples."""

    sensor: str
    sigma_mps: np.ndarray                #: (3,) N, E, D
    vertical: bool = False
    SCHEMA = {"sigma_mps": VEC3, "axes": {"enum": ["horizontal", "ned"]}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_mps": node.vector("sigma_mps"),
                "axes": node.get("axes", str, "horizontal", choices=["horizontal", "ned"])}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_mps"]), vertical=entry["axes"] == "ned")

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ()                        # its sensor only times it

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B, m = nav.lat_rad.shape[0], 3 if self.vertical else 2
        H = np.zeros((B, m, layout.n))
        s = layout.slice("vel").start
        H[:, np.arange(m), s + np.arange(m)] = 1.0
        sig2 = np.asarray(self.sigma_mps, float)[:m] ** 2
        return Linearised(nav.vel_n_mps[:, :m].copy(), H, _diag(sig2, B), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        m = 3 if self.vertical else 2
        return _compiled(velocity, m, np.asarray(self.sigma_mps, float)[:m] ** 2,
                         [layout.slice("vel").start],
                         lambda nav, data, j: (np.zeros((nav.lat_rad.shape[0], m)), _valid(data, j)))


@njit(cache=True, error_model="numpy")
def velocity(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus a NED velocity ``inp``, the first ``len(par)`` axes (``par`` the variances,
    ``cols[0]`` the velocity block): ``velocity``, ``zero_velocity`` (``inp`` zeros)."""
    m, s = par.shape[0], cols[0]
    for b in range(lat.shape[0]):
        for i in range(m):
            z[b, r0 + i] = vel[b, i] - inp[b, i]
            H[b, r0 + i, s + i] = 1.0
            R[b, r0 + i, r0 + i] = par[i]
