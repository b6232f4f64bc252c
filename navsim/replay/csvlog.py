"""A log as plain CSV files whose header names each column and its unit: :func:`read_csv_log`,
:func:`write_csv_log`.

One file per stream, comma-separated, the first line the header, ``name[unit]`` per column
(``time[s],lat[deg],...``), in any order; units are those of :data:`navsim.sensors.units.UNITS`
for the column's dimension (:data:`COLUMNS`). The IMU file holds either increments
(``dtheta_x..z`` angle, ``dv_x..z`` speed) or rates (``gyro_x..z`` angular rate, ``accel_x..z``
acceleration, each the mean over the interval ending at its time, as PX4 logs them); the GNSS
file ``time, lat, lon, height, sigma_n, sigma_e, sigma_d`` and optionally ``vel_n, vel_e, vel_d,
sigma_vn, sigma_ve, sigma_vd``; the reference ``time, lat, lon, height, vel_n, vel_e, vel_d,
roll, pitch, yaw``. The start, when given, is a YAML file with KF-GINS's keys
(:mod:`navsim.replay.kfgins`: ``starttime``, ``initpos``, ..., ``initattstd``).
"""

from __future__ import annotations

import re
from difflib import get_close_matches
from pathlib import Path

import numpy as np

from navsim.foundations.errors import LogError
from navsim.replay.kfgins import config_start, read_config, start_text
from navsim.replay.navlog import GnssLog, NavLog, Rows, Trajectory, imu_from, log_name, read_rows, rows_text, start_time
from navsim.replay.navlog import check_gnss, check_times, trim_gnss
from navsim.sensors.units import UNITS

_XYZ = ("x", "y", "z")
_NED = ("n", "e", "d")
#: every column a CSV log may hold: name -> its dimension (:data:`navsim.sensors.units.UNITS`)
COLUMNS = {"time": "time", "lat": "angle", "lon": "angle", "height": "length",
           **{f"sigma_{a}": "length" for a in _NED}, **{f"vel_{a}": "speed" for a in _NED},
           **{f"sigma_v{a}": "speed" for a in _NED}, "roll": "angle", "pitch": "angle", "yaw": "angle",
           **{f"dtheta_{a}": "angle" for a in _XYZ}, **{f"dv_{a}": "speed" for a in _XYZ},
           **{f"gyro_{a}": "angular_rate" for a in _XYZ}, **{f"accel_{a}": "acceleration" for a in _XYZ}}
#: the layouts each stream's file may have: (the columns required, the optional ones: all or none)
STREAMS = {
    "imu": ((("time", *(f"dtheta_{a}" for a in _XYZ), *(f"dv_{a}" for a in _XYZ)), ()),
            (("time", *(f"gyro_{a}" for a in _XYZ), *(f"accel_{a}" for a in _XYZ)), ())),
    "gnss": ((("time", "lat", "lon", "height", "sigma_n", "sigma_e", "sigma_d"),
              (*(f"vel_{a}" for a in _NED), *(f"sigma_v{a}" for a in _NED))),),
    "reference": ((("time", "lat", "lon", "height", "vel_n", "vel_e", "vel_d", "roll", "pitch", "yaw"), ()),),
}
#: the files :func:`write_csv_log` writes, by role
FILES = {"imu": "imu.csv", "gnss": "gnss.csv", "reference": "reference.csv", "start": "start.yaml"}
_HEADER = re.compile(r"^\s*([A-Za-z_]\w*)\s*\[\s*([^\]]*?)\s*\]\s*$")


