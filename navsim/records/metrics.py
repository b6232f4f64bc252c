"""The scores as typed objects: :class:`EstimatorMetrics` per estimator, :class:`CalibrationScore`
per calibrated magnetometer, :class:`RunMetrics` for a whole run (``metrics.json``).

Every class turns into the JSON's nested mapping with ``to_dict()`` (a section that was not
scored, None, is left out) and back with ``from_dict()``; :meth:`EstimatorMetrics.get` reads a
dotted path of that mapping (``rms.pos_m``, ``windows.low_leg.height_m.std``), as scenarios'
``reference`` and sweeps' ``metrics`` name them.

Units are in the names: ``_m``, ``_mps``, ``_deg``, ``_s``, ``_pct``; per-axis values are
``[N, E, D]`` for position and velocity and ``[x, y, z]`` (rotation vector) for attitude.

``from_dict()`` checks what it reads against the annotations (a number where a number is
expected, three per axis, every required key there): a mapping that is not what navsim writes
(a hand-edited or damaged ``metrics.json``) raises :class:`MetricsError` naming the key path;
:func:`read_metrics` reads the file and names it too.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path

from navsim.foundations.errors import UsageError

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


class MetricsError(ValueError):
    """A metrics mapping that is not what navsim writes: the key path (``estimators.KF.rms.pos_m[0]``,
    "" at the top), what is there and what was expected."""

    def __init__(self, message: str, key: str = ""):
        self.message, self.key = message, key
        super().__init__(f"{key}: {message}" if key else message)

    def under(self, part: str) -> "MetricsError":
        """The same error one level up, under the key (or ``[index]``) ``part``."""
        return MetricsError(self.message, part + ("." if self.key and not self.key.startswith("[") else "") + self.key)


_EXPECTED = {float: "a number (or null)", int: "an integer", str: "a string", bool: "true or false",
             dict: "a mapping", list: "a list"}


def _describe(v) -> str:
    """What ``v`` (from JSON) is, for a message."""
    if isinstance(v, (dict, list)):
        return f"a {'mapping' if isinstance(v, dict) else 'list'} of {len(v)}"
    text = json.dumps(v) if isinstance(v, (str, int, float, bool)) or v is None else repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _child(part: str, tp, v):
    """:func:`_build` of the value under ``part``, its errors named with the key."""
    try:
        return _build(tp, v)
    except MetricsError as exc:
        raise exc.under(part) from None


def _scalar(tp, v):
    """``v`` as the plain type ``tp`` (float, int, str, bool, dict, list); :class:`MetricsError`
    if it is not one."""
    if tp is float and isinstance(v, numbers.Real) and not isinstance(v, bool):
        return v
    if tp is int and isinstance(v, numbers.Real) and not isinstance(v, bool) and float(v).is_integer():
        return v if isinstance(v, numbers.Integral) else int(v)
    if tp in (str, bool, dict, list) and isinstance(v, tp):
        return v
    if tp not in _EXPECTED:
        return v
    raise MetricsError(f"is {_describe(v)} (expected {_EXPECTED[tp]})")


def _build(tp, v):
    """``v`` (from JSON) as the annotated type ``tp``, checked; null where a number is expected
    is NaN (strict JSON writes NaN as null), null where the type allows None is None."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        if v is None:
            return None
        if len(options) > 1:                  # float | list: the first that fits
            for option in options:
                try:
                    return _build(option, v)
                except MetricsError:
                    pass
            raise MetricsError(f"is {_describe(v)} (expected " + " or ".join(
                _EXPECTED.get(typing.get_origin(o) or o, "a mapping") for o in options) + ")")
        tp = options[0]
        origin, args = typing.get_origin(tp), typing.get_args(tp)
    if v is None:
        if tp is float:
            return math.nan
        raise MetricsError(f"is null (expected {_EXPECTED.get(origin or tp, 'a mapping')})")
    if isinstance(tp, type) and issubclass(tp, _Record):
        if not isinstance(v, dict):
            raise MetricsError(f"is {_describe(v)} (expected a mapping)")
        return None if v == {} else tp.from_dict(v)       # {}: a section left empty (older files)
    if origin is dict:
        return {k: _child(str(k), args[1], x) for k, x in _scalar(dict, v).items()}
    if origin is list and args:
        return [_child(f"[{i}]", args[0], x) for i, x in enumerate(_scalar(list, v))]
    return _scalar(tp, v)


def check_typed(tp, value, key: str) -> None:
    """:class:`MetricsError` naming ``key`` unless ``value`` is of the annotated type ``tp``
    (what :meth:`_Record.from_dict` checks; for the fields of another record, ``run.json``'s)."""
    _child(key, tp, value)


def _check_numbers(v, key: str) -> None:
    """:class:`MetricsError` unless every leaf of ``v`` (mappings and lists) is a number or null."""
    if isinstance(v, dict):
        for k, x in v.items():
            _check_numbers(x, f"{key}.{k}")
    elif isinstance(v, list):
        for i, x in enumerate(v):
            _check_numbers(x, f"{key}[{i}]")
    elif v is not None and not (isinstance(v, numbers.Real) and not isinstance(v, bool)):
        raise MetricsError(f"is {_describe(v)} (expected a number or null)", key)


