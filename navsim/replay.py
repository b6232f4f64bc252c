"""Replay of a real PX4 flight log (ULog) through navsim's estimators.

:func:`load_ulog` reads the log with ``pyulog`` and checks it: the IMU (``sensor_combined``:
gyro rad/s, accelerometer m/s², ~250 Hz), the magnetometer (``sensor_combined.magnetometer_ga``
or ``vehicle_magnetometer``, gauss), the barometric altitude when the log has one
(``sensor_combined.baro_alt_meter`` or ``vehicle_air_data``) and PX4's own attitude estimate
(``vehicle_attitude.q``, scalar first, body FRD to NED). Times are seconds from the first
``sensor_combined`` sample; values are SI (1 gauss = 1e-4 T).

:func:`replay` resamples the IMU to a uniform grid (increments ``dtheta_b``, ``dv_b``), puts each
magnetometer and baro sample on the first grid time at or after its own time, aligns the
estimator coarsely from the first second of data (:func:`coarse_alignment`), drives it as
:func:`navsim.montecarlo.run_batch` does (``propagate`` up to each epoch, ``epoch`` every
``period_s``) and records its roll, pitch and yaw with PX4's, slerped to the same times.
:func:`replay_metrics` scores the differences after ``settle_s``.

Every problem with a log raises :class:`navsim.errors.LogError` naming the file, what is missing
and a hint; what the replay works around (dropped samples, no baro, no position) is listed in
``ReplayLog.notes``.
"""

from __future__ import annotations

import gzip
import inspect
import io
import math
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navsim.errors import LogError, UsageError
from navsim.estimators import base
from navsim.montecarlo import Driver, InitialErrors
from navsim.sensors.base import SensorData
from navsim.strapdown import NavState
from navsim.transform import dcm_from_euler, euler_from_dcm, wrap_angle

GAUSS_T = 1e-4                    #: tesla per gauss
TIMESTAMP_INVALID = 2**31 - 1     #: PX4's RELATIVE_TIMESTAMP_INVALID (no sample of that sensor)
GAP_WARN_PERIODS = 5              #: a gap longer than this many IMU periods is listed in the notes
GAP_MAX_S = 0.5                   #: a longer gap is an error (the IMU cannot be bridged)
MIN_DURATION_S = 5.0              #: the shortest IMU record replayed
ALIGN_S = 1.0                     #: default length of the coarse-alignment window
RECORD_S = 0.02                   #: the solution is compared with PX4's at 50 Hz
#: without GNSS, an attitude EKF that takes it levels on a zero horizontal velocity of this sigma
NO_GNSS_SIGMA_MPS = 1.0
ALIGN_GYRO_MAX_RPS = 0.05         #: above this rate in the window the vehicle was not still
#: 1-sigma of the coarse alignment: attitude about N, E, D (rad), velocity (m/s), position N, E, D
#: (m): the accelerometer levels to ~1° (bias of ~0.1 m/s²), the magnetometer heading to ~5°
#: (uncalibrated iron), the vehicle is assumed still, and without GNSS the position is arbitrary.
ALIGN_SIGMA = {"att_rad": np.radians([1.0, 1.0, 5.0]), "vel_mps": np.array([0.3, 0.3, 0.3]),
               "pos_m": np.array([10.0, 10.0, 5.0])}
_ULOG_MAGIC = b"ULog\x01\x12\x35"
_ULOG_TYPES = frozenset(b"BFIMPQARDLCSO")
_HINT_LOG = ("replay a complete PX4 ULog (the shipped example: tests/data/px4_quad_real_69s.ulg.gz); "
             "--allow-damaged replays what a truncated or corrupt log still holds")


