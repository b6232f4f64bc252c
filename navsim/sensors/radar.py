"""Radar altimeter emulator (P2): height above the sea surface or terrain.

``values['h_agl_m']`` ``(B, M)``; no output (``valid`` False) outside ``[min_range, max_range]``.
Error model: white noise of std ``(noise + noise_ratio H) (1 + tilt_noise_gain * tilt)``, where
``tilt = acos(cos(roll) cos(pitch))`` is the beam's tilt from the vertical; beyond the beam's half
width the first return comes from a slant range, ``H / cos(tilt - half_width)``; a sea state adds
wave elevation of std ``wave_height / 4`` (significant wave height = 4 sigma). Fault windows
``bias`` add exactly their value. ``errors['h_error_m']`` is the total error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.sensors.base import SensorData, apply_outages, normals, sampling
from navsim.sensors.registry import ErrorTerm, Field, Output, SensorKind, register


@dataclass(frozen=True)
class RadarAltimeterSpec:
    """Radar altimeter (P2): sigma = noise + noise_ratio * H, range limits, slant error."""

    rate_hz: float = 10.0
    noise: float = 0.3                        #: m
    noise_ratio: float = 0.03                 #: of the height
    min_range: float = 0.0                    #: m
    max_range: float = 1500.0                 #: m
    beam_half_width: float = math.radians(20.0)  #: rad; tilt beyond this lengthens the range
    tilt_noise_gain: float = 1.0              #: extra sigma factor per rad of tilt
    wave_height: float = 0.0                  #: significant wave height (sea state), m


def emulate_radar_altimeter(truth, spec: RadarAltimeterSpec, seed: int, runs, faults=(),
                            name: str = "radar_altimeter") -> SensorData:
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M = smp.runs, smp.B, smp.step, smp.t, smp.M
    H = truth.h_agl_m[::step]
    roll, pitch = truth.euler_rad[::step, 0], truth.euler_rad[::step, 1]
    tilt = np.arccos(np.clip(np.cos(roll) * np.cos(pitch), -1.0, 1.0))
    slant = H / np.cos(np.clip(tilt - spec.beam_half_width, 0.0, 1.4)) - H
    sigma = (spec.noise + spec.noise_ratio * np.abs(H)) * (1.0 + spec.tilt_noise_gain * tilt)
    factor = np.ones(M)
    bias = np.zeros(M)
    for f in faults:
        if f.type == "degraded":
            factor[f.active(t)] *= f.factor
        elif f.type == "bias":
            bias[f.active(t)] += f.value
    err = np.broadcast_to(slant + bias, (B, M)).copy()
    if np.any(sigma):
        err += normals(smp.rng("noise"), (M,)) * (sigma * factor)
    if spec.wave_height:
        err += normals(smp.rng("waves"), (M,)) * (spec.wave_height / 4.0)
    h = H[None] + err
    valid = (h >= spec.min_range) & (h <= spec.max_range)
    apply_outages(valid, t, faults)
    return SensorData(name=name, kind="radar_altimeter", t_s=t, values={"h_agl_m": h}, valid=valid,
                      errors={"h_error_m": err, "sigma_m": sigma},
                      meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed})


KIND = register(SensorKind(
    name="radar_altimeter", spec=RadarAltimeterSpec, role="altimeter",
    description="radar altimeter: height above the surface (P2)",
    fields={"rate_hz": Field("rate_hz", None, "plain"), "noise": Field("noise", "length", "1"),
            "noise_ratio": Field("noise_ratio", "ratio", "1"), "min_range": Field("min_range", "length", "1"),
            "max_range": Field("max_range", "length", "1"), "beam_half_width": Field("beam_half_width", "angle", "1"),
            "tilt_noise_gain": Field("tilt_noise_gain", "dimensionless", "1"),
            "wave_height": Field("wave_height", "length", "1")},
    outputs=(Output("h_agl_m", "m", role="height", truth="h_agl_m", label="height above surface"),),
    # beam_half_width off: a beam as wide as the horizon, no slant error
    errors=(ErrorTerm("noise"), ErrorTerm("noise_ratio"), ErrorTerm("tilt_noise_gain"), ErrorTerm("wave_height"),
            ErrorTerm("beam_half_width", math.pi / 2)),
    emulate=emulate_radar_altimeter, faults=("outage", "bias", "degraded")))
