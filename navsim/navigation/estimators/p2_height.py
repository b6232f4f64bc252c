"""P2's switched height channel with dynamic weights (Chen, Lai, Wang), on the 18-state
error-state Kalman filter.

At each filter epoch the GPS height, averaged over a sliding window, decides the height
measurement: at or above ``threshold_m`` it is ``h_INS - h_GPS``; below, it is
``h_INS - (w_R h_R + w_A h_A + w_G h_G)`` with the radar altimeter (over the known surface),
barometric and GPS heights weighted by ``w_i = (1/sigma_i^2) / sum_j (1/sigma_j^2)``, and the
fused variance ``1 / sum_j (1/sigma_j^2)`` as R, recomputed every epoch; the radar's sigma is
``noise + ratio * H`` at the current radar height. A hysteresis of ``hysteresis_m`` around the
threshold keeps the switch from chattering.

``gating_sigma`` (off by default: P2 has none) is the improvement a reviewer would ask for:
each height sensor whose innovation ``|h_INS - h_i|`` exceeds ``gating_sigma`` times
``sqrt(P_hh + sigma_i^2)`` gets weight zero for that epoch, so a faulty sensor drops out of the
fusion during its fault. ``average_radar`` (off by default) uses every radar sample of the filter
period instead of the one at the epoch: their mean, with the variance divided by their number.
Horizontal position and velocity come from GPS as usual.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from navsim.foundations.config import Node, close_match
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import Innovation, register, sample
from navsim.navigation.estimators.eskf import ErrorStateKF


@dataclass(frozen=True)
class HeightFusion:
    gps: str                       #: sensor names
    radar: str
    baro: str
    gps_sigma_m: float = 30.0      #: P2
    baro_sigma_m: float = 25.0     #: P2
    radar_noise_m: float = 0.3     #: P2: 0.3 m + 3 % H
    radar_ratio: float = 0.03
    surface_m: float = 0.0         #: sea surface / terrain under the radar
    threshold_m: float = 500.0     #: P2
    hysteresis_m: float = 20.0
    window_s: float = 10.0         #: GPS height averaging window
    gating_sigma: float | None = None
    average_radar: bool = False    #: average the radar samples of the filter period (sigma / sqrt(n))


@register("p2_dynamic_height")
class DynamicHeightKF(ErrorStateKF):
    """The ES-KF with P2's dynamic-weight height channel (see the module docstring)."""

    SCHEMA = {**ErrorStateKF.SCHEMA, "height": {"type": "object", "description": "p2_dynamic_height: sensors "
                                                "gps, radar, baro and the fusion's numbers"}}

    def __init__(self, layout, noise, measurements, fusion: HeightFusion, **kw):
        super().__init__(layout, noise, measurements, **kw)
        self.fusion = fusion

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The ES-KF's keys plus ``height``: the sensors ``gps``, ``radar``, ``baro`` and the
        fusion's numbers (:class:`HeightFusion`)."""
        return {**super().parse(node, sensors), "height": _height(node.child("height"), sensors)}

    @classmethod
    def options(cls, params: dict) -> dict:
        return {"fusion": HeightFusion(**params["height"])}

    def initialize(self, nav0, sigma0):
        super().initialize(nav0, sigma0)
        B = nav0.lat_rad.shape[0]
        n = max(1, int(round(self.fusion.window_s / self.period_s)))
        self._gps_heights = deque(maxlen=n)
        self.low = np.zeros(B, bool)            # current mode of each run
        self.weights = np.zeros((B, 3))         # last weights (radar, baro, gps), for reports
        self._window = None                     # the epoch's sample window (latest_sample), from epoch()

    def epoch(self, t, sensors):
        self.predict()
        self._window = self._since(t)
        out = []
        for m in self.measurements:
            data, j = sample(sensors, m.sensor, t, self._window)
            if j is not None:
                out.append(self.correct(m, data, j, t))
        inn = self._height(t, sensors)
        if inn is not None:
            out.append(inn)
        self.feedback()
        return out

    def _sample(self, sensors, name, field, t):
        data, j = sample(sensors, name, t, self._window)
        if j is None:
            return None, None
        return data.values[field][:, j], data.valid[:, j]

    def _radar_mean(self, data, t):
        """Mean of the valid radar samples in ``(t - period, t]``, their count, validity."""
        m = (data.t_s > t - self.period_s + 1e-9) & (data.t_s <= t + 1e-9)
        h = data.values["h_agl_m"][:, m]
        v = data.valid[:, m]
        n = v.sum(axis=1)
        mean = np.where(n > 0, np.where(v, h, 0.0).sum(axis=1) / np.maximum(n, 1), np.nan)
        return mean, n > 0, np.maximum(n, 1).astype(float)

    def _height(self, t, sensors):
        f = self.fusion
        h_g, v_g = self._sample(sensors, f.gps, "h_m", t)
        h_r, v_r = self._sample(sensors, f.radar, "h_agl_m", t)
        n_r = np.ones(self.x.shape[0])
        if f.average_radar and f.radar in sensors:
            h_r, v_r, n_r = self._radar_mean(sensors[f.radar], t)
        h_a, v_a = self._sample(sensors, f.baro, "h_baro_m", t)
        B = self.x.shape[0]
        nav = self.sd.state
        if h_g is not None:
            self._gps_heights.append(np.where(v_g, h_g, np.nan))
        if not self._gps_heights:
            return None
        with np.errstate(all="ignore"):
            avg = np.nanmean(np.stack(self._gps_heights), axis=0)
        avg = np.where(np.isfinite(avg), avg, nav.h_m)
        self.low = np.where(self.low, avg < f.threshold_m + f.hysteresis_m, avg < f.threshold_m - f.hysteresis_m)
        # candidate heights and sigmas (B, 3): radar, baro, gps
        nan = np.full(B, np.nan)
        hs = np.stack([f.surface_m + h_r if h_r is not None else nan,
                       h_a if h_a is not None else nan, h_g if h_g is not None else nan], -1)
        ok = np.stack([v_r if v_r is not None else np.zeros(B, bool), v_a if v_a is not None else np.zeros(B, bool),
                       v_g if v_g is not None else np.zeros(B, bool)], -1) & np.isfinite(hs)
        radar_h = np.where(np.isfinite(hs[:, 0]), hs[:, 0] - f.surface_m, 0.0)
        sig = np.stack([(f.radar_noise_m + f.radar_ratio * np.abs(radar_h)) / np.sqrt(n_r),
                        np.full(B, f.baro_sigma_m), np.full(B, f.gps_sigma_m)], -1)
        # high mode: GPS height only
        ok[:, :2] &= self.low[:, None]
        h_idx = self.layout.slice("pos").start + 2
        if f.gating_sigma is not None:
            P_hh = self.P[:, h_idx, h_idx]
            r = nav.h_m[:, None] - hs
            ok &= ~(r * r > f.gating_sigma ** 2 * (P_hh[:, None] + sig * sig))
        w = np.where(ok, 1.0 / (sig * sig), 0.0)
        wsum = w.sum(-1)
        valid = wsum > 0
        wn = np.where(valid[:, None], w / np.where(valid, wsum, 1.0)[:, None], 0.0)
        self.weights = wn
        h_fused = np.nansum(np.where(ok, hs, 0.0) * wn, -1)
        var = np.where(valid, 1.0 / np.where(valid, wsum, 1.0), 1.0)
        z = (nav.h_m - h_fused)[:, None]
        H = np.zeros((B, 1, self.layout.n))
        H[:, 0, h_idx] = 1.0
        R = var[:, None, None]
        z = np.where(valid[:, None], z, 0.0)
        self.x, self.P, y, S, nis = kalman.update(self.x, self.P, z, H, R, valid)
        return Innovation("fused_height", "fusion", t, y, S, nis)


def _height(node: Node, sensors: dict) -> dict:
    """P2's height fusion: the ``gps``, ``radar``, ``baro`` sensor names and the model numbers
    (defaults: :class:`HeightFusion`'s)."""
    out = {}
    for role, kind in (("gps", "gnss"), ("radar", "radar_altimeter"), ("baro", "baro")):
        name = node.get(role, str)
        if sensors.get(name) != kind:
            raise node.error(f"'{name}' is not a {kind} of this scenario", role, expected=f"a sensor of kind {kind}",
                             hint=close_match(name, [k for k, v in sensors.items() if v == kind]))
        out[role] = name
    d = HeightFusion.__dataclass_fields__
    for key in ("gps_sigma_m", "baro_sigma_m", "radar_noise_m", "radar_ratio", "hysteresis_m", "window_s"):
        out[key] = node.get(key, float, d[key].default, minimum=0.0)
    out["threshold_m"] = node.get("threshold_m", float, d["threshold_m"].default)
    out["surface_m"] = node.get("surface_m", float, d["surface_m"].default)
    out["gating_sigma"] = node.get("gating_sigma", float, None, exclusive_minimum=0.0)
    out["average_radar"] = node.get("average_radar", bool, False)
    node.done()
    return out