@dataclass
class ReplayLog:
    """A PX4 log's streams, SI, times in seconds from the first IMU sample (``t0_us``)."""

    path: Path
    t0_us: int
    imu_t_s: np.ndarray            #: (N,) sample times (end of each sample's interval)
    omega_ib_b_rps: np.ndarray     #: (N, 3) gyro, mean rate over the interval, body FRD
    f_ib_b_mps2: np.ndarray        #: (N, 3) accelerometer specific force, body FRD
    mag_t_s: np.ndarray            #: (M,) own sample times (distinct samples only)
    mag_b_T: np.ndarray            #: (M, 3) magnetometer, tesla, body FRD
    baro_t_s: np.ndarray           #: (K,) empty when the log has no barometer
    h_baro_m: np.ndarray           #: (K,) barometric altitude
    att_t_s: np.ndarray            #: (A,) PX4's attitude estimate times
    quat_nb_px4: np.ndarray        #: (A, 4) PX4's attitude, scalar first, body FRD to NED
    lat_rad: float | None = None   #: position of the local frame's origin, if the log has one
    lon_rad: float | None = None
    h_ref_m: float | None = None   #: height of the first local position, if global
    declination_rad: float = 0.0
    declination_source: str = "none"
    gaps: list = field(default_factory=list)     #: (t_s, duration_s) of IMU gaps
    notes: list = field(default_factory=list)    #: what the replay works around, for the user
    info: dict = field(default_factory=dict)     #: the log's software, hardware, estimator group

    @property
    def duration_s(self) -> float:
        return float(self.imu_t_s[-1] - self.imu_t_s[0])

    @property
    def imu_rate_hz(self) -> float:
        """Nominal IMU rate: the inverse of the median sample interval."""
        return float(1.0 / np.median(np.diff(self.imu_t_s)))

    @property
    def mag_rate_hz(self) -> float:
        return float((len(self.mag_t_s) - 1) / max(np.ptp(self.mag_t_s), 1e-9))

    @property
    def baro_rate_hz(self) -> float:
        return float((len(self.baro_t_s) - 1) / np.ptp(self.baro_t_s)) if len(self.baro_t_s) > 1 else 0.0


# --- reading and checking -------------------------------------------------------------------

def check_structure(data: bytes) -> str | None:
    """Walk the ULog messages of ``data``: what is wrong with the file's framing, or None.

    PX4's logger writes whole messages, so a complete log ends exactly at a message boundary;
    a copy cut short ends inside one. Bytes of an unknown message type stop the walk (pyulog
    judges those: it resynchronises and flags the file corrupt)."""
    if len(data) < 16 or data[:7] != _ULOG_MAGIC:
        return "is not a ULog file (no ULog header)"
    off, n = 16, len(data)
    while off + 3 <= n:
        size, kind = struct.unpack_from("<HB", data, off)
        if kind not in _ULOG_TYPES:
            return None
        if off + 3 + size > n:
            return (f"is truncated: its last message ('{chr(kind)}', {size} bytes at byte {off}) "
                    f"is cut off after {n - off - 3} bytes")
        off += 3 + size
    return None if off == n else f"is truncated: it ends inside a message header at byte {off}"


def _read_ulog(path: Path, allow_damaged: bool, notes: list):
    from pyulog import ULog
    from pyulog.core import ULogException
    if not path.is_file():
        raise LogError("no such file", file=str(path), hint=_HINT_LOG)
    data = path.read_bytes()
    if data[:2] == b"\x1f\x8b":                      # a gzip-compressed log (.ulg.gz)
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:
            raise LogError(f"cannot be decompressed ({exc})", file=str(path), hint=_HINT_LOG) from exc
    problem = check_structure(data)
    if problem and (not allow_damaged or problem.startswith("is not")):
        raise LogError(problem, file=str(path), hint=_HINT_LOG)
    try:
        ulog = ULog(io.BytesIO(data))
    except (ULogException, ValueError, IndexError, struct.error, UnicodeDecodeError) as exc:
        raise LogError(f"cannot be read as a ULog ({exc})", file=str(path), hint=_HINT_LOG) from exc
    if ulog.file_corruption and not allow_damaged:
        raise LogError("is corrupt (pyulog skipped unreadable bytes)", file=str(path), hint=_HINT_LOG)
    if problem or ulog.file_corruption:
        notes.append(f"damaged log: {problem or 'corrupt'}; replaying what it holds")
    return ulog


def _topics(ulog) -> dict:
    """Topic name -> its fields (the first instance of each topic)."""
    out = {}
    for d in sorted(ulog.data_list, key=lambda d: d.multi_id):
        if d.name not in out and len(d.data.get("timestamp", ())):
            out[d.name] = d.data
    return out


def _vec(names: str, n: int) -> list[str]:
    return [f"{names}[{i}]" for i in range(n)]


