"""Tracks as data: a start condition and a list of segments, read from YAML.

A track is a mapping::

    start: {type: air, lat_deg: 37.38, lon_deg: 117.97, alt_m: 300, speed_mps: 13.9,
            heading_deg: 90}
    segments:
      - {type: straight, time_s: 60}          # or distance_m, or until_s (track time)
      - {type: speed, to_mps: 18, accel_mps2: 0.5}
      - {type: turn, by_deg: 90, bank_deg: 20}          # + right, - left
      - {type: circle, radius_m: 150, laps: 2, direction: left}
      - {type: climb, to_m: 450, rate_mps: 2}
      - {type: descend, to_m: 300, rate_mps: 1.5}
      - {type: goto, north_m: 500, east_m: 1200}

A multirotor (an aircraft whose ``navsim.yaml`` says ``class: multirotor``) starts hovering,
``start: {type: hover, lat_deg, lon_deg, alt_m, heading_deg, speed_mps}`` (``speed_mps``: the
horizontal speed its segments fly at unless they say, 5 m/s by default), and flies::

      - {type: hover, time_s: 60}                       # hold the point
      - {type: goto, north_m: 100, east_m: 0, alt_m: 40, speed_mps: 4, yaw: course}
      - {type: circle, radius_m: 20, laps: 2, direction: left, speed_mps: 3, yaw: center}
      - {type: land, rate_mps: 0.7}                     # straight down; motors stop at the touch

or stands on the surface, ``start: {type: ground, ...}`` (``alt_m`` the surface's height), and
takes off first, ``{type: takeoff, agl_m: 20, rate_mps: 1.5}`` (straight up to ``agl_m`` over
the surface); after a ``land`` only a ``takeoff`` may follow.

``yaw`` says what the nose does: ``hold`` (the heading it has), ``course`` (along the way
flown), ``center`` (at the circle's centre, a circle only) or a heading, ``heading_deg``. A
segment or start the class cannot fly is refused (:func:`check_segments`).

``start.type: launch`` starts on a launcher instead (P2's rocket-assisted launch at 14 deg
pitch). ``start.type: ground`` with ``hold`` segments parks the vehicle on the ground (P4's static test): heading
``heading_deg``, the ground's slope as ``roll_deg``/``pitch_deg``, and only ``hold`` segments
(``{type: hold, time_s: 360}``); no flight dynamics are run, the truth is the vehicle at rest on
the rotating Earth (:meth:`navsim.flight.truth.Truth.static`). Every segment may carry a ``label`` (shown on plots) and ``speed_mps`` (a new airspeed
target, reached at 0.5 m/s^2). Heights are geodetic (above the WGS-84 ellipsoid, which is also
JSBSim's sea level). Shipped tracks are referred to by name: ``p0``, ``p3``, ``p2_sea``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from navsim.flight.airframe import CLASSES, FIXED_WING, MULTIROTOR
from navsim.foundations.config import MAX_DURATION_S, Node, close_match, load_yaml, resolve_file
from navsim.foundations.errors import ScenarioError
from navsim.foundations.resources import data_folder

TRACKS_DIR = data_folder("tracks")


@dataclass(frozen=True)
class Start:
    """How the flight starts.

    ``type: air``: trimmed level flight at ``alt_m``, ``speed_mps``, ``heading_deg``.
    ``type: ground``: parked at ``alt_m`` (ground height), heading ``heading_deg``, tilted by the
    ground's ``roll_deg`` and ``pitch_deg``; ``speed_mps`` is 0.
    ``type: launch``: on a launcher ``launcher_height_m`` above the surface at ``alt_m``
    (surface height), pitched ``pitch_deg``; a booster gives ``booster_thrust_n`` for
    ``booster_time_s`` while the motor is at full power, then the autopilot takes
    ``speed_mps``.
    """

    type: str
    lat_deg: float
    lon_deg: float
    alt_m: float
    speed_mps: float
    heading_deg: float
    pitch_deg: float = 14.0
    launcher_height_m: float = 2.0
    booster_thrust_n: float = 120.0
    booster_time_s: float = 1.2
    roll_deg: float = 0.0


@dataclass(frozen=True)
class Segment:
    """One segment: ``type`` and its parameters (SI units and degrees as named)."""

    type: str
    label: str
    params: dict = field(default_factory=dict)
    speed_mps: float | None = None

    def __getitem__(self, key):
        return self.params[key]

    def get(self, key, default=None):
        return self.params.get(key, default)


@dataclass(frozen=True)
class Track:
    name: str
    start: Start
    segments: tuple[Segment, ...]
    description: str = ""


#: the fastest airspeed a track may ask for, m/s (the shipped 10 kg aircraft cruises at 14-18 m/s)
MAX_AIRSPEED_MPS = 40.0

#: a multirotor segment's ``yaw`` (besides a circle's ``center``): keep the heading, or the nose
#: along the way flown
YAW_CHOICES = ("hold", "course")
#: the segment keys only a multirotor reads (what its nose does)
MULTIROTOR_KEYS = ("yaw", "heading_deg")
#: a multirotor's horizontal speed where neither its start nor a segment says, m/s
MULTIROTOR_SPEED_MPS = 5.0

#: a multirotor's climb off the ground and its descent to touchdown where the segment does not
#: say, m/s (the airframe's max_climb_mps and max_descent_mps bound them)
TAKEOFF_RATE_MPS = 1.5
LAND_RATE_MPS = 0.7

# type -> {key: (kind, default or REQUIRED, constraint)}; one of the "one_of" groups is required
_REQ = object()
_POS = dict(exclusive_minimum=0.0)
_TIME = dict(exclusive_minimum=0.0, maximum=MAX_DURATION_S)
SEGMENT_KEYS: dict[str, dict] = {
    "straight": {"time_s": (float, None, _TIME), "distance_m": (float, None, _POS),
                 "until_s": (float, None, _TIME)},
    "speed": {"to_mps": (float, _REQ, dict(exclusive_minimum=0.0, maximum=MAX_AIRSPEED_MPS)), "accel_mps2": (float, 0.5, _POS)},
    "climb": {"to_m": (float, _REQ, {}), "rate_mps": (float, 2.0, _POS)},
    "descend": {"to_m": (float, _REQ, {}), "rate_mps": (float, 2.0, _POS)},
    "turn": {"by_deg": (float, _REQ, {}), "bank_deg": (float, None, dict(exclusive_minimum=0.0,
                                                                         maximum=45.0)),
             "rate_dps": (float, None, _POS)},
    "hold": {"time_s": (float, _REQ, _TIME)},
    "circle": {"radius_m": (float, _REQ, _POS), "laps": (float, None, _POS),
               "time_s": (float, None, _TIME),
               "direction": (str, "right", dict(choices=("right", "left"))),
               "yaw": (str, None, dict(choices=YAW_CHOICES + ("center",))),
               "heading_deg": (float, None, {})},
    "hover": {"time_s": (float, _REQ, _TIME), "yaw": (str, None, dict(choices=YAW_CHOICES)),
              "heading_deg": (float, None, {})},
    "takeoff": {"agl_m": (float, _REQ, dict(exclusive_minimum=0.0, maximum=1000.0)),
                "rate_mps": (float, TAKEOFF_RATE_MPS, _POS), "yaw": (str, None, dict(choices=YAW_CHOICES)),
                "heading_deg": (float, None, {})},
    "land": {"rate_mps": (float, LAND_RATE_MPS, _POS), "yaw": (str, None, dict(choices=YAW_CHOICES)),
             "heading_deg": (float, None, {})},
    "goto": {"north_m": (float, None, {}), "east_m": (float, None, {}),
             "lat_deg": (float, None, dict(minimum=-90.0, maximum=90.0)),
             "lon_deg": (float, None, dict(minimum=-180.0, maximum=180.0)),
             "alt_m": (float, None, {}), "acceptance_m": (float, 30.0, _POS),
             "yaw": (str, None, dict(choices=YAW_CHOICES)), "heading_deg": (float, None, {})},
}
_ONE_OF = {"straight": [("time_s",), ("distance_m",), ("until_s",)], "circle": [("laps",), ("time_s",)],
           "turn": [("bank_deg",), ("rate_dps",)],
           "goto": [("north_m", "east_m"), ("lat_deg", "lon_deg")]}
_DEFAULT_ONE = {"turn": {"bank_deg": 20.0}}
#: the airframe classes (:mod:`navsim.flight.airframe`) that fly each segment type: today's
#: segments are a fixed wing's; ``hold`` (a vehicle parked on the ground, no dynamics) any class's
SEGMENT_CLASSES: dict[str, tuple[str, ...]] = {
    "straight": (FIXED_WING,), "speed": (FIXED_WING,), "climb": (FIXED_WING,), "descend": (FIXED_WING,),
    "turn": (FIXED_WING,), "hold": CLASSES, "circle": CLASSES, "goto": CLASSES, "hover": (MULTIROTOR,),
    "takeoff": (MULTIROTOR,), "land": (MULTIROTOR,)}
#: the classes each start type is for (a ground start parks any vehicle: no dynamics)
START_CLASSES: dict[str, tuple[str, ...]] = {
    "air": (FIXED_WING,), "launch": (FIXED_WING,), "ground": CLASSES, "hover": (MULTIROTOR,)}


def parse_track(data, path: str = "track", file: str | None = None) -> Track:
    """A :class:`Track` from a YAML mapping, or a string naming a shipped track or a track
    file beside or below the scenario ``file`` (:func:`navsim.foundations.config.resolve_file`)."""
    if isinstance(data, str):
        track_file = resolve_file(data, catalog=TRACKS_DIR, file=file, key=path or "track",
                                  what="a shipped track", choices=available_tracks)
        return _track_file(track_file, file, path or "track")
    node = Node(data, path, file)
    name = node.get("name", str, "custom")
    description = node.get("description", str, "")
    start = _parse_start(node.child("start"))
    seg_key = node.key("segments")
    node._seen.add("segments")
    raw = node.data.get("segments")
    if not isinstance(raw, list) or not raw:
        raise ScenarioError("is missing or empty", file=file, key=seg_key,
                            expected="a list of segments",
                            hint="e.g. segments: [{type: straight, time_s: 60}]")
    segments = tuple(_parse_segment(item, f"{seg_key}[{i}]", file, i) for i, item in enumerate(raw))
    _check_order(start, segments, seg_key, file)
    node.done()
    return Track(name=name, start=start, segments=segments, description=description)


def _check_order(start: Start, segments, seg_key: str, file: str | None) -> None:
    """Refuse segments in an order no vehicle flies: on the ground, either ``hold`` alone (parked)
    or a ``takeoff`` first; in the air no ``hold``; a ``takeoff`` only from the ground (the start,
    or after a ``land``), and after a ``land`` only a ``takeoff``."""
    on_ground = start.type == "ground"
    parked = on_ground and segments[0].type == "hold"
    for i, seg in enumerate(segments):
        key = f"{seg_key}[{i}].type"
        if parked != (seg.type == "hold"):
            raise ScenarioError(f"a '{seg.type}' segment after a '{start.type}' start" if parked or seg.type == "hold"
                                else f"a '{seg.type}' segment", file=file, key=key,
                                expected="only 'hold' segments on the ground, and no 'hold' in flight",
                                hint="a parked vehicle: start: {type: ground, ...}, segments: "
                                     "[{type: hold, time_s: 360}]; a multirotor flies off the ground "
                                     "with a takeoff first")
        if parked:
            continue
        if on_ground != (seg.type == "takeoff"):
            raise ScenarioError(f"a '{seg.type}' segment {'on the ground' if on_ground else 'in the air'}", file=file,
                                key=key, expected="only 'hold' segments on the ground (parked), or a takeoff first "
                                                  "(a multirotor flying off it, at the start or after a land), and "
                                                  "a takeoff nowhere else")
        on_ground = seg.type == "land"


def check_segments(track: Track, kind: str, file: str | None) -> None:
    """Refuse a track with a segment that an airframe of class ``kind`` cannot fly
    (:data:`SEGMENT_CLASSES`).

    Raises
    ------
    ScenarioError
        Naming ``file``, the segment's key path ``track.segments[i]``, the class and the segment.
    """
    if kind not in START_CLASSES[track.start.type]:
        starts = [t for t, classes in START_CLASSES.items() if kind in classes]
        raise ScenarioError(f"a '{track.start.type}' start is not a {kind}'s", file=file, key="track.start.type",
                            expected=f"the starts of a {kind}: {', '.join(starts)}")
    for i, seg in enumerate(track.segments):
        if kind not in SEGMENT_CLASSES[seg.type]:
            flown = [t for t, classes in SEGMENT_CLASSES.items() if kind in classes]
            raise ScenarioError(f"a '{seg.type}' segment ({seg.label}) cannot be flown by a {kind}", file=file,
                                key=f"track.segments[{i}]",
                                expected=f"the segments a {kind} flies: {', '.join(flown) or 'none yet'}")
        extra = [k for k in MULTIROTOR_KEYS if k in seg.params] if kind != MULTIROTOR else []
        if extra:
            raise ScenarioError(f"'{extra[0]}' is a multirotor's key: a {kind} points its nose where it flies",
                                file=file, key=f"track.segments[{i}].{extra[0]}",
                                expected="no yaw or heading_deg on a fixed wing's segment")


def _parse_start(node: Node) -> Start:
    kind = node.get("type", str, "air", choices=tuple(START_CLASSES))
    ground = kind == "ground"
    values = dict(
        type=kind,
        lat_deg=node.get("lat_deg", float, minimum=-89.0, maximum=89.0),
        lon_deg=node.get("lon_deg", float, minimum=-180.0, maximum=180.0),
        alt_m=node.get("alt_m", float, minimum=-400.0, maximum=10000.0),
        speed_mps=0.0 if ground else node.get("speed_mps", float, *((MULTIROTOR_SPEED_MPS,) if kind == "hover" else ()),
                                              exclusive_minimum=0.0, maximum=MAX_AIRSPEED_MPS),
        heading_deg=node.get("heading_deg", float, 0.0),
    )
    if ground:
        values.update(roll_deg=node.get("roll_deg", float, 0.0, minimum=-30.0, maximum=30.0),
                      pitch_deg=node.get("pitch_deg", float, 0.0, minimum=-30.0, maximum=30.0))
    if kind == "launch":
        values.update(
            pitch_deg=node.get("pitch_deg", float, 14.0, minimum=0.0, maximum=45.0),
            launcher_height_m=node.get("launcher_height_m", float, 2.0, exclusive_minimum=0.5),
            booster_thrust_n=node.get("booster_thrust_n", float, 120.0, minimum=0.0),
            booster_time_s=node.get("booster_time_s", float, 1.2, minimum=0.0, maximum=MAX_DURATION_S))
    node.done()
    return Start(**values)


def _parse_segment(item, path: str, file: str | None, index: int) -> Segment:
    node = Node(item, path, file)
    kind = node.get("type", str, choices=tuple(SEGMENT_KEYS))
    label = node.get("label", str, f"{index}:{kind}")
    speed = node.get("speed_mps", float, None, exclusive_minimum=0.0, maximum=MAX_AIRSPEED_MPS)
    params = {}
    for key, (typ, default, cons) in SEGMENT_KEYS[kind].items():
        value = node.get(key, typ, None if default is _REQ else default, **cons)
        if value is None and default is _REQ:
            raise node.error("is missing", key, expected=f"{_TYPE(typ)} for a '{kind}' segment")
        if value is not None:
            params[key] = value
    node.done()
    groups = _ONE_OF.get(kind)
    if groups:
        given = [g for g in groups if all(k in params for k in g)]
        if not given:
            fallback = _DEFAULT_ONE.get(kind)
            if fallback is None:
                options = " or ".join("+".join(g) for g in groups)
                raise node.error(f"a '{kind}' segment needs {options}", expected=options)
            params.update(fallback)
        elif len(given) > 1:
            raise node.error(f"a '{kind}' segment takes only one of "
                             + " or ".join("+".join(g) for g in groups))
    if "yaw" in params and "heading_deg" in params:
        raise node.error("takes yaw or heading_deg, not both", "heading_deg",
                         expected="yaw: hold, course or center, or heading_deg: a heading to hold")
    if kind == "turn" and params["by_deg"] == 0.0:
        raise node.error("is 0", "by_deg", expected="a non-zero angle (+ right, - left)")
    return Segment(type=kind, label=label, params=params, speed_mps=speed)


def _TYPE(typ) -> str:
    return {float: "a number", str: "a string", int: "an integer"}.get(typ, str(typ))


def available_tracks() -> list[str]:
    """Names of the shipped tracks."""
    return sorted(p.stem for p in TRACKS_DIR.glob("*.yaml"))


def load_track(name_or_path: str | Path) -> Track:
    """A shipped track by name (``p0``) or a track YAML file by path."""
    path = Path(name_or_path)
    if not path.suffix:
        path = TRACKS_DIR / f"{name_or_path}.yaml"
        if not path.is_file():
            raise ScenarioError(f"'{name_or_path}' is not a shipped track", key="track",
                                expected="a track name or a mapping with start and segments",
                                hint=close_match(str(name_or_path), available_tracks()))
    return _track_file(path)


def _track_file(path: Path, file: str | None = None, key: str | None = None) -> Track:
    """The track in the YAML file ``path``: a mapping with start and segments (a file naming
    another track is refused, so no chain of files is followed). ``file`` and ``key``: where
    the scenario names it, for the error; the file's content is never echoed."""
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise ScenarioError(f"'{path.name}' is not a track", file=file or str(path), key=key,
                            expected="a YAML file holding a mapping with start and segments")
    return parse_track(data, "", str(path))


