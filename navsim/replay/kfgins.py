"""The text layout KF-GINS reads (i2Nav, Wuhan University), the de facto format of open INS/GNSS
datasets: :func:`read_kfgins`, :func:`write_kfgins`.

Files (whitespace-separated columns, ``#`` comment lines allowed):

- IMU, 7 columns: time (s, GNSS second of week), rotation increments x, y, z (rad), velocity
  increments x, y, z (m/s), body front-right-down, each over the interval ending at its time;
- GNSS, 7 columns: time, latitude, longitude (deg), ellipsoidal height (m), position 1-sigma
  north, east, down (m); or 13: the same, then velocity north, east, down (m/s) and its
  1-sigma (navsim's extension, for loosely coupled filters that take the velocity);
- reference and navigation result (``truth.nav``), 11 columns: GNSS week, second of week,
  latitude, longitude (deg), height (m), velocity north, east, down (m/s), roll, pitch, yaw
  (deg); 10 without the week;
- the configuration (``kf-gins.yaml``): ``imupath``, ``gnsspath``, ``starttime``, ``endtime``,
  ``initpos`` (deg, deg, m), ``initvel`` (m/s), ``initatt`` (deg), ``initposstd`` (m),
  ``initvelstd`` (m/s), ``initattstd`` (deg), and navsim's ``truthpath`` (the reference, read
  when ``--reference`` is not given). Paths are relative to the configuration's folder, else to
  the working folder, as KF-GINS takes them.

The roll, pitch and yaw 1-sigma of ``initattstd`` are taken as the attitude error's about north,
east and down (equal for a level start).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from navsim.foundations.config import load_yaml
from navsim.foundations.errors import LogError, ScenarioError
from navsim.replay.navlog import (
    GnssLog,
    NavLog,
    Start,
    Trajectory,
    check_gnss,
    check_times,
    imu_from,
    log_name,
    read_rows,
    rows_text,
    start_time,
    trim_gnss,
)

DEG = math.pi / 180.0
HINT_IMU = "KF-GINS IMU file: time (s), dtheta x y z (rad), dv x y z (m/s), one sample a line"
HINT_GNSS = ("KF-GINS GNSS file: time (s), lat (deg), lon (deg), height (m), sigma N E D (m), "
             "optionally vel N E D (m/s) and its sigma")
HINT_NAV = "KF-GINS navigation file: week, time (s), lat, lon (deg), h (m), vel N E D (m/s), roll pitch yaw (deg)"
#: the files :func:`write_kfgins` writes, by role
FILES = {"imu": "imu.txt", "gnss": "gnss.txt", "reference": "truth.nav", "config": "kf-gins.yaml"}
#: the start keys of the configuration and their units' factors to SI
START_KEYS = {"initpos": (DEG, DEG, 1.0), "initvel": (1.0, 1.0, 1.0), "initatt": (DEG, DEG, DEG),
              "initposstd": (1.0, 1.0, 1.0), "initvelstd": (1.0, 1.0, 1.0), "initattstd": (DEG, DEG, DEG)}


def read_imu(path) -> tuple:
    """``(rows, times, increments)``: the IMU file's absolute times and ``(N, 6)`` increments."""
    rows = read_rows(path, (7,), "IMU increments", hint=HINT_IMU)
    check_times(rows, rows.values[:, 0], "IMU")
    return rows, rows.values[:, 0], rows.values[:, 1:7]


def read_gnss(path, t0_s: float):
    """``(rows, GnssLog)`` of the GNSS file, times from ``t0_s``."""
    rows = read_rows(path, (7, 13), "GNSS fixes", hint=HINT_GNSS)
    v = rows.values
    check_times(rows, v[:, 0], "GNSS")
    vel = v[:, 7:10] if v.shape[1] == 13 else None
    g = GnssLog(v[:, 0] - t0_s, v[:, 1] * DEG, v[:, 2] * DEG, v[:, 3], v[:, 4:7], vel,
                v[:, 10:13] if vel is not None else None)
    check_gnss(rows, g)
    return rows, g


def read_nav(path, t0_s: float, what: str = "reference") -> Trajectory:
    """A ``.nav`` file (reference or navigation result), times from ``t0_s``."""
    rows = read_rows(path, (11, 10), what, hint=HINT_NAV)
    v = rows.values[:, 1:] if rows.values.shape[1] == 11 else rows.values
    check_times(rows, v[:, 0], what)
    return Trajectory(v[:, 0] - t0_s, v[:, 1] * DEG, v[:, 2] * DEG, v[:, 3], v[:, 4:7], v[:, 7:10] * DEG)


