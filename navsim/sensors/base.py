"""What every sensor shares: the data container, per-run random streams, Gauss-Markov
processes, fault windows (each kind's allowed ones declared in its
:class:`~navsim.sensors.registry.SensorKind`) and sampling on the truth grid."""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

import numpy as np

from navsim.foundations.config import MAX_DURATION_S, Node, check_number, check_numbers
from navsim.foundations.errors import ScenarioError
from navsim.sensors.kernels import first_order
from navsim.sensors.registry import FAULT_TYPES, get as get_kind


@dataclass(frozen=True)
class Measurements:
    """What an estimator sees of a sensor: its samples, never their true errors.

    ``t_s`` ``(M,)`` the sample times; ``values[key]`` ``(B, M, ...)`` in SI (the outputs its kind
    declares: :func:`navsim.sensors.output_fields`); ``valid`` ``(B, M)`` False where the sensor
    gave no output; ``meta`` what is known on board (rates, the landmarks' coordinates, the date)."""

    name: str
    kind: str
    t_s: np.ndarray
    values: dict
    valid: np.ndarray
    meta: dict


@dataclass
class SensorData:
    """Measurements of one sensor for ``B`` runs at ``M`` sample times.

    ``values[name]`` are ``(B, M, ...)`` arrays in SI (see each emulator for its keys);
    ``valid`` is ``(B, M)``: False where the sensor gave no output (outage, out of range).
    ``errors`` holds the true error components (for scoring estimators), broadcastable to
    ``(B, M, ...)``.
    """

    name: str
    kind: str
    t_s: np.ndarray
    values: dict
    valid: np.ndarray
    errors: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    @property
    def runs(self) -> int:
        return self.valid.shape[0]

    def measurements(self) -> Measurements:
        """The samples without their true errors (what an estimator is handed)."""
        return Measurements(self.name, self.kind, self.t_s, self.values, self.valid, self.meta)

    def run(self, i: int) -> "SensorData":
        """Run ``i`` as a batch of one."""
        pick = lambda a: a[i:i + 1] if np.ndim(a) and np.shape(a)[0] == self.runs else a
        return SensorData(self.name, self.kind, self.t_s, {k: pick(v) for k, v in self.values.items()},
                          self.valid[i:i + 1], {k: pick(v) for k, v in self.errors.items()},
                          dict(self.meta))


def zeros3():
    """A spec dataclass field defaulting to ``np.zeros(3)`` (a three-axis error that is off)."""
    return field(default_factory=lambda: np.zeros(3))


def truth_step(data: "SensorData", truth) -> slice:
    """The truth samples at ``data``'s sample times (every ``step``-th, as many as ``data.t_s``:
    the step from the sample period, as :func:`sampling` took them), for plots."""
    m = len(data.t_s)
    if m < 2:
        return slice(0, m)
    step = max(1, round((data.t_s[1] - data.t_s[0]) / truth.dt_s))
    return slice(0, step * (m - 1) + 1, step)


def stream_id(name: str) -> int:
    """A stable number for a sensor's random stream (independent of Python's hash seed)."""
    return zlib.crc32(name.encode())


#: the version of how the random streams are drawn (2: one stream per error process, 2026-12-04):
#: results and chunk stores keyed with another are not the same data (``data_key``)
RANDOM_STREAMS = 2


def run_generators(seed: int, runs, name: str, process: str | None = None) -> list[np.random.Generator]:
    """One Generator per run for sensor ``name``'s error ``process``: the stream of
    ``SeedSequence(seed, spawn_key=(i, stream_id(name), stream_id(process)))`` for run ``i``
    (without ``process``: ``(i, stream_id(name))``, a stream of its own such as the initial
    errors'). Each error process of each run draws from its own stream, so the same run gets
    the same numbers whatever the batch it is emulated in, a process draws only what it uses
    (a block can be drawn where it is used), and switching one process off or changing its
    length leaves every other's draws as they were."""
    key = (stream_id(name),) if process is None else (stream_id(name), stream_id(process))
    return [np.random.Generator(np.random.SFC64(np.random.SeedSequence(seed, spawn_key=(int(i),) + key)))
            for i in runs]


def normals(gens, shape, dtype=np.float64) -> np.ndarray:
    """Standard normal draws ``(B, *shape)``, one Generator per run. ``float32`` draws are
    twice as fast; white noise of long series uses them (7 significant digits of a noise
    sample are plenty)."""
    shape = tuple(np.atleast_1d(shape))
    out = np.empty((len(gens), *shape), dtype)
    for g, o in zip(gens, out):
        g.standard_normal(out=o, dtype=dtype)
    return out


