"""Scenario files: one YAML file describes an experiment.

So far a scenario describes the flight::

    name: p0_flight
    description: P0's track in calm air
    aircraft: survey10          # a folder of aircraft/, or ./my_plane beside the scenario
    track: p0                   # a shipped track, or a mapping with start and segments
    environment: {wind: {force: 3, from_deg: 270}}
    flight: {rate_hz: 100}
    sensors:                    # name -> catalog entry, overrides, error sources off, faults
      imu: {model: p0_imu}
      gnss: {model: p0_bd2, faults: [{type: outage, start_s: 200, end_s: 260}]}
    montecarlo: {runs: 100, seed: 1}

Every key is checked before anything runs; a mistake raises :class:`ScenarioError` naming the
file, the key path, what was expected and a hint.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navsim.experiment.closed_loop import parse_closed_loop
from navsim.experiment.driver import InitialErrors
from navsim.experiment.reference import parse_reference
from navsim.flight.airframe import ENVELOPE_FILE, JSBSIM_MODEL_KEY, MULTIROTOR, check_controller, load_airframe
from navsim.flight.rotorcraft import check_envelope, check_environment
from navsim.flight.environment import parse_environment
from navsim.flight.properties import AIRCRAFT_DIR
from navsim.flight.simulator import DEFAULT_AIRCRAFT, FlightConfig
from navsim.flight.track import check_segments, nominal_duration_s, parse_track
from navsim.foundations.config import (
    MAX_DURATION_S,
    MAX_RATE_HZ,
    MAX_RUNS,
    Node,
    check_number,
    check_numbers,
    close_match,
    load_yaml,
    plain_name,
    resolve_folder,
)
from navsim.foundations.errors import ScenarioError
from navsim.foundations.overrides import apply_overrides, blame
from navsim.navigation.estimators.factory import parse_estimators
from navsim.navigation.estimators.measurements import measurement_class, values_read as measurement_values_read
from navsim.records.reference import Reference
from navsim.records.vocabulary import check_metric_path
from navsim.sensors import height_fields, output_fields, parse_sensors, velocity_fields
from navsim.sensors.base import check_faults, decimation
from navsim.sensors.registry import INERTIAL

log = logging.getLogger(__name__)
#: the clipped fault windows already named (:func:`_warn_clipped_faults`): each once per process,
#: however many times the same scenario is checked (its parse, its flight, a budget's variants)
_CLIPPED_NAMED: set[str] = set()


@dataclass
class Scenario:
    name: str
    description: str
    flight: FlightConfig
    path: Path | None
    raw: dict
    sensors: tuple = ()
    runs: int = 1
    seed: int = 0
    workers: int = 1
    estimators: tuple = ()
    initial: object = None
    settle_s: float = 0.0
    windows: tuple = ()                  #: (name, start_s, end_s)
    reference: Reference | None = None    #: the published results it reproduces
    report: dict = field(default_factory=dict)
    closed_loop: object = None           #: navsim.experiment.closed_loop.ClosedLoopConfig, or None (open loop)
    #: the track's duration at its speeds, s (:func:`~navsim.flight.track.nominal_duration_s`,
    #: computed once by :func:`parse_scenario`): time-outs, progress, memory and window checks
    nominal_duration_s: float = math.nan
    #: the ``--set PATH=VALUE`` changes made to the file's mapping (already in :attr:`raw`)
    overrides: tuple = ()


def available_aircraft() -> list[str]:
    """The shipped aircraft: the folders of aircraft/ holding a ``navsim.yaml``."""
    return sorted(p.name for p in AIRCRAFT_DIR.iterdir() if (p / ENVELOPE_FILE).is_file())


TOP_KEYS = ("name", "description", "aircraft", "track", "environment", "flight", "sensors",
            "montecarlo", "estimators", "initial_errors", "metrics", "reference", "report",
            "closed_loop")


def parse_scenario(data, file: str | None = None) -> Scenario:
    node = Node(data, "", file)
    for key in node.data:
        if key not in TOP_KEYS:
            raise ScenarioError("is not a known key", file=file, key=str(key),
                                hint=close_match(str(key), TOP_KEYS))
    name = _name(node, file)
    description = node.get("description", str, "")
    aircraft, aircraft_dir, airframe = _aircraft(node, file)
    track = _track(node, file)
    check_segments(track, airframe.kind, file)
    node._seen.add("environment")
    environment = parse_environment(node.data.get("environment"), "environment", file)
    _check_start(track, environment, file)
    if airframe.kind == MULTIROTOR:
        check_environment(environment, file, track)
        check_envelope(track, airframe, file)
    node._seen.add("sensors")
    sensors = parse_sensors(node.data.get("sensors"), file)
    runs, seed, workers = _montecarlo(node.child("montecarlo", None))
    estimators = _estimators(node, sensors, file)
    initial = _initial(node.child("initial_errors", None))
    nominal_s = _duration(track, environment.surface_m, file)
    settle_s, windows = _metrics(node.child("metrics", None))
    reference = parse_reference(node.child("reference", None), [e.label for e in estimators],
                                lambda path, key: check_metric_path(path, windows, file=node.file, key=key))
    report = _report(node.child("report", None))
    rate_hz = _rate_hz(node.child("flight", None))
    _check_rates(sensors, rate_hz, file)
    closed_loop = None
    cl_node = node.child("closed_loop", None)
    if cl_node is not None:
        if not estimators:
            raise cl_node.error("needs estimators", "fly_on", expected="an estimators list to fly on")
        closed_loop = parse_closed_loop(cl_node, [e.label for e in estimators], sensors, track,
                                        nominal_s, rate_hz)
    node.done()
    config = FlightConfig(track=track, environment=environment, aircraft=aircraft, rate_hz=rate_hz,
                          aircraft_dir=aircraft_dir)
    scenario = Scenario(name=name, description=description, flight=config,
                        path=Path(file) if file else None, raw=data, sensors=sensors, runs=runs, seed=seed,
                        workers=workers, estimators=estimators, initial=initial, settle_s=settle_s,
                        windows=windows, reference=reference, report=report, closed_loop=closed_loop,
                        nominal_duration_s=nominal_s)
    check_scenario(scenario, nominal_s)   # closed loop too: its windows lie within the track as planned
    return scenario


def _duration(track, surface_m: float, file: str | None) -> float:
    """The track's nominal duration (over a surface at ``surface_m``), at most :data:`MAX_DURATION_S`."""
    duration = nominal_duration_s(track, surface_m)
    if not duration <= MAX_DURATION_S:
        raise ScenarioError(f"lasts {duration:.6g} s at its speeds", file=file, key="track",
                            expected=f"a flight of at most {MAX_DURATION_S:g} s")
    return duration


