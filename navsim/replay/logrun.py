"""An INS/GNSS log (:class:`~navsim.replay.navlog.NavLog`) through a scenario's estimators, as
one Monte Carlo run: :func:`run_log`.

The log takes the place of the flight and the emulated sensors: its IMU (on a uniform grid,
:func:`uniform_imu`) is the scenario's inertial sensor, its GNSS fixes the scenario's GNSS
receiver, and its reference trajectory, on the IMU grid (:func:`reference_truth`), the truth the
errors are recorded against. The estimators start from the log's start (else the reference's
first state) with the log's 1-sigma (else the scenario's ``initial_errors``), in the driver of
the Monte Carlo runs (:func:`navsim.experiment.driver.run_batch`): a run written by
``navsim sensors --export`` replays to the numbers of the run itself.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from navsim.experiment.driver import Batch, InitialErrors, run_batch
from navsim.experiment.runner import RunResult
from navsim.flight.truth import ARRAY_FIELDS, Truth
from navsim.foundations.errors import LogError
from navsim.foundations.transform import dcm_from_euler, quat_from_euler
from navsim.navigation.estimators import factory
from navsim.navigation.strapdown import NavState
from navsim.replay.navlog import ImuLog, NavLog, Start, Trajectory
from navsim.replay.run import on_grid
from navsim.sensors.base import SensorData
from navsim.sensors.registry import INERTIAL

#: the sensor kinds a log supplies (the scenario's sensors of other kinds get no data)
LOG_KINDS = ("gnss",)


def uniform_imu(imu: ImuLog, notes: list) -> ImuLog:
    """``imu`` on a uniform grid of its median interval: itself when its times are uniform,
    else its integrals (cumulative increments, piecewise linear in time) sampled at the grid
    times and differenced, so the increments still sum to the log's (a note says so)."""
    if imu.uniform:
        return imu
    dt = imu.dt_s
    grid = dt * np.arange(int(math.floor(imu.t_s[-1] / dt + 1e-9)) + 1)
    notes.append(f"IMU times not uniform (intervals {np.diff(imu.t_s).min():.4g}-{np.diff(imu.t_s).max():.4g} s): "
                 f"increments resampled to {1 / dt:.6g} Hz")
    out = []
    for inc in (imu.dtheta_b_rad, imu.dv_b_mps):
        cum = np.cumsum(inc, axis=0)
        at = np.stack([np.interp(grid, imu.t_s, cum[:, j]) for j in range(3)], -1)
        out.append(np.diff(at, axis=0, prepend=at[:1]))
    return ImuLog(grid, *out)


def reference_truth(ref: Trajectory, t_s: np.ndarray, name: str) -> Truth:
    """The reference on the grid ``t_s`` as a :class:`Truth`: position and velocity linear
    between its samples, attitude slerped; what a log does not hold (rates, air data) is NaN."""
    from scipy.spatial.transform import Rotation, Slerp
    n = len(t_s)
    lin = lambda x: np.interp(t_s, ref.t_s, x)
    quat = quat_from_euler(*ref.euler_rad.T)
    exact = len(ref.t_s) == n and np.array_equal(ref.t_s, t_s)
    if exact:                                    # the reference on the grid: its own numbers
        q, euler = quat, ref.euler_rad.copy()
    else:
        rot = Slerp(ref.t_s, Rotation.from_quat(quat[:, [1, 2, 3, 0]]))(np.clip(t_s, ref.t_s[0], ref.t_s[-1]))
        q = rot.as_quat()[:, [3, 0, 1, 2]]
        euler = rot.as_euler("ZYX")[:, ::-1]
    nan = lambda *shape: np.full((n, *shape), np.nan)
    arrays = {"t_s": t_s, "lat_rad": lin(ref.lat_rad), "lon_rad": lin(ref.lon_rad), "h_m": lin(ref.h_m),
              "vel_n_mps": np.stack([lin(ref.vel_n_mps[:, j]) for j in range(3)], -1), "quat_nb": q,
              "euler_rad": euler, "rotor_rpm": np.zeros((n, 0)), "segment": np.zeros(n, int),
              "omega_ib_b_rps": nan(3), "f_b_mps2": nan(3), "wind_n_mps": nan(3), "wind_steady_n_mps": nan(3)}
    arrays.update({k: nan() for k in ARRAY_FIELDS if k not in arrays})
    return Truth(**arrays, segment_labels=["the log"], meta={"track": name, "rate_hz": 1.0 / float(t_s[1] - t_s[0]),
                                                        "source": "log reference"})


