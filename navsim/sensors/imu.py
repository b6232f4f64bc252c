"""Strapdown IMU emulator: gyro and accelerometer triads with the errors of :class:`ImuSpec`.

Outputs (``SensorData.values``), ``(B, M, 3)``, body axes:

* ``omega_ib_b_rps``: angular rate, sampled at the IMU times;
* ``f_b_mps2``: specific force, sampled at the IMU times;
* ``dtheta_b_rad``, ``dv_b_mps``: increments over the interval ending at each sample: the
  true increments of the recorded trajectory (:func:`truth_increments`) plus the errors times
  the interval.

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

from navsim import kernels
from navsim.errors import ScenarioError
from navsim.sensors.base import (SensorData, decimation, gauss_markov, normals, random_walk,
                                 run_generators)
from navsim.sensors.specs import AxisErrors, ImuSpec
from navsim.strapdown import cross, rotation

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


def _triad(gens, truth_x, incr_x, dt, e: AxisErrors, n: int, need_rate: bool = True):
    """Corrupt one triad; returns (rate or None, increment, bias(t), matrix). The random draws
    come in this order from each run's stream: scale factors, misalignments, random-constant
    bias, bias-instability and Markov processes, random walk, white noise; the white noise
    and the signal are one compiled pass per run (:func:`navsim.kernels.imu_triad`)."""
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
    noisy = bool(np.any(e.noise_density))
    scale = np.broadcast_to(np.asarray(e.noise_density, float) / math.sqrt(dt), (3,)).copy()
    identity = np.array_equal(matrix, np.broadcast_to(np.eye(3), matrix.shape))
    truth_x, incr_x = np.ascontiguousarray(truth_x, float), np.ascontiguousarray(incr_x, float)
    rate = np.empty((B, n if need_rate else 0, 3))
    incr = np.empty((B, n, 3))
    for b, g in enumerate(gens):
        kernels.imu_triad(g, noisy, scale, matrix[b], identity, truth_x, incr_x, bias[b], float(dt), rate[b], incr[b])
    return (rate if need_rate else None), incr, bias, matrix


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


def _compensated_to_measured(dv_c, dth, dth_prev, dv_c_prev):
    """Invert the strapdown's rotation and sculling compensation
    ``dv_c = dv + dth x dv / 2 + (dth_p x dv + dv_p x dth) / 12`` (to third order)."""
    return (dv_c - 0.5 * cross(dth, dv_c)
            - (cross(dth_prev, dv_c) + cross(dv_c_prev, dth)) / 12.0)


def truth_increments(truth, step: int = 1):
    """Ideal increments ``dtheta_b``, ``dv_b`` ``(n, 3)`` over the IMU intervals ending at each
    IMU sample, such that the strapdown mechanization (coning and sculling compensation)
    reproduces the recorded trajectory.

    JSBSim integrates the attitude and the inertial velocity with Adams-Bashforth 3
    (:data:`navsim.flight.properties.INTEGRATORS`): over ``[t_k, t_k+1]`` the body rotates by
    ``dt (23 w_k - 16 w_k-1 + 5 w_k-2) / 12`` and the inertial velocity changes by the same
    combination of ``C_ib f``. These are the true increments of the recorded trajectory; a
    trapezoid on the samples instead would lag the attitude by up to 1e-3 rad in turns. JSBSim's
    initial conditions fill the history with the first derivative (``w_-1 = w_-2 = w_0``): the
    first step is Euler's, the second already ``(23 w_1 - 11 w_0) / 12``; taking it as Euler's
    too left a start-up attitude error of up to 150" wherever the first rates differ (a trim
    in wind). The increment ending at ``t_s[0]`` is zero (``step`` > 1: ``w_0 dt``, ``f_0 dt``).
    """
    cache = truth.__dict__.setdefault("_increments", {})     # the truth is shared by every chunk
    if step not in cache:
        cache[step] = _truth_increments(truth, step)
    return cache[step]


def _truth_increments(truth, step: int):
    om, fb = truth.omega_ib_b_rps, truth.f_b_mps2
    dt = truth.dt_s
    N = len(om)
    # JSBSim's initial conditions fill the Adams-Bashforth history with the first derivative:
    # samples -1 and -2 are copies of sample 0 (so step 0 is Euler's, step 1 already AB3)
    ab3 = lambda x: (23 * x - 16 * np.concatenate([x[:1], x[:-1]])
                     + 5 * np.concatenate([x[:1], x[:1], x[:-2]])) / 12.0
    if truth.meta.get("integrator", "ab3") != "ab3":
        ab3 = lambda x: x                                   # rectangular: rate held over the step
    # per truth step j (interval ending t_j): rotation and compensated velocity increment
    dth = np.zeros((N, 3))
    dth[1:] = ab3(om)[:-1] * dt
    R = rotation(-dth)                                          # body(j-1) vectors -> body(j)
    dv_c = np.zeros((N, 3))
    f1 = np.einsum("nij,nj->ni", R[1:], fb[:-1])            # f_{k-1} in body k   (k = j-1)
    dv_c[1:] = fb[:-1] * dt
    if truth.meta.get("integrator", "ab3") == "ab3":
        k = np.arange(1, N - 1)                             # interval ending j = k + 1
        f_km1 = f1[k - 1]                                   # f_{k-1} in body k
        g = np.concatenate([fb[:1], f1])                    # g[m] = f_{m-1} in body m, g[0] = f_0
        f_km2 = np.einsum("nij,nj->ni", R[k], g[k - 1])     # f_{k-2} in body k
        dv_c[k + 1] = dt * (23 * fb[k] - 16 * f_km1 + 5 * f_km2) / 12.0
    if step > 1:                                            # compose sub-steps into IMU intervals
        n = (N - 1) // step + 1
        tot_th = np.zeros((n, 3))
        tot_v = np.zeros((n, 3))
        C = np.broadcast_to(np.eye(3), (n - 1, 3, 3)).copy()   # body(start) <- body(current)
        for m in range(1, step + 1):
            j = np.arange(n - 1) * step + m
            tot_v[1:] += np.einsum("nij,nj->ni", C, dv_c[j])
            tot_th[1:] += np.einsum("nij,nj->ni", C, dth[j]) + 0.5 * np.cross(tot_th[1:], np.einsum("nij,nj->ni", C, dth[j]))
            C = C @ rotation(dth[j])
        tot_th[0], tot_v[0] = om[0] * dt * step, fb[0] * dt * step
        dth, dv_c = tot_th, tot_v
    dth_prev = np.concatenate([dth[:1], dth[:-1]])
    dv_prev = np.concatenate([dv_c[:1], dv_c[:-1]])
    dth_meas = dth.copy()
    dv_meas = _compensated_to_measured(dv_c, dth, dth_prev, dv_prev)
    dth_meas[0], dv_meas[0] = dth[0], dv_c[0]
    return dth_meas, dv_meas


def emulate_imu(truth, spec: ImuSpec, seed: int, runs, name: str = "imu",
                keep_rates: bool = True) -> SensorData:
    """IMU data of ``runs`` (run indices) from ``truth``; see the module docstring."""
    runs = list(runs)
    step = decimation(truth.meta.get("rate_hz", 1.0 / truth.dt_s), spec.rate_hz, name)
    t = truth.t_s[::step]
    dt = step * truth.dt_s
    n = len(t)
    gens = run_generators(seed, runs, name)
    om, fb = truth.omega_ib_b_rps, truth.f_b_mps2
    inc_g, inc_a = truth_increments(truth, step)
    # the rates are needed for the output, saturation or quantization (not for the increments)
    need = keep_rates or any(math.isfinite(e.range) or e.quantization for e in (spec.gyro, spec.accel))
    rate_g, incr_g, bias_g, mat_g = _triad(gens, om[::step], inc_g, dt, spec.gyro, n, need)
    rate_a, incr_a, bias_a, mat_a = _triad(gens, fb[::step], inc_a, dt, spec.accel, n, need)
    for vib in spec.vibration:
        va = _vibration(gens, t, dt, vib, spec.rate_hz, "amplitude")
        vg = _vibration(gens, t, dt, vib, spec.rate_hz, "gyro_amplitude")
        incr_a = incr_a + va * dt
        incr_g = incr_g + vg * dt
        if need:
            rate_a = rate_a + va
            rate_g = rate_g + vg
    for rate, incr, e in ((rate_g, incr_g, spec.gyro), (rate_a, incr_a, spec.accel)):
        if not need:
            continue
        if math.isfinite(e.range):
            np.clip(rate, -e.range, e.range, out=rate)
        if e.quantization:
            np.round(rate / e.quantization, out=rate)
            rate *= e.quantization
            q = e.quantization * dt
            np.round(incr / q, out=incr)
            incr *= q
    B = len(runs)
    return SensorData(
        name=name, kind="imu", t_s=t,
        values={"omega_ib_b_rps": rate_g, "f_b_mps2": rate_a, "dtheta_b_rad": incr_g,
                "dv_b_mps": incr_a} if keep_rates else {"dtheta_b_rad": incr_g, "dv_b_mps": incr_a},
        valid=np.ones((B, n), bool),
        errors={"gyro_bias": bias_g, "accel_bias": bias_a, "gyro_matrix": mat_g,
                "accel_matrix": mat_a},
        meta={"rate_hz": spec.rate_hz, "dt_s": dt, "runs": runs, "seed": seed})


class OnlineIncrements:
    """The ideal increments of :func:`truth_increments`, computed sample by sample for a batch
    of ``B`` trajectories that are not known in advance (navigation in the loop: every run flies
    its own aircraft). :meth:`update` takes the sample ``j`` of each run, ``omega_ib_b`` and
    ``f_b`` ``(B, 3)``, and returns the increments over the interval ending at ``t_j`` (they
    depend on the samples up to ``j - 1``: JSBSim's Adams-Bashforth 3 step). Same formulas, same
    start-up as the whole-record version, to rounding (the IMU rate is the flight rate)."""

    def __init__(self, B: int, dt: float):
        self.dt, self.j = dt, 0
        self.om = self.f = None                    # samples j-1, j-2, j-3
        self.R = None                              # R[j-1], R[j-2]
        self.dth_prev = np.zeros((B, 3))
        self.dvc_prev = np.zeros((B, 3))

    def update(self, omega_ib_b: np.ndarray, f_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        j, dt = self.j, self.dt
        omega_ib_b, f_b = np.asarray(omega_ib_b, float), np.asarray(f_b, float)
        if j == 0:
            # the Adams-Bashforth history starts filled with the first sample (as JSBSim's)
            self.om, self.f = [omega_ib_b] * 3, [f_b] * 3
            eye = np.broadcast_to(np.eye(3), omega_ib_b.shape + (3,))
            self.R = [eye, eye]
            dth, dv_c = np.zeros_like(omega_ib_b), np.zeros_like(f_b)
            dth_m, dv_m = dth, dv_c
        else:
            om, f = self.om, self.f
            dth = (23 * om[0] - 16 * om[1] + 5 * om[2]) / 12.0 * dt
            if j == 1:
                dv_c = f[0] * dt
            else:
                R1, R2 = self.R
                f_km1 = np.einsum("bij,bj->bi", R1, f[1])
                f_km2 = np.einsum("bij,bj->bi", R1, np.einsum("bij,bj->bi", R2, f[2]) if j > 2 else f[2])
                dv_c = dt * (23 * f[0] - 16 * f_km1 + 5 * f_km2) / 12.0
            dth_m, dv_m = dth, _compensated_to_measured(dv_c, dth, self.dth_prev, self.dvc_prev)
        self.R = [rotation(-dth), self.R[0]]
        self.om = [omega_ib_b, self.om[0], self.om[1]]
        self.f = [f_b, self.f[0], self.f[1]]
        self.dth_prev, self.dvc_prev = dth, dv_c
        self.j += 1
        return dth_m, dv_m


def error_increments(spec: ImuSpec, seed: int, runs, n: int, dt: float, name: str = "imu") -> dict:
    """The errors of :func:`emulate_imu` that do not depend on the trajectory, for ``n``
    samples of ``runs``: ``gyro``/``accel`` ``(B, n, 3)``, the increments of bias, noise and
    vibration over each interval, and ``gyro_matrix``/``accel_matrix`` ``(B, 3, 3)``
    (``I + M``), so that the measured increment is ``matrix @ ideal + error`` (then quantized):
    the same numbers as :func:`emulate_imu` with the same ``n``. Range saturation is not
    applied (it needs the rate, which a closed loop does not keep)."""
    runs = list(runs)
    gens = run_generators(seed, runs, name)
    zero = np.zeros((n, 3))
    t = np.arange(n) * dt
    _, err_g, bias_g, mat_g = _triad(gens, zero, zero, dt, spec.gyro, n, False)
    _, err_a, bias_a, mat_a = _triad(gens, zero, zero, dt, spec.accel, n, False)
    for vib in spec.vibration:
        err_a = err_a + _vibration(gens, t, dt, vib, spec.rate_hz, "amplitude") * dt
        err_g = err_g + _vibration(gens, t, dt, vib, spec.rate_hz, "gyro_amplitude") * dt
    B = len(runs)
    return {"gyro": np.broadcast_to(err_g, (B, n, 3)), "accel": np.broadcast_to(err_a, (B, n, 3)),
            "gyro_matrix": mat_g, "accel_matrix": mat_a, "gyro_bias": bias_g, "accel_bias": bias_a}


def quantize_increment(incr: np.ndarray, e: AxisErrors, dt: float) -> np.ndarray:
    """Increments rounded to the triad's ``quantization`` (rate LSB times the interval)."""
    if not e.quantization:
        return incr
    q = e.quantization * dt
    return np.round(incr / q) * q
