"""The batched Monte Carlo loop: one Python loop over time, every estimator and run inside it.

:func:`run_batch` draws each run's initial navigation errors from its own random stream, starts
every estimator from them, feeds the IMU increments at the IMU rate and the other sensors at
each estimator's filter epochs, and records at every epoch the errors against the truth, the
filter's 1-sigma, NEES and the innovations' NIS (:class:`EstimatorHistory`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from navsim import earth
from navsim.sensors.base import run_generators
from navsim.strapdown import NavState, rotation, state_from_truth
from navsim.transform import dcm_from_quat, euler_from_dcm, wrap_angle

ARCSEC = math.pi / 180 / 3600


@dataclass(frozen=True)
class InitialErrors:
    """1-sigma initial errors drawn per run: position NED (m), velocity NED (m/s), attitude
    (rad, about N, E, D). P0: 5, 5, 10 m; 0.1 m/s; 20", 20", 50". P3: 5, 5, 3 m; 0.2, 0.2,
    0.1 m/s; 1', 1', 1'. ``fixed``: use the sigmas as the errors themselves."""

    pos_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vel_mps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    att_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))
    fixed: bool = False

    def draw(self, seed: int, runs) -> np.ndarray:
        """``(B, 9)`` errors [att, vel, pos NED m] of the runs."""
        sig = np.concatenate([self.att_rad, self.vel_mps, self.pos_m])
        if self.fixed:
            return np.broadcast_to(sig, (len(list(runs)), 9)).copy()
        return np.stack([g.standard_normal(9) for g in run_generators(seed, runs, "initial")]) * sig

    def sigma_blocks(self, lat_rad: float, h_m: float) -> dict:
        r_m, r_n = earth.radii(lat_rad)
        pos = np.array([self.pos_m[0] / (r_m + h_m), self.pos_m[1] / ((r_n + h_m) * math.cos(lat_rad)),
                        self.pos_m[2]])
        return {"att": self.att_rad, "vel": self.vel_mps, "pos": pos}


def perturbed_start(truth, errors: np.ndarray, k: int = 0) -> NavState:
    """The true state at sample ``k`` with the drawn errors (estimate minus truth) applied."""
    B = errors.shape[0]
    nav = state_from_truth(truth, k, B)
    nav.C_nb = rotation(-errors[:, :3]) @ nav.C_nb           # C_est = (I - [phi x]) C
    nav.vel_n_mps = nav.vel_n_mps + errors[:, 3:6]
    r_m, r_n = earth.radii(nav.lat_rad)
    nav.lat_rad = nav.lat_rad + errors[:, 6] / (r_m + nav.h_m)
    nav.lon_rad = nav.lon_rad + errors[:, 7] / ((r_n + nav.h_m) * np.cos(nav.lat_rad))
    nav.h_m = nav.h_m - errors[:, 8]
    return nav


def nav_errors(nav: NavState, truth, k: int):
    """Errors of ``nav`` against truth sample ``k``: attitude phi (rad, ``(B, 3)``), velocity
    (m/s), position NED (m), and the position error in the filter's units (dL, dlambda, dh)."""
    C_true = dcm_from_quat(truth.quat_nb[k])                   # (3, 3), or (B, 3, 3) per run
    E = nav.C_nb @ np.swapaxes(C_true, -1, -2)                 # = I - [phi x]
    phi = 0.5 * np.stack([E[:, 1, 2] - E[:, 2, 1], E[:, 2, 0] - E[:, 0, 2], E[:, 0, 1] - E[:, 1, 0]], -1)
    dv = nav.vel_n_mps - truth.vel_n_mps[k]
    dlat = nav.lat_rad - truth.lat_rad[k]
    dlon = nav.lon_rad - truth.lon_rad[k]
    dh = nav.h_m - truth.h_m[k]
    r_m, r_n = earth.radii(truth.lat_rad[k])
    pos_m = np.stack([dlat * (r_m + truth.h_m[k]), dlon * (r_n + truth.h_m[k]) * np.cos(truth.lat_rad[k]), -dh], -1)
    return phi, dv, pos_m, np.stack([dlat, dlon, dh], -1)


@dataclass
class EstimatorHistory:
    """What one estimator did over the batch, sampled at its epochs ``t_s`` ``(E,)``."""

    label: str
    t_s: np.ndarray
    att_err_rad: np.ndarray        #: (B, E, 3)
    vel_err_mps: np.ndarray        #: (B, E, 3)
    pos_err_m: np.ndarray          #: (B, E, 3) NED
    sigma: np.ndarray | None       #: (B, E, 9) 1-sigma: att (rad), vel (m/s), pos NED (m)
    nees: np.ndarray | None        #: (B, E) NEES of the 9 navigation errors
    nis: dict                      #: measurement name -> (B, E_m) NIS, NaN without a sample
    nis_dim: dict                  #: measurement name -> its dimension
    diverged: np.ndarray           #: (B,) bool
    gyro_bias: np.ndarray | None = None    #: (B, E, 3) estimated, rad/s
    accel_bias: np.ndarray | None = None   #: (B, E, 3) estimated, m/s^2
    #: CPU seconds spent in ``propagate`` and in the epochs (predict + corrections), summed over
    #: the batches, and the number of runs and filter epochs they covered
    cost: dict | None = None
    #: (B, E, 3) roll, pitch, yaw of the solution minus the truth's, wrapped to [-pi, pi)
    euler_err_rad: np.ndarray | None = None
    #: per run, the estimator's reset events ``(t_s, cause)`` (P4's divergence monitor), or None
    resets: list | None = None