def covered(log: NavLog, imu: ImuLog) -> ImuLog:
    """The IMU record where the reference covers it: a log without a start of its own starts
    at the reference's first sample (a note says so); one with a start must be covered from
    it (a :class:`LogError` otherwise); a reference that ends early ends the replay (noted)."""
    ref = log.reference
    dt = imu.dt_s
    where = log.files.get("reference", log.files.get("solution"))
    if ref.t_s[-1] < imu.t_s[0] + 10 * dt or ref.t_s[0] > imu.t_s[-1] - 10 * dt:
        raise LogError(f"the reference spans {ref.t_s[0]:.3f}-{ref.t_s[-1]:.3f} s from the log's start, outside its "
                       f"IMU record (0-{imu.t_s[-1]:.3f} s)", file=where, hint="the reference and the IMU must be on "
                       "one clock")
    begin = 0
    if ref.t_s[0] > imu.t_s[0] + dt:
        if log.start is not None:
            raise LogError(f"the reference begins {ref.t_s[0]:.3f} s after the log's start", file=where,
                           hint="set a later starttime in the start file, or give no start (the replay then "
                           "begins where the reference does)")
        begin = int(np.searchsorted(imu.t_s, ref.t_s[0] - 1e-9 * dt))
        log.notes.append(f"the reference begins {ref.t_s[0]:.2f} s into the log: replayed from there")
    end = int(np.searchsorted(imu.t_s, ref.t_s[-1] + 1e-9 * dt, side="right"))
    if end < len(imu.t_s):
        log.notes.append(f"the reference ends {imu.t_s[-1] - ref.t_s[-1]:.1f} s before the IMU: replayed to its end")
    if begin == 0 and end == len(imu.t_s):
        return imu
    dth, dv = imu.dtheta_b_rad[begin:end].copy(), imu.dv_b_mps[begin:end].copy()
    dth[0] = dv[0] = 0.0                       # the increment before the start is not the replay's
    return ImuLog(imu.t_s[begin:end], dth, dv)


def sensors_of(log: NavLog, scenario, imu: ImuLog) -> tuple[SensorData, dict]:
    """The IMU as the scenario's inertial sensor and the GNSS as its GNSS receiver (their names),
    the fixes on the IMU grid; a :class:`LogError` when the scenario has no such sensor, an
    estimator reads a sensor the log lacks or a velocity it does not hold."""
    by_kind = {}
    for c in scenario.sensors:
        by_kind.setdefault("imu" if c.role == INERTIAL else c.kind, c.name)
    missing = [k for k in ("imu", "gnss") if k not in by_kind]
    if missing:
        raise LogError(f"the scenario '{scenario.name}' has no {' and no '.join(missing)} sensor to take the log's",
                       file=str(scenario.path or "<scenario>"), hint="replay with a scenario of an IMU and a GNSS receiver")
    imu_name, gnss_name = by_kind["imu"], by_kind["gnss"]
    _check_reads(scenario, {imu_name, gnss_name}, gnss_name, log.gnss.vel_n_mps is not None)
    dt = imu.dt_s
    data = SensorData(imu_name, "imu", imu.t_s, {"dtheta_b_rad": imu.dtheta_b_rad[None], "dv_b_mps": imu.dv_b_mps[None]},
                      np.ones((1, len(imu.t_s)), bool), meta={"dt_s": dt, "rate_hz": 1.0 / dt, "source": "log"})
    g = log.gnss
    if g.t_s[0] < imu.t_s[0] - 1e-9:                  # fixes before a late start (the reference's)
        keep = g.t_s >= imu.t_s[0] - 1e-9
        g = type(g)(*(None if a is None else a[keep] for a in (g.t_s, g.lat_rad, g.lon_rad, g.h_m, g.sigma_ned_m,
                                                             g.vel_n_mps, g.sigma_vel_mps)))
    values = {"lat_rad": g.lat_rad, "lon_rad": g.lon_rad, "h_m": g.h_m, "fix_type": np.full(len(g.t_s), 3, np.int8),
              "h_acc_m": np.hypot(g.sigma_ned_m[:, 0], g.sigma_ned_m[:, 1]), "v_acc_m": g.sigma_ned_m[:, 2]}
    if g.vel_n_mps is not None:
        values.update(vel_n_mps=g.vel_n_mps, s_acc_mps=np.linalg.norm(g.sigma_vel_mps, axis=1))
    return data, {gnss_name: on_grid(gnss_name, "gnss", g.t_s, values, imu.t_s)}


