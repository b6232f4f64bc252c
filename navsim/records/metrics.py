"""The scores as typed objects: :class:`EstimatorMetrics` per estimator, :class:`CalibrationScore`
per calibrated magnetometer, :class:`RunMetrics` for a whole run (``metrics.json``).

Every class turns into the JSON's nested mapping with ``to_dict()`` (a section that was not
scored, None, is left out) and back with ``from_dict()``; :meth:`EstimatorMetrics.get` reads a
dotted path of that mapping (``rms.pos_m``, ``windows.low_leg.height_m.std``), as scenarios'
``reference`` and sweeps' ``metrics`` name them.

Units are in the names: ``_m``, ``_mps``, ``_deg``, ``_s``, ``_pct``; per-axis values are
``[N, E, D]`` for position and velocity and ``[x, y, z]`` (rotation vector) for attitude.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass, field

#: the Euler axes of :class:`AttitudeStats`
EULER_AXES = ("roll", "pitch", "yaw")


def _plain(v):
    if dataclasses.is_dataclass(v):
        return v.to_dict()
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def _build(tp, v):
    """``v`` (from JSON) as the annotated type ``tp``; null where a number is expected is NaN
    (strict JSON writes NaN as null)."""
    if v is None:
        return math.nan if tp is float else None
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        tp = next(a for a in args if a is not type(None))
        origin, args = typing.get_origin(tp), typing.get_args(tp)
    if isinstance(tp, type) and issubclass(tp, _Record):
        return None if v == {} else tp.from_dict(v)       # {}: a section left empty (older files)
    if origin is dict:
        return {k: _build(args[1], x) for k, x in v.items()}
    if origin is list and args:
        return [_build(args[0], x) for x in v]
    return v


class _Record:
    """``to_dict`` / ``from_dict`` of a metrics dataclass: fields that are None are left out of
    the mapping (those named in ``_NULLS`` are kept, as JSON null)."""

    _NULLS: typing.ClassVar[tuple] = ()

    def to_dict(self) -> dict:
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)
                if getattr(self, f.name) is not None or f.name in self._NULLS}

    @classmethod
    def from_dict(cls, data: dict):
        hints = typing.get_type_hints(cls)
        return cls(**{f.name: _build(hints[f.name], data[f.name]) for f in dataclasses.fields(cls)
                      if f.name in data})


@dataclass(frozen=True)
class ErrorStats(_Record):
    """One statistic of the position, velocity and attitude errors, per axis."""

    pos_m: list[float]
    vel_mps: list[float]
    att_deg: list[float]


@dataclass(frozen=True)
class DivergedRun(_Record):
    run: int
    t_s: float | None          #: when it was first flagged (None: not recorded)
    cause: str

    _NULLS = ("t_s",)


@dataclass(frozen=True)
class Divergence(_Record):
    """The runs left out of the statistics: their count, the count per cause, the first runs."""

    count: int
    causes: dict[str, int]
    runs: list[DivergedRun]


@dataclass(frozen=True)
class AttitudeStats(_Record):
    """Roll, pitch, yaw errors (deg): 95th percentile, RMS and maximum of the absolute error, and
    the 95th percentile about each run's own mean (what a reference sharing the vehicle's bench,
    level and field sees: P4's MTi)."""

    p95_deg: list[float]
    rms_deg: list[float]
    max_abs_deg: list[float]
    p95_about_run_mean_deg: list[float]


@dataclass(frozen=True)
class Resets(_Record):
    """The divergence monitor's resets (P4): count, runs reset, per-run times and the causes."""

    count: int
    runs_with_reset: int
    mean_per_run: float
    times_s: list[list[float]]
    causes: list[str]


@dataclass(frozen=True)
class Cost(_Record):
    """CPU time of the estimator: per run, in propagation, per epoch and run; runs per batch;
    apart, the seconds spent compiling (or loading compiled) kernels in its calls, once per
    worker process, which the per-run figures never count (None: not measured, older files)."""

    ms_per_run: float
    propagate_ms_per_run: float
    epoch_us_per_run: float
    batch_runs: float
    compile_s: float | None = None


@dataclass(frozen=True)
class QuantityStats(_Record):
    """A quantity over a window (P2's Table 1 format): largest positive and negative values,
    standard deviation, RMS and the 95th percentile of its absolute value."""

    max_pos: float
    max_neg: float
    std: float
    rms: float
    p95_abs: float


@dataclass(frozen=True)
class HorizontalStats(_Record):
    """A window's horizontal position error, m: its RMS over the runs and epochs, and over the
    runs its value at the window's last epoch (``final``: an outage's drift at its end; a run
    with no record there, a closed-loop run landed before it, is left out) and each run's
    largest in the window (``max``: the drift's worst, as an RMS over the runs)."""

    rms: float                      #: m
    final: float | None = None      #: m
    max: float | None = None        #: m