def require(topics: dict, topic: str, fields: list[str], path, why: str) -> dict:
    """``topics[topic]`` after checking it has ``fields``; a :class:`LogError` naming the topic
    or the fields missing otherwise."""
    if topic not in topics:
        raise LogError(f"has no '{topic}' messages ({why})", file=str(path),
                       hint=f"log the topic '{topic}' (PX4 logger profile) or replay another log; "
                            f"the log has: {', '.join(sorted(topics)) or 'no data at all'}")
    missing = [f for f in fields if f not in topics[topic]]
    if missing:
        raise LogError(f"'{topic}' lacks the field(s) {', '.join(missing)} ({why})", file=str(path),
                       hint="a PX4 version whose messages navsim does not know; its fields: "
                            + ", ".join(sorted(topics[topic])))
    return topics[topic]


def _columns(data: dict, names: list[str]) -> np.ndarray:
    return np.stack([np.asarray(data[n], float) for n in names], axis=-1)


def _relative_times(data: dict, rel_field: str, t0_us: int) -> tuple[np.ndarray, np.ndarray]:
    """Own sample times (s) of a sensor logged inside ``sensor_combined`` and the mask of rows
    that carry a sample (``timestamp_relative`` not PX4's invalid marker)."""
    rel = np.asarray(data[rel_field], np.int64)
    ok = rel != TIMESTAMP_INVALID
    return (np.asarray(data["timestamp"], np.int64) + rel - t0_us) * 1e-6, ok


def _distinct(t_s: np.ndarray, ok: np.ndarray, *values: np.ndarray):
    """The distinct samples (first row of each own timestamp), in time order."""
    t_s = t_s[ok]
    _, first = np.unique(t_s, return_index=True)
    return (t_s[first], *(v[ok][first] for v in values))


def _magnetometer(topics, sc, t0_us, path):
    if "magnetometer_ga[0]" in sc and "magnetometer_timestamp_relative" in sc:
        t, ok = _relative_times(sc, "magnetometer_timestamp_relative", t0_us)
        t, m = _distinct(t, ok, _columns(sc, _vec("magnetometer_ga", 3)))
    else:
        mag = require(topics, "vehicle_magnetometer", _vec("magnetometer_ga", 3), path,
                      "the magnetometer: sensor_combined has no magnetometer_ga either")
        t = (np.asarray(mag["timestamp"], np.int64) - t0_us) * 1e-6
        m = _columns(mag, _vec("magnetometer_ga", 3))
    return t, m * GAUSS_T


def _barometer(topics, sc, t0_us, notes):
    if "baro_alt_meter" in sc and "baro_timestamp_relative" in sc:
        t, ok = _relative_times(sc, "baro_timestamp_relative", t0_us)
        t, h = _distinct(t, ok, np.asarray(sc["baro_alt_meter"], float))
    elif "vehicle_air_data" in topics and "baro_alt_meter" in topics["vehicle_air_data"]:
        air = topics["vehicle_air_data"]
        t = (np.asarray(air["timestamp"], np.int64) - t0_us) * 1e-6
        h = np.asarray(air["baro_alt_meter"], float)
    else:
        t = h = np.zeros(0)
    if len(t) == 0:
        notes.append("no barometer samples (PX4 marked them invalid or did not log them): "
                     "the estimator runs without baro")
    return t, h


def _declination(params: dict, notes: list) -> tuple[float, str]:
    """The declination PX4's attitude estimator used: ``EKF2_MAG_DECL`` with ekf2
    (``SYS_MC_EST_GROUP`` 2), ``ATT_MAG_DECL`` with attitude_estimator_q, degrees."""
    names = ["EKF2_MAG_DECL", "ATT_MAG_DECL"]
    if params.get("SYS_MC_EST_GROUP", 2) != 2:
        names.reverse()
    for name in names:
        if name in params:
            return math.radians(float(params[name])), name
    notes.append("the log has no magnetic declination parameter: 0° assumed (yaw is magnetic)")
    return 0.0, "none"


