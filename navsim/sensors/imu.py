"""Strapdown IMU emulator: gyro and accelerometer triads with the errors of :class:`ImuSpec`.
(Kept whole, over 600 lines: one concept, the IMU's error model, drawn whole, block by block or
sample by sample in a closed loop, and its linear forms; they share the triads' state and
helpers and must give the same numbers bit for bit; the vibration is
:mod:`navsim.sensors.vibration`.)

Outputs (``SensorData.values``), ``(B, M, 3)``, body axes:

* ``omega_ib_b_rps``: angular rate, sampled at the IMU times;
* ``f_b_mps2``: specific force, sampled at the IMU times;
* ``dtheta_b_rad``, ``dv_b_mps``: increments over the interval ending at each sample: the
  true increments of the recorded trajectory (:func:`truth_increments`) plus the errors times
  the interval.

The measurement model, per triad: ``y = (I + M) x + b(t) + n + v``, where ``M`` holds scale-factor
errors on the diagonal and misalignments off it, ``b`` is the sum of the fixed bias, the random
constant, the bias-instability and Markov Gauss-Markov processes and the random walk, ``n`` white
noise of density ``noise_density`` (std ``density / sqrt(dt)``, less the quantization's share:
:func:`white_noise_std`), ``v`` vibration; then saturation at ``range`` and quantization to
``quantization``. ``errors`` holds ``gyro_bias``,
``accel_bias`` (``b(t)``), ``gyro_matrix``, ``accel_matrix`` (``I + M``, ``(B, 3, 3)``).

:class:`ImuStream` generates the same numbers block by block (a Monte Carlo chunk asks for the
samples up to each filter epoch), so that no ``(B, n, 3)`` array is held: each error process
of each run draws from a random stream of its own (``"gyro.noise"``, ``"accel.markov"``, ...:
:func:`navsim.sensors.base.run_generators`) only the normals it uses, a block where it is
used, and carries its state from block to block
(:func:`navsim.sensors.kernels.bias_block`, :func:`navsim.sensors.kernels.imu_triad`). :func:`emulate_imu` is
the stream in one block, plus the vibration (band-limited vibration is normalised over the
whole record, so an IMU with vibration is emulated whole).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba.typed import List

from navsim.foundations.transform import cross, rotation
from navsim.sensors import kernels
from navsim.sensors.base import SensorData, decimation, normals, run_generators, zeros3
from navsim.sensors.registry import ErrorTerm, Field, Group, LinearError, Output, SensorKind, register
from navsim.sensors.vibration import RotorMotion, Tone, Vibration, band_vibration, rotor_vibration


@dataclass(frozen=True)
class AxisErrors:
    """Errors of a triad (gyros or accelerometers). Units: rad/s (gyro) or m/s^2 (accel)."""

    bias: np.ndarray = zeros3()               #: fixed constant bias
    bias_sigma: np.ndarray = zeros3()         #: random constant, drawn per run and axis
    bias_instability: np.ndarray = zeros3()   #: Allan-deviation floor B (flicker convention)
    bias_instability_tau_s: float = 100.0     #: correlation time of its Gauss-Markov model
    markov_sigma: np.ndarray = zeros3()       #: first-order Gauss-Markov bias, std
    markov_tau_s: float = 3600.0              #: its correlation time
    noise_density: np.ndarray = zeros3()      #: white noise: ARW rad/s/rtHz, VRW m/s^2/rtHz
    random_walk: np.ndarray = zeros3()        #: rate / acceleration random walk, per rt(s)
    scale_factor: np.ndarray = zeros3()       #: fixed scale-factor error (ratio)
    scale_factor_sigma: np.ndarray = zeros3() #: random scale-factor error per run (ratio)
    misalignment_sigma: float = 0.0           #: random axis misalignment per run, rad
    quantization: float = 0.0                 #: LSB of the output, 0: none
    range: float = math.inf                   #: saturation, +/-


@dataclass(frozen=True)
class ImuSpec:
    """Strapdown IMU: the gyro and accelerometer triads' errors and the vibration."""

    rate_hz: float = 100.0
    gyro: AxisErrors = field(default_factory=AxisErrors)
    accel: AxisErrors = field(default_factory=AxisErrors)
    vibration: tuple[Vibration, ...] = ()