def run_batch(truth, imu, sensors: dict, estimators: dict, initial: InitialErrors, seed: int,
              runs, progress=None) -> dict[str, EstimatorHistory]:
    """Run ``estimators`` (label -> estimator object) on the runs ``runs``.

    ``imu`` is the IMU :class:`~navsim.sensors.base.SensorData` of these runs, ``sensors`` the
    other sensors' data by name. All estimators share the time loop and the initial errors.
    """
    runs = list(runs)
    errors = initial.draw(seed, runs)
    dt = imu.meta["dt_s"]
    step = int(round(dt / truth.dt_s))
    nav0 = perturbed_start(truth, errors, 0)
    sigma0 = initial.sigma_blocks(truth.lat_rad[0], truth.h_m[0])
    for est in estimators.values():
        if hasattr(est, "noise_sigma0"):
            est.initialize(nav0, {**sigma0, **est.noise_sigma0()})
        else:
            est.initialize(nav0, sigma0)
    rec = {label: _Recorder(label) for label in estimators}
    dth, dv = imu.values["dtheta_b_rad"], imu.values["dv_b_mps"]
    n = dth.shape[1]
    epoch_every = {label: int(round(est.period_s / dt)) for label, est in estimators.items()}
    for label, est in estimators.items():
        rec[label].add(est, truth, 0, 0.0, [])
    clock = time.perf_counter
    for i in range(1, n):
        t = imu.t_s[i]
        for label, est in estimators.items():
            c0 = clock()
            est.propagate(dth[:, i], dv[:, i], dt)
            c1 = clock()
            rec[label].propagate_s += c1 - c0
            if i % epoch_every[label] == 0:
                innov = est.epoch(t, sensors)
                rec[label].epoch_s += clock() - c1
                rec[label].add(est, truth, i * step, t, innov)
        if progress is not None and i % 1000 == 0:
            progress(i, n)
    return {label: r.history(estimators[label]) for label, r in rec.items()}


class _Recorder:
    def __init__(self, label):
        self.label = label
        self.t, self.att, self.vel, self.pos, self.sig, self.nees = [], [], [], [], [], []
        self.euler = []
        self.bg, self.ba = [], []
        self.nis: dict = {}
        self.nis_dim: dict = {}
        self.propagate_s = self.epoch_s = 0.0

    def add(self, est, truth, k, t, innovations):
        sol = est.solution()
        phi, dv, pos_m, pos_filter = nav_errors(sol.nav, truth, k)
        self.t.append(t)
        self.att.append(phi)
        self.euler.append(wrap_angle(euler_from_dcm(sol.nav.C_nb) - truth.euler_rad[k]))
        self.vel.append(dv)
        self.pos.append(pos_m)
        if sol.gyro_bias is not None:
            self.bg.append(sol.gyro_bias.copy())
            self.ba.append(sol.accel_bias.copy())
        if sol.P_nav is not None:
            P = sol.P_nav
            e = np.concatenate([phi, dv, pos_filter], -1)
            self.nees.append(np.einsum("bi,bi->b", e, np.linalg.solve(P, e[..., None])[..., 0]))
            d = np.sqrt(np.maximum(np.diagonal(P, axis1=1, axis2=2), 0.0)).copy()
            r_m, r_n = earth.radii(truth.lat_rad[k])
            d[:, 6] *= r_m + truth.h_m[k]
            d[:, 7] *= (r_n + truth.h_m[k]) * np.cos(truth.lat_rad[k])
            self.sig.append(d)
        for inn in innovations:
            key = f"{inn.measurement}:{inn.sensor}"
            self.nis.setdefault(key, []).append((len(self.t) - 1, inn.nis))
            self.nis_dim[key] = inn.y.shape[-1]

    def history(self, est) -> EstimatorHistory:
        E = len(self.t)
        stack = lambda xs: np.stack(xs, axis=1)
        nis = {}
        for key, items in self.nis.items():
            arr = np.full((items[0][1].shape[0], E), np.nan)
            for e, v in items:
                arr[:, e] = v
            nis[key] = arr
        return EstimatorHistory(
            label=self.label, t_s=np.array(self.t), att_err_rad=stack(self.att),
            vel_err_mps=stack(self.vel), pos_err_m=stack(self.pos),
            sigma=stack(self.sig) if self.sig else None,
            nees=np.stack(self.nees, axis=1) if self.nees else None, nis=nis, nis_dim=self.nis_dim,
            diverged=np.asarray(est.solution().extra.get("diverged", False)) | ~np.all(
                np.isfinite(stack(self.pos)), axis=(1, 2)),
            gyro_bias=stack(self.bg) if self.bg else None, accel_bias=stack(self.ba) if self.ba else None,
            cost={"propagate_s": self.propagate_s, "epoch_s": self.epoch_s, "runs": len(self.pos[0]),
                  "epochs": E - 1, "batches": 1},
            euler_err_rad=stack(self.euler), resets=_copy_resets(est.solution().extra.get("resets")))


def _copy_resets(resets):
    return None if resets is None else [list(r) for r in resets]