def read_config(path) -> dict:
    """The KF-GINS configuration (a mapping), its paths resolved; a :class:`LogError` names a
    missing key or file."""
    path = Path(path)
    try:
        cfg = load_yaml(path)
    except ScenarioError as exc:
        raise LogError(exc.args[0].split(": ", 1)[-1], file=str(path)) from None
    if not isinstance(cfg, dict):
        raise LogError("is not a KF-GINS configuration (a mapping with imupath, gnsspath, initpos, ...)",
                       file=str(path))
    out = dict(cfg)
    for key in ("imupath", "gnsspath", "truthpath"):
        if key in cfg and not (isinstance(cfg[key], str) and cfg[key].strip()):
            raise LogError(f"'{key}' is {cfg[key]!r}, not a file name", file=str(path))
        if key in cfg:
            out[key] = _resolved(cfg[key], path, key)
    for key in ("starttime", "endtime"):
        if key in cfg and (isinstance(cfg[key], bool) or not isinstance(cfg[key], (int, float))
                           or not math.isfinite(cfg[key])):
            raise LogError(f"'{key}' is {cfg[key]!r}, not a number of seconds", file=str(path))
    return out


def _resolved(name: str, config: Path, key: str) -> Path:
    for candidate in (config.parent / name, Path(name)):
        if candidate.is_file():
            return candidate
    raise LogError(f"'{key}: {name}' is not a file (looked beside the configuration and in the working folder)",
                   file=str(config))


def config_start(cfg: dict, path) -> Start | None:
    """The start of the configuration's ``init*`` keys (None without ``initpos``)."""
    if "initpos" not in cfg:
        return None
    v = {}
    for key, factors in START_KEYS.items():
        x = cfg.get(key)
        if x is None:
            v[key] = None
            continue
        if not (isinstance(x, list) and len(x) == 3 and all(isinstance(a, (int, float)) and not isinstance(a, bool)
                                                            and math.isfinite(a) for a in x)):
            raise LogError(f"'{key}' is {x!r}, not three numbers", file=str(path))
        if key.endswith("std") and min(x) < 0:
            raise LogError(f"'{key}' is {x!r}: a standard deviation is not negative", file=str(path))
        v[key] = np.array(x, float) * factors
    if v["initatt"] is None:
        raise LogError("has 'initpos' but no 'initatt'", file=str(path), hint="the start needs roll, pitch, yaw (deg)")
    vel = v["initvel"] if v["initvel"] is not None else np.zeros(3)
    return Start(float(v["initpos"][0]), float(v["initpos"][1]), float(v["initpos"][2]), vel, v["initatt"],
                 v["initposstd"], v["initvelstd"], v["initattstd"])


def read_kfgins(imu, gnss=None, reference=None, config=None) -> NavLog:
    """A KF-GINS dataset: ``imu`` (or the configuration ``config``, a ``.yaml``) names the IMU
    file; ``gnss`` and ``reference`` the others (default: the configuration's ``gnsspath`` and
    ``truthpath``). The start time is the configuration's ``starttime`` when later than the
    first sample, else one IMU interval before the first sample; samples after ``endtime``
    (when positive) are left out.

    Raises
    ------
    LogError
        A file or line that cannot be read, naming it.
    """
    cfg = read_config(config) if config is not None else {}
    imu = imu or cfg.get("imupath")
    gnss = gnss or cfg.get("gnsspath")
    reference = reference or cfg.get("truthpath")
    if imu is None or gnss is None:
        raise LogError(f"names no {'IMU' if imu is None else 'GNSS'} file ({'imupath' if imu is None else 'gnsspath'})",
                       file=str(config or imu), hint="give the files on the command line (LOG, --gnss FILE)")
    rows, t, inc = read_imu(imu)
    if len(t) < 3:
        raise LogError(f"holds {len(t)} IMU samples, too few to replay", file=str(imu))
    t0 = start_time(cfg.get("starttime"), t)
    end = cfg["endtime"] if cfg.get("endtime", -1) > 0 else None
    log_imu = imu_from(rows, t, inc[:, :3], inc[:, 3:], t0, end)
    notes = _config_notes(cfg, t0)
    g_rows, g = read_gnss(gnss, t0)
    try:
        g = trim_gnss(g, log_imu.t_s[-1], notes)
    except ValueError as exc:
        raise LogError(str(exc), file=str(gnss), hint="the GNSS and IMU times must be on one clock") from None
    ref = read_nav(reference, t0) if reference is not None else None
    files = {"imu": str(imu), "gnss": str(gnss)} | ({"reference": str(reference)} if reference else {}) \
        | ({"config": str(config)} if config else {})
    return NavLog(log_name(imu), "kfgins", t0, log_imu, g, ref, config_start(cfg, config), files, notes)


