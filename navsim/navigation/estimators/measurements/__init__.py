"""Measurement models, registered by name: each returns the batched linearised model of one
sensor sample for the error-state filter, a :class:`Linearised` (``z``, ``H``, ``R``, ``valid``).

``z`` is the measured error, *INS minus sensor*, so that ``z = H dx + v`` with ``dx`` the error
state (estimate minus truth) and ``v ~ N(0, R)``. Each model knows which sensor it reads
(``sensor``) and the noise it assumes (its own numbers, not the sensor's truth spec).

The package holds the registry (:mod:`.registry`), the types every model shares (:mod:`.model`)
and one module per family of measurements, each type's compiled form beside its Python form:
:mod:`.gnss` (``gnss_position``, ``gnss_horizontal``), :mod:`.velocity` (``velocity``,
``zero_velocity``), :mod:`.height`, :mod:`.air_data` (``air_velocity``), :mod:`.landmark`,
:mod:`.magnetometer` (``mag_heading``). Importing the package registers them all; a new family
is a new module imported here.

A model type is a dataclass registered with :func:`measurement` that declares, once, how it is
read from a scenario's ``measurements:`` entry (``parse``: its keys checked, plain values in the
scenario's units), its keys' JSON Schema (``SCHEMA``, for ``navsim schema``), and how it is built
from what ``parse`` returned (``from_entry``). :func:`parse_measurements` reads a list of entries,
:func:`build_measurements` builds them; the estimator factory, the scenario schema and ``navsim
list`` take the types from the registry (:func:`measurement_types`), and a plug-in registers its
own the same way::

    @measurement("range_to_beacon")
    @dataclass
    class RangeToBeacon:
        sensor: str
        sigma_m: float
        SCHEMA = {"sigma_m": {"type": "number", "exclusiveMinimum": 0}}

        @classmethod
        def parse(cls, node, sensors):
            return {"sigma_m": node.get("sigma_m", float, exclusive_minimum=0.0)}

        @classmethod
        def from_entry(cls, entry):
            return cls(entry["sensor"], entry["sigma_m"])

        def model(self, nav, layout, data, j):
            ...
            return Linearised(z, H, R, data.valid[:, j])    # (B, m), (B, m, n), (B, m, m), (B,)

Optional: a method ``compiled(layout)`` returning the model's :class:`CompiledModel` (a numba
kernel that fills its rows of every run in one call, of the signature :mod:`.model` gives; the
ES-KF then stacks the models of an epoch without a Python operation per model,
:func:`stack_models`): the shipped types all have one; a type without one is evaluated by its
``model`` (Python speed, the same result). A classmethod ``reads(entry)`` naming the sensor
values the model reads beyond its ``field`` (checked against what its sensor produces before
anything runs; a chunk keeps the values no estimator reads in single precision,
:func:`values_read`; a type without it has every value of its sensor kept), and a
``state_sigma`` mapping of the initial std of a sensor-error state block the model observes
(``air_velocity``'s ``pitot_bias``), which the filter takes as that block's initial uncertainty.
"""

from navsim.navigation.estimators.measurements.air_data import AirVelocity, check_observed_states, reject_rotating_R
from navsim.navigation.estimators.measurements.gnss import POSITION_VALUES, GnssHorizontal, GnssPosition
from navsim.navigation.estimators.measurements.height import Height
from navsim.navigation.estimators.measurements.landmark import LandmarkFix
from navsim.navigation.estimators.measurements.magnetometer import MagneticHeading, magnetic_heading
from navsim.navigation.estimators.measurements.model import (
    LINEARISED_FIELDS,
    CompiledModel,
    Linearised,
    Stacked,
    _own,
    compiled_form,
    stack_models,
)
from navsim.navigation.estimators.measurements.registry import (
    MEASUREMENTS,
    build_measurements,
    measurement,
    measurement_class,
    measurement_types,
    measurements_schema,
    parse_measurements,
    sensor_names,
    sensor_of_kind,
    values_read,
)
from navsim.navigation.estimators.measurements.velocity import Velocity, ZeroVelocity

__all__ = ["LINEARISED_FIELDS", "MEASUREMENTS", "POSITION_VALUES", "AirVelocity", "CompiledModel", "GnssHorizontal",
           "GnssPosition", "Height", "LandmarkFix", "Linearised", "MagneticHeading", "Stacked", "Velocity",
           "ZeroVelocity", "build_measurements", "check_observed_states", "compiled_form", "magnetic_heading",
           "measurement", "measurement_class", "measurement_types", "measurements_schema", "parse_measurements",
           "reject_rotating_R", "sensor_names", "sensor_of_kind", "stack_models", "values_read"]
