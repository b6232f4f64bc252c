"""Truth-model specifications of the sensors, in SI: each kind's spec dataclass, gathered.

A spec says how a sensor corrupts the truth. It is *not* what an estimator assumes: the filter's
noise model is a separate object (built from a catalog entry of its own), so model mismatch can
be studied. Every field is SI; three-axis fields are ``(3,)`` arrays (x, y, z body axes, or
north, east, down for position errors). Each spec is declared in its kind's module with the
rest of the kind (:mod:`navsim.sensors.registry`); this module names the built-in ones in one
place. :func:`disable` switches error sources off by name; :func:`ideal` switches all of them
off.
"""

from __future__ import annotations

from navsim.sensors import registry
from navsim.sensors.airdata import AdsSpec, BaroSpec
from navsim.sensors.camera import CameraSpec
from navsim.sensors.gnss import GnssSpec
from navsim.sensors.imu import AxisErrors, ImuSpec
from navsim.sensors.vibration import Vibration
from navsim.sensors.magnetometer import MagnetometerSpec
from navsim.sensors.radar import RadarAltimeterSpec
from navsim.sensors.registry import kind_of

#: error sources per kind (dotted paths), read from the registry: ``ERROR_FIELDS[kind]``
ERROR_FIELDS = registry.View(lambda kind: kind.error_names())


def disable(spec, paths):
    """A copy of ``spec`` with the error sources at dotted ``paths`` switched off (each off as
    its kind's :class:`~navsim.sensors.registry.ErrorTerm` says: ``range`` off means no
    saturation, ``beam_half_width`` off no slant error)."""
    return registry.of(spec).disable(spec, paths)


def ideal(spec):
    """The spec with every error source off: the sensor reproduces the truth."""
    return registry.of(spec).ideal(spec)


__all__ = ["AdsSpec", "AxisErrors", "BaroSpec", "CameraSpec", "ERROR_FIELDS", "GnssSpec", "ImuSpec",
           "MagnetometerSpec", "RadarAltimeterSpec", "Vibration", "disable", "ideal", "kind_of"]
