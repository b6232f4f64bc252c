"""Radar altimeter emulator (P2): height above the sea surface or terrain.

``values['h_agl_m']`` ``(B, M)``; no output (``valid`` False) outside ``[min_range, max_range]``.
Error model: white noise of std ``(noise + noise_ratio H) (1 + tilt_noise_gain * tilt)``, where
``tilt = acos(cos(roll) cos(pitch))`` is the beam's tilt from the vertical; beyond the beam's half
width the first return comes from a slant range, ``H / cos(tilt - half_width)``; a sea state adds
wave elevation of std ``wave_height / 4`` (significant wave height = 4 sigma). Fault windows
``bias`` add exactly their value. ``errors['h_error_m']`` is the total error.
"""

from __future__ import annotations

import numpy as np

from navsim.sensors.base import SensorData, apply_outages, normals, sampling
from navsim.sensors.specs import RadarAltimeterSpec


def emulate_radar_altimeter(truth, spec: RadarAltimeterSpec, seed: int, runs, faults=(),
                            name: str = "radar_altimeter") -> SensorData:
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M, gens = smp.runs, smp.B, smp.step, smp.t, smp.M, smp.gens
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
        err += normals(gens, (M,)) * (sigma * factor)
    if spec.wave_height:
        err += normals(gens, (M,)) * (spec.wave_height / 4.0)
    h = H[None] + err
    valid = (h >= spec.min_range) & (h <= spec.max_range)
    apply_outages(valid, t, faults)
    return SensorData(name=name, kind="radar_altimeter", t_s=t, values={"h_agl_m": h}, valid=valid,
                      errors={"h_error_m": err, "sigma_m": sigma},
                      meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed})
