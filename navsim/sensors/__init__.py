"""Sensor emulators and the sensor catalog.

Every sensor reads the truth record and emits timestamped measurements at its own rate for a
batch of Monte Carlo runs, each run from its own random stream
(:func:`navsim.sensors.base.run_generators`), so the same seed gives the same data whatever the
batch size. Specs (truth models) come from the catalog ``sensors/*.yaml``
(:mod:`navsim.sensors.catalog`); :func:`emulate` dispatches on the spec's kind.

In a scenario::

    sensors:
      imu:  {model: p0_imu}
      gnss: {model: p0_bd2, faults: [{type: outage, start_s: 200, end_s: 260}]}
      baro: {model: p0_baro, override: {noise: 0.5 m}, off: [offset_sigma]}
"""

from __future__ import annotations

from dataclasses import dataclass

from navsim.foundations.config import Node, plain_name
from navsim.sensors import specs
from navsim.sensors.airdata import emulate_ads, emulate_baro
from navsim.sensors.base import Fault, SensorData, check_faults, parse_faults
from navsim.sensors.camera import emulate_camera
from navsim.sensors.catalog import load_spec
from navsim.sensors.gnss import emulate_gnss
from navsim.sensors.imu import emulate_imu
from navsim.sensors.magnetometer import emulate_magnetometer
from navsim.sensors.radar import emulate_radar_altimeter

EMULATORS = {"imu": emulate_imu, "gnss": emulate_gnss, "baro": emulate_baro, "ads": emulate_ads,
             "radar_altimeter": emulate_radar_altimeter, "magnetometer": emulate_magnetometer,
             "camera": emulate_camera}


@dataclass(frozen=True)
class SensorConfig:
    """One sensor of a scenario: its name, truth-model spec and fault windows."""

    name: str
    model: str
    spec: object
    faults: tuple[Fault, ...] = ()

    @property
    def kind(self) -> str:
        return specs.kind_of(self.spec)


#: the measurement values of each sensor kind (``SensorData.values`` keys), whatever its spec
OUTPUTS = {"imu": ("omega_ib_b_rps", "f_b_mps2", "dtheta_b_rad", "dv_b_mps"), "baro": ("h_baro_m", "p_static_pa"),
           "gnss": ("lat_rad", "lon_rad", "h_m", "fix_type", "h_acc_m", "v_acc_m", "s_acc_mps"),
           "ads": ("p_static_pa", "p_total_pa", "temp_k", "h_pressure_m", "cas_mps", "tas_mps", "vel_n_mps"),
           "radar_altimeter": ("h_agl_m",), "magnetometer": ("mag_b_T",),
           "camera": ("lat_rad", "lon_rad", "h_m", "landmark")}
#: the values a ``velocity`` measurement may read (NED velocity) and a ``height`` measurement
VELOCITY_FIELDS = ("vel_n_mps",)
HEIGHT_FIELDS = ("h_m", "h_baro_m", "h_pressure_m", "h_agl_m")


def output_fields(spec) -> tuple[str, ...]:
    """The ``values`` keys the emulator of ``spec`` produces (:func:`emulate`)."""
    out = OUTPUTS[specs.kind_of(spec)]
    if getattr(spec, "velocity_output", False):
        out += ("vel_n_mps",)
    if getattr(spec, "velocity_axis", None) == "air":
        out += ("alpha_rad", "beta_rad")
    return out


def emulate(truth, config: SensorConfig, seed: int, runs) -> SensorData:
    """Emulate ``config`` on ``truth`` for the run indices ``runs``."""
    fn = EMULATORS[config.kind]
    if config.kind == "imu":
        return fn(truth, config.spec, seed, runs, name=config.name)
    check_faults(config.faults, config.kind, truth.duration_s, config.name)
    return fn(truth, config.spec, seed, runs, faults=config.faults, name=config.name)


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
        kind = specs.kind_of(spec)
        item._seen.add("faults")
        faults = parse_faults(item.data.get("faults"), item.key("faults"), file, vector=(kind == "gnss"))
        item.done()
        out.append(SensorConfig(name=str(name), model=model, spec=spec, faults=faults))
    node.done()
    return tuple(out)


__all__ = ["EMULATORS", "HEIGHT_FIELDS", "VELOCITY_FIELDS", "output_fields", "Fault", "SensorConfig", "SensorData", "emulate", "load_spec",
           "parse_sensors"]