#: Allan-deviation peak of a first-order Gauss-Markov process, in units of its std
#: (max over T of sigma_A(T) / sigma); bias instability B is modelled by a Gauss-Markov process
#: whose Allan peak equals the flicker floor 0.664 B.
GM_ALLAN_PEAK = 0.61736
FLICKER_FLOOR = 0.6643


def gm_allan_variance(x: np.ndarray) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov process of unit std at averaging times
    ``x = T / tau``: ``2/x (1 - (3 - 4 e^-x + e^-2x) / (2x))``."""
    x = np.asarray(x, float)
    return 2.0 / x * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


def gauss_markov_biases(e: AxisErrors) -> tuple:
    """The triad's Gauss-Markov bias processes ``((sigma (3,), tau_s), ...)``: the bias
    instability (its std set so that its Allan peak is the flicker floor ``0.664 B``), then the
    Markov bias."""
    return ((np.asarray(e.bias_instability, float) * FLICKER_FLOOR / GM_ALLAN_PEAK, e.bias_instability_tau_s),
            (np.asarray(e.markov_sigma, float), e.markov_tau_s))


def gm_allan_peak() -> float:
    """max_T sigma_A(T)/sigma of a first-order Gauss-Markov process (numerically)."""
    return float(np.sqrt(gm_allan_variance(np.logspace(-2, 3, 20001)).max()))


def allan_variance(e: AxisErrors, tau_s: np.ndarray) -> np.ndarray:
    """The Allan variance ``(3, K)`` that a triad's datasheet predicts at averaging times
    ``tau_s`` (white noise ``N^2 / tau``, the bias instability's and the Markov bias's
    Gauss-Markov processes as emulated, the random walk ``K^2 tau / 3``; constants have
    none): what the emulator's output at rest must show."""
    tau = np.asarray(tau_s, float)
    col = lambda v: np.broadcast_to(np.asarray(v, float), (3,))[:, None]
    avar = col(e.noise_density) ** 2 / tau + col(e.random_walk) ** 2 * tau / 3.0
    for sigma, tau_c in gauss_markov_biases(e):
        avar = avar + col(sigma) ** 2 * gm_allan_variance(tau / tau_c)
    return avar


def _constants(rng, B: int, e: AxisErrors):
    """The triad's constant errors, each drawn from its own stream (``rng(process)``, the runs'
    generators): scale factors, misalignments, random-constant bias. Returns ``I + M``
    ``(B, 3, 3)`` and the constant bias ``(B, 1, 3)``."""
    matrix = np.broadcast_to(np.eye(3), (B, 3, 3)).copy()
    if np.any(e.scale_factor) or np.any(e.scale_factor_sigma):
        sf = e.scale_factor + normals(rng("scale_factor"), (3,)) * e.scale_factor_sigma
        matrix[:, [0, 1, 2], [0, 1, 2]] += sf
    if e.misalignment_sigma:
        mis = normals(rng("misalignment"), (3, 3)) * e.misalignment_sigma
        mis[:, [0, 1, 2], [0, 1, 2]] = 0.0
        matrix += mis
    bias = np.broadcast_to(e.bias, (B, 1, 3)).copy()
    if np.any(e.bias_sigma):
        bias = bias + (normals(rng("bias"), (3,)) * e.bias_sigma)[:, None, :]
    return matrix, bias


#: the names of a triad's time-varying error processes (their random streams), in
#: :func:`_processes`' order
PROCESS_NAMES = ("bias_instability", "markov", "random_walk", "noise")


def _processes(e: AxisErrors, dt: float) -> list:
    """The triad's time-varying errors, each ``(name, kind, first_scale, step_scale, a)`` for
    :func:`navsim.sensors.kernels.bias_block` (kind 0 Gauss-Markov, 1 random walk, 2 white
    noise; ``name`` of :data:`PROCESS_NAMES`, its random stream): bias instability (a
    Gauss-Markov process whose Allan peak is the flicker floor), Markov bias, random walk,
    white noise."""
    out = []
    for name, (sigma, tau) in zip(PROCESS_NAMES, gauss_markov_biases(e)):
        if np.any(sigma):
            a = math.exp(-dt / tau)
            out.append((name, 0, _three(sigma), _three(sigma * math.sqrt(1.0 - a * a)), a))
    if np.any(e.random_walk):
        out.append(("random_walk", 1, np.zeros(3), _three(np.asarray(e.random_walk, float) * math.sqrt(dt)), 1.0))
    white = white_noise_std(e, dt)
    if np.any(white):
        out.append(("noise", 2, np.zeros(3), _three(white), 0.0))
    return out


