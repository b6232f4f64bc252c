"""Airframes: an aircraft folder's class and flight envelope, read from its ``navsim.yaml``.

An aircraft folder (a shipped one of ``aircraft/``, or one beside a scenario) holds ``<name>.xml``,
the JSBSim model, and ``navsim.yaml``, what navsim's controller and failure checks need of it::

    class: fixed_wing             # or multirotor; a file without it is a fixed wing
    mass_kg: 10.0
    stall_speed_mps: 9.6
    ...

Each class has its envelope, a typed object (:class:`FixedWing`, :class:`Multirotor`), read by
:func:`load_airframe`: every key is checked (range, type, unknown keys) and a mistake raises
:class:`~navsim.foundations.errors.ScenarioError` naming ``navsim.yaml`` and the key. The keys of
each class, their units and ranges are in :data:`FIXED_WING_KEYS`, :data:`MULTIROTOR_KEYS` and
:data:`ROTOR_KEYS` (documented in ``aircraft/README.md``).

navsim flies both classes: a fixed wing under :mod:`navsim.flight.autopilot`, a multirotor under
:mod:`navsim.flight.multirotor`'s cascade (:mod:`navsim.flight.rotorcraft`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import jsbsim

from navsim.foundations.config import Node, check_numbers, close_match, load_yaml, plain_name
from navsim.foundations.errors import ScenarioError

FIXED_WING, MULTIROTOR = "fixed_wing", "multirotor"
#: the airframe classes, the values of ``class:`` in ``navsim.yaml``
CLASSES = (FIXED_WING, MULTIROTOR)
#: the classes navsim has a controller for (the others are read and checked, then refused)
FLOWN_CLASSES = (FIXED_WING, MULTIROTOR)
#: the envelope file of an aircraft folder, beside ``<name>.xml``
ENVELOPE_FILE = "navsim.yaml"
#: the fewest rotors of a multirotor (thrust, roll, pitch and yaw from fixed-pitch rotors: the
#: mixer's four)
MIN_ROTORS = 4

_POS = dict(exclusive_minimum=0.0)
#: the fixed wing's keys (all required, SI and degrees as named) and their ranges
FIXED_WING_KEYS = {
    "mass_kg": _POS,
    "stall_speed_mps": _POS,               # 1 g stall, sea level
    "min_speed_mps": _POS,                 # the lowest airspeed a segment may command
    "max_speed_mps": _POS,
    "stall_alpha_deg": dict(exclusive_minimum=0.0, maximum=60.0),
    "max_bank_deg": dict(exclusive_minimum=0.0, maximum=60.0),     # the autopilot's bank limit
    "max_climb_mps": _POS,                 # the fastest climb a segment may ask for
    "trim_throttle": dict(minimum=0.0, maximum=1.0),               # first guess of the air start
    "trim_alpha_deg": dict(minimum=-30.0, maximum=60.0),
}
#: the multirotor's keys besides ``rotors`` (all required) and their ranges
MULTIROTOR_KEYS = {
    "mass_kg": _POS,
    "max_tilt_deg": dict(exclusive_minimum=0.0, maximum=89.0),     # the attitude loop's tilt limit
    "max_climb_mps": _POS,
    "max_descent_mps": _POS,
    "max_speed_mps": _POS,                 # the fastest horizontal speed a segment may command
    "hover_throttle": dict(exclusive_minimum=0.0, maximum=1.0),    # first guess of the hover
}
#: each rotor's keys besides ``position_m`` and ``spin``: (default or None if required, range)
ROTOR_KEYS = {
    "tilt_deg": (0.0, dict(minimum=-60.0, maximum=60.0)),
    "thrust_coefficient": (None, _POS),    # thrust = k * omega^2, N/(rad/s)^2
    "torque_coefficient": (None, _POS),    # drag torque = k * omega^2, N m/(rad/s)^2
}
#: a rotor's JSBSim properties (``{i}``: its index in the table, JSBSim's engine index), each a
#: key of its own in the table where the model has others: the motor's command in [0, 1] and the
#: rotor's speed, r/min
ROTOR_PROPERTIES = {
    "command": "fcs/throttle-cmd-norm[{i}]",
    "rpm": "propulsion/engine[{i}]/propeller-rpm",
}
#: the optional key naming a model that ships with the ``jsbsim`` package (a folder of its
#: ``aircraft/``), flown from an aircraft folder holding ``navsim.yaml`` only
JSBSIM_MODEL_KEY = "jsbsim_model"
#: a rotor's spin: +1 clockwise seen from above (turning about the body's +z, down), -1 the other way
SPINS = (1, -1)


@dataclass(frozen=True)
class FixedWing:
    """A fixed wing's flight envelope (:data:`FIXED_WING_KEYS`), as the autopilot, the segments
    and the failure checks use it."""

    kind: ClassVar[str] = FIXED_WING
    mass_kg: float
    stall_speed_mps: float
    min_speed_mps: float
    max_speed_mps: float
    stall_alpha_deg: float
    max_bank_deg: float
    max_climb_mps: float
    trim_throttle: float
    trim_alpha_deg: float
    #: a model of the ``jsbsim`` package flown instead of the folder's ``<name>.xml``
    jsbsim_model: str | None = None


@dataclass(frozen=True)
class Rotor:
    """One rotor of a multirotor, in body axes (x forward, y right, z down) from the centre of
    gravity."""

    position_m: tuple[float, float, float]
    spin: int                   #: +1 clockwise seen from above, -1 counter-clockwise (:data:`SPINS`)
    #: the rotor's axis tilted from the body's -z about the arm (the horizontal line from the
    #: centre of gravity out to the rotor: its position's x, y; right-handed), deg
    tilt_deg: float
    thrust_coefficient: float   #: N/(rad/s)^2
    torque_coefficient: float   #: N m/(rad/s)^2
    command: str                #: the JSBSim property of its motor's command, 0..1
    rpm: str                    #: the JSBSim property of its speed, r/min


@dataclass(frozen=True)
class Multirotor:
    """A multirotor's flight envelope (:data:`MULTIROTOR_KEYS`) and its rotor geometry, from
    which the controller's mixer is derived."""

    kind: ClassVar[str] = MULTIROTOR
    mass_kg: float
    max_tilt_deg: float
    max_climb_mps: float
    max_descent_mps: float
    max_speed_mps: float
    hover_throttle: float
    rotors: tuple[Rotor, ...]
    #: a model of the ``jsbsim`` package flown instead of the folder's ``<name>.xml``
    jsbsim_model: str | None = None