def _check_rates(sensors, rate_hz: float, file: str | None) -> None:
    """Each sensor samples the truth at its rate: at most the flight's (truth) rate, dividing it."""
    for cfg in sensors:
        rate = cfg.spec.rate_hz
        key = f"sensors.{cfg.name}.rate_hz"
        if rate > rate_hz + 1e-9:
            raise ScenarioError(f"is {rate:g} Hz, above the flight's (truth) rate {rate_hz:g} Hz", file=file, key=key,
                                expected=f"at most flight.rate_hz ({rate_hz:g} Hz), dividing it",
                                hint=f"flight: {{rate_hz: {rate:g}}}, or a lower sensor rate")
        try:
            decimation(rate_hz, rate, cfg.name)
        except ScenarioError as exc:
            raise exc.with_file(file or "<scenario>") from None


def _name(node: Node, file: str | None) -> str:
    """``name``: a plain name, by default the file's stem."""
    default = re.sub(r"[^A-Za-z0-9._-]", "_", Path(file).stem).lstrip(".") if file else "scenario"
    name = node.get("name", str, default or "scenario")
    if not plain_name(name):
        raise node.error(f"is '{name}'", "name",
                         expected="a plain name (letters, digits, '.', '_', '-'; no '/', no '..'): it names "
                         "the output folder reports/<name>",
                         hint="name: my_run (and --out DIR to write elsewhere than reports/)")
    return name