def white_noise_std(e: AxisErrors, dt: float) -> np.ndarray:
    """The std of the white noise drawn per sample ``(3,)``: the datasheet's noise density over
    ``sqrt(dt)`` less the quantization's own share. A datasheet measures the noise density on
    the quantized output, so rounding to the LSB ``q`` (uniform, variance ``q^2 / 12`` per
    sample, white once the noise spans a few LSBs) is already in it; drawing the full density
    and then rounding would count it twice (the MPU6050's gyro: 1.12 times its density). An LSB
    coarser than the datasheet noise leaves no white noise to draw."""
    var = np.asarray(e.noise_density, float) ** 2 / dt - e.quantization ** 2 / 12.0
    return np.where(np.asarray(e.noise_density, float) > 0, np.sqrt(np.maximum(var, 0.0)), 0.0)


def _three(x) -> np.ndarray:
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, float), (3,)))


def typed_generators(gens) -> List:
    """The runs' generators as a :class:`numba.typed.List` (the same objects: drawing from it
    moves them on), for the kernels that draw from every run in one call."""
    out = List()
    for g in gens:
        out.append(g)
    return out


class _Normals:
    """One error process's standard normals ``(B, ., 3)``, drawn from each run's generator a
    block of ``size`` samples at a time, in sample order (so the numbers do not depend on how
    the record is cut into blocks), never beyond sample ``n``."""

    def __init__(self, gens, n: int, size: int):
        self.gens, self.n, self.size = typed_generators(gens), n, size
        self.buf = np.empty((len(gens), 0, 3))
        self.start = self.end = 0                 # buf rows hold the samples [start, end)

    def take(self, i0: int, i1: int) -> tuple[np.ndarray, int]:
        """The buffer holding samples ``[i0, i1)`` and the row of ``i0`` in it; requests go
        forward (``i0`` at or after the last request's)."""
        if i1 > self.end:
            lo = max(min(i0, self.end), self.start)
            keep = self.buf[:, lo - self.start:self.end - self.start].copy()
            size = min(max(self.size, i1 - lo), self.n - lo)
            if self.buf.shape[1] < size:
                self.buf = np.empty((len(self.gens), size, 3))
            k = keep.shape[1]
            self.buf[:, :k] = keep
            kernels.draw_normals(self.gens, self.buf, k, size)
            self.start, self.end = lo, lo + size
        return self.buf, i0 - self.start


class SampledMotion(NamedTuple):
    """The true motion at an IMU's samples, what its errors are added to (:class:`ImuStream`):
    the body rate (rad/s) and its increments (rad), the specific force (m/s^2) and its
    increments (m/s), ``(n, 3)`` each, at the times ``t_s`` ``(n,)``, every ``dt_s`` seconds."""

    omega: np.ndarray
    incr_g: np.ndarray
    f: np.ndarray
    incr_a: np.ndarray
    t_s: np.ndarray
    dt_s: float
    #: each rotor's speed (r/min) and the angle it has turned (rad, from 0 at the start),
    #: ``(n, R)``: what a rotor vibration is made of (R = 0, or None: no rotors)
    rotor_rpm: np.ndarray | None = None
    rotor_angle_rad: np.ndarray | None = None

    @classmethod
    def of_truth(cls, truth, rate_hz: float, name: str = "imu") -> "SampledMotion":
        """``truth`` sampled at ``rate_hz`` (dividing its rate; ``name``: the sensor's, for the
        error); the rotors' angles integrated at the truth's rate (trapezoids)."""
        step = decimation(truth.meta.get("rate_hz", 1.0 / truth.dt_s), rate_hz, name)
        inc_g, inc_a = truth_increments(truth, step)
        rpm = truth.rotor_rpm
        angle = np.zeros_like(rpm)
        np.cumsum(0.5 * (rpm[1:] + rpm[:-1]) * (truth.dt_s * 2.0 * np.pi / 60.0), axis=0, out=angle[1:])
        return cls(truth.omega_ib_b_rps[::step], inc_g, truth.f_b_mps2[::step], inc_a, truth.t_s[::step],
                   step * truth.dt_s, rpm[::step], angle[::step])

    @classmethod
    def still(cls, n: int, dt_s: float) -> "SampledMotion":
        """No motion over ``n`` samples of ``dt_s`` (an IMU's errors alone)."""
        zero = np.zeros((n, 3))
        return cls(zero, zero, zero, zero, np.arange(n) * dt_s, dt_s)