def _check_reads(scenario, have: set, gnss: str, velocity: bool) -> None:
    for e in scenario.estimators:
        reads = {(m["sensor"], m["type"]) for m in e.params.get("measurements", [])}
        lacking = sorted({s for s, _ in reads} - have)
        if lacking:
            raise LogError(f"the estimator '{e.label}' reads the sensor(s) {', '.join(lacking)}, which a log of "
                           "IMU and GNSS does not have", file=str(scenario.path or "<scenario>"),
                           hint="replay with a scenario whose estimators take the IMU and GNSS only")
        if not velocity and (gnss, "velocity") in reads:
            raise LogError(f"the estimator '{e.label}' takes the GNSS velocity, which the log's GNSS file does not "
                           "hold", file=str(scenario.path or "<scenario>"),
                           hint="add the velocity columns to the GNSS file, or replay with a scenario whose "
                           "estimators take the position only")


def without_gnss_velocity(scenario, notes: list):
    """``scenario`` with its estimators' GNSS ``velocity`` measurements left out (a log whose
    fixes hold no velocity, replayed through the default scenario), a note naming them."""
    gnss = {c.name for c in scenario.sensors if c.kind == "gnss"}
    out, dropped = [], []
    for e in scenario.estimators:
        ms = e.params.get("measurements", [])
        kept = [m for m in ms if not (m["type"] == "velocity" and m["sensor"] in gnss)]
        if len(kept) < len(ms):
            dropped.append(e.label)
            e = dataclasses.replace(e, params={**e.params, "measurements": kept})
        out.append(e)
    if dropped:
        notes.append(f"the GNSS file holds no velocity: the velocity measurement of {', '.join(dropped)} left out")
    return dataclasses.replace(scenario, estimators=tuple(out))


def start_state(start: Start | None, truth: Truth) -> NavState:
    """The one-run state the filters start from: the log's start, else the reference's first."""
    if start is None:
        return NavState(truth.lat_rad[:1].copy(), truth.lon_rad[:1].copy(), truth.h_m[:1].copy(),
                        truth.vel_n_mps[:1].copy(), dcm_from_euler(*truth.euler_rad[0])[None])
    return NavState(np.array([start.lat_rad]), np.array([start.lon_rad]), np.array([start.h_m]),
                    np.asarray(start.vel_n_mps, float)[None], dcm_from_euler(*start.euler_rad)[None])


def start_sigma(start: Start | None, initial: InitialErrors) -> InitialErrors:
    """The log's 1-sigma where it gives them, the scenario's elsewhere."""
    if start is None:
        return initial
    pick = lambda mine, theirs: theirs if mine is None else np.asarray(mine, float)
    return InitialErrors(pick(start.sigma_pos_m, initial.pos_m), pick(start.sigma_vel_mps, initial.vel_mps),
                         pick(start.sigma_att_rad, initial.att_rad))


def run_log(log: NavLog, scenario, progress=None) -> tuple[RunResult, Truth]:
    """Every estimator of ``scenario`` over ``log`` as run 0; returns the runner's result (the
    histories against the reference) and the reference as a :class:`Truth`. ``progress(i, n)``
    now and then."""
    if log.reference is None:
        raise LogError("has no reference trajectory to score against", file=log.files.get("imu"),
                       hint="give --reference FILE (a truth.nav or reference CSV) or --solution FILE")
    imu = covered(log, uniform_imu(log.imu, log.notes))
    truth = reference_truth(log.reference, imu.t_s, log.name)
    data, others = sensors_of(log, scenario, imu)
    estimators = {e.label: factory.build(e) for e in scenario.estimators}
    initial = start_sigma(log.start, scenario.initial)
    hist = run_batch(truth, data, others, estimators, Batch(initial, scenario.seed, [0], start_state(log.start, truth)),
                     progress)
    return RunResult(hist, np.array([0])), truth