def nominal_duration_s(track: Track, surface_m: float = 0.0) -> float:
    """A rough duration of the track at its speeds (for time-outs and progress bars);
    ``surface_m``: the surface's height, where a landing ends."""
    speed = track.start.speed_mps
    alt = track.start.alt_m
    total = 0.0
    for seg in track.segments:
        speed = seg.speed_mps or speed
        p = seg.params
        if seg.type == "straight":
            if "until_s" in p:
                total = max(total, p["until_s"])
            else:
                total += p.get("time_s") or p["distance_m"] / speed
        elif seg.type == "speed":
            total += abs(p["to_mps"] - speed) / p["accel_mps2"] + 5.0
            speed = p["to_mps"]
        elif seg.type in ("climb", "descend"):
            total += abs(p["to_m"] - alt) / p["rate_mps"] + 5.0
            alt = p["to_m"]
        elif seg.type == "turn":
            bank = math.radians(p.get("bank_deg", 20.0))
            rate = math.radians(p["rate_dps"]) if "rate_dps" in p else 9.81 * math.tan(bank) / speed
            total += abs(math.radians(p["by_deg"])) / rate
        elif seg.type == "circle":
            total += p.get("time_s") or p["laps"] * 2 * math.pi * p["radius_m"] / speed
        elif seg.type in ("hold", "hover"):
            total += p["time_s"]
        elif seg.type == "takeoff":
            total += p["agl_m"] / p["rate_mps"] + 5.0
            alt = surface_m + p["agl_m"]
        elif seg.type == "land":
            total += max(alt - surface_m, 0.0) / p["rate_mps"] + 5.0
            alt = surface_m
        else:
            total += 60.0
    return total