class _Triad:
    """One triad's errors for ``B`` runs, generated block by block (:class:`ImuStream`): added to
    the true rate ``truth_x`` and increments ``incr_x`` ``(n, 3)`` every ``dt`` seconds."""

    def __init__(self, rng, B: int, e: AxisErrors, block: int, truth_x, incr_x, dt: float):
        self.dt, self.n = dt, len(truth_x)
        self.matrix, self.bias0 = _constants(rng, B, e)
        self.identity = np.array_equal(self.matrix, np.broadcast_to(np.eye(3), self.matrix.shape))
        self.truth_x = np.ascontiguousarray(truth_x, float)
        self.incr_x = np.ascontiguousarray(incr_x, float)
        self.procs = _processes(e, dt)
        self.varying = any(kind < 2 for _, kind, *_ in self.procs)     #: a bias that changes
        self.streams = [_Normals(rng(name), self.n, block) for name, *_ in self.procs]     #: one per process
        self.state = np.zeros((B, len(self.procs), 4))
        self.block_size = block
        self.next = 0                    #: the first sample not generated yet
        self.record = False              #: keep the bias at each block's last sample
        self.bias_at: dict = {}          #: sample -> bias (B, 3) there

    def block(self, i0: int, i1: int, need_rate: bool):
        """``(rate or None, increments, bias)`` of samples ``[i0, i1)`` (requests go forward);
        the bias is ``(B, 1, 3)`` when constant."""
        if not 0 <= i0 <= i1 <= self.n or i0 < self.next:
            raise ValueError(f"samples {i0}-{i1} of {self.n}: requests go forward from sample {self.next}")
        if i0 > self.next:               # the processes' recursions start at sample 0
            self.block(self.next, i0, False)
        self.next = i1
        B, K = self.bias0.shape[0], i1 - i0
        bias = np.repeat(self.bias0, K, axis=1) if self.varying else self.bias0
        white = np.empty((B, 0, 3))
        scale = np.zeros(3)
        for p, ((_, kind, first, step, a), stream) in enumerate(zip(self.procs, self.streams)):
            w, j0 = stream.take(i0, i1)
            if kind == 2:
                white, scale = w[:, j0:j0 + K], step
            else:
                kernels.bias_block(w, j0, first, step, a, kind, self.state[:, p], bias)
        rate = np.empty((B, K if need_rate else 0, 3))
        incr = np.empty((B, K, 3))
        kernels.imu_triad(white, scale, self.matrix, self.identity, self.truth_x[i0:i1], self.incr_x[i0:i1],
                          np.ascontiguousarray(bias), float(self.dt), rate, incr)
        if self.record:
            self.bias_at[i1 - 1] = bias[:, -1].copy()
        return (rate if need_rate else None), incr, bias


