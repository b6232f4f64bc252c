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

from dataclasses import dataclass
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


def available_aircraft() -> list[str]:
    return sorted(p.name for p in AIRCRAFT_DIR.iterdir() if (p / f"{p.name}.xml").is_file())


def parse_scenario(data, file: str | None = None) -> Scenario:
    node = Node(data, "", file)
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
    runs, seed = 1, 0
    if mc is not None:
        runs = mc.get("runs", int, 1, minimum=1)
        seed = mc.get("seed", int, 0, minimum=0)
        mc.done()
    flight_node = node.child("flight", None)
    rate_hz = 100.0
    if flight_node is not None:
        rate_hz = flight_node.get("rate_hz", float, 100.0, minimum=20.0, maximum=1000.0)
        flight_node.done()
    node.done()
    config = FlightConfig(track=track, environment=environment, aircraft=aircraft, rate_hz=rate_hz)
    return Scenario(name=name, description=description, flight=config,
                    path=Path(file) if file else None, raw=data, sensors=sensors, runs=runs, seed=seed)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file."""
    data = load_yaml(path)
    if data is None:
        raise ScenarioError("is empty", file=str(path), expected="a mapping with at least 'track'")
    return parse_scenario(data, str(path))