def load_airframe(folder: str | Path) -> FixedWing | Multirotor:
    """The airframe of the aircraft ``folder`` from its ``navsim.yaml`` (:data:`ENVELOPE_FILE`).

    Parameters
    ----------
    folder : path
        An aircraft folder: ``<name>.xml`` and ``navsim.yaml``.

    Returns
    -------
    FixedWing or Multirotor
        As ``class:`` says (:data:`FIXED_WING` where the file does not say).

    Raises
    ------
    ScenarioError
        A folder without ``navsim.yaml`` (naming the folder); an unknown class, an unknown key, a
        missing or bad value (naming ``navsim.yaml`` and the key).
    """
    path = Path(folder) / ENVELOPE_FILE
    if not path.is_file():
        raise ScenarioError(f"has no {ENVELOPE_FILE}", file=str(folder),
                            expected=f"{ENVELOPE_FILE}: the aircraft's class and envelope (aircraft/README.md)")
    data = load_yaml(path)
    node = Node({} if data is None else data, "", str(path))
    kind = node.get("class", str, FIXED_WING, choices=CLASSES)
    model = node.get(JSBSIM_MODEL_KEY, str, None)
    if model is not None and not plain_name(model):
        raise node.error(f"'{model}' is not a model's name", JSBSIM_MODEL_KEY,
                         expected="the plain name of a folder of the jsbsim package's aircraft/ (letters, digits, "
                                  "'.', '_', '-')")
    if model is not None and not (jsbsim_aircraft_dir() / model / f"{model}.xml").is_file():
        known = sorted(p.name for p in jsbsim_aircraft_dir().iterdir() if (p / f"{p.name}.xml").is_file())
        raise node.error(f"'{model}' is not a model of the jsbsim package", JSBSIM_MODEL_KEY,
                         expected=f"a folder of {jsbsim_aircraft_dir()} holding <name>.xml",
                         hint=close_match(model, known))
    airframe = _fixed_wing(node, model) if kind == FIXED_WING else _multirotor(node, model)
    node.done()
    return airframe


def jsbsim_aircraft_dir() -> Path:
    """The ``aircraft/`` folder of the ``jsbsim`` package: the models :data:`JSBSIM_MODEL_KEY`
    names."""
    return Path(jsbsim.get_default_root_dir()) / "aircraft"


