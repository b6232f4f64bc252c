"""A PX4 ULog with GNSS as an INS/GNSS log (:func:`ulog_navlog`): its IMU, its GNSS receiver,
and PX4's own EKF2 solution as the trajectory the estimators are compared with.

Topics read (pyulog): ``sensor_combined`` (the IMU, resampled to a uniform grid as the attitude
replay does, :func:`navsim.replay.run.imu_increments`); ``sensor_gps`` or, in older PX4,
``vehicle_gps_position`` (latitude and longitude in 1e-7 deg or ``latitude_deg``, altitude
above mean sea level in mm or ``altitude_msl_m``, ``eph``/``epv`` as the 1-sigma, the NED
velocity and ``s_variance_m_s``; fixes of ``fix_type`` below 3 left out); EKF2's
``vehicle_global_position`` (latitude, longitude, altitude above mean sea level), its velocity
from ``vehicle_local_position`` (``vx``, ``vy``, ``vz``) and ``vehicle_attitude``. Heights are
all above mean sea level, so the fixes and the solution share a datum. Times are seconds from
the first IMU sample.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from navsim.foundations.errors import LogError
from navsim.replay.navlog import GnssLog, ImuLog, NavLog, Trajectory, log_name, trim_gnss
from navsim.replay.run import imu_increments
from navsim.replay.ulog import MIN_DURATION_S, columns, read_ulog_file, require, topics_of, vec

DEG = math.pi / 180.0
#: the GNSS topics, newest first
GPS_TOPICS = ("sensor_gps", "vehicle_gps_position")
GPS_FIX_3D = 3                   #: ``fix_type`` of a 3-D fix


def _gps(topics: dict, t0_us: int, path, notes: list) -> GnssLog:
    """The receiver's 3-D fixes."""
    name = next((t for t in GPS_TOPICS if t in topics), None)
    if name is None:
        raise LogError(f"has no GNSS ({' or '.join(GPS_TOPICS)})", file=str(path),
                       hint="a position replay needs the receiver's fixes; replay the attitude without --scenario")
    d = topics[name]
    new = "latitude_deg" in d
    fields = (["latitude_deg", "longitude_deg", "altitude_msl_m"] if new else ["lat", "lon", "alt"]) + \
        ["timestamp", "eph", "epv", "vel_n_m_s", "vel_e_m_s", "vel_d_m_s", "s_variance_m_s", "fix_type"]
    require(topics, name, fields, path, "the GNSS fixes")
    scale = (1.0, 1.0, 1.0) if new else (1e-7, 1e-7, 1e-3)
    lat, lon, alt = (np.asarray(d[f], float) * s for f, s in zip(fields[:3], scale))
    t = (np.asarray(d["timestamp"], np.int64) - t0_us) * 1e-6
    ok = np.asarray(d["fix_type"]) >= GPS_FIX_3D
    if (~ok).any():
        notes.append(f"{int((~ok).sum())} of {ok.size} '{name}' samples without a 3-D fix left out")
    _, first = np.unique(t[ok], return_index=True)         # one fix per timestamp
    pick = lambda x: np.asarray(x)[ok][first]
    eph, epv, s_vel = pick(d["eph"]).astype(float), pick(d["epv"]).astype(float), pick(d["s_variance_m_s"])
    if not first.size:
        raise LogError(f"'{name}' holds no 3-D fix", file=str(path), hint="replay a log where the receiver had a fix")
    return GnssLog(pick(t), pick(lat) * DEG, pick(lon) * DEG, pick(alt), np.c_[eph, eph, epv],
                   columns({k: pick(d[k]) for k in ("vel_n_m_s", "vel_e_m_s", "vel_d_m_s")},
                           ["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"]),
                   np.repeat(np.asarray(s_vel, float)[:, None], 3, axis=1))


def _ekf2(topics: dict, t0_us: int, path) -> Trajectory:
    """EKF2's solution at its global position's times: velocity and attitude interpolated."""
    from scipy.spatial.transform import Rotation, Slerp
    why = "PX4's own solution, compared with"
    gp = require(topics, "vehicle_global_position", ["timestamp", "lat", "lon", "alt"], path, why)
    lp = require(topics, "vehicle_local_position", ["timestamp", "vx", "vy", "vz"], path, why)
    va = require(topics, "vehicle_attitude", ["timestamp"] + vec("q", 4), path, why)
    rel = lambda d: (np.asarray(d["timestamp"], np.int64) - t0_us) * 1e-6
    t, t_lp, t_va = rel(gp), rel(lp), rel(va)
    t, first = np.unique(t, return_index=True)
    vel = np.stack([np.interp(t, t_lp, np.asarray(lp[k], float)) for k in ("vx", "vy", "vz")], -1)
    q = columns(va, vec("q", 4))
    t_va, keep = np.unique(t_va, return_index=True)
    if len(t) < 2 or len(t_va) < 2:
        raise LogError("EKF2's solution has fewer than 2 samples", file=str(path))
    rot = Slerp(t_va, Rotation.from_quat(q[keep][:, [1, 2, 3, 0]]))(np.clip(t, t_va[0], t_va[-1]))
    return Trajectory(t, np.asarray(gp["lat"], float)[first] * DEG, np.asarray(gp["lon"], float)[first] * DEG,
                      np.asarray(gp["alt"], float)[first], vel, rot.as_euler("ZYX")[:, ::-1])


def ulog_navlog(path, allow_damaged: bool = False, rate_hz: float | None = None) -> NavLog:
    """A PX4 ULog with GNSS as a :class:`NavLog`: the IMU on a uniform grid of ``rate_hz``
    (default the log's), the receiver's 3-D fixes, EKF2's solution (the scores are differences
    from it); the start is the solution's first state.

    Raises
    ------
    LogError
        The file cannot be read, lacks a topic or a field, holds no fix or too little IMU data.
    """
    path = Path(path)
    notes: list[str] = []
    ulog = read_ulog_file(path, allow_damaged, notes)
    topics = topics_of(ulog)
    sc = require(topics, "sensor_combined", ["timestamp"] + vec("gyro_rad", 3) + vec("accelerometer_m_s2", 3),
                 path, "the IMU")
    t_us = np.asarray(sc["timestamp"], np.int64)
    t0_us = int(t_us[0])
    t = (t_us - t0_us) * 1e-6
    if len(t) < 2 or t[-1] < MIN_DURATION_S:
        raise LogError(f"sensor_combined holds {t[-1] if len(t) else 0:.2f} s of IMU data; the replay needs "
                       f"{MIN_DURATION_S:.0f} s", file=str(path))
    rate = rate_hz or round(1.0 / float(np.median(np.diff(t))))
    grid = imu_increments(t, columns(sc, vec("gyro_rad", 3)), columns(sc, vec("accelerometer_m_s2", 3)), rate)
    imu = ImuLog(grid.t_s, grid.dtheta_b_rad, grid.dv_b_mps)
    gnss = _gps(topics, t0_us, path, notes)
    try:
        gnss = trim_gnss(gnss, float(imu.t_s[-1]), notes)
    except ValueError as exc:
        raise LogError(str(exc), file=str(path)) from None
    solution = _ekf2(topics, t0_us, path)
    files = {"imu": f"{path} (sensor_combined)", "gnss": f"{path} ({next(n for n in GPS_TOPICS if n in topics)})",
             "solution": f"{path} (vehicle_global_position, vehicle_local_position, vehicle_attitude)"}
    return NavLog(log_name(path).split(".")[0], "ulog", t0_us * 1e-6, imu, gnss, solution, None, files, notes)