def gauss_markov(gens, n: int, dt: float, sigma, tau: float) -> np.ndarray:
    """First-order Gauss-Markov processes ``(B, n, k)`` (``k = len(sigma)``), stationary with
    std ``sigma`` and correlation time ``tau``: ``x[j] = a x[j-1] + w[j]``, ``a = exp(-dt/tau)``,
    ``x[0] ~ N(0, sigma^2)``."""
    sigma = np.atleast_1d(np.asarray(sigma, float))
    a = math.exp(-dt / tau)
    w = normals(gens, (n, sigma.size))
    w[:, 0, :] *= sigma
    w[:, 1:, :] *= sigma * math.sqrt(1.0 - a * a)
    first_order(w, a)
    return w


def random_walk(gens, n: int, dt: float, density) -> np.ndarray:
    """Random walks ``(B, n, k)`` starting at 0 with ``density`` per sqrt(s)."""
    density = np.atleast_1d(np.asarray(density, float))
    w = normals(gens, (n, density.size)) * (density * math.sqrt(dt))
    w[:, 0, :] = 0.0
    return np.cumsum(w, axis=1)


def decimation(truth_rate_hz: float, rate_hz: float, name: str) -> int:
    """Truth samples per sensor sample; the sensor rate must divide the truth rate."""
    step = truth_rate_hz / rate_hz
    if abs(step - round(step)) > 1e-9 or round(step) < 1:
        raise ScenarioError(f"rate {rate_hz:g} Hz does not divide the truth rate {truth_rate_hz:g} Hz",
                            key=f"sensors.{name}.rate_hz",
                            expected=f"{truth_rate_hz:g} Hz divided by a whole number")
    return int(round(step))


@dataclass
class Sampling:
    """Where a sensor samples the truth: run indices, truth step, times, and the seed and
    sensor name of its error processes' random streams (:meth:`rng`)."""

    runs: list
    B: int
    step: int
    t: np.ndarray
    M: int
    dt: float
    seed: int
    name: str

    def rng(self, process: str) -> list[np.random.Generator]:
        """The runs' generators of the sensor's error ``process`` (:func:`run_generators`)."""
        return run_generators(self.seed, self.runs, self.name, process)


def sampling(truth, rate_hz: float, seed: int, runs, name: str) -> Sampling:
    """The common set-up of every emulator."""
    runs = list(runs)
    step = decimation(truth.meta.get("rate_hz", 1.0 / truth.dt_s), rate_hz, name)
    t = truth.t_s[::step]
    return Sampling(runs, len(runs), step, t, len(t), step * truth.dt_s, seed, name)


# --- fault windows -------------------------------------------------------------------------------

#: the largest bias, radius or distance of a fault, m; the largest noise factor; the strongest
#: disturbance field per axis, uT (the Earth's is 25-65 uT); the most points of a power line
MAX_FAULT_M = 1e6
MAX_FAULT_FACTOR = 1e6
MAX_FAULT_UT = 1e4
MAX_SOURCE_POINTS = 10_000


@dataclass(frozen=True)
class Fault:
    """A fault in ``[start_s, end_s)``.

    ``outage``: no output. ``bias``: ``value`` (m, or a NED vector in m for GNSS position) added
    exactly. ``degraded``: white noise times ``factor``. ``interference`` (GNSS, P1's power line):
    near ``source`` (list of ``[lat_deg, lon_deg, h_m]`` points, a polyline) the noise grows as
    ``1 + (radius_m / d)^2`` and lock is lost within ``lost_m``. ``disturbance``
    (magnetometer, P4): a body-fixed field ``value`` (T, from ``hard_iron_uT``) that ramps in
    over ``ramp_s`` from ``start_s`` and out over ``ramp_s`` after ``end_s`` (a magnetised payload,
    a motor or pump current switched on).
    """

    type: str
    start_s: float = 0.0
    end_s: float = math.inf
    value: np.ndarray | float = 0.0
    factor: float = 1.0
    source: tuple = ()
    radius_m: float = 100.0
    lost_m: float = 30.0
    ramp_s: float = 0.0

    def ramp(self, t_s: np.ndarray) -> np.ndarray:
        """0..1: how much of a ``disturbance`` is on at ``t_s``: fully on over ``[start_s +
        ramp_s, end_s)``, ramping in from ``start_s`` and out until ``end_s + ramp_s``
        (``ramp_s = 0``: exactly the window ``[start_s, end_s)``)."""
        if self.ramp_s <= 0.0:
            return self.active(t_s).astype(float)
        on = np.clip((t_s - self.start_s) / self.ramp_s, 0.0, 1.0)
        return on * np.clip(1.0 - (t_s - self.end_s) / self.ramp_s, 0.0, 1.0)

    def active(self, t_s: np.ndarray) -> np.ndarray:
        return (t_s >= self.start_s) & (t_s < self.end_s)


