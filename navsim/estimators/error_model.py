"""The SINS error model in NED: state layout, system matrix F, process noise.

Error states (estimate minus truth, closed loop), in blocks named as in the papers:

========== ===== =========================================================================
block      size  meaning (NED; the papers' ENU names in brackets)
========== ===== =========================================================================
att        3     attitude error phi: ``C_nb_est = (I - [phi x]) C_nb`` (phi_E, phi_N, phi_U)
vel        3     velocity error, m/s (dv_E, dv_N, dv_U)
pos        3     latitude and longitude error (rad), height error (m) (dL, dlambda, dh)
gyro_bias  3     residual gyro constant drift ``b - b_est``, rad/s, body (eps)
accel_bias 3     residual accelerometer constant bias, m/s^2, body (nabla)
baro       1     barometric altimeter first-order Markov error, m (P0's dh_b)
gyro_markov 3    first-order Markov gyro drift, rad/s (P2's eps_r)
accel_markov 3   first-order Markov accelerometer bias, m/s^2 (P2's nabla)
========== ===== =========================================================================

P3's 15 states are ``att vel pos gyro_bias accel_bias``; P0's 16 add ``baro``; P2's 18 are
``att vel pos gyro_bias gyro_markov accel_markov``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim import earth, kernels
from navsim.strapdown import skew

BLOCK_SIZES = {"att": 3, "vel": 3, "pos": 3, "gyro_bias": 3, "accel_bias": 3, "baro": 1,
               "gyro_markov": 3, "accel_markov": 3}
REQUIRED = ("att", "vel", "pos")
PRESETS = {"p3_15": ("att", "vel", "pos", "gyro_bias", "accel_bias"),
           "p0_16": ("att", "vel", "pos", "gyro_bias", "accel_bias", "baro"),
           "p2_18": ("att", "vel", "pos", "gyro_bias", "gyro_markov", "accel_markov")}
#: report names of the states, the papers' ENU-style labels mapped on our NED blocks
STATE_LABELS = {"att": ["phi_N", "phi_E", "phi_D"], "vel": ["dv_N", "dv_E", "dv_D"],
                "pos": ["dL", "dlambda", "dh"], "gyro_bias": ["eps_x", "eps_y", "eps_z"],
                "accel_bias": ["nabla_x", "nabla_y", "nabla_z"], "baro": ["dh_b"],
                "gyro_markov": ["eps_r_x", "eps_r_y", "eps_r_z"],
                "accel_markov": ["nabla_r_x", "nabla_r_y", "nabla_r_z"]}


@dataclass(frozen=True)
class Layout:
    """Which blocks the state has, in order, and where each starts."""

    blocks: tuple[str, ...]

    def __post_init__(self):
        for b in REQUIRED:
            if b not in self.blocks:
                raise ValueError(f"the state needs block '{b}'")
        unknown = [b for b in self.blocks if b not in BLOCK_SIZES]
        if unknown:
            raise ValueError(f"unknown state blocks {unknown}; known: {', '.join(BLOCK_SIZES)}")

    @property
    def n(self) -> int:
        return sum(BLOCK_SIZES[b] for b in self.blocks)

    def slice(self, block: str) -> slice:
        i = 0
        for b in self.blocks:
            if b == block:
                return slice(i, i + BLOCK_SIZES[b])
            i += BLOCK_SIZES[b]
        raise KeyError(block)

    def has(self, block: str) -> bool:
        return block in self.blocks

    def labels(self) -> list[str]:
        return [label for b in self.blocks for label in STATE_LABELS[b]]


@dataclass(frozen=True)
class ProcessNoise:
    """The filter's own noise model (continuous-time), SI."""

    gyro_white: np.ndarray          #: ARW, rad/s/rtHz (3,)
    accel_white: np.ndarray         #: VRW, m/s^2/rtHz (3,)
    gyro_bias_walk: np.ndarray      #: rad/s/rts (3,)
    accel_bias_walk: np.ndarray     #: m/s^2/rts (3,)
    gyro_markov_sigma: np.ndarray   #: (3,)
    gyro_markov_tau_s: float
    accel_markov_sigma: np.ndarray  #: (3,)
    accel_markov_tau_s: float
    baro_sigma: float = 0.0
    baro_tau_s: float = 300.0