def _position(topics, notes) -> tuple:
    """Origin of PX4's local frame (lat, lon rad) and the first height, when global."""
    lp = topics.get("vehicle_local_position")
    lat = lon = h = None
    if lp is not None and {"ref_lat", "ref_lon", "xy_global"} <= set(lp):
        la, lo = np.asarray(lp["ref_lat"], float), np.asarray(lp["ref_lon"], float)
        ok = (np.asarray(lp["xy_global"], bool) & (np.abs(la) <= 90) & (np.abs(lo) <= 180)
              & ((la != 0) | (lo != 0)))          # 0, 0: PX4 had no reference yet
        if np.any(ok):
            lat, lon = math.radians(float(np.median(la[ok]))), math.radians(float(np.median(lo[ok])))
    if lp is not None and "ref_alt" in lp and np.any(np.asarray(lp.get("z_global", [0]), bool)):
        k = int(np.argmax(np.asarray(lp["z_global"], bool)))
        h = float(lp["ref_alt"][k]) - float(lp["z"][k])
    if lat is None:
        notes.append("no global position in the log (vehicle_local_position.xy_global false): "
                     "latitude and longitude 0 assumed (they only set gravity and Earth rate)")
    return lat, lon, h


def _imu_gaps(t_s: np.ndarray, path, allow_damaged: bool, notes: list) -> list:
    dt = np.diff(t_s)
    if np.any(dt <= 0):
        raise LogError(f"sensor_combined timestamps go backwards at t = {t_s[1:][dt <= 0][0]:.3f} s",
                       file=str(path), hint=_HINT_LOG)
    nominal = float(np.median(dt))
    idx = np.flatnonzero(dt > GAP_WARN_PERIODS * nominal)
    gaps = [(float(t_s[i]), float(dt[i])) for i in idx]
    if gaps:
        notes.append(f"{len(gaps)} IMU gap(s) over {GAP_WARN_PERIODS} periods (longest "
                     f"{max(g for _, g in gaps) * 1e3:.0f} ms at t = {max(gaps, key=lambda x: x[1])[0]:.2f} s): "
                     "bridged with the next sample's rates")
    long = [g for g in gaps if g[1] > GAP_MAX_S]
    if long and not allow_damaged:
        raise LogError(f"sensor_combined has a {long[0][1]:.2f} s gap at t = {long[0][0]:.2f} s "
                       f"(over {GAP_MAX_S} s cannot be bridged)", file=str(path), hint=_HINT_LOG)
    return gaps


def load_ulog(path, allow_damaged: bool = False) -> ReplayLog:
    """Read and check a PX4 ULog for :func:`replay`.

    Parameters
    ----------
    path : str or Path
        The ``.ulg`` file.
    allow_damaged : bool
        Replay what a truncated or corrupt log still holds (noted in ``notes``) instead of
        refusing it.

    Raises
    ------
    LogError
        The file is missing, truncated, corrupt, lacks ``sensor_combined``, ``vehicle_attitude``,
        a magnetometer or a field of theirs, or holds less than ``MIN_DURATION_S`` of IMU data.
    """
    path = Path(path)
    notes: list[str] = []
    ulog = _read_ulog(path, allow_damaged, notes)
    topics = _topics(ulog)
    sc = require(topics, "sensor_combined", ["timestamp"] + _vec("gyro_rad", 3)
                 + _vec("accelerometer_m_s2", 3), path, "the IMU")
    va = require(topics, "vehicle_attitude", ["timestamp"] + _vec("q", 4), path,
                 "PX4's attitude estimate, the reference")
    t_us = np.asarray(sc["timestamp"], np.int64)
    t0_us = int(t_us[0])
    imu_t = (t_us - t0_us) * 1e-6
    if len(imu_t) < 2 or imu_t[-1] < MIN_DURATION_S:
        raise LogError(f"sensor_combined holds {imu_t[-1] if len(imu_t) else 0:.2f} s of IMU data "
                       f"({len(imu_t)} samples); the replay needs {MIN_DURATION_S:.0f} s",
                       file=str(path), hint=_HINT_LOG)
    gaps = _imu_gaps(imu_t, path, allow_damaged, notes)
    mag_t, mag_T = _magnetometer(topics, sc, t0_us, path)
    if len(mag_t) < 2:
        raise LogError(f"has {len(mag_t)} magnetometer sample(s)", file=str(path), hint=_HINT_LOG)
    baro_t, baro_h = _barometer(topics, sc, t0_us, notes)
    att_t = (np.asarray(va["timestamp"], np.int64) - t0_us) * 1e-6
    att_t, quat = _distinct(att_t, np.ones(len(att_t), bool), _columns(va, _vec("q", 4)))
    if len(att_t) < 2:
        raise LogError(f"vehicle_attitude has {len(att_t)} sample(s)", file=str(path), hint=_HINT_LOG)
    params = ulog.initial_parameters
    decl, decl_src = _declination(params, notes)
    lat, lon, h = _position(topics, notes)
    if ulog.dropouts:
        notes.append(f"the logger dropped data {len(ulog.dropouts)} time(s), "
                     f"{sum(d.duration for d in ulog.dropouts)} ms in all")
    info = {k: ulog.msg_info_dict.get(k) for k in ("sys_name", "ver_hw", "ver_sw")}
    info["SYS_MC_EST_GROUP"] = params.get("SYS_MC_EST_GROUP")
    return ReplayLog(path=path, t0_us=t0_us, imu_t_s=imu_t, omega_ib_b_rps=_columns(sc, _vec("gyro_rad", 3)),
                     f_ib_b_mps2=_columns(sc, _vec("accelerometer_m_s2", 3)), mag_t_s=mag_t, mag_b_T=mag_T,
                     baro_t_s=baro_t, h_baro_m=baro_h, att_t_s=att_t,
                     quat_nb_px4=quat / np.linalg.norm(quat, axis=-1, keepdims=True), lat_rad=lat,
                     lon_rad=lon, h_ref_m=h, declination_rad=decl, declination_source=decl_src,
                     gaps=gaps, notes=notes, info=info)