@dataclass(frozen=True)
class WindowNees(_Record):
    average: float
    fraction_inside: float       #: of the window's epochs whose average NEES is in its band


@dataclass(frozen=True)
class Window(_Record):
    """The statistics of a time window: per quantity (``north_m``, ``east_m``, ``height_m`` (up
    positive), ``speed_mps`` (horizontal speed error norm), ``heading_deg`` (yaw error), and
    ``roll_deg``, ``pitch_deg``, ``yaw_deg`` where the Euler errors are recorded); in the mapping
    the quantities sit beside ``horizontal_m`` and ``nees``."""

    quantities: dict[str, QuantityStats] = field(default_factory=dict)
    horizontal_m: HorizontalStats | None = None
    nees: WindowNees | None = None

    def to_dict(self) -> dict:
        out = {k: q.to_dict() for k, q in self.quantities.items()}
        out.update({k: v.to_dict() for k, v in (("horizontal_m", self.horizontal_m), ("nees", self.nees))
                    if v is not None})
        return out

    @classmethod
    def from_dict(cls, data: dict) -> Window:
        return cls({k: QuantityStats.from_dict(v) for k, v in data.items() if k not in ("horizontal_m", "nees")},
                   _build(HorizontalStats, data.get("horizontal_m")), _build(WindowNees, data.get("nees")))


@dataclass(frozen=True)
class Nees(_Record):
    """The average over runs of the NEES of the 9 navigation errors against its chi-square band."""

    average: float               #: dimensionless, over the epochs from the settling time on
    band: list[float]            #: two-sided 95 % band of the average over the runs counted, dimensionless
    fraction_inside: float       #: fraction of the epochs whose average is inside its own band
    dim: int                     #: the states it is taken over (9)
    average_from_start: float    #: dimensionless, over every epoch after the first
    #: the mean of (error / sigma)^2 of each navigation error from the settling time on, over
    #: runs and epochs, in the order of :data:`~navsim.records.states.SIGMA_STATES`
    #: (att, vel, pos; N, E, D): 1 where the sigma describes the error (dimensionless)
    per_state: list[float] | None = None


@dataclass(frozen=True)
class Nis(_Record):
    """The average NIS of one measurement against its chi-square band."""

    average: float                #: dimensionless (its expected value is ``dim``)
    band: list[float]             #: two-sided 95 % band of the average, dimensionless
    dim: int                      #: the measurement's rows
    fraction_inside: float        #: fraction of the epochs whose average is inside its band


@dataclass(frozen=True)
class Sighting(_Record):
    """The position error at the last fix of one landmark sighting."""

    name: str
    t_s: float
    sigma_m: float               #: the camera's fix noise per axis there
    rms_ne_m: list[float]        #: RMS over runs of the north and east errors
    max_ratio: float             #: the largest abs(error) / sigma
    rms_before_m: float          #: RMS horizontal error just before the sighting


@dataclass(frozen=True)
class SpreadStats(_Record):
    median: float
    max: float


@dataclass(frozen=True)
class WindStats(_Record):
    """The wind estimate's error against the truth's steady wind (the scenario's, changing as it
    sets), m/s, horizontal, from the settling time on (score from 60 s after the first GNSS
    fix with ``settle_s``): ``rms_mps`` over the runs and epochs, ``final_mps`` the RMS over the
    runs of the last epoch's; ``rms_axes_mps`` per axis N, E, D (None on an axis not estimated)."""

    rms_mps: float
    final_mps: float
    rms_axes_mps: list[float | None]


@dataclass(frozen=True)
class Landmarks(_Record):
    """Landmark fixes: the share of (run, sighting, axis) within 3 sigma, the largest ratio, the
    RMS error after the sightings and before them (the growth between them)."""

    count: int
    fraction_within_3sigma: float
    max_ratio: float
    rms_after_m: float
    rms_before_m: SpreadStats
    sightings: list[Sighting]