class _Record:
    """``to_dict`` / ``from_dict`` of a metrics dataclass: fields that are None are left out of
    the mapping (those named in ``_NULLS`` are kept, as JSON null)."""

    _NULLS: typing.ClassVar[tuple] = ()
    #: field -> the length of its list (3 per axis)
    _LENGTHS: typing.ClassVar[dict] = {}
    #: the fields that are trees (mappings, lists) of numbers only (the intervals)
    _NUMBER_TREES: typing.ClassVar[tuple] = ()

    def to_dict(self) -> dict:
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)
                if getattr(self, f.name) is not None or f.name in self._NULLS}

    @classmethod
    def from_dict(cls, data: dict):
        """The record of the mapping ``data``, checked: :class:`MetricsError` naming the key path
        of a value of the wrong type or length, or of a required key that is missing."""
        if not isinstance(data, dict):
            raise MetricsError(f"is {_describe(data)} (expected a mapping)")
        hints = typing.get_type_hints(cls)
        fields = dataclasses.fields(cls)
        missing = [f.name for f in fields if f.name not in data and f.default is dataclasses.MISSING
                   and f.default_factory is dataclasses.MISSING]
        if missing:
            raise MetricsError(f"is missing the key{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
        out = {}
        for f in (f for f in fields if f.name in data):
            out[f.name] = _child(f.name, hints[f.name], data[f.name])
            n = cls._LENGTHS.get(f.name)
            if n is not None and out[f.name] is not None and len(out[f.name]) != n:
                raise MetricsError(f"has {len(out[f.name])} values (expected {n} numbers)", f.name)
            if f.name in cls._NUMBER_TREES:
                _check_numbers(out[f.name], f.name)
        return cls(**out)


@dataclass(frozen=True)
class ErrorStats(_Record):
    """One statistic of the position, velocity and attitude errors, per axis."""

    pos_m: list[float]
    vel_mps: list[float]
    att_deg: list[float]

    _LENGTHS = {"pos_m": 3, "vel_mps": 3, "att_deg": 3}


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

    _LENGTHS = {"p95_deg": 3, "rms_deg": 3, "max_abs_deg": 3, "p95_about_run_mean_deg": 3}


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
        if not isinstance(data, dict):
            raise MetricsError(f"is {_describe(data)} (expected a mapping)")
        return cls({k: _child(k, QuantityStats, v) for k, v in data.items() if k not in ("horizontal_m", "nees")},
                   _child("horizontal_m", HorizontalStats | None, data.get("horizontal_m")),
                   _child("nees", WindowNees | None, data.get("nees")))


@dataclass(frozen=True)
class Nees(_Record):
    """The average over runs of the NEES of the 9 navigation errors against its chi-square band."""

    _LENGTHS = {"band": 2}

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

    _LENGTHS = {"band": 2}

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
    """A quantity's spread (over the landmark sightings): its median and its largest value, in
    the quantity's unit."""

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
    _NUMBER_TREES = ("ci95",)

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
    _NUMBER_TREES = ("ci95",)


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
        if not isinstance(data, dict):
            raise MetricsError(f"is {_describe(data)} (expected a mapping)")
        missing = [k for k in ("runs", "turns_total", "final") if k not in data]
        if missing:
            raise MetricsError(f"is missing the key{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
        after = [k for k in data if k.startswith("after_") and k.endswith("_turns")]
        try:
            turns = float(after[0][len("after_"):-len("_turns")]) if after else 2.0
        except ValueError:
            raise MetricsError("is not after_<turns>_turns with a number of turns", after[0]) from None
        return cls(_child("runs", int, data["runs"]), _child("turns_total", float, data["turns_total"]),
                   _child("final", CalibrationAt, data["final"]), turns,
                   _child(after[0], CalibrationAt, data[after[0]]) if after else None)


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
    #: what the paper's number is (:data:`navsim.records.reference.KINDS`); for ``single_run``
    #: the fields below: judged against the spread of our single runs, not on ``ours_ci95``
    kind: str = "population"
    run_range: list | None = None        #: the 95 % range of one run, ``[lo, hi]`` per component (None: open)
    percentile: list | None = None       #: the paper's number's percentile among our runs, per component
    share: float | None = None           #: a bound: the share of our runs meeting it (every component)
    share_ci95: list | None = None       #: its Clopper-Pearson 95 % interval
    coverage_ci95: list | None = None    #: the 95 % interval of the share of single runs the range holds

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


def read_metrics(path) -> RunMetrics:
    """``metrics.json`` at ``path``, checked (:meth:`RunMetrics.from_dict`); a file that is not
    JSON or not what navsim writes is a :class:`~navsim.foundations.errors.UsageError` naming
    the file and the key path. ``OSError`` where it cannot be read."""
    hint = "hint: navsim run writes it; run the scenario again (or undo the edit)"
    try:
        data = json.loads(Path(path).read_bytes())
    except (UnicodeDecodeError, ValueError) as exc:
        raise UsageError(f"{path}: not JSON ({exc}); {hint}") from None
    try:
        return RunMetrics.from_dict(data)
    except MetricsError as exc:
        raise UsageError(f"{path}: {exc}; {hint}") from None


def lookup(metrics: dict, path: str):
    """The value at a dotted path of a metrics mapping; None if absent."""
    node = metrics
    for part in path.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node