def read_header(path: Path, stream: str) -> tuple[dict, int]:
    """Column name -> (index, factor to SI) of a CSV file's header, and the header's line number."""
    try:
        with path.open(encoding="utf-8-sig", errors="replace") as f:
            numbered = ((n + 1, line) for n, line in enumerate(f))
            n, header = next(((n, line) for n, line in numbered if line.strip() and line.lstrip()[0] != "#"), (0, ""))
    except OSError as exc:
        raise LogError(f"cannot be read ({exc.strerror or exc})", file=str(path)) from None
    if not header:
        raise LogError(f"holds no {stream} (an empty file)", file=str(path))
    columns = {}
    for i, cell in enumerate(header.strip().split(",")):
        m = _HEADER.match(cell)
        if not m:
            raise LogError(f"header column {i + 1} is {cell.strip()!r}, not name[unit]", file=f"{path}:{n}",
                           hint=f"name each column and its unit: {', '.join(_expected(stream))}")
        name, unit = m.groups()
        if name not in COLUMNS:
            close = get_close_matches(name, list(COLUMNS), 1)
            raise LogError(f"header column {i + 1} is '{name}', no column navsim reads", file=f"{path}:{n}",
                           hint=f"did you mean '{close[0]}'?" if close else f"the {stream} columns: "
                           + ", ".join(_expected(stream)))
        units = UNITS[COLUMNS[name]]
        if unit not in units:
            raise LogError(f"column '{name}' is in '{unit}', not a unit of {COLUMNS[name].replace('_', ' ')}",
                           file=f"{path}:{n}", hint=f"{name}[{'|'.join(units)}]")
        if name in columns:
            raise LogError(f"header column {i + 1} is '{name}' again", file=f"{path}:{n}")
        columns[name] = (i, units[unit])
    return columns, n


def _expected(stream: str) -> list[str]:
    """The columns of the stream's layouts, each with its first unit."""
    names = dict.fromkeys(c for req, opt in STREAMS[stream] for c in (*req, *opt))
    return [f"{c}[{next(iter(UNITS[COLUMNS[c]]))}]" for c in names]


def read_stream(path, stream: str) -> tuple[Rows, dict]:
    """The rows of a CSV file of ``stream`` and its columns by name, SI: a :class:`LogError` for
    a missing column (naming the header line), a short row, a value that is not a number, NaN."""
    path = Path(path)
    columns, n = read_header(path, stream)
    layout = next((lay for lay in STREAMS[stream] if set(lay[0]) <= set(columns)), None)
    if layout is None:
        closest = min(STREAMS[stream], key=lambda lay: len(set(lay[0]) - set(columns)))[0]
        missing = [c for c in closest if c not in columns]
        raise LogError(f"lacks the column(s) {', '.join(missing)} ({stream})", file=f"{path}:{n}",
                       hint="the columns: " + ", ".join(_expected(stream)))
    opt = layout[1]
    partial = [c for c in opt if c not in columns] if any(c in columns for c in opt) else []
    if partial:
        raise LogError(f"has some of {', '.join(opt)} but not {', '.join(partial)}", file=f"{path}:{n}")
    rows = read_rows(path, (len(columns),), f"{stream} samples", sep=",", skip=n)
    out = {name: rows.values[:, i] * factor for name, (i, factor) in columns.items()}
    check_times(rows, out["time"], stream)
    return rows, out


def _stack(cols: dict, names) -> np.ndarray:
    return np.column_stack([cols[n] for n in names])


def read_imu_csv(path) -> tuple[Rows, np.ndarray, np.ndarray, np.ndarray]:
    """``(rows, time, dtheta, dv)``: increments as written, or rates times the interval ending at
    each sample (the first sample, whose interval is unknown, is the start)."""
    rows, c = read_stream(path, "imu")
    t = c["time"]
    if "dtheta_x" in c:
        return rows, t, _stack(c, [f"dtheta_{a}" for a in _XYZ]), _stack(c, [f"dv_{a}" for a in _XYZ])
    dt = np.r_[np.nan, np.diff(t)][:, None]
    return rows, t, _stack(c, [f"gyro_{a}" for a in _XYZ]) * dt, _stack(c, [f"accel_{a}" for a in _XYZ]) * dt


