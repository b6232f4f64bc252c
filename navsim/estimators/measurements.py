"""Measurement models: each returns the batched linearised model ``z, H, R, valid`` of one
sensor sample for the error-state filter.

``z`` is the measured error, *INS minus sensor*, so that ``z = H dx + v`` with ``dx`` the error
state (estimate minus truth) and ``v ~ N(0, R)``. Each model knows which sensor it reads
(``sensor``) and the noise it assumes (its own numbers, not the sensor's truth spec).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim import earth
from navsim.estimators.error_model import Layout
from navsim.strapdown import NavState


def _diag(sig2: np.ndarray, B: int) -> np.ndarray:
    return np.broadcast_to(np.diag(sig2), (B, sig2.size, sig2.size)).copy()


@dataclass
class GnssPosition:
    """INS minus GNSS position, NED metres: ``[dL (R_M+h), dlambda (R_N+h) cos L, -dh]``."""

    sensor: str
    sigma_m: np.ndarray                  #: (3,) NED
    name: str = "gnss_position"

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
        return z, H, _diag(np.asarray(self.sigma_m, float) ** 2, B), data.valid[:, j]


@dataclass
class Velocity:
    """INS minus a NED velocity (GNSS, or P0's ADS ground velocity), m/s."""

    sensor: str
    sigma_mps: np.ndarray                #: (3,)
    field: str = "vel_n_mps"
    name: str = "velocity"

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        z = nav.vel_n_mps - data.values[self.field][:, j]
        H = np.zeros((B, 3, layout.n))
        s = layout.slice("vel").start
        H[:, [0, 1, 2], [s, s + 1, s + 2]] = 1.0
        return z, H, _diag(np.asarray(self.sigma_mps, float) ** 2, B), data.valid[:, j]


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
    name: str = "height"

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        z = (nav.h_m - (data.values[self.field][:, j] + self.offset_m))[:, None]
        H = np.zeros((B, 1, layout.n))
        H[:, 0, layout.slice("pos").start + 2] = 1.0
        if self.use_baro_state and layout.has("baro"):
            H[:, 0, layout.slice("baro").start] = -1.0
        return z, H, np.full((B, 1, 1), float(self.sigma_m) ** 2), data.valid[:, j]


MODELS = {"gnss_position": GnssPosition, "velocity": Velocity, "height": Height}


@dataclass
class GnssHorizontal:
    """INS minus GNSS horizontal position, NED metres: ``[dL (R_M+h), dlambda (R_N+h) cos L]``
    (the height is left to a separate height channel, as in P2)."""

    sensor: str
    sigma_m: np.ndarray                  #: (2,) north, east
    name: str = "gnss_horizontal"

    def model(self, nav: NavState, layout: Layout, data, j: int):
        z, H, R, valid = GnssPosition(self.sensor, np.r_[self.sigma_m, 1.0]).model(nav, layout, data, j)
        return z[:, :2], H[:, :2], R[:, :2, :2], valid


MODELS["gnss_horizontal"] = GnssHorizontal


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
    name: str = "landmark"

    def model(self, nav: NavState, layout: Layout, data, j: int):
        z, H, _, valid = GnssPosition(self.sensor, np.ones(3)).model(nav, layout, data, j)
        idx = data.values["landmark"][:, j]
        anchors = np.asarray(data.meta.get("landmarks") or [(0.0, 0.0, 0.0)], float)
        a = anchors[np.clip(idx, 0, len(anchors) - 1)]
        r_m, r_n = earth.radii(nav.lat_rad)
        d = np.stack([(np.radians(a[:, 0]) - nav.lat_rad) * (r_m + nav.h_m),
                      (np.radians(a[:, 1]) - nav.lon_rad) * (r_n + nav.h_m) * np.cos(nav.lat_rad),
                      nav.h_m - a[:, 2]], -1)
        sigma = self.sigma_m + self.ratio * np.linalg.norm(d, axis=-1)
        R = sigma[:, None, None] ** 2 * np.eye(3)
        return z, H, R, valid & (idx >= 0)


MODELS["landmark"] = LandmarkFix


@dataclass
class MagneticField:
    """INS-predicted minus calibrated magnetometer field, body axes, tesla (P1: the calibrated
    magnetometer corrects the attitude, the heading above all).

    From ``calibrate_from_s`` (once the filter has its heading) until ``calibrate_until_s`` (the
    calibration turns) the model only calibrates the sensor, online, by recursive least
    squares on the INS attitude and the World Magnetic Model field at the INS position
    (:class:`navsim.magcal.AttitudeRLS`; the filter should then have GNSS and turns), and makes
    no correction; then it freezes the calibration and measures
    ``z = C_bn m_n - S^-1 (m - b)``, ``H = -C_bn [m_n x]`` on the attitude error (the component
    along the field carries no information). ``date`` is the WMM epoch the filter assumes."""

    sensor: str
    sigma_T: float
    calibrate_until_s: float
    date: str = "2025-01-01"
    calibrate_from_s: float = 0.0
    name: str = "magnetic_field"

    def __post_init__(self):
        self._rls = self._frozen = None
        self.record = {"t_s": [], "hard_iron_T": [], "soft_iron": []}

    def field_n_T(self, nav: NavState) -> np.ndarray:
        """WMM field at each run's INS position (rounded to 0.01 deg and 100 m, cached)."""
        from navsim.sensors.magnetometer import wmm_field_n_T
        lat, lon = np.round(np.degrees(nav.lat_rad), 2), np.round(np.degrees(nav.lon_rad), 2)
        h = np.round(nav.h_m, -2)
        return np.array([wmm_field_n_T(float(a), float(b), float(c), self.date) for a, b, c in zip(lat, lon, h)])

    def model(self, nav: NavState, layout: Layout, data, j: int):
        from navsim.magcal import AttitudeRLS, calibrate
        from navsim.strapdown import skew
        B = nav.lat_rad.shape[0]
        m = data.values["mag_b_T"][:, j]
        valid = data.valid[:, j]
        m_n = self.field_n_T(nav)
        C_bn = np.swapaxes(nav.C_nb, 1, 2)
        pred = np.einsum("bij,bj->bi", C_bn, m_n)
        H = np.zeros((B, 3, layout.n))
        R = np.broadcast_to(np.eye(3) * self.sigma_T ** 2, (B, 3, 3)).copy()
        if self._rls is None:
            self._rls = AttitudeRLS(B)
        if data.t_s[j] <= self.calibrate_until_s + 1e-9:
            self._rls.update(m, pred, valid & (data.t_s[j] >= self.calibrate_from_s - 1e-9))
            b, S = self._rls.estimate()
            self.record["t_s"].append(float(data.t_s[j]))
            self.record["hard_iron_T"].append(b)
            self.record["soft_iron"].append(S)
            return np.zeros((B, 3)), H, R, np.zeros(B, bool)
        if self._frozen is None:
            self._frozen = self._rls.estimate()
        z = pred - calibrate(m, *self._frozen)
        H[:, :, layout.slice("att")] = -C_bn @ skew(m_n)
        return z, H, R, valid

    def calibration_record(self) -> dict:
        """The calibration against time: ``t_s`` ``(E,)``, ``hard_iron_T`` ``(B, E, 3)``,
        ``soft_iron`` ``(B, E, 3, 3)``."""
        r = self.record
        if not r["t_s"]:
            return {}
        return {"t_s": np.array(r["t_s"]), "hard_iron_T": np.stack(r["hard_iron_T"], 1),
                "soft_iron": np.stack(r["soft_iron"], 1)}


MODELS["magnetic_field"] = MagneticField