# --- IMU increments and the sensor streams on its grid -----------------------------------------

def imu_increments(t_s: np.ndarray, omega_b: np.ndarray, f_b: np.ndarray, rate_hz: float):
    """Increments on a uniform grid from samples at jittered times.

    Each sample is PX4's mean rate over the interval ending at its timestamp, so the rates are
    piecewise constant between timestamps and their integrals ``theta(t)``, ``v(t)`` piecewise
    linear: sampled at the grid times by linear interpolation, they are exact for any grid, and
    the increments sum to the integral of the logged rates whatever the jitter. Across a gap
    the sample after it holds its rate over the whole gap.

    Returns
    -------
    grid_t_s : (N,) ``t_s[0] + j / rate_hz``
    dtheta_b_rad, dv_b_mps : (N, 3) the increment over ``(grid[j-1], grid[j]]``; row 0 is zero.
    """
    dt = 1.0 / rate_hz
    grid = t_s[0] + dt * np.arange(int(math.floor((t_s[-1] - t_s[0]) / dt + 1e-9)) + 1)
    step = np.diff(t_s)[:, None]

    def increments(rate):
        cum = np.concatenate([np.zeros((1, 3)), np.cumsum(rate[1:] * step, axis=0)])
        at = np.stack([np.interp(grid, t_s, cum[:, j]) for j in range(3)], axis=-1)
        return np.diff(at, axis=0, prepend=at[:1])
    return grid, increments(omega_b), increments(f_b)


