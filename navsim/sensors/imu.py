"""Strapdown IMU emulator: gyro and accelerometer triads with the errors of :class:`ImuSpec`.

Outputs (``SensorData.values``), ``(B, M, 3)``, body axes:

* ``omega_ib_b_rps``: angular rate, sampled at the IMU times;
* ``f_b_mps2``: specific force, sampled at the IMU times;
* ``dtheta_b_rad``, ``dv_b_mps``: increments over the interval ending at each sample (the
  truth integrated by the trapezoid rule at the truth rate, plus the errors times the interval;
  the first increment covers one interval before ``t_s[0]`` by extrapolation).

The measurement model, per triad: ``y = (I + M) x + b(t) + n + v``, where ``M`` holds scale-factor
errors on the diagonal and misalignments off it, ``b`` is the sum of the fixed bias, the random
constant, the bias-instability and Markov Gauss-Markov processes and the random walk, ``n`` white
noise of density ``noise_density`` (std ``density / sqrt(dt)``), ``v`` vibration; then
saturation at ``range`` and quantization to ``quantization``. ``errors`` holds ``gyro_bias``,
``accel_bias`` (``b(t)``), ``gyro_matrix``, ``accel_matrix`` (``I + M``, ``(B, 3, 3)``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, sosfilt

from navsim.errors import ScenarioError
from navsim.sensors.base import (SensorData, decimation, gauss_markov, normals, random_walk,
                                 run_generators)
from navsim.sensors.specs import AxisErrors, ImuSpec

#: Allan-deviation peak of a first-order Gauss-Markov process, in units of its std
#: (max over T of sigma_A(T) / sigma); bias instability B is modelled by a Gauss-Markov process
#: whose Allan peak equals the flicker floor 0.664 B.
GM_ALLAN_PEAK = 0.61736
FLICKER_FLOOR = 0.6643


def gm_allan_peak() -> float:
    """max_T sigma_A(T)/sigma of a first-order Gauss-Markov process (numerically)."""
    x = np.logspace(-2, 3, 20001)        # T / tau
    avar = 2.0 / x * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    return float(np.sqrt(avar.max()))


def _triad(gens, truth_x, incr_x, dt, e: AxisErrors, n: int):
    """Corrupt one triad; returns (rate, increment, bias(t), matrix)."""
    B = len(gens)
    matrix = np.broadcast_to(np.eye(3), (B, 3, 3)).copy()
    if np.any(e.scale_factor) or np.any(e.scale_factor_sigma):
        sf = e.scale_factor + normals(gens, (3,)) * e.scale_factor_sigma
        matrix[:, [0, 1, 2], [0, 1, 2]] += sf
    if e.misalignment_sigma:
        mis = normals(gens, (3, 3)) * e.misalignment_sigma
        mis[:, [0, 1, 2], [0, 1, 2]] = 0.0
        matrix += mis
    bias = np.broadcast_to(e.bias, (B, 1, 3)).copy()
    if np.any(e.bias_sigma):
        bias = bias + (normals(gens, (3,)) * e.bias_sigma)[:, None, :]
    if np.any(e.bias_instability):
        sigma = e.bias_instability * FLICKER_FLOOR / GM_ALLAN_PEAK
        bias = bias + gauss_markov(gens, n, dt, sigma, e.bias_instability_tau_s)
    if np.any(e.markov_sigma):
        bias = bias + gauss_markov(gens, n, dt, e.markov_sigma, e.markov_tau_s)
    if np.any(e.random_walk):
        bias = bias + random_walk(gens, n, dt, e.random_walk)
    # white noise drawn straight into the output, then the signal added in place:
    # rate = (I + M) x + b + n;  incr = rate dt + (I + M) (incr_x - x dt)
    rate = np.empty((B, n, 3))
    if np.any(e.noise_density):
        for g, r in zip(gens, rate):
            g.standard_normal(out=r)
        rate *= e.noise_density / math.sqrt(dt)
    else:
        rate[...] = 0.0
    identity = np.array_equal(matrix, np.broadcast_to(np.eye(3), matrix.shape))
    if identity:
        rate += truth_x
        corr = incr_x - truth_x * dt
    else:
        rate += np.einsum("bij,nj->bni", matrix, truth_x)
        corr = np.einsum("bij,nj->bni", matrix, incr_x - truth_x * dt)
    rate += bias
    incr = np.multiply(rate, dt)
    incr += corr
    return rate, incr, bias, matrix


def _vibration(gens, t, dt, vib, rate_hz, amp_attr):
    amp = getattr(vib, amp_attr)
    if not np.any(amp):
        return 0.0
    if vib.type == "sine":
        if vib.frequency_hz >= 0.5 * rate_hz:
            raise ScenarioError(f"vibration at {vib.frequency_hz:g} Hz is above the IMU's Nyquist "
                                f"frequency ({0.5 * rate_hz:g} Hz)", key="sensors.imu.vibration")
        phase = np.stack([g.uniform(0.0, 2 * np.pi, 3) for g in gens])
        return amp * np.sin(2 * np.pi * vib.frequency_hz * t[None, :, None] + phase[:, None, :])
    lo, hi = vib.band_hz
    if hi >= 0.5 * rate_hz:
        raise ScenarioError(f"vibration band {lo:g}-{hi:g} Hz reaches the IMU's Nyquist frequency "
                            f"({0.5 * rate_hz:g} Hz)", key="sensors.imu.vibration")
    sos = butter(4, [lo, hi], btype="bandpass", fs=rate_hz, output="sos")
    w = normals(gens, (len(t) + 200, 3))
    x = sosfilt(sos, w, axis=1)[:, 200:, :]
    # scale to peak = 3 sigma, using the filter's exact noise gain
    x /= x.std(axis=1, keepdims=True)
    return x * (amp / 3.0)


def emulate_imu(truth, spec: ImuSpec, seed: int, runs, name: str = "imu") -> SensorData:
    """IMU data of ``runs`` (run indices) from ``truth``; see the module docstring."""
    runs = list(runs)
    step = decimation(truth.meta.get("rate_hz", 1.0 / truth.dt_s), spec.rate_hz, name)
    t = truth.t_s[::step]
    dt = step * truth.dt_s
    n = len(t)
    gens = run_generators(seed, runs, name)
    om, fb = truth.omega_ib_b_rps, truth.f_b_mps2
    # increments over each IMU interval (trapezoid on the truth grid)
    dt_truth = truth.dt_s

    def increments(x):
        c = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (x[1:] + x[:-1]) * dt_truth, axis=0)])
        ci = c[::step]
        out = np.empty((n, 3))
        out[1:] = ci[1:] - ci[:-1]
        out[0] = x[0] * dt
        return out

    rate_g, incr_g, bias_g, mat_g = _triad(gens, om[::step], increments(om), dt, spec.gyro, n)
    rate_a, incr_a, bias_a, mat_a = _triad(gens, fb[::step], increments(fb), dt, spec.accel, n)
    for vib in spec.vibration:
        va = _vibration(gens, t, dt, vib, spec.rate_hz, "amplitude")
        vg = _vibration(gens, t, dt, vib, spec.rate_hz, "gyro_amplitude")
        rate_a = rate_a + va
        incr_a = incr_a + va * dt
        rate_g = rate_g + vg
        incr_g = incr_g + vg * dt
    for rate, incr, e in ((rate_g, incr_g, spec.gyro), (rate_a, incr_a, spec.accel)):
        if math.isfinite(e.range):
            np.clip(rate, -e.range, e.range, out=rate)
        if e.quantization:
            np.round(rate / e.quantization, out=rate)
            rate *= e.quantization
            q = e.quantization * dt
            np.round(incr / q, out=incr)
            incr *= q
    B = len(runs)
    if rate_g.shape[0] != B:
        rate_g, incr_g = np.broadcast_to(rate_g, (B, n, 3)).copy(), np.broadcast_to(incr_g, (B, n, 3)).copy()
    if rate_a.shape[0] != B:
        rate_a, incr_a = np.broadcast_to(rate_a, (B, n, 3)).copy(), np.broadcast_to(incr_a, (B, n, 3)).copy()
    return SensorData(
        name=name, kind="imu", t_s=t,
        values={"omega_ib_b_rps": rate_g, "f_b_mps2": rate_a, "dtheta_b_rad": incr_g,
                "dv_b_mps": incr_a},
        valid=np.ones((B, n), bool),
        errors={"gyro_bias": bias_g, "accel_bias": bias_a, "gyro_matrix": mat_g,
                "accel_matrix": mat_a},
        meta={"rate_hz": spec.rate_hz, "dt_s": dt, "runs": runs, "seed": seed})