def read_csv_log(imu, gnss, reference=None, start=None) -> NavLog:
    """A CSV log: the IMU, GNSS and (optionally) reference files, and a start file (YAML with
    KF-GINS's keys). The start time is the start file's ``starttime``, else one IMU interval
    before the first sample (for increments) or the first sample (for rates)."""
    if gnss is None:
        raise LogError("no GNSS file: give --gnss FILE", file=str(imu))
    rows, t, dth, dv = read_imu_csv(imu)
    if len(t) < 3:
        raise LogError(f"holds {len(t)} IMU samples, too few to replay", file=str(imu))
    cfg = read_config(start) if start is not None else {}
    rates = np.isnan(dth[0, 0])        # the first rate's interval is unknown: at the earliest, the start
    t0 = start_time(cfg.get("starttime"), t)
    t0 = max(t0, float(t[0])) if rates else t0
    log_imu = imu_from(rows, t, dth, dv, t0, cfg["endtime"] if cfg.get("endtime", -1) > 0 else None)
    g_rows, g = read_stream(gnss, "gnss")
    vel = "vel_n" in g
    fixes = GnssLog(g["time"] - t0, g["lat"], g["lon"], g["height"], _stack(g, [f"sigma_{a}" for a in _NED]),
                    _stack(g, [f"vel_{a}" for a in _NED]) if vel else None,
                    _stack(g, [f"sigma_v{a}" for a in _NED]) if vel else None)
    check_gnss(g_rows, fixes)
    notes = []
    try:
        fixes = trim_gnss(fixes, log_imu.t_s[-1], notes)
    except ValueError as exc:
        raise LogError(str(exc), file=str(gnss), hint="the GNSS and IMU times must be on one clock") from None
    ref = None
    if reference is not None:
        _, r = read_stream(reference, "reference")
        ref = Trajectory(r["time"] - t0, r["lat"], r["lon"], r["height"], _stack(r, ["vel_n", "vel_e", "vel_d"]),
                         _stack(r, ["roll", "pitch", "yaw"]))
    files = {"imu": str(imu), "gnss": str(gnss)} | ({"reference": str(reference)} if reference else {}) \
        | ({"start": str(start)} if start else {})
    return NavLog(log_name(imu), "csv", t0, log_imu, fixes, ref, config_start(cfg, start), files, notes)


def _write(path: Path, header: list[str], a: np.ndarray) -> None:
    path.write_text(",".join(header) + "\n" + rows_text(a, ","))


def write_csv_log(folder, log: NavLog) -> dict:
    """Write ``log`` as CSV files in ``folder``: ``imu.csv`` (increments, rad and m/s),
    ``gnss.csv``, ``reference.csv`` (with a reference, angles in deg) and ``start.yaml``; returns
    role -> path. Numbers are written to read back bit for bit (degrees to the last bit of the
    conversion)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    imu, g, t0 = log.imu, log.gnss, log.t0_s
    out = {role: folder / FILES[role] for role in ("imu", "gnss")}
    _write(out["imu"], ["time[s]"] + [f"dtheta_{a}[rad]" for a in _XYZ] + [f"dv_{a}[m/s]" for a in _XYZ],
           np.c_[imu.t_s[1:] + t0, imu.dtheta_b_rad[1:], imu.dv_b_mps[1:]])
    head = ["time[s]", "lat[rad]", "lon[rad]", "height[m]"] + [f"sigma_{a}[m]" for a in _NED]
    cols = [g.t_s + t0, g.lat_rad, g.lon_rad, g.h_m, g.sigma_ned_m]
    if g.vel_n_mps is not None:
        head += [f"vel_{a}[m/s]" for a in _NED] + [f"sigma_v{a}[m/s]" for a in _NED]
        cols += [g.vel_n_mps, g.sigma_vel_mps]
    _write(out["gnss"], head, np.column_stack(cols))
    if log.reference is not None:
        r = log.reference
        out["reference"] = folder / FILES["reference"]
        _write(out["reference"], ["time[s]", "lat[rad]", "lon[rad]", "height[m]", "vel_n[m/s]", "vel_e[m/s]",
                                  "vel_d[m/s]", "roll[rad]", "pitch[rad]", "yaw[rad]"],
               np.column_stack([r.t_s + t0, r.lat_rad, r.lon_rad, r.h_m, r.vel_n_mps, r.euler_rad]))
    out["start"] = folder / FILES["start"]
    out["start"].write_text("# the start of the log written by navsim (KF-GINS's keys)\n" + start_text(log))
    return out