def _config_notes(cfg: dict, t0: float) -> list:
    """What of the configuration the replay does not take, for the user."""
    notes = []
    start = cfg.get("starttime")
    if start is not None and abs(start - t0) > 1e-6:
        notes.append(f"starttime {start} is not an IMU sample's time: the replay starts at {t0!r}, the last sample "
                     "before it (or one interval before the first)")
    lever = cfg.get("antlever")
    if isinstance(lever, list) and any(isinstance(x, (int, float)) and x for x in lever):
        notes.append(f"antlever {lever} not applied: the fixes are taken at the IMU (model the lever arm in the "
                     "scenario's filter, or give fixes at the IMU)")
    if isinstance(cfg.get("imunoise"), dict):
        notes.append("imunoise not read: the filters' IMU model is the scenario's (--set estimators[LABEL].noise...)")
    return notes


def write_kfgins(folder, log: NavLog) -> dict:
    """Write ``log`` as a KF-GINS dataset in ``folder``: ``imu.txt``, ``gnss.txt`` (13 columns
    with velocity), ``truth.nav`` (with a reference) and ``kf-gins.yaml`` (the start, the paths).
    Returns role -> path written. Numbers are written to read back bit for bit."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    imu, g, t0 = log.imu, log.gnss, log.t0_s
    out = {role: folder / FILES[role] for role in ("imu", "gnss")}
    out["imu"].write_text(rows_text(np.c_[imu.t_s[1:] + t0, imu.dtheta_b_rad[1:], imu.dv_b_mps[1:]]))
    cols = [g.t_s + t0, np.degrees(g.lat_rad), np.degrees(g.lon_rad), g.h_m, g.sigma_ned_m]
    if g.vel_n_mps is not None:
        cols += [g.vel_n_mps, g.sigma_vel_mps]
    out["gnss"].write_text(rows_text(np.column_stack(cols)))
    if log.reference is not None:
        r = log.reference
        out["reference"] = folder / FILES["reference"]
        out["reference"].write_text(rows_text(np.column_stack(
            [np.zeros_like(r.t_s), r.t_s + t0, np.degrees(r.lat_rad), np.degrees(r.lon_rad), r.h_m, r.vel_n_mps,
             np.degrees(r.euler_rad)])))
    out["config"] = folder / FILES["config"]
    out["config"].write_text(_config_text(log, out))
    return out


def _config_text(log: NavLog, files: dict) -> str:
    lines = ["# KF-GINS configuration written by navsim (navsim replay reads it; truthpath is navsim's)",
             f"imupath: {files['imu'].name}", f"gnsspath: {files['gnss'].name}"]
    if "reference" in files:
        lines.append(f"truthpath: {files['reference'].name}")
    lines += ["imudatalen: 7", f"imudatarate: {1.0 / log.imu.dt_s!r}"]
    return "\n".join(lines) + "\n" + start_text(log)


def start_text(log: NavLog) -> str:
    """The configuration's time span and start keys (``starttime``, ``endtime``, ``initpos``,
    ..., ``initattstd``) of ``log``, as YAML lines that read back bit for bit."""
    lines = [f"starttime: {log.t0_s!r}", "endtime: -1"]
    s = log.start
    if s is not None:
        vec = lambda x: "[" + ", ".join(repr(float(a)) for a in x) + "]"
        lines += [f"initpos: {vec([math.degrees(s.lat_rad), math.degrees(s.lon_rad), s.h_m])}",
                  f"initvel: {vec(s.vel_n_mps)}", f"initatt: {vec(np.degrees(s.euler_rad))}"]
        for key, x in (("initposstd", s.sigma_pos_m), ("initvelstd", s.sigma_vel_mps),
                       ("initattstd", None if s.sigma_att_rad is None else np.degrees(s.sigma_att_rad))):
            if x is not None:
                lines.append(f"{key}: {vec(x)}")
    return "\n".join(lines) + "\n"