def parse_faults(data, path: str, file: str | None = None, vector: bool = False) -> tuple[Fault, ...]:
    """Read a list of fault windows (see :class:`Fault`)."""
    if data is None:
        return ()
    if not isinstance(data, list):
        raise ScenarioError("is not a list", file=file, key=path, expected="a list of fault windows")
    out = []
    for i, item in enumerate(data):
        node = Node(item, f"{path}[{i}]", file)
        kind = node.get("type", str, choices=FAULT_TYPES)
        kw = dict(type=kind, start_s=node.get("start_s", float, 0.0, minimum=0.0, maximum=MAX_DURATION_S),
                  end_s=node.get("end_s", float, math.inf, minimum=0.0, maximum=MAX_DURATION_S))
        if kw["end_s"] <= kw["start_s"]:
            raise node.error(f"is {kw['end_s']:g}", "end_s", expected=f"a time after start_s ({kw['start_s']:g})")
        err = lambda key: (lambda m, e: node.error(m, key, e))
        if kind == "bias":
            if vector:
                node._seen.add("value_m")
                raw = node.data.get("value_m")
                if raw is None:
                    raise node.missing("value_m", "a NED vector in metres, e.g. [0, 0, -80]")
                if not isinstance(raw, list):
                    raw = [0.0, 0.0, check_number(raw, float, minimum=-MAX_FAULT_M, maximum=MAX_FAULT_M,
                                                  error=err("value_m"))]
                kw["value"] = np.array(check_numbers(raw, 3, minimum=-MAX_FAULT_M, maximum=MAX_FAULT_M,
                                                     error=err("value_m")), float)
            else:
                kw["value"] = node.get("value_m", float, minimum=-MAX_FAULT_M, maximum=MAX_FAULT_M)
        elif kind == "degraded":
            kw["factor"] = node.get("factor", float, minimum=1.0, maximum=MAX_FAULT_FACTOR)
        elif kind == "disturbance":
            node._seen.add("hard_iron_uT")
            raw = node.data.get("hard_iron_uT")
            if raw is None:
                raise node.missing("hard_iron_uT", "a body-axes field in microtesla, e.g. [12, -8, 5]")
            kw["value"] = np.array(check_numbers(raw, 3, minimum=-MAX_FAULT_UT, maximum=MAX_FAULT_UT,
                                                 error=err("hard_iron_uT")), float) * 1e-6
            kw["ramp_s"] = node.get("ramp_s", float, 0.0, minimum=0.0, maximum=MAX_DURATION_S)
        elif kind == "interference":
            node._seen.add("source")
            src = node.data.get("source")
            if not (isinstance(src, list) and src and len(src) <= MAX_SOURCE_POINTS):
                raise node.error("is missing or malformed", "source",
                                 expected=f"a list of 1 to {MAX_SOURCE_POINTS} [lat_deg, lon_deg, h_m] points (a power line)")
            kw["source"] = tuple(_point(p, err(f"source[{j}]")) for j, p in enumerate(src))
            kw["radius_m"] = node.get("radius_m", float, 100.0, exclusive_minimum=0.0, maximum=MAX_FAULT_M)
            kw["lost_m"] = node.get("lost_m", float, 30.0, minimum=0.0, maximum=MAX_FAULT_M)
        node.done()
        out.append(Fault(**kw))
    return tuple(out)


def _point(p, error) -> tuple:
    """A ``[lat_deg, lon_deg, h_m]`` point of an interference source."""
    lat, lon, h = check_numbers(p, 3, error=error)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and abs(h) <= MAX_FAULT_M):
        raise error(f"is {p!r}", f"[lat_deg, lon_deg, h_m]: latitude -90..90, longitude -180..180, "
                    f"|h_m| <= {MAX_FAULT_M:g}")
    return (lat, lon, h)


def check_faults(faults, kind: str, duration_s: float, name: str) -> None:
    """Each fault of sensor ``name`` (of ``kind``) is one a ``kind`` can have and starts within
    a flight of ``duration_s`` (a window starting at or after its end would score nothing)."""
    allowed = get_kind(kind).faults
    for i, f in enumerate(faults):
        if f.type not in allowed:
            raise ScenarioError(f"a {kind} cannot have a '{f.type}' fault", key=f"sensors.{name}.faults[{i}]",
                                expected="one of " + ", ".join(allowed) if allowed else "no fault windows")
        if f.start_s >= duration_s:
            raise ScenarioError(f"the {f.type} window {_window(f)} starts after the flight ends "
                                f"({duration_s:.6g} s): it would change nothing",
                                key=f"sensors.{name}.faults[{i}].start_s",
                                expected=f"a start within the flight (0 to {duration_s:.6g} s)")


def _window(f: Fault) -> str:
    return f"[{f.start_s:g}, {f.end_s:g}) s" if math.isfinite(f.end_s) else f"from {f.start_s:g} s"


def apply_outages(valid: np.ndarray, t_s: np.ndarray, faults) -> None:
    for f in faults:
        if f.type == "outage":
            valid[:, f.active(t_s)] = False
