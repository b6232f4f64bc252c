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
pitot_bias 1     the ADS's dynamic-pressure bias, Pa, a random constant (``air_velocity``)
wind       2     the horizontal wind (air-mass velocity N, E), m/s: a random walk or a
                 first-order Markov process (``air_velocity``)
wind_down  1     the vertical wind, m/s, the same model
gust       2     the horizontal gusts (N, E), m/s: a first-order Markov process, Dryden's
                 first-order form (``sigma`` the gusts' std, ``tau = L / V`` their scale length
                 over the airspeed), observed with the wind by ``air_velocity``
gust_down  1     the vertical gust, m/s, the same model
========== ===== =========================================================================

The sensor-error blocks ``baro`` and ``pitot_bias`` and the air mass's (wind, gusts) stay in the filter (they are
the sensors' errors and the air mass's motion, not fed back). A gust state takes the gusts
out of the ``air_velocity`` measurement's R on its axes, so the wind state is the steady wind. P3's 15 states are ``att vel pos gyro_bias accel_bias``; P0's 16 add ``baro``; P2's 18 are
``att vel pos gyro_bias gyro_markov accel_markov``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.navigation.kernels.dynamics import error_dynamics

BLOCK_SIZES = {"att": 3, "vel": 3, "pos": 3, "gyro_bias": 3, "accel_bias": 3, "baro": 1,
               "gyro_markov": 3, "accel_markov": 3, "pitot_bias": 1, "wind": 2, "wind_down": 1, "gust": 2, "gust_down": 1}
#: the wind's blocks and the axes (N, E, D) they hold
WIND_AXES = {"wind": (0, 1), "wind_down": (2,)}
#: the gusts' blocks and their axes
GUST_AXES = {"gust": (0, 1), "gust_down": (2,)}
#: every block of the air mass's velocity an ``air_velocity`` measurement sees, and its axes
AIR_MASS_AXES = {**WIND_AXES, **GUST_AXES}
REQUIRED = ("att", "vel", "pos")
PRESETS = {"p3_15": ("att", "vel", "pos", "gyro_bias", "accel_bias"),
           "p0_16": ("att", "vel", "pos", "gyro_bias", "accel_bias", "baro"),
           "p2_18": ("att", "vel", "pos", "gyro_bias", "gyro_markov", "accel_markov")}
#: report names of the states, the papers' ENU-style labels mapped on our NED blocks
STATE_LABELS = {"att": ["phi_N", "phi_E", "phi_D"], "vel": ["dv_N", "dv_E", "dv_D"],
                "pos": ["dL", "dlambda", "dh"], "gyro_bias": ["eps_x", "eps_y", "eps_z"],
                "accel_bias": ["nabla_x", "nabla_y", "nabla_z"], "baro": ["dh_b"],
                "gyro_markov": ["eps_r_x", "eps_r_y", "eps_r_z"],
                "accel_markov": ["nabla_r_x", "nabla_r_y", "nabla_r_z"], "pitot_bias": ["dq_c"],
                "wind": ["w_N", "w_E"], "wind_down": ["w_D"],
                "gust": ["g_N", "g_E"], "gust_down": ["g_D"]}


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
    #: the wind's driving noise density, m/s/sqrt(s) (a Markov process: ``sigma sqrt(2 / tau)``),
    #: horizontal and vertical
    wind_walk: float = 0.0
    wind_down_walk: float = 0.0
    #: the wind's correlation time, s (``inf``: a random walk)
    wind_tau_s: float = math.inf
    #: the gusts' std, m/s, and correlation time, s, horizontal and vertical
    gust_sigma: float = 0.0
    gust_down_sigma: float = 0.0
    gust_tau_s: float = 1.0
    gust_down_tau_s: float = 1.0


def system_matrix(layout: Layout, lat, h, vel_n, C_nb, f_n) -> np.ndarray:
    """Continuous error dynamics ``F`` ``(B, n, n)`` at the navigation state (batched;
    compiled, run by run: :func:`navsim.navigation.kernels.dynamics.error_dynamics`).

    With ``R_M = r_m + h``, ``R_N = r_n + h``, ``M = d(omega_en)/d(v)`` and
    ``D = d(omega_ie + omega_en)/d(L, lambda, h)``:

    * attitude: ``F_aa = -[(omega_ie + omega_en) x]``, ``F_av = M``, ``F_ap = D``, and
      ``-C_nb`` on the gyro bias and Markov blocks;
    * velocity: ``F_va = [f_n x]``, ``F_vv = -[(2 omega_ie + omega_en) x] + [v x] M``,
      ``F_vp = [v x] (2 d(omega_ie) + d(omega_en))/d(pos)`` plus the J2 gravity gradient by
      central differences (1e-5 rad, 1 m), and ``C_nb`` on the accelerometer blocks;
    * position: ``dL' = dv_N / R_M - v_N dh / R_M^2``, ``dlambda' = dv_E / (R_N cos L) +
      v_E tan L dL / (R_N cos L) - v_E dh / (R_N^2 cos L)``, ``dh' = -dv_D``.
    """
    n = layout.n
    F = np.empty((lat.shape[0], n, n))
    starts = [layout.slice(b).start if layout.has(b) else -1 for b in
              ("att", "vel", "pos", "gyro_bias", "gyro_markov", "accel_bias", "accel_markov")]
    f = lambda x: np.ascontiguousarray(x, float)
    error_dynamics(f(lat), f(h), f(vel_n), f(C_nb), f(f_n), np.array(starts, np.int64), 1e-5, 1.0, F)
    return F


def add_markov_decay(F: np.ndarray, layout: Layout, noise: ProcessNoise) -> np.ndarray:
    """``F`` with the first-order Markov blocks' decay ``-1 / tau`` on their diagonal (a random
    walk's ``tau`` is infinite: none)."""
    for block, tau in (("gyro_markov", noise.gyro_markov_tau_s), ("accel_markov", noise.accel_markov_tau_s),
                       ("baro", noise.baro_tau_s), ("wind", noise.wind_tau_s), ("wind_down", noise.wind_tau_s),
                       ("gust", noise.gust_tau_s), ("gust_down", noise.gust_down_tau_s)):
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
    for block, walk in (("wind", noise.wind_walk), ("wind_down", noise.wind_down_walk)):
        if layout.has(block):
            q[layout.slice(block)] = walk ** 2
    for block, sigma, tau in (("gust", noise.gust_sigma, noise.gust_tau_s),
                              ("gust_down", noise.gust_down_sigma, noise.gust_down_tau_s)):
        if layout.has(block):
            q[layout.slice(block)] = 2.0 * sigma ** 2 / tau
    return np.diag(q)