class ImuStream:
    """The IMU of :func:`emulate_imu` (but its vibration) generated block by block: the same
    numbers bit for bit, drawn from the same per-run streams, but no ``(B, n, 3)`` arrays
    are held; :meth:`block` gives the increments of the samples ``[i0, i1)``, requests going
    forward. The constants are drawn at construction; each time-varying error process reads
    its own stream (:meth:`streams`).

    Parameters
    ----------
    truth : Truth or SampledMotion
        The flight, or the true motion at the IMU's samples (:meth:`SampledMotion.still`: the
        errors alone).
    spec : ImuSpec
        Its vibration is not emulated here (band-limited vibration is normalised over the whole
        record): :func:`emulate_imu` adds it to the whole record, each vibration from streams of
        its own (``"vibration0.accel"``, ...).
    seed : int
    runs : iterable of int
    name : str
        The sensor's name (its random streams).
    block : int
        Samples of normals drawn per process and run at a time (memory ``B x block x 24`` bytes
        per process: 3 MB for 250 runs; larger blocks cost memory and were not faster:
        docs/performance.md).

    A stream cannot be pickled or copied (its generators sit in a :class:`numba.typed.List`):
    build it where it is used, as a chunk does.
    """

    def __init__(self, truth, spec: ImuSpec, seed: int, runs, name: str = "imu", block: int = 500):
        self.runs = list(runs)
        self.spec, self.name, self.seed = spec, name, seed
        motion = truth if isinstance(truth, SampledMotion) else SampledMotion.of_truth(truth, spec.rate_hz, name)
        self.t_s, dt_s = motion.t_s, motion.dt_s
        self.dt_s, self.n = dt_s, len(motion.t_s)
        self.rotor_rpm, self.rotor_angle_rad = motion.rotor_rpm, motion.rotor_angle_rad
        self.meta = {"rate_hz": spec.rate_hz, "dt_s": dt_s, "runs": self.runs, "seed": seed}
        B = len(self.runs)
        self.gyro = _Triad(self.streams("gyro"), B, spec.gyro, block, motion.omega, motion.incr_g, dt_s)
        self.accel = _Triad(self.streams("accel"), B, spec.accel, block, motion.f, motion.incr_a, dt_s)
        self.need_rate = any(math.isfinite(e.range) or e.quantization for e in (spec.gyro, spec.accel))

    def streams(self, group: str):
        """``process -> the runs' generators`` of the error processes of ``group`` (``gyro``,
        ``accel``, ``vibration0``, ...): each its own stream, ``"{group}.{process}"``
        (:func:`~navsim.sensors.base.run_generators`)."""
        return lambda process: run_generators(self.seed, self.runs, self.name, f"{group}.{process}")

    def block(self, i0: int, i1: int, keep_rates: bool = False):
        """``(dtheta_b_rad, dv_b_mps)`` ``(B, i1 - i0, 3)`` of the samples ``[i0, i1)``, and the
        rates ``(omega_ib_b_rps, f_b_mps2)`` when ``keep_rates`` (else None)."""
        need = keep_rates or self.need_rate
        rate_g, incr_g, bias_g = self.gyro.block(i0, i1, need)
        rate_a, incr_a, bias_a = self.accel.block(i0, i1, need)
        for rate, incr, e in ((rate_g, incr_g, self.spec.gyro), (rate_a, incr_a, self.spec.accel)):
            _saturate_quantize(rate, incr, e, self.dt_s)
        return (incr_g, incr_a), ((rate_g, rate_a) if keep_rates else None)

    def record_bias(self) -> None:
        """Keep the true biases at the last sample of each block from now on (:meth:`bias`)."""
        self.gyro.record = self.accel.record = True

    def bias(self, samples) -> dict:
        """``gyro_bias``, ``accel_bias`` ``(B, len(samples), 3)`` at samples that ended a block
        since :meth:`record_bias` (or sample 0, which the first block after it passes), and
        ``gyro_bias_seen``, ``accel_bias_seen``: the whole error of the sample less its noise,
        ``b + (S + M) x`` with the scale factors and misalignments ``S + M`` times the true rate
        or specific force ``x``: what a bias state of a filter without those states sees."""
        out = {}
        idx = np.asarray(samples, int)
        for key, t in (("gyro_bias", self.gyro), ("accel_bias", self.accel)):
            out[key] = np.stack([t.bias_at[int(k)] for k in idx], axis=1)
            out[f"{key}_seen"] = seen_bias(out[key], t.matrix, t.truth_x[idx])
        return out


def seen_bias(bias: np.ndarray, matrix: np.ndarray, x: np.ndarray) -> np.ndarray:
    """What a bias state sees ``(B, E, 3)``: the bias plus the scale factors and misalignments
    ``matrix - I`` ``(B, 3, 3)`` times the true rate or specific force ``x`` ``(E, 3)``."""
    return bias + np.einsum("bij,ej->bei", matrix - np.eye(3), x)


def _saturate_quantize(rate, incr, e: AxisErrors, dt: float) -> None:
    """Rates saturated at the triad's ``range``, rates and increments rounded to its
    ``quantization`` (rate LSB, times ``dt`` for the increments), in place."""
    if math.isfinite(e.range):
        np.clip(rate, -e.range, e.range, out=rate)
    if e.quantization:
        np.round(rate / e.quantization, out=rate)
        rate *= e.quantization
        q = e.quantization * dt
        np.round(incr / q, out=incr)
        incr *= q


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
    """IMU data of ``runs`` (run indices) from ``truth``; see the module docstring. The whole
    record at once: an :class:`ImuStream` of one block, then the vibration."""
    stream = ImuStream(truth, spec, seed, runs, name, block=1)
    return _whole(stream, spec, keep_rates)


