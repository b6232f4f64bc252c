"""A replay scored: the estimator's roll, pitch and yaw against PX4's own estimate.

:func:`replay_metrics` gives a :class:`ReplayMetrics`, the replay's ``metrics.json`` as typed
objects: ``to_dict()`` turns it into the JSON's nested mapping and ``from_dict()`` reads it
back (the base of :mod:`navsim.records.metrics`). Units and frames are in the names: ``_s``,
``_hz``, ``_deg``, ``_rps``, ``_n_T`` (tesla, north-east-down).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations.distributions import chi2_ppf
from navsim.records.metrics import EULER_AXES as AXES, Nis, _Record
from navsim.replay.run import ReplayResult


@dataclass(frozen=True)
class ImuGap(_Record):
    """A gap in the log's IMU samples: when (s from the first sample) and how long."""

    t_s: float
    duration_s: float


@dataclass(frozen=True)
class LogInfo(_Record):
    """The log replayed: its file, length, metadata (``info``: software, hardware, estimator
    group, as :attr:`navsim.replay.ulog.ReplayLog.info`; in the mapping its keys stand beside
    the others, after ``duration_s``), its sensors' rates, the declination used, IMU gaps and
    what the replay worked around (``notes``)."""

    file: str
    duration_s: float
    info: dict
    imu_rate_hz: float
    mag_rate_hz: float
    baro_rate_hz: float
    px4_attitude_rate_hz: float
    declination_deg: float
    declination_source: str
    imu_gaps: list[ImuGap]
    notes: list[str]

    def to_dict(self) -> dict:
        out = super().to_dict()
        info = out.pop("info")
        head = {k: out.pop(k) for k in ("file", "duration_s")}
        return {**head, **info, **out}

    @classmethod
    def from_dict(cls, data: dict) -> LogInfo:
        names = [f.name for f in dataclasses.fields(cls) if f.name != "info"]
        typed = super().from_dict({k: v for k, v in data.items() if k in names} | {"info": {}})
        return dataclasses.replace(typed, info={k: v for k, v in data.items() if k not in names})


@dataclass(frozen=True)
class SensorStream(_Record):
    """A sensor of the log given to the estimator: samples given and their rate."""

    samples: int
    rate_hz: float | None

    _NULLS = ("rate_hz",)


@dataclass(frozen=True)
class Alignment(_Record):
    """The coarse alignment over the first ``window_s``: roll, pitch, yaw found and PX4's at
    the first record, the field (NED, tesla), the largest rate and whether it was still."""

    window_s: float
    euler_deg: list[float]
    px4_euler_deg: list[float]
    field_n_T: list[float]
    gyro_max_rps: float
    still: bool


@dataclass(frozen=True)
class AxisDiff(_Record):
    """|estimator - PX4| on one Euler axis (degrees): RMS, maximum, 95th percentile."""

    rms: float
    max: float
    p95: float


@dataclass(frozen=True)
class AttitudeDiff(_Record):
    """:class:`AxisDiff` per Euler axis (None: no sample scored)."""

    roll: AxisDiff | None
    pitch: AxisDiff | None
    yaw: AxisDiff | None

    _NULLS = AXES

    def axis(self, name: str) -> AxisDiff | None:
        """The differences on the axis ``name`` (one of :data:`AXES`)."""
        if name not in AXES:
            raise KeyError(name)
        return getattr(self, name)


@dataclass(frozen=True)
class ResetEvent(_Record):
    """A reset the estimator reported: when (s, on the replay's clock, as its epochs) and why
    (the estimator's own words)."""

    t_s: float
    cause: str


@dataclass(frozen=True)
class ReplayCost(_Record):
    """CPU time of the replay: µs per IMU step propagated, per epoch, per IMU cycle (both), and
    how many times faster than real time."""

    us_per_imu_step_propagated: float
    us_per_epoch: float
    us_per_imu_cycle: float
    real_time_factor: float