def snap_to_grid(t_s: np.ndarray, grid_t_s: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Index of the first grid time at or after each time (``len(grid)`` past its end)."""
    return np.searchsorted(grid_t_s, t_s - tol, side="left")


def on_grid(name: str, kind: str, t_s, values: dict, grid_t_s) -> SensorData:
    """A sensor's samples moved to the grid (first grid time at or after each), one batch run.
    Samples past the grid's end are dropped; of several falling on one grid time (a grid slower
    than the sensor) the latest is kept."""
    idx = snap_to_grid(np.asarray(t_s), grid_t_s)
    keep = idx < len(grid_t_s)
    idx = idx[keep]
    last = np.r_[idx[1:] != idx[:-1], True] if len(idx) else np.zeros(0, bool)
    vals = {k: np.asarray(v)[keep][last][None] for k, v in values.items()}
    return SensorData(name=name, kind=kind, t_s=grid_t_s[idx[last]], values=vals,
                      valid=np.ones((1, int(last.sum())), bool),
                      meta={"rate_hz": float(len(idx) / max(np.ptp(grid_t_s), 1e-9)), "source": "log"})


def sensor_streams(log: ReplayLog, grid_t_s: np.ndarray) -> dict:
    """The magnetometer (``"mag"``, ``mag_b_T``) and, if the log has one, the baro (``"baro"``,
    ``h_baro_m``) as :class:`SensorData` on the IMU grid."""
    out = {"mag": on_grid("mag", "magnetometer", log.mag_t_s, {"mag_b_T": log.mag_b_T}, grid_t_s)}
    if len(log.baro_t_s):
        out["baro"] = on_grid("baro", "baro", log.baro_t_s, {"h_baro_m": log.h_baro_m}, grid_t_s)
    return out


# --- coarse alignment -------------------------------------------------------------------------

@dataclass
class Alignment:
    euler_rad: np.ndarray      #: (3,) roll, pitch, yaw (true heading)
    field_n_T: np.ndarray      #: (3,) the Earth field N, E, D measured in the window
    window_s: float
    gyro_max_rps: float        #: largest rate in the window (the vehicle should be still)
    still: bool


def coarse_alignment(log: ReplayLog, window_s: float = ALIGN_S) -> Alignment:
    """Level with the mean specific force of the first ``window_s`` (``roll = atan2(-fy, -fz)``,
    ``pitch = atan2(fx, hypot(fy, fz))``), head with the levelled mean magnetometer plus the
    declination, and measure the Earth field there.

    The field is the one measured, not the WMM's: its magnitude and inclination come from the
    levelled magnetometer and its horizontal part is turned by the declination. It carries the
    sensor's residual calibration errors and the local anomaly, so the estimator's model of the
    field matches what the magnetometer reads (a WMM field that disagrees in inclination would
    pull roll and pitch through the magnetometer update); and it needs no position, which this
    log lacks.
    """
    w = log.imu_t_s <= window_s
    f = log.f_ib_b_mps2[w].mean(axis=0)
    roll, pitch = math.atan2(-f[1], -f[2]), math.atan2(f[0], math.hypot(f[1], f[2]))
    wm = log.mag_t_s <= window_s
    m_b = log.mag_b_T[wm].mean(axis=0) if np.any(wm) else log.mag_b_T[0]
    m_l = dcm_from_euler(roll, pitch, 0.0) @ m_b          # levelled: heading-north frame
    heading_mag = -math.atan2(m_l[1], m_l[0])
    yaw = float(wrap_angle(heading_mag + log.declination_rad))
    h = math.hypot(m_l[0], m_l[1])
    decl = log.declination_rad
    gyro_max = float(np.abs(log.omega_ib_b_rps[w]).max())
    return Alignment(np.array([roll, pitch, yaw]), np.array([h * math.cos(decl), h * math.sin(decl), m_l[2]]),
                     window_s, gyro_max, gyro_max <= ALIGN_GYRO_MAX_RPS)


def initial_state(log: ReplayLog, align: Alignment) -> tuple[NavState, dict]:
    """``nav0`` (one run) and its ``sigma0`` blocks (:data:`ALIGN_SIGMA`)."""
    lat = log.lat_rad or 0.0
    h = float(log.h_baro_m[0]) if len(log.h_baro_m) else (log.h_ref_m or 0.0)
    nav0 = NavState(np.array([lat]), np.array([log.lon_rad or 0.0]), np.array([h]), np.zeros((1, 3)),
                    dcm_from_euler(*align.euler_rad)[None])
    sigma = InitialErrors(ALIGN_SIGMA["pos_m"], ALIGN_SIGMA["vel_mps"], ALIGN_SIGMA["att_rad"])
    return nav0, sigma.sigma_blocks(lat, h)


# --- the estimator ------------------------------------------------------------------------------

def build_estimator(name: str, params: dict, defaults: dict):
    """``base.get(name)(**kw)``: ``defaults`` the constructor accepts, overridden by ``params``;
    a :class:`NavsimError` for an unknown name or a parameter the class does not take."""
    try:
        cls = base.get(name)
    except KeyError as exc:
        raise UsageError(f"{exc.args[0]}; available: {', '.join(base.available())}") from exc
    sig = inspect.signature(cls.__init__).parameters
    takes_any = any(p.kind is p.VAR_KEYWORD for p in sig.values())
    accepted = {k for k in sig if k != "self"}
    unknown = [k for k in params if k not in accepted and not takes_any]
    if unknown:
        raise UsageError(f"estimator '{name}' takes no parameter {', '.join(map(repr, unknown))} "
                          f"(it takes: {', '.join(sorted(accepted)) or 'none'})")
    kw = {k: v for k, v in defaults.items() if k in accepted or takes_any}
    kw.update(params)
    try:
        return cls(**kw), kw
    except (TypeError, ValueError) as exc:
        raise UsageError(f"estimator '{name}' with {kw}: {exc}") from exc


@dataclass
class ReplayResult:
    """An estimator's attitude over a log, against PX4's, every ``record_s``."""

    log: ReplayLog
    estimator: str
    params: dict                   #: the constructor's keyword arguments
    alignment: Alignment
    imu_rate_hz: float
    period_s: float                #: the estimator's epoch period on the IMU grid
    t_s: np.ndarray                #: (E,) record times (0 first: the initial state)
    euler_rad: np.ndarray          #: (E, 3) the estimator's roll, pitch, yaw
    euler_px4_rad: np.ndarray      #: (E, 3) PX4's, slerped to t_s (NaN outside its record)
    settle_s: float
    resets: list                   #: (t_s, cause) the estimator reported for run 0
    cost: dict                     #: CPU seconds in propagate and epoch, their counts
    sensors: dict = field(default_factory=dict)   #: name -> samples given, rate (Hz)

    @property
    def diff_rad(self) -> np.ndarray:
        """Estimator minus PX4 (roll, pitch, yaw), yaw wrapped to ±180°."""
        d = self.euler_rad - self.euler_px4_rad
        d[:, 2] = wrap_angle(d[:, 2])
        return d


def px4_euler_at(log: ReplayLog, t_s: np.ndarray) -> np.ndarray:
    """PX4's roll, pitch, yaw slerped to ``t_s`` ``(E, 3)``; NaN outside its record."""
    from scipy.spatial.transform import Rotation, Slerp
    slerp = Slerp(log.att_t_s, Rotation.from_quat(log.quat_nb_px4[:, [1, 2, 3, 0]]))
    inside = (t_s >= log.att_t_s[0]) & (t_s <= log.att_t_s[-1])
    out = np.full((len(t_s), 3), np.nan)
    if np.any(inside):
        out[inside] = euler_from_dcm(slerp(t_s[inside]).as_matrix())
    return out