@dataclass(frozen=True)
class EstimatorMetrics(_Record):
    """The scores of one estimator over the runs counted (the diverged ones left out).

    Errors, NEES and NIS are scored from ``settle_s`` on; ``convergence_s`` and the windows use
    the whole run; ``final`` is the RMS over runs of each run's last recorded epoch. Sections
    are None where nothing was scored (no run counted, no covariance, no Euler errors, ...)."""

    runs_counted: int
    diverged_runs: int
    settle_s: float
    divergence: Divergence | None = None
    rms: ErrorStats | None = None
    max_abs: ErrorStats | None = None
    p99: ErrorStats | None = None          #: 99th percentile of the absolute error
    #: when the RMS position error settles (:func:`navsim.scoring.stats.convergence_time`)
    convergence_s: float | None = None
    final: ErrorStats | None = None
    attitude: AttitudeStats | None = None
    resets: Resets | None = None
    cost: Cost | None = None
    windows: dict[str, Window] | None = None
    nees: Nees | None = None
    nis: dict[str, Nis] | None = None
    landmarks: Landmarks | None = None
    wind: WindStats | None = None          #: with a wind state: its error (estimate - steady wind)
    #: the 95 % intervals of the metrics, the runs as the samples, in the mapping's shape
    #: (``ci95.rms.pos_m`` is ``[[lo, hi]] * 3`` for ``rms.pos_m``; :meth:`interval`); NaN
    #: (JSON null) where a metric has none: a maximum, fewer than two runs
    #: (:mod:`navsim.scoring.intervals` gives the method of each)
    ci95: dict | None = None

    _NULLS = ("convergence_s",)

    def to_dict(self) -> dict:
        out = super().to_dict()
        if self.rms is None:                  # nothing scored: no convergence either
            out.pop("convergence_s", None)
        return out

    def get(self, path: str):
        """The value at a dotted path of :meth:`to_dict` (``rms.pos_m``); None if absent."""
        return lookup(self.to_dict(), path)

    def interval(self, path: str):
        """The 95 % interval of the metric at ``path`` (``[lo, hi]``, per axis a list of them);
        None where there is none."""
        return None if self.ci95 is None else lookup(self.ci95, path)


@dataclass(frozen=True)
class IronErrors(_Record):
    """A calibration error (%) over the runs: mean, 95th percentile, maximum (None: no run)."""

    mean: float | None
    p95: float | None
    max: float | None
    #: the 95 % intervals of ``mean`` (Student's t) and ``p95`` (order statistics), the runs
    #: as the samples; the maximum has none
    ci95: dict | None = None

    _NULLS = ("mean", "p95", "max")


@dataclass(frozen=True)
class CalibrationAt(_Record):
    t_s: float
    hard_iron_pct: IronErrors    #: hard-iron error in % of the field magnitude
    soft_iron_pct: IronErrors    #: soft-iron error, relative Frobenius norm in %


@dataclass(frozen=True)
class CalibrationScore(_Record):
    """A magnetometer's online calibration scored when the true heading has made ``turns`` full
    turns (``after_<turns>_turns`` in the mapping; None: it never did) and at the end."""

    runs: int
    turns_total: float
    final: CalibrationAt
    turns: float = 2.0
    after_turns: CalibrationAt | None = None

    def to_dict(self) -> dict:
        out = {"runs": self.runs, "turns_total": self.turns_total}
        if self.after_turns is not None:
            out[self.after_key(self.turns)] = self.after_turns.to_dict()
        out["final"] = self.final.to_dict()
        return out

    @staticmethod
    def after_key(turns: float) -> str:
        return f"after_{turns:g}_turns"

    @classmethod
    def from_dict(cls, data: dict) -> CalibrationScore:
        after = [k for k in data if k.startswith("after_") and k.endswith("_turns")]
        turns = float(after[0][len("after_"):-len("_turns")]) if after else 2.0
        return cls(data["runs"], data["turns_total"], CalibrationAt.from_dict(data["final"]), turns,
                   CalibrationAt.from_dict(data[after[0]]) if after else None)


@dataclass(frozen=True)
class Verdict(_Record):
    """A published number or claim (:class:`navsim.records.reference.PaperCheck`) against
    ours: ``passed`` is None where there is no verdict (rule ``none``, or no number of ours)."""

    estimator: str
    metric: str
    rule: str
    bound: float | list | None           #: the paper's number or the threshold (None: not resolved)
    ours: float | list | None
    passed: bool | None
    tolerance: float | None = None       #: ``close`` only
    claim: str | None = None
    of: str | None = None                #: a claim relative to this estimator (``bound``: its metric × ``times``)
    times: float | None = None
    ours_ci95: list | None = None        #: our metric's 95 % interval, ``[lo, hi]`` per component, if any
    runs: int | None = None              #: the runs behind the interval
    #: True where the interval straddles the bound: no verdict at these runs (``passed`` None)
    undecided: bool | None = None
    runs_needed: int | None = None       #: undecided: the runs at which it would be decided

    _NULLS = ("bound", "ours", "passed")


@dataclass(frozen=True)
class RunMetrics(_Record):
    """The scores of a run of a scenario, as ``metrics.json`` holds them.

    ``closed_loop`` (navigation in the loop: outcomes, miss distances, landing consistency) is
    the mapping of :func:`navsim.scoring.closed_loop.closed_loop_metrics`."""

    scenario: str
    runs: int
    runs_done: int
    seed: int
    failed_runs: dict[str, str]
    interrupted: bool
    estimators: dict[str, EstimatorMetrics]
    calibration: dict[str, CalibrationScore] | None = None
    closed_loop: dict | None = None
    wall_s: float | None = None
    paper_checks: list[Verdict] | None = None    #: the scenario's ``reference``, judged


def lookup(metrics: dict, path: str):
    """The value at a dotted path of a metrics mapping; None if absent."""
    node = metrics
    for part in path.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node