@dataclass(frozen=True)
class ReplayMetrics(_Record):
    """A replay's scores, as its ``metrics.json`` holds them.

    ``params``: the estimator's keyword arguments; ``imu_grid_hz``, ``period_s``: the IMU grid
    and the epoch period on it; ``record_s``: the median record period (None: one record).
    ``wall_s`` and ``provenance`` (:func:`navsim.foundations.provenance.provenance`) are set by
    the command that wrote the file (None: not yet, left out of the mapping)."""

    log: LogInfo
    estimator: str
    params: dict
    imu_grid_hz: float
    period_s: float
    sensors: dict[str, SensorStream]
    alignment: Alignment
    settle_s: float
    samples_scored: int
    record_s: float | None
    attitude_diff_deg: AttitudeDiff
    resets: list[ResetEvent]
    cost: ReplayCost
    wall_s: float | None = None
    provenance: dict | None = None
    #: each measurement's NIS over the epochs after ``settle_s`` (``measurement:sensor`` ->
    #: :class:`~navsim.records.metrics.Nis`: its average against the band of an average over
    #: that many epochs, the share of epochs inside one epoch's band); None: none recorded
    nis: dict[str, Nis] | None = None

    _NULLS = ("record_s",)


def _log_info(result: ReplayResult) -> LogInfo:
    log = result.log
    return LogInfo(
        file=str(log.path), duration_s=log.duration_s, info=dict(log.info),
        imu_rate_hz=log.imu_rate_hz, mag_rate_hz=log.mag_rate_hz, baro_rate_hz=log.baro_rate_hz,
        px4_attitude_rate_hz=float((len(log.att_t_s) - 1) / np.ptp(log.att_t_s)),
        declination_deg=math.degrees(log.declination_rad), declination_source=log.declination_source,
        imu_gaps=[ImuGap(t, g) for t, g in log.gaps], notes=list(log.notes))


def _cost(result: ReplayResult) -> ReplayCost:
    c = result.cost
    return ReplayCost(
        us_per_imu_step_propagated=1e6 * c["propagate_s"] / max(c["steps"], 1),
        us_per_epoch=1e6 * c["epoch_s"] / max(c["epochs"], 1),
        us_per_imu_cycle=1e6 * (c["propagate_s"] + c["epoch_s"]) / max(c["steps"], 1),
        real_time_factor=result.log.duration_s / max(c["propagate_s"] + c["epoch_s"], 1e-9))


def replay_metrics(result: ReplayResult) -> ReplayMetrics:
    """RMS, max and 95th percentile of |estimator - PX4| per axis (degrees) over the records
    after ``settle_s``; the alignment, the log's rates and notes, resets and the CPU cost."""
    r, a = result, result.alignment
    keep = (r.t_s >= r.settle_s) & np.all(np.isfinite(r.euler_px4_rad), axis=1)
    d = np.degrees(np.abs(r.diff_rad[keep]))
    diff = AttitudeDiff(*(AxisDiff(rms=float(np.sqrt(np.mean(d[:, j] ** 2))), max=float(d[:, j].max()),
                                   p95=float(np.percentile(d[:, j], 95))) if len(d) else None
                          for j in range(len(AXES))))
    return ReplayMetrics(
        log=_log_info(r), estimator=r.estimator, params=dict(r.params), imu_grid_hz=r.imu_rate_hz,
        period_s=r.period_s, sensors={k: SensorStream(**s) for k, s in r.sensors.items()},
        alignment=Alignment(window_s=a.window_s, euler_deg=np.degrees(a.euler_rad).tolist(),
                            px4_euler_deg=np.degrees(r.euler_px4_rad[0]).tolist(),
                            field_n_T=a.field_n_T.tolist(), gyro_max_rps=a.gyro_max_rps, still=a.still),
        settle_s=r.settle_s, samples_scored=int(keep.sum()),
        record_s=float(np.median(np.diff(r.t_s))) if len(r.t_s) > 1 else None,
        attitude_diff_deg=diff, resets=[ResetEvent(t, cause) for t, cause in r.resets], cost=_cost(r),
        nis=replay_nis(r.nis, r.settle_s) or None)


def replay_nis(epochs: list, settle_s: float) -> dict:
    """``measurement:sensor`` -> :class:`Nis` of one run's epochs ``(t_s, key, nis (1,), rows)``
    after ``settle_s``: the average against the 95 % band of an average of that many chi-square
    values, and the share of epochs inside one's band."""
    by_key: dict = {}
    for t, key, nis, dim in epochs:
        if t >= settle_s and np.isfinite(nis[0]):
            by_key.setdefault(key, (dim, []))[1].append(float(nis[0]))
    out = {}
    for key, (dim, v) in by_key.items():
        v = np.asarray(v)
        lo, hi = chi2_ppf(np.array([0.025, 0.975]), dim)
        band = (chi2_ppf(np.array([0.025, 0.975]), dim * v.size) / v.size).tolist()
        out[key] = Nis(average=float(v.mean()), band=band, dim=int(dim),
                       fraction_inside=float(np.mean((v >= lo) & (v <= hi))))
    return out
