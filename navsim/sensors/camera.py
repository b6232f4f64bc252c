"""Landmark camera emulator (P1, GNSS-denied flight).

A downward-looking camera (boresight along body z) sees anchor points of known position; when
one is inside the field of view (``half_fov`` from the boresight) and within ``max_range``, the
camera yields a position fix of the aircraft with noise of std ``noise + noise_ratio * range``
per NED axis (the nearest visible landmark is used). Values: ``lat_rad``, ``lon_rad``, ``h_m``
``(B, M)``, ``landmark`` ``(B, M)`` (index, -1 when none); ``valid`` where a landmark was seen.
``errors['pos_error_n_m']`` is the fix error (NED, m), ``errors['range_m']`` ``(M,)`` the range to
the landmark seen (NaN when none); ``meta['landmarks']`` the anchors' coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from navsim.foundations import earth
from navsim.foundations.transform import dcm_from_quat
from navsim.sensors.base import SensorData, apply_outages, check_faults, normals, sampling
from navsim.sensors.gnss import position_channels
from navsim.sensors.registry import ErrorTerm, Field, Output, SensorKind, register


@dataclass(frozen=True)
class CameraSpec:
    """Landmark camera (P1): a downward camera sees anchor points of known position."""

    rate_hz: float = 1.0
    half_fov: float = math.radians(30.0)      #: rad
    max_range: float = 1500.0                 #: m
    noise: float = 2.0                        #: position-fix std at 0 m, m
    noise_ratio: float = 0.01                 #: extra std per metre of range
    landmarks: tuple[tuple[float, float, float], ...] = ()   #: (lat_deg, lon_deg, h_m)


def emulate_camera(truth, spec: CameraSpec, seed: int, runs, faults=(), name: str = "camera") -> SensorData:
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M = smp.runs, smp.B, smp.step, smp.t, smp.M
    lat, lon, h = truth.lat_rad[::step], truth.lon_rad[::step], truth.h_m[::step]
    lat0, lon0 = truth.lat_rad[0], truth.lon_rad[0]
    north, east = earth.local_ne(lat, lon, lat0, lon0)
    C_bn = np.swapaxes(dcm_from_quat(truth.quat_nb[::step]), -1, -2)
    landmark = np.full(M, -1)
    best_range = np.full(M, np.inf)
    for i, (la, lo, hl) in enumerate(spec.landmarks):
        ln, le = earth.local_ne(np.radians(la), np.radians(lo), lat0, lon0)
        los_n = np.stack([ln - north, le - east, h - hl], axis=-1)      # aircraft -> landmark, NED
        rng = np.linalg.norm(los_n, axis=-1)
        los_b = np.einsum("nij,nj->ni", C_bn, los_n)
        cos_off = los_b[:, 2] / np.maximum(rng, 1e-9)
        seen = (cos_off >= np.cos(spec.half_fov)) & (rng <= spec.max_range) & (rng < best_range)
        landmark[seen] = i
        best_range[seen] = rng[seen]
    valid = np.broadcast_to(landmark >= 0, (B, M)).copy()
    apply_outages(valid, t, faults)
    sigma = np.where(landmark >= 0, spec.noise + spec.noise_ratio * np.where(np.isfinite(best_range), best_range, 0.0), 0.0)
    err = normals(smp.rng("noise"), (M, 3)) * sigma[None, :, None] if np.any(sigma) else np.zeros((B, M, 3))
    r_m, r_n = earth.radii(lat)
    return SensorData(name=name, kind="camera", t_s=t,
                      values={"lat_rad": lat + err[..., 0] / (r_m + h),
                              "lon_rad": lon + err[..., 1] / ((r_n + h) * np.cos(lat)),
                              "h_m": h - err[..., 2], "landmark": np.broadcast_to(landmark, (B, M)).copy()},
                      valid=valid, errors={"pos_error_n_m": err,
                                           "range_m": np.where(landmark >= 0, best_range, np.nan)},
                      meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed,
                            "landmarks": [tuple(map(float, lm)) for lm in spec.landmarks]})


class SightingSpan(NamedTuple):
    """One landmark sighting of a camera: the landmark seen without a break from ``start_s`` to
    ``end_s`` (its first and last fix, s) and the camera's fix noise per axis at the last fix,
    ``sigma_m`` (``noise + noise_ratio * range``); ``name`` ``"<camera> landmark <index>"``."""

    name: str
    start_s: float
    end_s: float
    sigma_m: float


def sightings(data: SensorData, spec: CameraSpec) -> list[SightingSpan]:
    """The sightings of the first run of the camera data ``data`` (emulated with ``spec``: the
    sightings do not depend on the run, the flight being shared), read from its validity, its
    landmarks and its ranges."""
    out = []
    v = data.valid[0].astype(int)
    edges = np.flatnonzero(np.diff(np.r_[0, v, 0]))
    for a, b in zip(edges[::2], edges[1::2]):
        lm = int(data.values["landmark"][0, a])
        sigma = spec.noise + spec.noise_ratio * float(data.errors["range_m"][b - 1])
        out.append(SightingSpan(f"{data.name} landmark {lm}", float(data.t_s[a]), float(data.t_s[b - 1]), sigma))
    return out


def flight_sightings(truth, configs, seed: int = 0) -> list[SightingSpan]:
    """Every landmark sighting of the cameras among ``configs`` (a scenario's
    :class:`~navsim.sensors.SensorConfig` objects) on the flight ``truth``, camera by camera: each
    emulated for run 0 with its faults and read (:func:`sightings`). What the scorer and the
    report are handed (they only read them)."""
    out = []
    for c in configs:
        if isinstance(c.spec, CameraSpec):
            check_faults(c.faults, KIND.name, truth.duration_s, c.name)
            out += sightings(emulate_camera(truth, c.spec, seed, [0], faults=c.faults, name=c.name), c.spec)
    return out


KIND = register(SensorKind(
    name="camera", spec=CameraSpec, role="landmark_fix", description="downward landmark camera: position fixes (P1)",
    fields={"rate_hz": Field("rate_hz", None, "plain"), "half_fov": Field("half_fov", "angle", "1"),
            "max_range": Field("max_range", "length", "1"), "noise": Field("noise", "length", "1"),
            "noise_ratio": Field("noise_ratio", "ratio", "1"), "landmarks": Field("landmarks", None, "landmarks")},
    outputs=(Output("lat_rad", "rad"), Output("lon_rad", "rad"), Output("h_m", "m", role="height"),
             Output("landmark", "1")),
    errors=(ErrorTerm("noise"), ErrorTerm("noise_ratio")),
    emulate=emulate_camera, channels=position_channels))
