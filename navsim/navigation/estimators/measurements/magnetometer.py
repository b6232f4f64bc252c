"""The magnetic heading (``mag_heading``: the magnetometer calibrated online, P1), its
geometry (:func:`magnetic_heading`) and its compiled form (:func:`magnetic_heading_kernel`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations.compiled import njit
from navsim.foundations.config import Node
from navsim.foundations.jsonschema import POS
from navsim.navigation import magcal
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.measurements.model import CompiledModel, Linearised, _compiled
from navsim.navigation.estimators.measurements.registry import measurement, sensor_of_kind
from navsim.navigation.strapdown import NavState
from navsim.sensors.magnetometer import WMM_DATE


@measurement("mag_heading")
@dataclass
class MagneticHeading:
    """INS minus magnetic heading, rad, from the magnetometer calibrated online (P1).

    Every call feeds the magnetometer samples since the last one to a recursive least-squares
    ellipsoid fit (:class:`navsim.navigation.magcal.EllipsoidRLS`, its noise model ``noise_T`` the
    filter's own) and calibrates the current sample, ``m_c = S^-1 (m - b)``. Rotated to NED
    with the INS attitude, ``v = C_nb m_c``, its declination ``atan2(v_E, v_N)`` minus the
    declination of the filter's own field model (WMM at the INS position) is the measurement:
    identical to the tilt-compensated magnetic heading (the field levelled with the INS roll
    and pitch, plus the model declination) subtracted from the INS yaw. With
    ``C_nb_est = (I - [phi x]) C_nb``, ``v = m_n + [m_n x] phi`` and::

        z = (m_N m_D phi_N + m_E m_D phi_E) / H^2 - phi_D,   H^2 = m_N^2 + m_E^2

    (roll and pitch errors enter through the inclination, as in the tilt compensation). The
    measurement is used once the INS heading has turned ``min_turns`` full turns since the
    start (the calibration manoeuvre) and the fit is an ellipsoid.

    ``calibration: none`` takes the samples as calibrated already (a replayed autopilot's
    magnetometer) and uses them from the first epoch; ``field_uT`` (N, E, D) replaces the WMM as
    the filter's model of the Earth field (a field measured on the ground; ``navsim replay``
    gives the one of its coarse alignment).
    """

    sensor: str
    sigma_rad: float
    noise_T: float                       #: the filter's model of the magnetometer noise, per axis
    forgetting: float = 1.0
    min_turns: float = 2.0
    field_n_T: np.ndarray | None = None  #: (3,) the filter's Earth field, NED; None: the WMM
    online: bool = True                  #: calibrate online; False: the samples are calibrated
    _fit: object = dataclasses.field(default=None, init=False, repr=False)     #: the RLS fit, from the first call

    SCHEMA = {"sigma_deg": POS, "noise_uT": {"type": "number", "minimum": 0},
              "forgetting": {"type": "number", "exclusiveMinimum": 0, "maximum": 1},
              "min_turns": {"type": "number", "minimum": 0}, "calibration": {"enum": ["online", "none"]},
              "field_uT": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The heading's ``sigma_deg``, the filter's model of the magnetometer noise ``noise_uT``
        (per axis, for the online fit), the calibration (``online`` or ``none``), its
        ``forgetting`` and ``min_turns``, and the Earth field ``field_uT`` (None: the WMM)."""
        sensor_of_kind(node, sensors, "magnetometer")
        field = node.vector("field_uT", None, minimum=-math.inf) if node.data.get("field_uT") is not None else None
        calibration = node.get("calibration", str, "online", choices=["online", "none"])
        noise = (node.get("noise_uT", float, minimum=0.0) if calibration == "online"     # the fit's noise model
                 else node.get("noise_uT", float, 0.0, minimum=0.0))
        return {"sigma_deg": node.get("sigma_deg", float, exclusive_minimum=0.0), "noise_uT": noise,
                "calibration": calibration,
                "forgetting": node.get("forgetting", float, 1.0, exclusive_minimum=0.0, maximum=1.0),
                "min_turns": node.get("min_turns", float, 2.0, minimum=0.0), "field_uT": field}

    @classmethod
    def from_entry(cls, entry: dict):
        field = entry.get("field_uT")
        return cls(entry["sensor"], np.radians(entry["sigma_deg"]), entry["noise_uT"] * 1e-6,
                   forgetting=entry["forgetting"], min_turns=entry["min_turns"],
                   field_n_T=None if field is None else np.asarray(field, float) * 1e-6,
                   online=entry.get("calibration", "online") == "online")

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ("mag_b_T",)

    def _field_n_T(self, nav: NavState, date: str, grid: bool = True) -> np.ndarray:
        """The filter's Earth field at the INS position ``(B, 3)``."""
        if self.field_n_T is not None:
            return np.broadcast_to(self.field_n_T, (nav.lat_rad.shape[0], 3))
        return magcal.field_model_n_T(nav.lat_rad, nav.lon_rad, nav.h_m, date, grid=grid)

    def _calibrated(self, nav: NavState, data, j: int, date: str):
        """Sample ``j`` calibrated, and the runs whose calibration may be used."""
        B = nav.lat_rad.shape[0]
        mag = data.values["mag_b_T"]
        if not self.online:
            return mag[:, j], np.ones(B, bool)
        yaw = np.arctan2(nav.C_nb[:, 1, 0], nav.C_nb[:, 0, 0])
        if self._fit is None:
            field = self._field_n_T(nav, date, grid=False)
            self._fit = magcal.EllipsoidRLS(np.linalg.norm(field, axis=-1), self.noise_T, self.forgetting)
            self._fed, self._turns, self._yaw = 0, np.zeros(B), yaw
        self._fit.update(mag[:, self._fed:j + 1], data.valid[:, self._fed:j + 1])
        self._fed = j + 1
        self._turns += np.abs((yaw - self._yaw + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi)
        self._yaw = yaw
        hard, soft, ok = self._fit.estimate()
        return magcal.calibrate(mag[:, j], hard, soft), ok & (self._turns >= self.min_turns)

    def _sample(self, nav: NavState, data, j: int) -> tuple:
        """Sample ``j`` calibrated ``(B, 3)`` (body, T), the filter's Earth field ``(B, 3)``
        (NED, T) and the runs whose calibration is usable ``(B,)``."""
        date = data.meta.get("date", WMM_DATE)
        m_b, ok = self._calibrated(nav, data, j, date)
        return m_b, self._field_n_T(nav, date), ok

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        m_b, field_n, ok = self._sample(nav, data, j)
        z, h_att = magnetic_heading(nav.C_nb, m_b, field_n)
        valid = data.valid[:, j] & ok & np.isfinite(z)
        H = np.zeros((B, 1, layout.n))
        H[:, 0, layout.slice("att")] = h_att
        return Linearised(np.where(valid, z, 0.0)[:, None], H, np.full((B, 1, 1), float(self.sigma_rad) ** 2), valid)

    def compiled(self, layout: Layout) -> CompiledModel:
        """The heading's geometry compiled; the online calibration stays in Python (its fit is
        fed the samples since the last call)."""
        def inputs(nav, data, j):
            m_b, field_n, ok = self._sample(nav, data, j)
            return np.concatenate([m_b, field_n], 1), data.valid[:, j] & ok
        return _compiled(magnetic_heading_kernel, 1, [float(self.sigma_rad) ** 2],
                         [layout.slice("att").start], inputs)


def magnetic_heading(C_nb: np.ndarray, mag_cal_b: np.ndarray, field_n: np.ndarray):
    """INS minus magnetic heading ``z`` ``(B,)``, rad, and its row ``(B, 3)`` in the attitude
    error ``phi`` (NED): the declination of ``C_nb mag_cal_b`` minus that of ``field_n`` (see
    :class:`MagneticHeading`)."""
    v = np.einsum("bij,bj->bi", C_nb, mag_cal_b)
    z = (np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(field_n[:, 1], field_n[:, 0]) + np.pi) % (2 * np.pi) - np.pi
    h2 = field_n[:, 0] ** 2 + field_n[:, 1] ** 2
    H = np.stack([field_n[:, 0] * field_n[:, 2] / h2, field_n[:, 1] * field_n[:, 2] / h2,
                  -np.ones_like(h2)], -1)
    return z, H


@njit(cache=True, error_model="numpy")
def magnetic_heading_kernel(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus magnetic heading, rad, from the calibrated sample ``inp[:, :3]`` (body) and
    the filter's Earth field ``inp[:, 3:6]`` (NED); ``par[0]`` its variance, ``cols[0]`` the
    attitude block. A run whose heading is not finite is dropped from ``valid``; an invalid
    run's ``z`` is 0."""
    a = cols[0]
    for b in range(lat.shape[0]):
        v0 = C[b, 0, 0] * inp[b, 0] + C[b, 0, 1] * inp[b, 1] + C[b, 0, 2] * inp[b, 2]
        v1 = C[b, 1, 0] * inp[b, 0] + C[b, 1, 1] * inp[b, 1] + C[b, 1, 2] * inp[b, 2]
        f0, f1, f2 = inp[b, 3], inp[b, 4], inp[b, 5]
        d = (math.atan2(v1, v0) - math.atan2(f1, f0) + math.pi) % (2 * math.pi) - math.pi
        valid[b] = valid[b] and math.isfinite(d)
        z[b, r0] = d if valid[b] else 0.0
        h2 = f0 * f0 + f1 * f1
        H[b, r0, a], H[b, r0, a + 1], H[b, r0, a + 2] = f0 * f2 / h2, f1 * f2 / h2, -1.0
        R[b, r0, r0] = par[0]