def system_matrix(layout: Layout, lat, h, vel_n, C_nb, f_n) -> np.ndarray:
    """Continuous error dynamics ``F`` ``(B, n, n)`` at the navigation state (batched)."""
    B = lat.shape[0]
    n = layout.n
    F = np.zeros((B, n, n))
    A, V, Pp = layout.slice("att"), layout.slice("vel"), layout.slice("pos")
    r_m, r_n = earth.radii(lat)
    Rm, Rn = r_m + h, r_n + h
    sl, cl, tl = np.sin(lat), np.cos(lat), np.tan(lat)
    vn, ve = vel_n[:, 0], vel_n[:, 1]
    W = earth.OMEGA_IE_RPS
    w_ie = np.stack([W * cl, np.zeros(B), -W * sl], -1)
    w_en = np.stack([ve / Rn, -vn / Rm, -ve * tl / Rn], -1)
    # d(omega_en)/d(v), d(omega_ie + omega_en)/d(L, lambda, h), d(2 omega_ie + omega_en)/d(pos)
    Mv = np.zeros((B, 3, 3))
    Mv[:, 0, 1] = 1.0 / Rn
    Mv[:, 1, 0] = -1.0 / Rm
    Mv[:, 2, 1] = -tl / Rn
    dwie_dp = np.zeros((B, 3, 3))
    dwie_dp[:, 0, 0] = -W * sl
    dwie_dp[:, 2, 0] = -W * cl
    dwen_dp = np.zeros((B, 3, 3))
    dwen_dp[:, 2, 0] = -ve / (Rn * cl * cl)
    dwen_dp[:, 0, 2] = -ve / Rn ** 2
    dwen_dp[:, 1, 2] = vn / Rm ** 2
    dwen_dp[:, 2, 2] = ve * tl / Rn ** 2
    # attitude
    F[:, A, A] = -skew(w_ie + w_en)
    F[:, A, V] = Mv
    F[:, A, Pp] = dwie_dp + dwen_dp
    # velocity
    Vx = skew(vel_n)
    F[:, V, A] = skew(f_n)
    F[:, V, V] = -skew(2.0 * w_ie + w_en) + Vx @ Mv
    F[:, V, Pp] = Vx @ (2.0 * dwie_dp + dwen_dp)
    # gravity gradient (J2 model, by central differences): latitude and height
    dL, dh = 1e-5, 1.0
    grad = np.empty((B, 3, 2))
    kernels.gravity_gradient(np.ascontiguousarray(lat, float), np.ascontiguousarray(h, float), dL, dh, grad)
    F[:, V, Pp.start] += grad[:, :, 0]
    F[:, V, Pp.start + 2] += grad[:, :, 1]
    # position
    F[:, Pp.start, V.start] = 1.0 / Rm
    F[:, Pp.start, Pp.start + 2] = -vn / Rm ** 2
    F[:, Pp.start + 1, V.start + 1] = 1.0 / (Rn * cl)
    F[:, Pp.start + 1, Pp.start] = ve * tl / (Rn * cl)
    F[:, Pp.start + 1, Pp.start + 2] = -ve / (Rn ** 2 * cl)
    F[:, Pp.start + 2, V.start + 2] = -1.0
    # sensor errors
    for block, target in (("gyro_bias", A), ("gyro_markov", A), ("accel_bias", V), ("accel_markov", V)):
        if layout.has(block):
            sign = -1.0 if target == A else 1.0
            F[:, target, layout.slice(block)] = sign * C_nb
    return F


def add_markov_decay(F: np.ndarray, layout: Layout, noise: ProcessNoise) -> np.ndarray:
    for block, tau in (("gyro_markov", noise.gyro_markov_tau_s), ("accel_markov", noise.accel_markov_tau_s),
                       ("baro", noise.baro_tau_s)):
        if layout.has(block):
            s = layout.slice(block)
            idx = np.arange(s.start, s.stop)
            F[:, idx, idx] = -1.0 / tau
    return F


def process_noise(layout: Layout, noise: ProcessNoise) -> np.ndarray:
    """Continuous process-noise density ``Qc`` ``(n, n)`` (white noise is isotropic per triad,
    so its rotation by ``C_nb`` leaves it diagonal)."""
    q = np.zeros(layout.n)
    q[layout.slice("att")] = noise.gyro_white ** 2
    q[layout.slice("vel")] = noise.accel_white ** 2
    if layout.has("gyro_bias"):
        q[layout.slice("gyro_bias")] = noise.gyro_bias_walk ** 2
    if layout.has("accel_bias"):
        q[layout.slice("accel_bias")] = noise.accel_bias_walk ** 2
    if layout.has("gyro_markov"):
        q[layout.slice("gyro_markov")] = 2.0 * noise.gyro_markov_sigma ** 2 / noise.gyro_markov_tau_s
    if layout.has("accel_markov"):
        q[layout.slice("accel_markov")] = 2.0 * noise.accel_markov_sigma ** 2 / noise.accel_markov_tau_s
    if layout.has("baro"):
        q[layout.slice("baro")] = 2.0 * noise.baro_sigma ** 2 / noise.baro_tau_s
    return np.diag(q)
