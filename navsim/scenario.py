"""Scenario files: one YAML file describes an experiment.

So far a scenario describes the flight::

    name: p0_flight
    description: P0's track in calm air
    aircraft: survey10          # a folder of aircraft/
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

import math
from dataclasses import dataclass, field

import numpy as np
from pathlib import Path

from navsim.config import Node, close_match, load_yaml
from navsim.errors import ScenarioError
from navsim.flight.environment import parse_environment
from navsim.flight.properties import AIRCRAFT_DIR
from navsim.flight.simulator import FlightConfig
from navsim.flight.track import parse_track


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
    reference: dict | None = None
    report: dict = field(default_factory=dict)
    closed_loop: object = None           #: navsim.closedloop.ClosedLoopConfig, or None (open loop)


def available_aircraft() -> list[str]:
    return sorted(p.name for p in AIRCRAFT_DIR.iterdir() if (p / f"{p.name}.xml").is_file())


TOP_KEYS = ("name", "description", "aircraft", "track", "environment", "flight", "sensors",
            "montecarlo", "estimators", "initial_errors", "metrics", "reference", "report",
            "closed_loop")


def parse_scenario(data, file: str | None = None) -> Scenario:
    node = Node(data, "", file)
    for key in node.data:
        if key not in TOP_KEYS:
            raise ScenarioError("is not a known key", file=file, key=str(key),
                                hint=close_match(str(key), TOP_KEYS))
    name = node.get("name", str, Path(file).stem if file else "scenario")
    description = node.get("description", str, "")
    aircraft = node.get("aircraft", str, "survey10")
    if aircraft not in available_aircraft():
        raise ScenarioError(f"'{aircraft}' is not an aircraft of {AIRCRAFT_DIR}", file=file,
                            key="aircraft", expected="a folder name of aircraft/",
                            hint=close_match(aircraft, available_aircraft()))
    node._seen.add("track")
    if "track" not in node.data:
        raise ScenarioError("is missing", file=file, key="track",
                            expected="a shipped track name (p0, p3, p2_sea) or a mapping")
    try:
        track = parse_track(node.data["track"], "track", file)
    except ScenarioError as exc:
        raise (exc if exc.file else exc.with_file(file or "<scenario>")) from None
    node._seen.add("environment")
    environment = parse_environment(node.data.get("environment"), "environment", file)
    from navsim.sensors import parse_sensors
    node._seen.add("sensors")
    sensors = parse_sensors(node.data.get("sensors"), file)
    mc = node.child("montecarlo", None)
    runs, seed, workers = 1, 0, 1
    if mc is not None:
        runs = mc.get("runs", int, 1, minimum=1)
        seed = mc.get("seed", int, 0, minimum=0)
        workers = mc.get("workers", int, 1, minimum=1, maximum=256)
        mc.done()
    estimators = ()
    if "estimators" in node.data:
        from navsim.estimators.factory import parse_estimators
        node._seen.add("estimators")
        estimators = parse_estimators(node.data["estimators"], {c.name: c.kind for c in sensors}, file)
        imu = [c for c in sensors if c.kind == "imu"]
        if len(imu) != 1:
            raise ScenarioError(f"has {len(imu)} IMUs", file=file, key="sensors",
                                expected="exactly one sensor of kind imu when estimators are given")
    initial = _initial(node.child("initial_errors", None))
    duration = nominal_s = _duration(node, file)
    if node.data.get("closed_loop") is not None:
        duration = math.inf           # each run's flight ends where its navigation takes it
    settle_s, windows = 0.0, ()
    metrics = node.child("metrics", None)
    if metrics is not None:
        settle_s = metrics.get("settle_s", float, 0.0, minimum=0.0)
        windows = _windows(metrics, duration)
        metrics.done()
    reference = _reference(node.child("reference", None), [e.label for e in estimators], windows)
    report = {"formats": ["pdf", "png"]}
    rep = node.child("report", None)
    if rep is not None:
        rep._seen.add("formats")
        fmts = rep.data.get("formats", ["pdf", "png"])
        if not (isinstance(fmts, list) and fmts and all(f in ("pdf", "png") for f in fmts)):
            raise rep.error(f"is {fmts!r}", "formats", expected="a list of pdf and/or png")
        report["formats"] = fmts
        report["runs_plotted"] = rep.get("runs_plotted", int, 5, minimum=0)
        rep.done()
    flight_node = node.child("flight", None)
    rate_hz = 100.0
    if flight_node is not None:
        rate_hz = flight_node.get("rate_hz", float, 100.0, minimum=20.0, maximum=1000.0)
        flight_node.done()
    closed_loop = None
    cl_node = node.child("closed_loop", None)
    if cl_node is not None:
        if not estimators:
            raise cl_node.error("needs estimators", "fly_on", expected="an estimators list to fly on")
        from navsim.closedloop import parse_closed_loop
        closed_loop = parse_closed_loop(cl_node, [e.label for e in estimators], sensors, track,
                                        nominal_s, rate_hz)
    node.done()
    config = FlightConfig(track=track, environment=environment, aircraft=aircraft, rate_hz=rate_hz)
    return Scenario(name=name, description=description, flight=config,
                    path=Path(file) if file else None, raw=data, sensors=sensors, runs=runs, seed=seed,
                    workers=workers, estimators=estimators, initial=initial, settle_s=settle_s,
                    windows=windows, reference=reference, report=report, closed_loop=closed_loop)


ARCSEC = math.pi / 180 / 3600


def _three(node, key, default, scale=1.0):
    node._seen.add(key)
    v = node.data.get(key, default)
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) or (
        isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v))
    if not ok or np.any(np.asarray(v, float) < 0):
        raise node.error(f"is {v!r}", key, expected="a non-negative number or a list of three (N, E, D)")
    return np.broadcast_to(np.asarray(v, float) * scale, (3,)).copy()


def _initial(node):
    """``initial_errors: {pos_m, vel_mps, att_arcsec, fixed}`` (1-sigma, NED axes)."""
    from navsim.montecarlo import InitialErrors
    if node is None:
        return InitialErrors()
    out = InitialErrors(pos_m=_three(node, "pos_m", 0.0), vel_mps=_three(node, "vel_mps", 0.0),
                        att_rad=_three(node, "att_arcsec", 0.0, ARCSEC),
                        fixed=node.get("fixed", bool, False))
    node.done()
    return out


def _duration(node, file):
    from navsim.flight.track import nominal_duration_s
    try:
        from navsim.flight.track import parse_track
        return nominal_duration_s(parse_track(node.data["track"], "track", file))
    except Exception:
        return math.inf


def _windows(node, duration):
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
        a = w.get("start_s", float, minimum=0.0)
        b = w.get("end_s", float, exclusive_minimum=a)
        if b > duration + 1e-6:
            raise w.error(f"is {b:g} s, after the end of the flight ({duration:.0f} s)", "end_s",
                          expected=f"a time within the flight (0-{duration:.0f} s)")
        w.done()
        out.append((name, a, b))
    return tuple(out)


def _reference(node, labels, windows):
    """``reference: {source, note, values: {estimator label: {metric path: number or [3]}}}``."""
    if node is None:
        return None
    ref = {"source": node.get("source", str), "note": node.get("note", str, ""), "values": {}}
    vals = node.child("values")
    for label, metrics in vals.data.items():
        if label not in labels:
            raise vals.error(f"'{label}' is not an estimator label", str(label),
                             expected="one of " + ", ".join(labels), hint=close_match(str(label), labels))
        vals._seen.add(label)
        m = Node(metrics, vals.key(str(label)), node.file)
        for path, value in m.data.items():
            m._seen.add(path)
            head = str(path).split(".")[0]
            heads = ("rms", "final", "max_abs", "p99", "windows", "attitude", "resets")
            if head not in heads:
                raise m.error(f"'{path}' is not a metric", str(path),
                              expected="rms.*, final.*, max_abs.*, p99.*, attitude.*, resets.* or windows.<name>.*",
                              hint=close_match(head, heads))
            if head == "windows":
                wname = str(path).split(".")[1] if "." in str(path) else ""
                if wname not in [w[0] for w in windows]:
                    raise m.error(f"window '{wname}' is not defined under metrics.windows", str(path))
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) or (
                isinstance(value, list) and len(value) == 3)
            if not ok:
                raise m.error(f"is {value!r}", str(path), expected="a number or a list of three")
        ref["values"][label] = dict(m.data)
    vals.done()
    node.done()
    return ref


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file."""
    data = load_yaml(path)
    if data is None:
        raise ScenarioError("is empty", file=str(path), expected="a mapping with at least 'track'")
    return parse_scenario(data, str(path))
