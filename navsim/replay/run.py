"""A PX4 log replayed through an estimator: :func:`replay`.

The IMU is resampled to a uniform grid (increments ``dtheta_b``, ``dv_b``), each magnetometer and
baro sample put on the first grid time at or after its own time, the estimator aligned coarsely
from the first second of data (:func:`coarse_alignment`) and driven as the Monte Carlo driver
drives it (:class:`navsim.experiment.driver.Driver`: ``propagate`` up to each epoch, ``epoch``
every ``period_s``); its roll, pitch and yaw are recorded with PX4's, slerped to the same times.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from navsim.experiment.driver import Driver, InitialErrors
from navsim.foundations.config import Node
from navsim.foundations.errors import UsageError
from navsim.foundations.transform import dcm_from_euler, euler_from_dcm, wrap_angle
from navsim.navigation.estimators import base
from navsim.navigation.strapdown import NavState
from navsim.replay.ulog import ReplayLog
from navsim.sensors.base import SensorData

ALIGN_S = 1.0                     #: default length of the coarse-alignment window
#: the IMU grid rates a replay takes, Hz (a strapdown below 10 Hz follows no vehicle's rotation)
IMU_RATE_HZ = (10.0, 10_000.0)
RECORD_S = 0.02                   #: the solution is compared with PX4's at 50 Hz
#: without GNSS, an attitude EKF that takes it levels on a zero horizontal velocity of this sigma
NO_GNSS_SIGMA_MPS = 1.0
#: the heading's 1-sigma the ES-KF family assumes on a replayed, PX4-calibrated magnetometer
MAG_HEADING_SIGMA_DEG = 5.0
ALIGN_GYRO_MAX_RPS = 0.05         #: above this rate in the window the vehicle was not still
#: 1-sigma of the coarse alignment: attitude about N, E, D (rad), velocity (m/s), position N, E, D
#: (m): the accelerometer levels to ~1° (bias of ~0.1 m/s²), the magnetometer heading to ~5°
#: (uncalibrated iron), the vehicle is assumed still, and without GNSS the position is arbitrary.
ALIGN_SIGMA = {"att_rad": np.radians([1.0, 1.0, 5.0]), "vel_mps": np.array([0.3, 0.3, 0.3]),
               "pos_m": np.array([10.0, 10.0, 5.0])}

# --- IMU increments and the sensor streams on its grid -----------------------------------------

class GridIncrements(NamedTuple):
    """The IMU on a uniform grid (:func:`imu_increments`): the grid times and the increments
    over ``(grid[j-1], grid[j]]``."""

    t_s: np.ndarray               #: (N,) the grid
    dtheta_b_rad: np.ndarray      #: (N, 3) rotation increments; row 0 is zero
    dv_b_mps: np.ndarray          #: (N, 3) velocity increments; row 0 is zero


def imu_increments(t_s: np.ndarray, omega_b: np.ndarray, f_b: np.ndarray, rate_hz: float) -> GridIncrements:
    """Increments on a uniform grid from samples at jittered times.

    Each sample is PX4's mean rate over the interval ending at its timestamp, so the rates are
    piecewise constant between timestamps and their integrals ``theta(t)``, ``v(t)`` piecewise
    linear: sampled at the grid times by linear interpolation, they are exact for any grid, and
    the increments sum to the integral of the logged rates whatever the jitter. Across a gap
    the sample after it holds its rate over the whole gap.

    Returns
    -------
    GridIncrements
        ``t_s``: ``t_s[0] + j / rate_hz``; ``dtheta_b_rad``, ``dv_b_mps``: (N, 3) the increment
        over ``(grid[j-1], grid[j]]``, row 0 zero.
    """
    dt = 1.0 / rate_hz
    grid = t_s[0] + dt * np.arange(int(math.floor((t_s[-1] - t_s[0]) / dt + 1e-9)) + 1)
    step = np.diff(t_s)[:, None]

    def increments(rate):
        cum = np.concatenate([np.zeros((1, 3)), np.cumsum(rate[1:] * step, axis=0)])
        at = np.stack([np.interp(grid, t_s, cum[:, j]) for j in range(3)], axis=-1)
        return np.diff(at, axis=0, prepend=at[:1])
    return GridIncrements(grid, increments(omega_b), increments(f_b))


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

def default_measurements(align: Alignment) -> list:
    """The measurements an estimator that takes ``measurements`` (the ES-KF family) gets on a
    log without GNSS: the velocity held near zero (:data:`NO_GNSS_SIGMA_MPS`, horizontal; it
    levels, as the attitude filters' no-GNSS velocity does) and the magnetic heading of PX4's
    calibrated magnetometer against the field measured in the alignment."""
    return [{"type": "zero_velocity", "sensor": "mag", "sigma_mps": NO_GNSS_SIGMA_MPS},
            {"type": "mag_heading", "sensor": "mag", "sigma_deg": MAG_HEADING_SIGMA_DEG, "calibration": "none",
             "field_uT": [float(x) * 1e6 for x in align.field_n_T]}]


def build_estimator(name: str, params: dict, defaults: dict, sensors: dict):
    """The estimator registered as ``name``, as a scenario builds it: an estimator that reads its
    own entry (``parse``) gets ``defaults`` (entry keys: the log's sensor names, the aligned field,
    the attitude filters' no-GNSS sigma, the ES-KF family's measurements; those its ``SCHEMA``
    names) overridden by ``params``
    (``--set``), checked as a scenario's entry would be; another gets the constructor keywords
    of ``defaults`` it takes, overridden by ``params``. Returns the object and the parameters.
    ``sensors``: the log's sensor name -> kind."""
    try:
        cls = base.get(name)
    except KeyError as exc:
        raise UsageError(f"{exc.args[0]}; available: {', '.join(base.available())}") from exc
    if hasattr(cls, "parse"):
        return _parsed(cls, name, params, defaults, sensors)
    sig = inspect.signature(cls.__init__).parameters
    takes_any = any(p.kind is p.VAR_KEYWORD for p in sig.values())
    accepted = {k for k in sig if k != "self"}
    unknown = [k for k in params if k not in accepted and not takes_any]
    if unknown:
        raise UsageError(f"estimator '{name}' takes no parameter {', '.join(map(repr, unknown))} "
                          f"(it takes: {', '.join(sorted(accepted)) or 'none'})")
    kw = {k: v for k, v in _constructor(defaults).items() if k in accepted or takes_any}
    kw.update(params)
    try:
        return cls(**kw), kw
    except (TypeError, ValueError) as exc:
        raise UsageError(f"estimator '{name}' with {kw}: {exc}") from exc


def _parsed(cls, name: str, params: dict, defaults: dict, sensors: dict):
    """An estimator that reads its entry, from the defaults it knows and ``params``."""
    known = getattr(cls, "SCHEMA", {})
    entry = {k: v for k, v in defaults.items() if k in known and v is not None and _fits(known[k], v)}
    for k, v in params.items():            # a mapping given with --set completes the default's
        entry[k] = {**entry[k], **v} if isinstance(entry.get(k), dict) and isinstance(v, dict) else v
    node = Node(entry, f"estimator '{name}'", "--set")
    p = base.parse_params(cls, node, sensors)
    node.done()
    try:
        return base.build(cls, p), entry
    except (TypeError, ValueError) as exc:
        raise UsageError(f"estimator '{name}' with {entry}: {exc}") from exc


def _fits(schema: dict, value) -> bool:
    """Whether ``value`` has the JSON type ``schema`` wants (a replay default named like another
    key of the estimator: ``baro``, the CPF's sensor, is the ES-KF's baro model)."""
    if "anyOf" in schema or "oneOf" in schema:
        return any(_fits(s, value) for s in schema.get("anyOf", schema.get("oneOf")))
    kinds = {"object": dict, "string": str, "boolean": bool, "array": list, "number": (int, float)}
    want = kinds.get(schema.get("type"))
    return want is None or isinstance(value, want)


def _constructor(defaults: dict) -> dict:
    """The replay's defaults as constructor keywords (for an estimator without ``parse``)."""
    out = {k: v for k, v in defaults.items() if k not in ("field_uT", "sigma", "latest_sample", "measurements")}
    out["field_n_T"] = [x * 1e-6 for x in defaults["field_uT"]]
    out["no_gnss_sigma_mps"] = defaults["sigma"]["no_gnss_mps"]
    return out


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
    #: every epoch's innovations: ``(t_s, "measurement:sensor", nis (1,), rows)``
    nis: list = field(default_factory=list)

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


def check_options(log: ReplayLog, rate_hz: float, settle_s: float, align_s: float) -> None:
    """Refuse (:class:`UsageError`) an IMU grid rate outside :data:`IMU_RATE_HZ`, and a settling
    time or an alignment window that does not end inside the log."""
    if not IMU_RATE_HZ[0] <= rate_hz <= IMU_RATE_HZ[1]:
        raise UsageError(f"the IMU grid rate {rate_hz:g} Hz is outside {IMU_RATE_HZ[0]:g}-{IMU_RATE_HZ[1]:g} Hz "
                         f"(--imu-rate; the log's is {log.imu_rate_hz:.0f} Hz)")
    end = log.duration_s
    for what, value in (("the settling time (--settle)", settle_s), ("the alignment window (--align)", align_s)):
        if not (math.isfinite(value) and 0 <= value < end):
            raise UsageError(f"{what} is {value:g} s, not before the end of the log ({end:.1f} s)")


@dataclass(frozen=True)
class ReplayOptions:
    """How a log is replayed (``navsim replay``'s ``--imu-rate``, ``--settle``, ``--align``).

    Attributes
    ----------
    imu_rate_hz : float, optional
        The grid the IMU is resampled to (None: the log's nominal rate).
    settle_s : float
        Seconds left out of the metrics (the estimator converging from the coarse alignment).
    align_s : float
        Length of the coarse-alignment window from the first sample.
    record_s : float
        The solution's attitude is sampled this often (or every epoch if the estimator's period
        is shorter), after the epoch when one falls on the same IMU step.
    """

    imu_rate_hz: float | None = None
    settle_s: float = 10.0
    align_s: float = ALIGN_S
    record_s: float = RECORD_S


def replay(log: ReplayLog, estimator: str, params: dict | None = None, options: ReplayOptions = ReplayOptions(),
           *, progress=None) -> ReplayResult:
    """Run ``estimator`` (a registered name) over ``log`` and compare its attitude with PX4's.

    Parameters
    ----------
    log : ReplayLog
    estimator : str
        Registered estimator name, built by :func:`build_estimator` (as a scenario's entry, for
        an estimator with ``parse``: the log's sensor names, the aligned field ``field_uT``,
        ``sigma: {no_gnss_mps}``, ``latest_sample: true`` and :func:`default_measurements`
        where it reads them).
    params : dict, optional
        Entry keys (``--set``) overriding those defaults (constructor keywords for an estimator
        without ``parse``).
    options : ReplayOptions
        The IMU grid rate, the settling time, the alignment window and the record interval.
    progress : callable, optional
        ``progress(t_s, duration_s)`` now and then.
    """
    rate = float(options.imu_rate_hz or round(log.imu_rate_hz))
    check_options(log, rate, options.settle_s, options.align_s)
    imu = imu_increments(log.imu_t_s, log.omega_ib_b_rps, log.f_ib_b_mps2, rate)
    sensors = sensor_streams(log, imu.t_s)
    align = coarse_alignment(log, options.align_s)
    defaults = {"mag": "mag", "baro": "baro" if "baro" in sensors else None, "gnss": None,
                "field_uT": [float(x) * 1e6 for x in align.field_n_T], "sigma": {"no_gnss_mps": NO_GNSS_SIGMA_MPS},
                "latest_sample": True,         # the ES-KF family: the log's sensors are not on its epochs
                "measurements": default_measurements(align)}
    est, kw = build_estimator(estimator, dict(params or {}), defaults, {k: d.kind for k, d in sensors.items()})
    nav0, sigma0 = initial_state(log, align)
    dt = 1.0 / rate
    loop = Driver({estimator: est}, dt, 1, isolate=False, keep_nis=True)
    loop.start(nav0, sigma0)
    every = loop.every[estimator]
    rec_every = max(1, int(round(min(options.record_s, every * dt) / dt)))
    t_rec, C_rec = _drive(loop, est, imu, sensors, rec_every, progress)
    resets = est.solution().extra.get("resets")
    resets = [(float(t), str(c)) for t, c in resets[0]] if resets else []
    return ReplayResult(
        log=log, estimator=estimator, params=kw, alignment=align, imu_rate_hz=rate,
        period_s=every * dt, t_s=t_rec, euler_rad=euler_from_dcm(np.asarray(C_rec)),
        euler_px4_rad=px4_euler_at(log, t_rec), settle_s=options.settle_s, resets=resets,
        cost=loop.cost(estimator),
        sensors={k: {"samples": int(s.t_s.size), "rate_hz": s.meta["rate_hz"]} for k, s in sensors.items()},
        nis=loop.nis[estimator])


def _drive(loop: Driver, est, imu: GridIncrements, sensors: dict, rec_every: int, progress) -> tuple[np.ndarray, list]:
    """Drive ``loop`` (the one estimator ``est``) over the IMU increments ``imu`` with
    ``sensors`` on its grid; returns the record times (0 first: the initial state) and the
    solution's ``C_nb`` there, every ``rec_every`` grid steps."""
    grid, dth, dv = imu
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
    return np.asarray(t_rec), C_rec