def _whole(stream: "ImuStream", spec: ImuSpec, keep_rates: bool) -> SensorData:
    """The whole record of ``stream`` with its vibration, as SensorData."""
    n, dt, t = stream.n, stream.dt_s, stream.t_s
    need = keep_rates or stream.need_rate
    rate_g, incr_g, bias_g = stream.gyro.block(0, n, need)
    rate_a, incr_a, bias_a = stream.accel.block(0, n, need)
    vib = _vibrations(stream, spec)
    for va, vg in vib:
        incr_a = incr_a + va * dt
        incr_g = incr_g + vg * dt
        if need:
            rate_a = rate_a + va
            rate_g = rate_g + vg
    for rate, incr, e in ((rate_g, incr_g, spec.gyro), (rate_a, incr_a, spec.accel)):
        _saturate_quantize(rate, incr, e, dt)
    B = len(stream.runs)
    return SensorData(
        name=stream.name, kind="imu", t_s=t,
        values={"omega_ib_b_rps": rate_g, "f_b_mps2": rate_a, "dtheta_b_rad": incr_g,
                "dv_b_mps": incr_a} if keep_rates else {"dtheta_b_rad": incr_g, "dv_b_mps": incr_a},
        valid=np.ones((B, n), bool),
        errors={"gyro_bias": bias_g, "accel_bias": bias_a, "gyro_matrix": stream.gyro.matrix,
                "accel_matrix": stream.accel.matrix},
        meta=dict(stream.meta))