def _aircraft(node: Node, file: str | None) -> tuple[str, str | None, object]:
    """``aircraft``: a shipped folder of aircraft/ by name, or a folder beside or below the
    scenario by a relative path, holding ``navsim.yaml`` and ``<name>.xml`` (or naming a model of
    the jsbsim package in ``navsim.yaml``). Returns the model's
    name, the folder holding it (None: a shipped one) and its airframe
    (:func:`~navsim.flight.airframe.load_airframe`), refused where navsim has no controller for
    its class yet."""
    ref = node.get("aircraft", str, DEFAULT_AIRCRAFT)
    if "/" not in ref and "\\" not in ref:
        if ref not in available_aircraft():
            beside = plain_name(ref) and (Path(file).resolve().parent if file else Path.cwd()).joinpath(ref).is_dir()
            raise ScenarioError(f"'{ref}' is not a shipped aircraft ({AIRCRAFT_DIR})", file=file, key="aircraft",
                                expected="a folder name of aircraft/ (navsim list) or a relative path to a "
                                         "folder beside the scenario",
                                hint=f"the folder beside the scenario is aircraft: ./{ref}" if beside
                                else close_match(ref, available_aircraft()))
        folder, aircraft_dir = AIRCRAFT_DIR / ref, None
    else:
        folder = resolve_folder(ref, file=file, key="aircraft", what="an aircraft folder")
        aircraft_dir = str(folder.parent)
    if not plain_name(folder.name):
        raise ScenarioError(f"'{ref}' is a folder named '{folder.name}'", file=file, key="aircraft",
                            expected="a folder of a plain name (letters, digits, '.', '_', '-'): JSBSim loads "
                                     "the model by it")
    if not (folder / ENVELOPE_FILE).is_file():
        raise ScenarioError(f"'{ref}' has no {ENVELOPE_FILE}", file=file, key="aircraft",
                            expected=f"{ENVELOPE_FILE}: the aircraft's class and envelope (aircraft/README.md)")
    airframe = load_airframe(folder)
    if airframe.jsbsim_model is None and not (folder / f"{folder.name}.xml").is_file():
        raise ScenarioError(f"'{ref}' has no {folder.name}.xml", file=file, key="aircraft",
                            expected=f"{folder.name}.xml: the JSBSim model, named after its folder",
                            hint=f"or {JSBSIM_MODEL_KEY}: in its {ENVELOPE_FILE}, naming a model of the jsbsim package")
    check_controller(airframe, ref, file=file, key="aircraft")
    return folder.name, aircraft_dir, airframe


def _track(node: Node, file: str | None):
    """``track``: a shipped track name or a mapping (required)."""
    node._seen.add("track")
    if "track" not in node.data:
        raise ScenarioError("is missing", file=file, key="track",
                            expected="a shipped track name (p0, p3, p2_sea) or a mapping")
    try:
        return parse_track(node.data["track"], "track", file)
    except ScenarioError as exc:
        raise (exc if exc.file else exc.with_file(file or "<scenario>")) from None


def _montecarlo(mc: Node | None) -> tuple:
    """``montecarlo: {runs, seed, workers}`` as a tuple (defaults 1, 0, 1)."""
    if mc is None:
        return 1, 0, 1
    runs = mc.get("runs", int, 1, minimum=1, maximum=MAX_RUNS)
    seed = mc.get("seed", int, 0, minimum=0, maximum=MAX_SEED)
    workers = mc.get("workers", int, 1, minimum=1, maximum=MAX_WORKERS)
    mc.done()
    return runs, seed, workers


def _estimators(node: Node, sensors, file: str | None) -> tuple:
    """``estimators`` (none if absent); with estimators, exactly one IMU among ``sensors``."""
    if "estimators" not in node.data:
        return ()
    node._seen.add("estimators")
    estimators = parse_estimators(node.data["estimators"], {c.name: c.kind for c in sensors}, file)
    imu = [c for c in sensors if c.role == INERTIAL]
    if len(imu) != 1:
        raise ScenarioError(f"has {len(imu)} IMUs", file=file, key="sensors",
                            expected="exactly one sensor of kind imu when estimators are given")
    return estimators


def _metrics(node: Node | None) -> tuple:
    """``metrics: {settle_s, windows}`` as ``(settle_s, windows)``."""
    if node is None:
        return 0.0, ()
    settle_s = node.get("settle_s", float, 0.0, minimum=0.0, maximum=MAX_DURATION_S)
    windows = _windows(node)
    node.done()
    return settle_s, windows


#: the report's formats: the PDF, a PNG per page, the interactive page (report.html)
REPORT_FORMATS = ("pdf", "png", "html")