def model_location(folder: str | Path, airframe: FixedWing | Multirotor) -> tuple[str, Path]:
    """The JSBSim model an aircraft ``folder`` flies: its name and the folder holding it (the
    ``jsbsim`` package's ``aircraft/`` for an airframe naming a :data:`JSBSIM_MODEL_KEY`)."""
    folder = Path(folder)
    if airframe.jsbsim_model is not None:
        return airframe.jsbsim_model, jsbsim_aircraft_dir()
    return folder.name, folder.parent


def _fixed_wing(node: Node, model: str | None) -> FixedWing:
    """A :class:`FixedWing` of ``node``'s keys, its speeds in order."""
    values = {name: node.get(name, float, **bounds) for name, bounds in FIXED_WING_KEYS.items()}
    if values["min_speed_mps"] < values["stall_speed_mps"]:
        raise node.error(f"is {values['min_speed_mps']:g} m/s", "min_speed_mps",
                         expected=f"at least stall_speed_mps ({values['stall_speed_mps']:g} m/s)")
    if values["max_speed_mps"] <= values["min_speed_mps"]:
        raise node.error(f"is {values['max_speed_mps']:g} m/s", "max_speed_mps",
                         expected=f"above min_speed_mps ({values['min_speed_mps']:g} m/s)")
    return FixedWing(**values, jsbsim_model=model)


def _multirotor(node: Node, model: str | None) -> Multirotor:
    """A :class:`Multirotor` of ``node``'s keys and its ``rotors`` list."""
    values = {name: node.get(name, float, **bounds) for name, bounds in MULTIROTOR_KEYS.items()}
    raw = node.items("rotors", MIN_ROTORS, f"a list of at least {MIN_ROTORS} rotors, each "
                     "{position_m: [x, y, z], spin: 1 or -1, " + ", ".join([*ROTOR_KEYS, *ROTOR_PROPERTIES]) + "}")
    rotors = tuple(_rotor(Node(item, node.key(f"rotors[{i}]"), node.file), i) for i, item in enumerate(raw))
    for key in ROTOR_PROPERTIES:              # each motor commanded and each rotor read once
        names = [getattr(r, key) for r in rotors]
        for i, name in enumerate(names):
            if name in names[:i]:
                raise node.error(f"names '{name}' as rotors[{names.index(name)}] does", f"rotors[{i}].{key}",
                                 expected="a JSBSim property of its own for each rotor")
    return Multirotor(**values, rotors=rotors, jsbsim_model=model)


def _rotor(node: Node, index: int) -> Rotor:
    """The rotor ``index`` of the ``rotors`` list."""
    node._seen.add("position_m")
    if not node.has("position_m"):
        raise node.missing("position_m", "[x, y, z] in body axes from the centre of gravity, m")
    position = check_numbers(node.data["position_m"], 3,
                             error=lambda m, e: node.error(m, "position_m", f"{e}, body axes, m"))
    spin = node.get("spin", int, choices=SPINS)
    values = {name: node.get(name, float, **bounds) if default is None else node.get(name, float, default, **bounds)
              for name, (default, bounds) in ROTOR_KEYS.items()}
    names = {key: node.get(key, str, default.format(i=index)) for key, default in ROTOR_PROPERTIES.items()}
    node.done()
    return Rotor(position_m=tuple(position), spin=spin, **values, **names)


def check_controller(airframe: FixedWing | Multirotor, name: str, *, file: str | None, key: str) -> None:
    """Refuse the airframe of the aircraft ``name`` where navsim has no controller for its class
    yet (:data:`FLOWN_CLASSES`).

    Raises
    ------
    ScenarioError
        Naming ``file`` and ``key``, for a class navsim reads but has no controller for.
    """
    if airframe.kind not in FLOWN_CLASSES:
        raise ScenarioError(f"'{name}' is a {airframe.kind}: navsim's {airframe.kind} controller is not there yet",
                            file=file, key=key, expected="an aircraft of class " + ", ".join(FLOWN_CLASSES),
                            hint="its envelope reads and checks, but nothing flies it")


def model_digest(folder: str | Path) -> str:
    """The identity of an aircraft folder's model: a SHA-256 of every file under ``folder``
    (sub-folders too), by relative path and content, so that an edited model flies again.

    Returns
    -------
    str
        64 hex digits.
    """
    folder = Path(folder)
    h = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        content = path.read_bytes()
        h.update(f"{path.relative_to(folder).as_posix()}\0{len(content)}\0".encode())
        h.update(content)
    return h.hexdigest()