class OnlineIncrements:
    """The ideal increments of :func:`truth_increments`, computed sample by sample for a batch
    of ``B`` trajectories that are not known in advance (navigation in the loop: every run flies
    its own aircraft). :meth:`update` takes the sample ``j`` of each run, ``omega_ib_b`` and
    ``f_b`` ``(B, 3)``, and returns the increments over the interval ending at ``t_j`` (they
    depend on the samples up to ``j - 1``: JSBSim's Adams-Bashforth 3 step). Same formulas, same
    start-up as the whole-record version, to rounding (the IMU rate is the flight rate)."""

    def __init__(self, B: int, dt: float):
        self.dt, self.j = dt, 0
        self.om, self.f = np.zeros((B, 4, 3)), np.zeros((B, 4, 3))   # samples j, j-1, j-2, j-3
        self.R = np.zeros((B, 2, 3, 3))                              # R[j-1], R[j-2]
        self.prev = np.zeros((B, 2, 3))                              # the last dtheta, compensated dv
        #: the increments of the last update: ``[:, 0]`` dtheta, ``[:, 1]`` dv ``(B, 3)`` each
        self.out = np.zeros((B, 2, 3))

    def update(self, omega_ib_b: np.ndarray, f_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The increments ``dtheta_b``, ``dv_b`` ``(B, 3)`` over the interval ending at this
        sample (compiled, run by run: :func:`navsim.sensors.kernels.online_increments`)."""
        self.om[:, 0], self.f[:, 0] = omega_ib_b, f_b
        kernels.online_increments(self.om, self.f, self.R, self.prev, self.j, self.dt, self.out)
        self.j += 1
        return self.out[:, 0].copy(), self.out[:, 1].copy()


def error_increments(spec: ImuSpec, seed: int, runs, n: int, dt: float, name: str = "imu") -> dict:
    """The errors of :func:`emulate_imu` that do not depend on the trajectory, for ``n``
    samples of ``runs``: ``gyro``/``accel`` ``(B, n, 3)``, the increments of bias, noise and
    vibration over each interval, and ``gyro_matrix``/``accel_matrix`` ``(B, 3, 3)``
    (``I + M``), so that the measured increment is ``matrix @ ideal + error`` (then quantized):
    the same numbers as :func:`emulate_imu` with the same ``n``. Range saturation is not
    applied (it needs the rate, which a closed loop does not keep)."""
    # (a rotor vibration, whose rotors a closed loop does not know in advance, is refused when the
    # scenario is read: navsim.experiment.closed_loop; here it would be zero, as on a still vehicle)
    stream = ImuStream(SampledMotion.still(n, dt), spec, seed, runs, name, block=1)
    _, err_g, bias_g = stream.gyro.block(0, n, False)
    _, err_a, bias_a = stream.accel.block(0, n, False)
    for va, vg in _vibrations(stream, spec):
        err_a = err_a + va * dt
        err_g = err_g + vg * dt
    return {"gyro": err_g, "accel": err_a, "gyro_matrix": stream.gyro.matrix, "accel_matrix": stream.accel.matrix,
            "gyro_bias": bias_g, "accel_bias": bias_a}


def _vibrations(stream: "ImuStream", spec: ImuSpec) -> list:
    """Each vibration's accelerometer and gyro signals ``(B, n, 3)`` (or 0), each from its own
    stream."""
    out = []
    for k, v in enumerate(spec.vibration):
        gens = stream.streams(f"vibration{k}")
        if v.type == "rotor":
            rotors = RotorMotion(stream.rotor_rpm, stream.rotor_angle_rad, stream.name)
            out.append(tuple(rotor_vibration(gens(triad), rotors, v, spec.rate_hz, amp)
                             for triad, amp in (("accel", v.amplitude), ("gyro", v.gyro_amplitude))))
        else:
            out.append(tuple(band_vibration(gens(triad), stream.t_s, v, spec.rate_hz, amp)
                             for triad, amp in (("accel", v.amplitude), ("gyro", v.gyro_amplitude))))
    return out


# --- the kind's declaration ----------------------------------------------------------------------

#: a gyro triad's datasheet keys
_GYRO = {
    "bias": Field("bias", "angular_rate", "3", signed=True),
    "bias_sigma": Field("bias_sigma", "angular_rate", "3"),
    "bias_instability": Field("bias_instability", "angular_rate", "3"),
    "bias_instability_tau": Field("bias_instability_tau_s", "time", "1"),
    "markov_sigma": Field("markov_sigma", "angular_rate", "3"),
    "markov_tau": Field("markov_tau_s", "time", "1"),
    "noise_density": Field("noise_density", "angle_random_walk", "3"),
    "random_walk": Field("random_walk", "rate_random_walk", "3"),
    "scale_factor": Field("scale_factor", "ratio", "3", signed=True),
    "scale_factor_sigma": Field("scale_factor_sigma", "ratio", "3"),
    "misalignment_sigma": Field("misalignment_sigma", "angle", "1"),
    "quantization": Field("quantization", "angular_rate", "1"),
    "range": Field("range", "angular_rate", "1"),
}
#: an accelerometer triad's: the gyro's keys in the accelerometer's dimensions
_ACCEL = {k: f._replace(dim={"angular_rate": "acceleration", "angle_random_walk": "velocity_random_walk",
                             "rate_random_walk": "acceleration_random_walk"}.get(f.dim, f.dim))
          for k, f in _GYRO.items()}
_TONE = {"order": Field("order", None, "plain"), "level": Field("level", None, "plain")}
_VIBRATION = {
    "type": Field("type", ("sine", "random", "rotor"), "str"),
    "amplitude": Field("amplitude", "acceleration", "3"),
    "gyro_amplitude": Field("gyro_amplitude", "angular_rate", "3"),
    "frequency_hz": Field("frequency_hz", None, "plain"),
    "band_hz": Field("band_hz", None, "pair"),
    "tones": Field("tones", Group(_TONE, Tone), "list"),
    "reference_hz": Field("reference_hz", None, "plain"),
}
#: a triad's error sources (``off: [gyro.noise_density]``), ``range`` off: no saturation
_TRIAD_ERRORS = ("bias", "bias_sigma", "bias_instability", "markov_sigma", "noise_density", "random_walk",
                 "scale_factor", "scale_factor_sigma", "misalignment_sigma", "quantization", "range")


#: the off-diagonal entries of a triad's misalignment matrix, the states of its linear form
_OFF_DIAGONAL = tuple((i, j) for i in range(3) for j in range(3) if i != j)


def _constant(value, coupling=None, fixed: bool = False):
    """A random constant of std ``value`` (``fixed``: the error ``value`` itself, its outer
    product the second moment) as the ``(P0, tau_s, q, coupling)`` of a linear form."""
    v = np.asarray(value, float)
    P0 = np.outer(v, v) if fixed else np.diag(v * v)
    return dict(P0=P0, tau_s=np.full(v.size, np.inf), q=np.zeros(v.size), coupling=coupling)


def _markov(sigma, tau_s: float):
    """A stationary first-order Gauss-Markov process of std ``sigma`` ``(3,)``."""
    s2 = np.asarray(sigma, float) ** 2
    return dict(P0=np.diag(s2), tau_s=np.full(3, float(tau_s)), q=2.0 * s2 / tau_s)


def triad_linear(group: str, term: str):
    """The linear form (:class:`~navsim.sensors.registry.LinearError`) of the triad ``group``'s
    (``gyro``, ``accel``) error ``term``, as :func:`emulate_imu` applies it, or None where there
    is none (quantization, saturation). The bias instability is its Gauss-Markov process
    (:func:`gauss_markov_biases`), the white noise its whole density (as the emulator draws it
    without quantization: an error budget's term alone); scale factors and misalignments
    multiply the true rate or specific force."""
    quantity = "rate_b" if group == "gyro" else "force_b"
    true = (lambda m: m.omega_ib_b_rps) if group == "gyro" else (lambda m: m.f_b_mps2)

    def misaligned(m):
        C = np.zeros((3, len(_OFF_DIAGONAL)))
        x = true(m)
        for k, (i, j) in enumerate(_OFF_DIAGONAL):
            C[i, k] = x[j]
        return C

    def form(spec: ImuSpec) -> LinearError | None:
        e = getattr(spec, group)
        scale = lambda m: np.diag(true(m))
        parts = {
            "bias": lambda: _constant(e.bias, fixed=True),
            "bias_sigma": lambda: _constant(e.bias_sigma),
            "bias_instability": lambda: _markov(*gauss_markov_biases(e)[0]),
            "markov_sigma": lambda: _markov(*gauss_markov_biases(e)[1]),
            "random_walk": lambda: dict(P0=np.zeros((3, 3)), tau_s=np.full(3, np.inf),
                                        q=np.asarray(e.random_walk, float) ** 2 * np.ones(3)),
            "scale_factor": lambda: _constant(e.scale_factor, scale, fixed=True),
            "scale_factor_sigma": lambda: _constant(e.scale_factor_sigma, scale),
            "misalignment_sigma": lambda: _constant(np.full(len(_OFF_DIAGONAL), e.misalignment_sigma), misaligned),
        }
        if term == "noise_density":        # the whole density: alone, the noise is drawn without quantization
            return LinearError(quantity, white=np.asarray(e.noise_density, float) ** 2 * np.ones(3))
        if term not in parts:
            return None
        return LinearError(quantity, **parts[term]())

    return form


def _emulate(truth, spec: ImuSpec, seed: int, runs, faults=(), name: str = "imu") -> SensorData:
    """:func:`emulate_imu` as every kind's emulator is called (an IMU has no fault windows)."""
    return emulate_imu(truth, spec, seed, runs, name=name)


def imu_channels(data: SensorData, truth, run: int = 0) -> list:
    """The plot's channels: each gyro (deg/s) and accelerometer (m/s²) axis against the truth."""
    v, t = data.values, data.t_s
    k = max(1, round(truth.meta.get("rate_hz", 100.0) / data.meta["rate_hz"]))
    out = [(f"gyro {axis}", "deg/s", t, np.degrees(v["omega_ib_b_rps"][run, :, j]),
            np.degrees(truth.omega_ib_b_rps[::k, j])) for j, axis in enumerate("xyz")]
    return out + [(f"accel {axis}", "m/s²", t, v["f_b_mps2"][run, :, j], truth.f_b_mps2[::k, j])
                  for j, axis in enumerate("xyz")]


KIND = register(SensorKind(
    name="imu", spec=ImuSpec, role="inertial", description="strapdown gyro and accelerometer triads",
    fields={"rate_hz": Field("rate_hz", None, "plain"), "gyro": Field("gyro", Group(_GYRO, AxisErrors), "group"),
            "accel": Field("accel", Group(_ACCEL, AxisErrors), "group"),
            "vibration": Field("vibration", Group(_VIBRATION, Vibration), "list")},
    outputs=(Output("omega_ib_b_rps", "rad/s", truth="omega_ib_b_rps", axes=("x", "y", "z")),
             Output("f_b_mps2", "m/s^2", truth="f_b_mps2", axes=("x", "y", "z")),
             Output("dtheta_b_rad", "rad", axes=("x", "y", "z")), Output("dv_b_mps", "m/s", axes=("x", "y", "z"))),
    errors=tuple(ErrorTerm(f"{g}.{f}", math.inf if f == "range" else None, triad_linear(g, f))
                 for g in ("gyro", "accel") for f in _TRIAD_ERRORS) + (ErrorTerm("vibration"),),
    emulate=_emulate, faults=(), channels=imu_channels))
