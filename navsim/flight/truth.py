"""The truth record of a flight: one container, SI units, named frames, at the IMU rate.

Layout (``N`` samples, sample ``k`` at ``t_s[k]``; frames as in :mod:`navsim`):

=================  ===========  ==============================================================
field              shape        meaning
=================  ===========  ==============================================================
t_s                (N,)         time since the start of the track, s
lat_rad, lon_rad   (N,)         geodetic latitude, longitude (WGS-84), rad
h_m                (N,)         geodetic height above the WGS-84 ellipsoid (= JSBSim sea level), m
vel_n_mps          (N, 3)       velocity relative to the Earth, NED, m/s
quat_nb            (N, 4)       attitude, body -> NED, scalar first
euler_rad          (N, 3)       roll, pitch, yaw (true heading), rad
omega_ib_b_rps     (N, 3)       inertial angular rate of the body, body axes, rad/s
f_b_mps2           (N, 3)       specific force at the centre of gravity, body axes, m/s^2
tas_mps, cas_mps   (N,)         true and calibrated airspeed, m/s
p_static_pa        (N,)         static pressure, Pa
p_total_pa         (N,)         total (pitot) pressure, Pa
temp_k             (N,)         static air temperature, K
h_agl_m            (N,)         height above the terrain or sea surface, m
terrain_m          (N,)         terrain / sea-surface height above the ellipsoid, m
wind_n_mps         (N, 3)       air-mass velocity (steady wind plus turbulence), NED, m/s
wind_steady_n_mps  (N, 3)       its steady part (the scenario's wind, changing as it sets), m/s
alpha_rad, beta_rad (N,)        angle of attack and sideslip, rad
throttle           (N,)         throttle position, 0..1 (a multirotor's: its first motor's)
rotor_rpm          (N, R)       each rotor's speed, r/min: the fixed wing's propeller (R = 1), a
                                multirotor's rotors in its rotor table's order, none at rest (R = 0)
segment            (N,)         index of the active track segment (-1 during the launch)
=================  ===========  ==============================================================

``segment_labels`` names the segments; ``meta`` holds the aircraft, the rate and the track.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import NamedTuple

import numpy as np

from navsim.flight import properties as P
from navsim.foundations import atmosphere, earth
from navsim.foundations.transform import dcm_from_quat, quat_from_euler

ARRAY_FIELDS = ("t_s", "lat_rad", "lon_rad", "h_m", "vel_n_mps", "quat_nb", "euler_rad",
                "omega_ib_b_rps", "f_b_mps2", "tas_mps", "cas_mps", "p_static_pa", "p_total_pa",
                "temp_k", "h_agl_m", "terrain_m", "wind_n_mps", "wind_steady_n_mps", "alpha_rad", "beta_rad",
                "throttle", "rotor_rpm", "segment")
#: what :meth:`Truth.save` writes of a truth: the arrays, the segment labels, the meta (JSON)
_CONTENT = (*ARRAY_FIELDS, "segment_labels", "meta")
#: the entries a cached flight carries beside: its cache key and the SHA-256 of its contents
CACHE_KEY, DIGEST = "cache_key", "sha256"


def _digest(entries: dict, key: str) -> str:
    """SHA-256 of ``key`` and the :data:`_CONTENT` entries (name, dtype, shape, bytes)."""
    h = hashlib.sha256(key.encode())
    for name in _CONTENT:
        a = np.ascontiguousarray(entries[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


class Pose(NamedTuple):
    """Where and how a vehicle rests (:meth:`Truth.static`): geodetic position and attitude."""

    lat_deg: float = 37.38      #: geodetic latitude (WGS-84)
    lon_deg: float = 117.97     #: longitude
    h_m: float = 0.0            #: height above the ellipsoid, m
    yaw_deg: float = 0.0        #: true heading
    roll_deg: float = 0.0       #: roll (the ground's tilt)
    pitch_deg: float = 0.0      #: pitch


@dataclass
class Truth:
    """Truth of one flight (see the module docstring for the layout)."""

    t_s: np.ndarray
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    h_m: np.ndarray
    vel_n_mps: np.ndarray
    quat_nb: np.ndarray
    euler_rad: np.ndarray
    omega_ib_b_rps: np.ndarray
    f_b_mps2: np.ndarray
    tas_mps: np.ndarray
    cas_mps: np.ndarray
    p_static_pa: np.ndarray
    p_total_pa: np.ndarray
    temp_k: np.ndarray
    h_agl_m: np.ndarray
    terrain_m: np.ndarray
    wind_n_mps: np.ndarray
    wind_steady_n_mps: np.ndarray
    alpha_rad: np.ndarray
    beta_rad: np.ndarray
    throttle: np.ndarray
    rotor_rpm: np.ndarray
    segment: np.ndarray
    segment_labels: list[str] = field(default_factory=list)
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.t_s)

    @property
    def dt_s(self) -> float:
        return float(self.t_s[1] - self.t_s[0])

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def segment_spans(self) -> list[tuple[int, str, float, float]]:
        """``(index, label, t_start, t_end)`` for each segment flown, in order."""
        spans = []
        seg = self.segment
        change = np.flatnonzero(np.diff(seg)) + 1
        starts = np.concatenate([[0], change])
        ends = np.concatenate([change, [len(seg)]])
        for a, b in zip(starts, ends):
            i = int(seg[a])
            label = "launch" if i < 0 else self.segment_labels[i]
            spans.append((i, label, float(self.t_s[a]), float(self.t_s[b - 1])))
        return spans

    def slice(self, start: int, stop: int) -> "Truth":
        """Samples ``start:stop``."""
        kw = {name: getattr(self, name)[start:stop] for name in ARRAY_FIELDS}
        return Truth(**kw, segment_labels=list(self.segment_labels), meta=dict(self.meta))

    def save(self, path: str | Path, *, key: str | None = None) -> None:
        """Write to a compressed ``.npz``; with ``key`` (a cache key), the key and a SHA-256 of
        the contents and the key are stored with it (:meth:`load` checks them)."""
        entries = {name: getattr(self, name) for name in ARRAY_FIELDS}
        entries.update(segment_labels=np.array(self.segment_labels), meta=np.array(json.dumps(self.meta)))
        if key is not None:
            entries.update({CACHE_KEY: np.array(key), DIGEST: np.array(_digest(entries, key))})
        np.savez_compressed(path, **entries)

    @classmethod
    def load(cls, path: str | Path, *, key: str | None = None) -> "Truth":
        """The truth written by :meth:`save`; with ``key``, a :class:`ValueError` unless the file
        was saved with that key and its contents match their stored SHA-256 (a damaged or a
        foreign file)."""
        with np.load(path, allow_pickle=False) as data:
            entries = {name: data[name] for name in (*_CONTENT, CACHE_KEY, DIGEST) if name in data.files}
        missing = [name for name in _CONTENT if name not in entries]
        if missing:
            raise KeyError(f"{path}: not a flight's truth (no {', '.join(missing)})")
        if key is not None:
            stored = str(entries[CACHE_KEY]) if CACHE_KEY in entries else None
            if stored != key:
                raise ValueError(f"{path}: holds the flight {stored or '(no key)'}, not {key}")
            if DIGEST not in entries or str(entries[DIGEST]) != _digest(entries, key):
                raise ValueError(f"{path}: its contents do not match their SHA-256 (damaged)")
        kw = {name: entries[name] for name in ARRAY_FIELDS}
        labels = [str(s) for s in entries["segment_labels"]]
        return cls(**kw, segment_labels=labels, meta=json.loads(str(entries["meta"])))

    @classmethod
    def static(cls, duration_s: float, rate_hz: float = 100.0, pose: Pose = Pose(),
               h_agl_m=None) -> "Truth":
        """A vehicle at rest on the rotating Earth at ``pose`` (a :class:`Pose`: where, heading
        ``yaw_deg``, tilted by ``roll_deg`` and ``pitch_deg``; default level): the specific force
        is minus gravity, the inertial rate the Earth rate. ``h_agl_m`` (array or scalar)
        overrides the height above the surface (for altimeter tests)."""
        lat_deg, lon_deg, h_m, yaw_deg, roll_deg, pitch_deg = pose
        n = int(round(duration_s * rate_hz)) + 1
        lat, lon, yaw = np.radians(lat_deg), np.radians(lon_deg), np.radians(yaw_deg)
        ones = np.ones(n)
        euler = np.column_stack([np.radians(roll_deg) * ones, np.radians(pitch_deg) * ones, yaw * ones])
        quat = quat_from_euler(euler[:, 0], euler[:, 1], euler[:, 2])
        C_bn = dcm_from_quat(quat[0]).T
        g_n = earth.gravity_n(lat, h_m)
        w_n = earth.OMEGA_IE_RPS * np.array([np.cos(lat), 0.0, -np.sin(lat)])
        p = float(atmosphere.pressure(h_m))
        hagl = np.broadcast_to(np.asarray(h_agl_m if h_agl_m is not None else h_m, float), (n,)).copy()
        return cls(
            t_s=np.arange(n) / rate_hz, lat_rad=lat * ones, lon_rad=lon * ones, h_m=h_m * ones,
            vel_n_mps=np.zeros((n, 3)), quat_nb=quat, euler_rad=euler,
            omega_ib_b_rps=np.tile(C_bn @ w_n, (n, 1)), f_b_mps2=np.tile(-(C_bn @ g_n), (n, 1)),
            tas_mps=0 * ones, cas_mps=0 * ones, p_static_pa=p * ones, p_total_pa=p * ones,
            temp_k=float(atmosphere.temperature(h_m)) * ones, h_agl_m=hagl,
            terrain_m=h_m - hagl, wind_n_mps=np.zeros((n, 3)), wind_steady_n_mps=np.zeros((n, 3)),
            alpha_rad=0 * ones,
            beta_rad=0 * ones, throttle=0 * ones, rotor_rpm=np.zeros((n, 0)), segment=np.zeros(n, np.int16),
            segment_labels=["static"], meta={"rate_hz": rate_hz, "track": "static"})

    def __eq__(self, other) -> bool:  # arrays compare element-wise
        if not isinstance(other, Truth):
            return NotImplemented
        return all(np.array_equal(getattr(self, f.name), getattr(other, f.name))
                   if f.name in ARRAY_FIELDS else getattr(self, f.name) == getattr(other, f.name)
                   for f in fields(self))


def truth_from_rows(rows: np.ndarray, t_s: np.ndarray, segment: np.ndarray,
                    segment_labels: list[str], meta: dict) -> Truth:
    """Build the container from raw rows of :func:`JSBSimIO.read_row` (already SI), each followed
    by the rotors' speeds (r/min) where there are more columns than
    :data:`~navsim.flight.properties.RAW_PROPERTIES` (a multirotor's), else the propeller's."""
    r = rows
    n_raw = len(P.RAW_PROPERTIES)
    rotor_rpm = r[:, n_raw:].copy() if r.shape[1] > n_raw else r[:, P.COL_RPM:P.COL_RPM + 1].copy()
    euler = r[:, [P.COL_ROLL, P.COL_PITCH, P.COL_YAW]].copy()
    euler[:, 2] = (euler[:, 2] + np.pi) % (2 * np.pi) - np.pi
    mass = r[:, P.COL_MASS:P.COL_MASS + 1]
    return Truth(
        t_s=t_s,
        lat_rad=r[:, P.COL_LAT].copy(),
        lon_rad=r[:, P.COL_LON].copy(),
        h_m=r[:, P.COL_H].copy(),
        vel_n_mps=r[:, P.COL_VN:P.COL_VD + 1].copy(),
        quat_nb=quat_from_euler(euler[:, 0], euler[:, 1], euler[:, 2]),
        euler_rad=euler,
        omega_ib_b_rps=r[:, P.COL_PI:P.COL_RI + 1].copy(),
        f_b_mps2=r[:, P.COL_FX:P.COL_FZ + 1] / mass,
        tas_mps=r[:, P.COL_TAS].copy(),
        cas_mps=r[:, P.COL_CAS].copy(),
        p_static_pa=r[:, P.COL_PS].copy(),
        p_total_pa=r[:, P.COL_PT].copy(),
        temp_k=r[:, P.COL_TEMP].copy(),
        h_agl_m=r[:, P.COL_HAGL].copy(),
        terrain_m=r[:, P.COL_TERRAIN].copy(),
        wind_n_mps=r[:, P.COL_WN:P.COL_WD + 1].copy(),
        wind_steady_n_mps=r[:, P.COL_WSN:P.COL_WSD + 1].copy(),
        alpha_rad=r[:, P.COL_ALPHA].copy(),
        beta_rad=r[:, P.COL_BETA].copy(),
        throttle=r[:, P.COL_THROTTLE].copy(),
        rotor_rpm=rotor_rpm,
        segment=segment.astype(np.int16),
        segment_labels=list(segment_labels),
        meta=meta,
    )