def replay(log: ReplayLog, estimator: str, params: dict | None = None, *, imu_rate_hz: float | None = None,
           settle_s: float = 10.0, align_s: float = ALIGN_S, record_s: float = RECORD_S,
           progress=None) -> ReplayResult:
    """Run ``estimator`` (a registered name) over ``log`` and compare its attitude with PX4's.

    Parameters
    ----------
    log : ReplayLog
    estimator : str
        Registered estimator name; built with the keyword parameters its ``__init__`` takes
        among ``mag="mag"``, ``baro="baro"`` (None without a barometer), ``gnss=None``,
        ``field_n_T`` (the aligned field, list N, E, D tesla), then ``params``.
    params : dict, optional
        Extra constructor parameters (override the above).
    imu_rate_hz : float, optional
        The grid the IMU is resampled to (default: the log's nominal rate).
    settle_s : float
        Seconds left out of the metrics (the estimator converging from the coarse alignment).
    align_s : float
        Length of the coarse-alignment window from the first sample.
    record_s : float
        The solution's attitude is sampled this often (or every epoch if the estimator's period
        is shorter), after the epoch when one falls on the same IMU step.
    progress : callable, optional
        ``progress(t_s, duration_s)`` now and then.
    """
    rate = float(imu_rate_hz or round(log.imu_rate_hz))
    grid, dth, dv = imu_increments(log.imu_t_s, log.omega_ib_b_rps, log.f_ib_b_mps2, rate)
    sensors = sensor_streams(log, grid)
    align = coarse_alignment(log, align_s)
    defaults = {"mag": "mag", "baro": "baro" if "baro" in sensors else None, "gnss": None,
                "field_n_T": [float(x) for x in align.field_n_T],
                "no_gnss_sigma_mps": NO_GNSS_SIGMA_MPS}
    est, kw = build_estimator(estimator, dict(params or {}), defaults)
    nav0, sigma0 = initial_state(log, align)
    dt = 1.0 / rate
    loop = Driver({estimator: est}, dt, 1, isolate=False)
    loop.start(nav0, sigma0)
    every = loop.every[estimator]
    rec_every = max(1, int(round(min(record_s, every * dt) / dt)))
    t_rec, C_rec = [0.0], [est.solution().nav.C_nb[0].copy()]
    n = len(grid)
    stops = np.union1d(loop.stops(n), np.arange(rec_every, n, rec_every))
    for i in stops:
        i0 = loop.i + 1
        loop.advance(dth[None, i0:i + 1], dv[None, i0:i + 1], float(grid[i]), sensors)
        if i % rec_every == 0:
            t_rec.append(float(grid[i]))
            C_rec.append(est.solution().nav.C_nb[0].copy())
        if progress is not None and i // 2000 > (i0 - 1) // 2000:
            progress(grid[i], grid[-1])
    t_rec = np.asarray(t_rec)
    resets = est.solution().extra.get("resets")
    resets = [(float(t), str(c)) for t, c in resets[0]] if resets else []
    return ReplayResult(
        log=log, estimator=estimator, params=kw, alignment=align, imu_rate_hz=rate,
        period_s=every * dt, t_s=t_rec, euler_rad=euler_from_dcm(np.asarray(C_rec)),
        euler_px4_rad=px4_euler_at(log, t_rec), settle_s=settle_s, resets=resets,
        cost=loop.cost(estimator),
        sensors={k: {"samples": int(s.t_s.size), "rate_hz": s.meta["rate_hz"]} for k, s in sensors.items()})


