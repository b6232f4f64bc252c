"""Sensor emulators and the sensor catalog.

Every sensor reads the truth record and emits timestamped measurements at its own rate for a
batch of Monte Carlo runs, each run from its own random stream
(:func:`navsim.sensors.base.run_generators`), so the same seed gives the same data whatever the
batch size. Specs (truth models) come from the catalog ``sensors/*.yaml``
(:mod:`navsim.sensors.catalog`); :func:`emulate` dispatches on the spec's kind. Each kind is
declared once, in its own module, as a :class:`~navsim.sensors.registry.SensorKind` (spec,
catalog fields, outputs with units, error sources, faults, emulator, plot); every module of
this package is imported here, so a new kind is one new module (``docs/sensors.md``).

In a scenario::

    sensors:
      imu:  {model: p0_imu}
      gnss: {model: p0_bd2, faults: [{type: outage, start_s: 200, end_s: 260}]}
      baro: {model: p0_baro, override: {noise: 0.5 m}, off: [offset_sigma]}
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass

from navsim.foundations.config import Node, plain_name
from navsim.sensors import registry
from navsim.sensors.base import Fault, SensorData, check_faults, parse_faults
from navsim.sensors.catalog import load_spec
from navsim.sensors.registry import SensorKind, register

for _module in pkgutil.iter_modules(__path__):       # every built-in kind registers itself on import
    importlib.import_module(f"{__name__}.{_module.name}")


@dataclass(frozen=True)
class SensorConfig:
    """One sensor of a scenario: its name, truth-model spec and fault windows."""

    name: str
    model: str
    spec: object
    faults: tuple[Fault, ...] = ()

    @property
    def kind(self) -> str:
        return registry.kind_of(self.spec)

    @property
    def role(self) -> str | None:
        """What its kind is to the navigation (:data:`~navsim.sensors.registry.KIND_ROLES`)."""
        return registry.get(self.kind).role


#: the measurement values of each sensor kind (``SensorData.values`` keys) whatever its spec, read
#: from the registry (each kind's declared ``outputs``; :func:`output_fields` for one spec's)
OUTPUTS = registry.View(lambda kind: tuple(o.name for o in kind.outputs if o.when is None))


def output_fields(spec) -> tuple[str, ...]:
    """The ``values`` keys the emulator of ``spec`` produces (:func:`emulate`)."""
    return registry.of(spec).output_fields(spec)


def height_fields() -> tuple[str, ...]:
    """The values a ``height`` measurement may read (every kind's outputs of role ``height``)."""
    return registry.fields_of_role("height")


def velocity_fields() -> tuple[str, ...]:
    """The values a ``velocity`` measurement may read (NED velocities: role ``velocity``)."""
    return registry.fields_of_role("velocity")


def emulate(truth, config: SensorConfig, seed: int, runs) -> SensorData:
    """Emulate ``config`` on ``truth`` for the run indices ``runs`` (its kind's emulator, its
    faults checked against those the kind can have)."""
    check_faults(config.faults, config.kind, truth.duration_s, config.name)
    return registry.get(config.kind).emulate(truth, config.spec, seed, runs, faults=config.faults,
                                              name=config.name)


def parse_sensors(data, file: str | None = None, path: str = "sensors") -> tuple[SensorConfig, ...]:
    """Read the ``sensors`` mapping of a scenario (see the module docstring)."""
    if data is None:
        return ()
    node = Node(data, path, file)
    out = []
    for name in list(node.data):
        if not plain_name(str(name)):
            raise node.error(f"'{name}' is not a sensor name", str(name),
                             expected="a plain name (letters, digits, '.', '_', '-'): it names report files")
        item = node.child(str(name))
        model = item.get("model", str)
        override = item.child("override", None)
        off = item.data.get("off", [])
        item._seen.add("off")
        if off != "all" and not (isinstance(off, list) and all(isinstance(x, str) for x in off)):
            raise item.error("is malformed", "off", expected="a list of error sources, or 'all'")
        spec = load_spec(model, override.data if override else None, off, file, item.path)
        item._seen.add("faults")
        faults = parse_faults(item.data.get("faults"), item.key("faults"), file, vector=registry.of(spec).vector_bias)
        item.done()
        out.append(SensorConfig(name=str(name), model=model, spec=spec, faults=faults))
    node.done()
    return tuple(out)


__all__ = ["OUTPUTS", "Fault", "SensorConfig", "SensorData", "SensorKind", "emulate", "height_fields", "load_spec",
           "output_fields", "parse_sensors", "register", "velocity_fields"]