def _report(node: Node | None) -> dict:
    """``report: {formats, runs_plotted}`` (formats: any of :data:`REPORT_FORMATS`, all by
    default)."""
    report = {"formats": list(REPORT_FORMATS)}
    if node is None:
        return report
    node._seen.add("formats")
    fmts = node.data.get("formats", list(REPORT_FORMATS))
    if not (isinstance(fmts, list) and fmts and all(f in REPORT_FORMATS for f in fmts)):
        raise node.error(f"is {fmts!r}", "formats", expected="a list of " + ", ".join(REPORT_FORMATS))
    report["formats"] = fmts
    report["runs_plotted"] = node.get("runs_plotted", int, 5, minimum=0, maximum=MAX_RUNS)
    node.done()
    return report


def _rate_hz(node: Node | None) -> float:
    """``flight: {rate_hz}``, the simulation (truth) rate, Hz."""
    if node is None:
        return 100.0
    rate_hz = node.get("rate_hz", float, 100.0, minimum=RATE_HZ[0], maximum=RATE_HZ[1])
    node.done()
    return rate_hz


def _check_start(track, environment, file) -> None:
    """An air start at least :data:`MIN_START_AGL_M` above the surface, a hover at least
    :data:`MIN_HOVER_AGL_M`; a launch or a parked vehicle not below it."""
    start = track.start
    margin = {"air": MIN_START_AGL_M, "hover": MIN_HOVER_AGL_M}.get(start.type, 0.0)
    if start.alt_m < environment.surface_m + margin:
        where = "below" if start.alt_m < environment.surface_m else "just above"
        raise ScenarioError(f"is {start.alt_m:g} m, {where} the surface at {environment.surface_m:g} m",
                            file=file, key="track.start.alt_m",
                            expected=f"a start at least {margin:g} m above environment.surface_m")


def check_scenario(scenario: Scenario, duration_s: float) -> None:
    """The checks that need the whole scenario and its flight's duration: every time window
    (sensor faults, the wind's changes, ``metrics.settle_s``, the metric windows) within the flight (a closed-loop
    flight's: up to ``closed_loop.time_limit_s``, where its navigation may take it), each
    estimator's period a whole number of IMU steps, each measurement's ``field`` one its sensor
    produces.

    :func:`parse_scenario` runs it with the track's nominal duration (closed loop too);
    ``navsim run`` runs it
    again with the duration actually flown, before any sensor is emulated. Raises
    :class:`ScenarioError` naming the scenario file and the key.
    """
    file = str(scenario.path) if scenario.path else None
    # a closed-loop flight ends where its navigation takes it, at the latest at its time limit
    last_s = max(scenario.closed_loop.time_limit_s, duration_s) if scenario.closed_loop is not None else duration_s
    for cfg in scenario.sensors:
        try:
            check_faults(cfg.faults, cfg.kind, last_s, cfg.name)
        except ScenarioError as exc:
            raise exc.with_file(file or "<scenario>") from None
        _warn_clipped_faults(cfg, last_s, file)
    if scenario.settle_s >= last_s:
        raise ScenarioError(f"is {scenario.settle_s:g} s, not before the end of the flight ({last_s:.0f} s)",
                            file=file, key="metrics.settle_s",
                            expected=f"a time within the flight (0-{last_s:.0f} s)")
    for i, (t, _) in enumerate(scenario.flight.environment.wind_changes):
        if t >= last_s:
            raise ScenarioError(f"is {t:g} s, after the end of the flight ({last_s:.6g} s)", file=file,
                                key=f"environment.wind_changes[{i}].at_s",
                                expected=f"a time within the flight (0 to {last_s:.6g} s)")
    for i, (name, a, b) in enumerate(scenario.windows):
        for key, t, end in (("start_s", a, last_s), ("end_s", b, last_s + 1e-6)):
            if t >= end:
                raise ScenarioError(f"window '{name}' [{a:g}, {b:g}] s {'starts' if key == 'start_s' else 'ends'} "
                                    f"after the end of the flight ({end:.6g} s)", file=file,
                                    key=f"metrics.windows[{i}].{key}",
                                    expected=f"a window within the flight (0 to {end:.6g} s)")
    imu = [c for c in scenario.sensors if c.role == INERTIAL]
    if not scenario.estimators or not imu:
        return
    dt = 1.0 / imu[0].spec.rate_hz
    outputs = {c.name: output_fields(c.spec) for c in scenario.sensors}
    for i, est in enumerate(scenario.estimators):
        period = est.params.get("period_s")
        steps = None if period is None else period / dt
        if steps is not None and (round(steps) < 1 or abs(steps - round(steps)) > 1e-6 * steps):
            raise ScenarioError(f"is {period:g} s", file=file, key=f"estimators[{i}].period_s",
                                expected=f"a whole number of the IMU's steps ({dt:g} s at {imu[0].spec.rate_hz:g} Hz)")
        for key, m in _measurement_entries(est.params, f"estimators[{i}]"):
            _check_field(m, outputs[m["sensor"]], file, key)
            _check_reads(m, outputs[m["sensor"]], file, key)