# --- metrics -----------------------------------------------------------------------------------

AXES = ("roll", "pitch", "yaw")


def replay_metrics(result: ReplayResult) -> dict:
    """RMS, max and 95th percentile of |estimator - PX4| per axis (degrees) over the records
    after ``settle_s``; the alignment, the log's rates and notes, resets and the CPU cost."""
    r, log = result, result.log
    keep = (r.t_s >= r.settle_s) & np.all(np.isfinite(r.euler_px4_rad), axis=1)
    d = np.degrees(np.abs(r.diff_rad[keep]))
    diff = {ax: ({"rms": float(np.sqrt(np.mean(d[:, j] ** 2))), "max": float(d[:, j].max()),
                  "p95": float(np.percentile(d[:, j], 95))} if len(d) else None)
            for j, ax in enumerate(AXES)}
    c = r.cost
    a = r.alignment
    return {
        "log": {"file": str(log.path), "duration_s": log.duration_s, **log.info,
                "imu_rate_hz": log.imu_rate_hz, "mag_rate_hz": log.mag_rate_hz,
                "baro_rate_hz": log.baro_rate_hz, "px4_attitude_rate_hz":
                float((len(log.att_t_s) - 1) / np.ptp(log.att_t_s)),
                "declination_deg": math.degrees(log.declination_rad),
                "declination_source": log.declination_source,
                "imu_gaps": [{"t_s": t, "duration_s": g} for t, g in log.gaps], "notes": list(log.notes)},
        "estimator": r.estimator,
        "params": {k: v for k, v in r.params.items()},
        "imu_grid_hz": r.imu_rate_hz, "period_s": r.period_s, "sensors": r.sensors,
        "alignment": {"window_s": a.window_s, "euler_deg": np.degrees(a.euler_rad).tolist(),
                      "px4_euler_deg": np.degrees(r.euler_px4_rad[0]).tolist(),
                      "field_n_T": a.field_n_T.tolist(), "gyro_max_rps": a.gyro_max_rps, "still": a.still},
        "settle_s": r.settle_s, "samples_scored": int(keep.sum()),
        "record_s": float(np.median(np.diff(r.t_s))) if len(r.t_s) > 1 else None,
        "attitude_diff_deg": diff,
        "resets": [{"t_s": t, "cause": cause} for t, cause in r.resets],
        "cost": {"us_per_imu_step_propagated": 1e6 * c["propagate_s"] / max(c["steps"], 1),
                 "us_per_epoch": 1e6 * c["epoch_s"] / max(c["epochs"], 1),
                 "us_per_imu_cycle": 1e6 * (c["propagate_s"] + c["epoch_s"]) / max(c["steps"], 1),
                 "real_time_factor": log.duration_s / max(c["propagate_s"] + c["epoch_s"], 1e-9)},
    }
