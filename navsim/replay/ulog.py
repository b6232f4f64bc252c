"""A PX4 flight log (ULog) read and checked for a replay: :func:`load_ulog`.

It reads the log with ``pyulog``: the IMU (``sensor_combined``: gyro rad/s, accelerometer m/s²,
~250 Hz), the magnetometer (``sensor_combined.magnetometer_ga`` or ``vehicle_magnetometer``,
gauss), the barometric altitude when the log has one (``sensor_combined.baro_alt_meter`` or
``vehicle_air_data``) and PX4's own attitude estimate (``vehicle_attitude.q``, scalar first, body
FRD to NED). Times are seconds from the first ``sensor_combined`` sample; values are SI (1 gauss
= 1e-4 T).

Every problem with a log raises :class:`navsim.foundations.errors.LogError` naming the file, what
is missing and a hint; what the replay works around (dropped samples, no baro, no position) is
listed in ``ReplayLog.notes``.
"""

from __future__ import annotations

import gzip
import io
import math
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navsim.foundations.errors import LogError

GAUSS_T = 1e-4                    #: tesla per gauss
TIMESTAMP_INVALID = 2**31 - 1     #: PX4's RELATIVE_TIMESTAMP_INVALID (no sample of that sensor)
GAP_WARN_PERIODS = 5              #: a gap longer than this many IMU periods is listed in the notes
GAP_MAX_S = 0.5                   #: a longer gap is an error (the IMU cannot be bridged)
MIN_DURATION_S = 5.0              #: the shortest IMU record replayed
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


def read_ulog_file(path: Path, allow_damaged: bool, notes: list):
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


def topics_of(ulog) -> dict:
    """Topic name -> its fields (the first instance of each topic)."""
    out = {}
    for d in sorted(ulog.data_list, key=lambda d: d.multi_id):
        if d.name not in out and len(d.data.get("timestamp", ())):
            out[d.name] = d.data
    return out


def vec(names: str, n: int) -> list[str]:
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


def columns(data: dict, names: list[str]) -> np.ndarray:
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
        t, m = _distinct(t, ok, columns(sc, vec("magnetometer_ga", 3)))
    else:
        mag = require(topics, "vehicle_magnetometer", vec("magnetometer_ga", 3), path,
                      "the magnetometer: sensor_combined has no magnetometer_ga either")
        t = (np.asarray(mag["timestamp"], np.int64) - t0_us) * 1e-6
        m = columns(mag, vec("magnetometer_ga", 3))
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


def imu_gaps(t_s: np.ndarray, path, allow_damaged: bool, notes: list) -> list:
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
    """Read and check a PX4 ULog for :func:`navsim.replay.run.replay`.

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
    ulog = read_ulog_file(path, allow_damaged, notes)
    topics = topics_of(ulog)
    sc = require(topics, "sensor_combined", ["timestamp"] + vec("gyro_rad", 3)
                 + vec("accelerometer_m_s2", 3), path, "the IMU")
    va = require(topics, "vehicle_attitude", ["timestamp"] + vec("q", 4), path,
                 "PX4's attitude estimate, the reference")
    t_us = np.asarray(sc["timestamp"], np.int64)
    t0_us = int(t_us[0])
    imu_t = (t_us - t0_us) * 1e-6
    if len(imu_t) < 2 or imu_t[-1] < MIN_DURATION_S:
        raise LogError(f"sensor_combined holds {imu_t[-1] if len(imu_t) else 0:.2f} s of IMU data "
                       f"({len(imu_t)} samples); the replay needs {MIN_DURATION_S:.0f} s",
                       file=str(path), hint=_HINT_LOG)
    gaps = imu_gaps(imu_t, path, allow_damaged, notes)
    mag_t, mag_T = _magnetometer(topics, sc, t0_us, path)
    if len(mag_t) < 2:
        raise LogError(f"has {len(mag_t)} magnetometer sample(s)", file=str(path), hint=_HINT_LOG)
    baro_t, baro_h = _barometer(topics, sc, t0_us, notes)
    att_t = (np.asarray(va["timestamp"], np.int64) - t0_us) * 1e-6
    att_t, quat = _distinct(att_t, np.ones(len(att_t), bool), columns(va, vec("q", 4)))
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
    return ReplayLog(path=path, t0_us=t0_us, imu_t_s=imu_t, omega_ib_b_rps=columns(sc, vec("gyro_rad", 3)),
                     f_ib_b_mps2=columns(sc, vec("accelerometer_m_s2", 3)), mag_t_s=mag_t, mag_b_T=mag_T,
                     baro_t_s=baro_t, h_baro_m=baro_h, att_t_s=att_t,
                     quat_nb_px4=quat / np.linalg.norm(quat, axis=-1, keepdims=True), lat_rad=lat,
                     lon_rad=lon, h_ref_m=h, declination_rad=decl, declination_source=decl_src,
                     gaps=gaps, notes=notes, info=info)