def _warn_clipped_faults(cfg, last_s: float, file: str | None) -> None:
    """A logging warning for each fault window of sensor ``cfg`` that starts within the flight
    (``last_s``, s) and ends after it: it is clipped to the flight's end. Each message once."""
    for i, f in enumerate(cfg.faults):
        if not (f.start_s < last_s < f.end_s < math.inf):
            continue
        message = (f"{file or '<scenario>'}: sensors.{cfg.name}.faults[{i}]: the {f.type} window of sensor "
                   f"'{cfg.name}' [{f.start_s:g}, {f.end_s:g}) s ends after the flight ({last_s:.6g} s): "
                   f"it is clipped to [{f.start_s:g}, {last_s:.6g}) s (end it by {last_s:.6g} s, or leave "
                   "end_s out for a fault to the end)")
        if message not in _CLIPPED_NAMED:
            _CLIPPED_NAMED.add(message)
            log.warning("%s", message)


#: the estimator types that read sensors through their measurement models alone (their
#: ``measurements``, a federated filter's locals'), and those that read none
MEASUREMENT_READERS = ("eskf", "sage_husa", "fuzzy_adaptive", "two_stage_adaptive", "federated")
NO_SENSORS = ("sins",)


def values_read(scenario) -> dict | None:
    """Sensor name -> the set of its values the scenario's estimators read (their measurement
    models' :func:`~navsim.navigation.estimators.measurements.values_read`); None where that is
    not known: an estimator of another type (it reads sensors by keys of its own) or a model
    whose type does not say."""
    out = {c.name: set() for c in scenario.sensors}
    for est in scenario.estimators:
        if est.type in NO_SENSORS:
            continue
        if est.type not in MEASUREMENT_READERS:
            return None
        for _, m in _measurement_entries(est.params, ""):
            read = measurement_values_read(m)
            if read is None:
                return None
            out[m["sensor"]].update(read)
    return out


def _measurement_entries(params: dict, path: str):
    """``(key path, entry)`` of every measurement of an estimator, its federated locals' too."""
    for j, m in enumerate(params.get("measurements", [])):
        yield f"{path}.measurements[{j}]", m
    for k, loc in enumerate((params.get("federated") or {}).get("locals", [])):
        for j, m in enumerate(loc["measurements"]):
            yield f"{path}.federated.locals[{k}].measurements[{j}]", m


def _check_field(m: dict, produced: tuple, file, key: str) -> None:
    if "field" not in m:
        return
    family = velocity_fields() if m["type"] == "velocity" else height_fields()
    usable = [f for f in produced if f in family]
    if m["field"] not in usable:
        raise ScenarioError(f"'{m['field']}' is not a {'velocity' if m['type'] == 'velocity' else 'height'} "
                            f"that sensor '{m['sensor']}' produces", file=file, key=f"{key}.field",
                            expected="one of " + ", ".join(usable) if usable else "another sensor",
                            hint=close_match(m["field"], usable) if usable else None)


def _check_reads(m: dict, produced: tuple, file, key: str) -> None:
    """The values a measurement model reads beyond its ``field`` (its class's ``reads(entry)``,
    if it has one) are ones its sensor produces."""
    reads = getattr(measurement_class(m["type"]), "reads", None)
    missing = [f for f in (reads(m) if reads else ()) if f not in produced]
    if missing:
        raise ScenarioError(f"reads {', '.join(missing)}, which sensor '{m['sensor']}' does not produce", file=file,
                            key=key, expected="a sensor that produces them",
                            hint="an ADS model with vanes (velocity_axis: air) needs a sensor with vanes"
                            if m["type"] == "air_velocity" else None)


ARCSEC = math.pi / 180 / 3600
#: the most worker processes, the largest seed, the simulation (truth) rate range in Hz
MAX_WORKERS = 256
MAX_SEED = 2**63 - 1
RATE_HZ = (20.0, MAX_RATE_HZ)
#: the lowest an air start may be above the surface, m
MIN_START_AGL_M = 10.0
#: the lowest a multirotor may start hovering above the surface, m (its skids clear of it)
MIN_HOVER_AGL_M = 2.0


#: the largest initial error (1-sigma per axis) of each kind: position m, velocity m/s,
#: attitude arcsec (30 deg: beyond it an error-state filter's small angles do not hold)
MAX_INITIAL = {"pos_m": 10_000.0, "vel_mps": 50.0, "att_arcsec": 30 * 3600.0}


def _three(node, key, default, scale=1.0):
    """``key``: a non-negative number or three (N, E, D), at most ``MAX_INITIAL[key]``."""
    node._seen.add(key)
    v = node.data.get(key, default)
    err = lambda m, e: node.error(m, key, expected=f"a non-negative number or a list of three (N, E, D): {e}")
    bounds = dict(minimum=0.0, maximum=MAX_INITIAL[key])
    values = (check_numbers(v, 3, error=err, **bounds) if isinstance(v, list)
              else [check_number(v, float, error=err, **bounds)])
    return np.broadcast_to(np.asarray(values, float) * scale, (3,)).copy()


def _initial(node):
    """``initial_errors: {pos_m, vel_mps, att_arcsec, fixed}`` (1-sigma, NED axes, within
    :data:`MAX_INITIAL`)."""
    if node is None:
        return InitialErrors()
    out = InitialErrors(pos_m=_three(node, "pos_m", 0.0), vel_mps=_three(node, "vel_mps", 0.0),
                        att_rad=_three(node, "att_arcsec", 0.0, ARCSEC),
                        fixed=node.get("fixed", bool, False))
    node.done()
    return out


def _windows(node):
    node._seen.add("windows")
    raw = node.data.get("windows", [])
    if not isinstance(raw, list):
        raise node.error("is not a list", "windows", expected="a list of {name, start_s, end_s}")
    out, names = [], set()
    for i, item in enumerate(raw):
        w = Node(item, node.key(f"windows[{i}]"), node.file)
        name = w.get("name", str)
        if name in names:
            raise w.error(f"'{name}' is used twice", "name", expected="a unique window name")
        names.add(name)
        a = w.get("start_s", float, minimum=0.0, maximum=MAX_DURATION_S)
        b = w.get("end_s", float, exclusive_minimum=a, maximum=MAX_DURATION_S)
        w.done()
        out.append((name, a, b))
    return tuple(out)


def load_scenario(path: str | Path, overrides=()) -> Scenario:
    """Read and validate a scenario file, changed first by ``overrides``
    (:func:`parse_changed`)."""
    data = load_yaml(path)
    if data is None and not overrides:
        raise ScenarioError("is empty", file=str(path), expected="a mapping with at least 'track'")
    return parse_changed(data, str(path), overrides)


def parse_changed(data, file: str | None, overrides=()) -> Scenario:
    """:func:`parse_scenario` of ``data`` changed by ``overrides``
    (:class:`~navsim.foundations.overrides.Override`, the ``--set`` of every command): the
    changed mapping is validated as a file would be, an error at a path a ``--set`` wrote naming
    it; the scenario's :attr:`Scenario.raw` is the changed mapping and
    :attr:`Scenario.overrides` the changes as ``PATH=VALUE``."""
    if not overrides:
        return parse_scenario(data, file)
    try:
        changed, written = apply_overrides(data, overrides)
    except ScenarioError as exc:
        raise (exc.with_file(file) if file else exc) from None
    try:
        scenario = parse_scenario(changed, file)
    except ScenarioError as exc:
        raise blame(exc, written) from None
    scenario.overrides = tuple(o.as_text() for o in overrides)
    return scenario
