"""Measurement models, registered by name: each returns the batched linearised model of one
sensor sample for the error-state filter, a :class:`Linearised` (``z``, ``H``, ``R``, ``valid``).

``z`` is the measured error, *INS minus sensor*, so that ``z = H dx + v`` with ``dx`` the error
state (estimate minus truth) and ``v ~ N(0, R)``. Each model knows which sensor it reads
(``sensor``) and the noise it assumes (its own numbers, not the sensor's truth spec).

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
kernel that fills its rows of every run in one call; the ES-KF then stacks the models of an epoch
without a Python operation per model, :func:`stack_models`): the shipped types all have one
(:mod:`navsim.navigation.estimators.compiled_models`); a type without one is evaluated by its
``model`` (Python speed, the same result). A classmethod ``reads(entry)`` naming the sensor
values the model reads beyond its ``field`` (checked against what its sensor produces before
anything runs; a chunk keeps the values no estimator reads in single precision,
:func:`values_read`; a type without it has every value of its sensor kept), and a
``state_sigma`` mapping of the
initial std of a sensor-error state block the model observes (``air_velocity``'s
``pitot_bias``), which the filter takes as that block's initial uncertainty.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings
from dataclasses import dataclass

import numpy as np

from navsim.foundations import atmosphere, earth
from navsim.flight.environment import MAX_WIND_MPS
from navsim.foundations.config import Node, check_numbers, close_match
from navsim.foundations.jsonschema import NUM, POS, VEC3, merge_properties
from navsim.foundations.transform import skew
from navsim.navigation import magcal
from navsim.navigation.estimators import compiled_models
from navsim.navigation.estimators.error_model import AIR_MASS_AXES, GUST_AXES, WIND_AXES, Layout
from navsim.navigation.strapdown import NavState
from navsim.sensors import registry
from navsim.sensors.catalog import load_spec
from navsim.sensors.magnetometer import WMM_DATE
from navsim.sensors.specs import AdsSpec

_MEASUREMENTS: dict[str, type] = {}

#: the fields of :class:`Linearised`, in the order of the former ``(z, H, R, valid)`` tuple
LINEARISED_FIELDS = ("z", "H", "R", "valid")


@dataclass(frozen=True, eq=False)
class Linearised:
    """The batched linearised model of one sensor sample, what a measurement model's ``model``
    returns: ``z = H dx + v``, ``dx`` the error state (estimate minus truth), ``v ~ N(0, R)``.

    Attributes
    ----------
    z : ndarray, (B, m)
        The measured error, *INS minus sensor*.
    H : ndarray, (B, m, n)
        Its rows in the error state (``n = layout.n``).
    R : ndarray, (B, m, m)
        The noise covariance the model assumes.
    valid : ndarray of bool, (B,), or None
        The runs that have a usable sample (None: all of them).

    Unpacking it (``z, H, R, valid = m.model(...)``) or indexing it (``[0]`` for ``z``), as
    for the tuple models returned before, still works but is deprecated (a
    ``DeprecationWarning``): read the attributes.
    """

    z: np.ndarray
    H: np.ndarray
    R: np.ndarray
    valid: np.ndarray | None

    def _deprecated(self) -> tuple:
        warnings.warn("a measurement model's result is a Linearised: read .z, .H, .R, .valid "
                      "(unpacking or indexing it as a tuple is deprecated)", DeprecationWarning, stacklevel=3)
        return tuple(getattr(self, f) for f in LINEARISED_FIELDS)

    def __iter__(self):
        return iter(self._deprecated())

    def __getitem__(self, i):
        return self._deprecated()[i]


@dataclass(frozen=True, eq=False)
class CompiledModel:
    """A measurement model's compiled form for one state layout (its ``compiled(layout)``).

    Attributes
    ----------
    kernel : numba function
        ``kernel(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid)``, the signature of
        :mod:`navsim.navigation.estimators.compiled_models`: fills the model's rows of every run.
    rows : int
        Its rows ``m``.
    params : ndarray of float
        Its constants (``par``).
    cols : ndarray of int
        Its columns in the error state (``cols``; -1: no such state).
    inputs : callable
        ``inputs(nav, data, j)`` -> ``(inp (B, k) float array, valid (B,) bool array)``: what the
        kernel reads of sample ``j``, gathered in Python (a fresh ``valid`` the kernel may narrow).
    """

    kernel: object
    rows: int
    params: np.ndarray
    cols: np.ndarray
    inputs: object

    def fill(self, nav: NavState, data, j: int, r0: int, z, H, R) -> np.ndarray:
        """Rows ``r0:r0 + rows`` of the zeroed ``z``, ``H``, ``R``; returns the valid runs."""
        inp, valid = self.inputs(nav, data, j)
        self.kernel(nav.lat_rad, nav.lon_rad, nav.h_m, nav.vel_n_mps, nav.C_nb, np.ascontiguousarray(inp, float),
                    self.params, self.cols, r0, z, H, R, valid)
        return valid


def _compiled(kernel, rows: int, params, cols, inputs) -> CompiledModel:
    return CompiledModel(kernel, rows, np.ascontiguousarray(params, float), np.asarray(cols, np.int64), inputs)


def _own(cls: type, attr: str):
    """``cls``'s ``attr`` where the class that defines its ``model`` defines it too, else None:
    a subclass that changes ``model`` does not inherit its parent's compiled form or reads."""
    home = next((c for c in cls.__mro__ if "model" in c.__dict__), cls)
    return getattr(cls, attr) if attr in home.__dict__ else None


def compiled_form(model, layout: Layout) -> CompiledModel | None:
    """``model``'s compiled form for ``layout``, or None (a type without ``compiled``, or whose
    ``model`` is not the one its ``compiled`` mirrors)."""
    make = _own(type(model), "compiled")
    return make(model, layout) if callable(make) else None


@dataclass(frozen=True, eq=False)
class Stacked:
    """The models of one epoch stacked for :func:`navsim.navigation.estimators.kalman.update_stacked`:
    ``z`` ``(B, M)``, ``H`` ``(B, M, n)``, ``R`` ``(B, M, M)`` (block diagonal), ``valid`` ``(B, G)``
    and ``ends`` ``(G + 1,)``, model ``g`` the rows ``ends[g]:ends[g + 1]``."""

    z: np.ndarray
    H: np.ndarray
    R: np.ndarray
    valid: np.ndarray
    ends: np.ndarray


def stack_models(taken: list, nav: NavState, layout: Layout) -> Stacked:
    """The linearised models of ``taken``, a list of ``(model, compiled, data, j)`` (``compiled``
    the model's :class:`CompiledModel` or None), stacked: a compiled form fills its rows for
    every run in one call, a model without one is evaluated by its ``model``."""
    B, n = nav.lat_rad.shape[0], layout.n
    lins = [None if c is not None else m.model(nav, layout, data, j) for m, c, data, j in taken]
    rows = [c.rows if c is not None else lin.H.shape[-2] for (_, c, _, _), lin in zip(taken, lins)]
    ends = np.cumsum([0] + rows)
    M = int(ends[-1])
    z, H, R = np.zeros((B, M)), np.zeros((B, M, n)), np.zeros((B, M, M))
    valid = np.empty((B, len(taken)), bool)
    for g, ((_, c, data, j), lin) in enumerate(zip(taken, lins)):
        r = slice(ends[g], ends[g + 1])
        if c is not None:
            valid[:, g] = c.fill(nav, data, j, int(ends[g]), z, H, R)
        else:
            z[:, r], H[:, r], R[:, r, r] = lin.z, lin.H, lin.R
            valid[:, g] = True if lin.valid is None else lin.valid
    return Stacked(z, H, R, valid, ends)


def _columns(data, j: int, keys) -> np.ndarray:
    """Sample ``j`` of the values ``keys`` ``(B, len(keys))``."""
    return np.stack([data.values[k][:, j] for k in keys], -1)


def _valid(data, j: int) -> np.ndarray:
    return np.array(data.valid[:, j], bool)


def _returns_linearised(name: str, model):
    """``model`` whose result is a :class:`Linearised`: a plug-in's model that returns the former
    ``(z, H, R, valid)`` tuple gets it wrapped (with a ``DeprecationWarning``), anything else is a
    ``TypeError`` naming the type."""
    @functools.wraps(model)
    def wrapped(self, nav, layout, data, j):
        out = model(self, nav, layout, data, j)
        if isinstance(out, Linearised):
            return out
        if isinstance(out, tuple) and len(out) == len(LINEARISED_FIELDS):
            warnings.warn(f"measurement '{name}': model() returns a tuple; return a Linearised(z, H, R, valid) "
                          "(navsim.navigation.estimators.Linearised)", DeprecationWarning, stacklevel=2)
            return Linearised(*out)
        raise TypeError(f"measurement '{name}': model() returned {type(out).__name__}, expected a Linearised")
    wrapped.returns_linearised = True
    return wrapped


def measurement(name: str):
    """Class decorator: register a measurement model type as ``name`` (the ``type`` of its
    scenario entries; also the model's ``name``, the first part of its NIS key). Its ``model``
    returns a :class:`Linearised` (a former tuple is wrapped, deprecated)."""
    def deco(cls):
        for attr in ("parse", "from_entry", "model"):
            if not callable(getattr(cls, attr, None)):
                raise TypeError(f"measurement '{name}': {cls.__name__} has no {attr}()")
        if not getattr(cls.model, "returns_linearised", False):
            cls.model = _returns_linearised(name, cls.model)
        cls.name = name
        _MEASUREMENTS[name] = cls
        return cls
    return deco


def measurement_types() -> list[str]:
    """The registered measurement types, sorted."""
    return sorted(_MEASUREMENTS)


def measurement_class(name: str) -> type:
    return _MEASUREMENTS[name]


def sensor_of_kind(node: Node, sensors: dict, kind: str) -> str:
    """The entry's ``sensor``, checked to be a sensor of ``kind`` (``sensors``: name -> kind)."""
    name = node.data["sensor"]
    if sensors[name] != kind:
        raise node.error(f"'{name}' is a {sensors[name]}", "sensor", expected=f"a {kind} sensor",
                         hint=close_match(name, [k for k, v in sensors.items() if v == kind]))
    return name


def sensor_names(node: Node, key: str, sensors: dict) -> list | None:
    """The optional list of sensor names under ``key``, each a sensor of the scenario."""
    node._seen.add(key)
    names = node.data.get(key)
    if names is None:
        return None
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise node.error(f"is {names!r}", key, expected="a list of sensor names")
    for n in names:
        if n not in sensors:
            raise node.error(f"'{n}' is not a sensor of this scenario", key, expected="one of " + ", ".join(sensors),
                             hint=close_match(n, sensors))
    return list(names)


def parse_measurements(node: Node, sensors: dict, key: str = "measurements") -> list:
    """The list under ``key`` of an estimator's entry, each checked by its type's ``parse``:
    ``{"type", "sensor", **its values}``. ``sensors``: the scenario's sensor name -> kind."""
    raw = node.items(key, 1, "a list of measurement models", "e.g. [{type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}]")
    out = []
    for j, item in enumerate(raw):
        m = Node(item, node.key(f"{key}[{j}]"), node.file)
        mtype = m.get("type", str, choices=measurement_types())
        sensor = m.get("sensor", str)
        if sensor not in sensors:
            raise m.error(f"'{sensor}' is not a sensor of this scenario", "sensor",
                          expected="one of " + ", ".join(sensors) if sensors else "a sensor under 'sensors'",
                          hint=close_match(sensor, sensors))
        entry = {"type": mtype, "sensor": sensor, **measurement_class(mtype).parse(m, sensors)}
        m.done()
        out.append(entry)
    return out


def build_measurements(entries: list) -> list:
    """The measurement models of entries read by :func:`parse_measurements`."""
    return [measurement_class(e["type"]).from_entry(e) for e in entries]


def measurements_schema(built_in: bool = False) -> dict:
    """The JSON Schema of a ``measurements`` entry: every registered type's keys (``built_in``:
    navsim's own types only)."""
    names = [n for n in measurement_types() if not built_in or measurement_class(n).__module__.startswith("navsim.")]
    props = {"type": {"enum": names}, "sensor": {"type": "string"}}
    for name in names:
        merge_properties(props, measurement_class(name).SCHEMA)
    return {"type": "object", "properties": props, "additionalProperties": False, "required": ["type", "sensor"]}


def _diag(sig2: np.ndarray, B: int) -> np.ndarray:
    return np.broadcast_to(np.diag(sig2), (B, sig2.size, sig2.size)).copy()


#: the values a position fix reads of its sensor
POSITION_VALUES = ("lat_rad", "lon_rad", "h_m")


def values_read(entry: dict) -> tuple | None:
    """The sensor values the model of ``entry`` reads (its ``field`` and its type's
    ``reads(entry)``), or None when its type does not say (a plug-in without ``reads``)."""
    reads = _own(measurement_class(entry["type"]), "reads")
    if reads is None:
        return None
    return tuple(reads(entry)) + ((entry["field"],) if "field" in entry else ())


def _height_output(kind: str) -> str:
    """The output a ``height`` measurement of a sensor of ``kind`` reads without a ``field``: the
    first the kind declares with the role ``height`` (:mod:`navsim.sensors.registry`), else ``h_m``."""
    return registry.default_output(kind, "height") or "h_m"


@measurement("gnss_position")
@dataclass
class GnssPosition:
    """INS minus GNSS position, NED metres: ``[dL (R_M+h), dlambda (R_N+h) cos L, -dh]``."""

    sensor: str
    sigma_m: np.ndarray                  #: (3,) NED
    SCHEMA = {"sigma_m": VEC3}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_m": node.vector("sigma_m")}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_m"]))

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return POSITION_VALUES

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        v = data.values
        r_m, r_n = earth.radii(nav.lat_rad)
        k_n, k_e = r_m + nav.h_m, (r_n + nav.h_m) * np.cos(nav.lat_rad)
        z = np.stack([(nav.lat_rad - v["lat_rad"][:, j]) * k_n,
                      (nav.lon_rad - v["lon_rad"][:, j]) * k_e,
                      -(nav.h_m - v["h_m"][:, j])], -1)
        H = np.zeros((B, 3, layout.n))
        p = layout.slice("pos").start
        H[:, 0, p], H[:, 1, p + 1], H[:, 2, p + 2] = k_n, k_e, -1.0
        return Linearised(z, H, _diag(np.asarray(self.sigma_m, float) ** 2, B), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        return _position_fix(np.asarray(self.sigma_m, float)[:3] ** 2, layout)


def _position_fix(var, layout: Layout) -> CompiledModel:
    """The compiled position fix of ``len(var)`` rows (N, E, D)."""
    return _compiled(compiled_models.position_fix, len(var), var, [layout.slice("pos").start],
                     lambda nav, data, j: (_columns(data, j, POSITION_VALUES), _valid(data, j)))


@measurement("velocity")
@dataclass
class Velocity:
    """INS minus a NED velocity (GNSS, or P0's ADS ground velocity), m/s."""

    sensor: str
    sigma_mps: np.ndarray                #: (3,)
    field: str = "vel_n_mps"
    SCHEMA = {"sigma_mps": VEC3, "field": {"type": "string"}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_mps": node.vector("sigma_mps"), "field": node.get("field", str, "vel_n_mps")}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_mps"]), field=entry["field"])

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ()                        # its field alone

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        z = nav.vel_n_mps - data.values[self.field][:, j]
        H = np.zeros((B, 3, layout.n))
        s = layout.slice("vel").start
        H[:, [0, 1, 2], [s, s + 1, s + 2]] = 1.0
        return Linearised(z, H, _diag(np.asarray(self.sigma_mps, float) ** 2, B), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        return _compiled(compiled_models.velocity, 3, np.asarray(self.sigma_mps, float) ** 2,
                         [layout.slice("vel").start],
                         lambda nav, data, j: (data.values[self.field][:, j], _valid(data, j)))


@measurement("height")
@dataclass
class Height:
    """INS height minus a measured height (barometer, ADS pressure altitude, a fused height),
    m. With a ``baro`` state in the filter, the sensor's Markov error is modelled:
    ``z = dh - dh_b``. ``offset_m`` is added to the sensor value (e.g. the surface height under
    a radar altimeter)."""

    sensor: str
    sigma_m: float
    field: str = "h_m"
    use_baro_state: bool = False
    offset_m: float = 0.0
    SCHEMA = {"sigma_m": VEC3, "field": {"type": "string"}, "baro_state": {"type": "boolean"}, "offset_m": NUM}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_m": node.get("sigma_m", float, exclusive_minimum=0.0),
                "field": node.get("field", str, _height_output(sensors[node.data["sensor"]])),
                "baro_state": node.get("baro_state", bool, False), "offset_m": node.get("offset_m", float, 0.0)}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], entry["sigma_m"], field=entry["field"], use_baro_state=entry["baro_state"],
                   offset_m=entry["offset_m"])

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ()                        # its field alone

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        z = (nav.h_m - (data.values[self.field][:, j] + self.offset_m))[:, None]
        H = np.zeros((B, 1, layout.n))
        H[:, 0, layout.slice("pos").start + 2] = 1.0
        if self.use_baro_state and layout.has("baro"):
            H[:, 0, layout.slice("baro").start] = -1.0
        return Linearised(z, H, np.full((B, 1, 1), float(self.sigma_m) ** 2), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        baro = layout.slice("baro").start if self.use_baro_state and layout.has("baro") else -1
        return _compiled(compiled_models.height, 1, [float(self.sigma_m) ** 2], [layout.slice("pos").start + 2, baro],
                         lambda nav, data, j: ((data.values[self.field][:, j] + self.offset_m)[:, None],
                                               _valid(data, j)))


@measurement("zero_velocity")
@dataclass
class ZeroVelocity:
    """INS velocity against zero, m/s: a pseudo-measurement for a vehicle with no position or
    velocity aiding that stays near one spot (a replayed log without GNSS, a hover, a test
    stand). The horizontal velocity error grows as gravity times the tilt error, so holding it
    near zero keeps roll and pitch observable from the accelerometers, as PX4's EKF2 fuses a
    fake position when it has no aiding. ``sigma_mps`` (N, E, D) must cover the vehicle's true
    motion; ``axes: horizontal`` (the default) uses N and E only. ``sensor`` only times it: one
    update at each of its samples."""

    sensor: str
    sigma_mps: np.ndarray                #: (3,) N, E, D
    vertical: bool = False
    SCHEMA = {"sigma_mps": VEC3, "axes": {"enum": ["horizontal", "ned"]}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_mps": node.vector("sigma_mps"),
                "axes": node.get("axes", str, "horizontal", choices=["horizontal", "ned"])}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_mps"]), vertical=entry["axes"] == "ned")

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ()                        # its sensor only times it

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B, m = nav.lat_rad.shape[0], 3 if self.vertical else 2
        H = np.zeros((B, m, layout.n))
        s = layout.slice("vel").start
        H[:, np.arange(m), s + np.arange(m)] = 1.0
        sig2 = np.asarray(self.sigma_mps, float)[:m] ** 2
        return Linearised(nav.vel_n_mps[:, :m].copy(), H, _diag(sig2, B), data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        m = 3 if self.vertical else 2
        return _compiled(compiled_models.velocity, m, np.asarray(self.sigma_mps, float)[:m] ** 2,
                         [layout.slice("vel").start],
                         lambda nav, data, j: (np.zeros((nav.lat_rad.shape[0], m)), _valid(data, j)))


@measurement("air_velocity")
@dataclass
class AirVelocity:
    """INS velocity minus the ground velocity the air data make with the INS attitude, m/s:
    ``z = v - (C_nb u V + w)``, ``V`` the ADS's true airspeed, ``u`` its direction in the body,
    ``[cos a cos b, sin b, sin a cos b]``, from the angle-of-attack and sideslip vanes when the
    filter's ADS model has them (``velocity_axis: air``), else the body x axis (P0's ground
    velocity), ``w`` the filter's wind (``wind_n_mps``, default calm).

    ``model`` (and ``override``) is the filter's own model of the ADS, a catalog entry as the
    ES-KF's ``noise.imu``: ``R`` is derived from it at each epoch, from the measured airspeed
    and density, in the air axes: along ``u`` the airspeed's std ``sigma_qc / (rho V)`` (the
    dynamic-pressure sensor's noise and per-run bias, the static one's too with an absolute
    pitot) with the density's share ``V/2 sqrt((sigma_ps/ps)^2 + (sigma_T/T)^2)``; across it
    ``V sigma_angle``, ``sigma_angle`` the vanes' noise, or without vanes ``angle_sigma_deg``,
    what the filter allows for the angles it does not measure (about 4 deg on P0's track: the
    mean angle of attack and its spread; that mean is a bias, not white, so this mode is not
    consistent: P0's ES-KF with it has NEES 12.5 on 200 runs). With ``C_nb_est = (I - [phi x]) C_nb`` the
    attitude row is ``-[a x]``, ``a = C_nb u V``: the INS attitude error turns the air velocity.

    With ``wind`` (and ``wind_down``) states the wind is estimated: ``z = v - C_nb u V -
    wind_n_mps`` is the wind the filter has not been told plus the errors, so the wind block's
    columns are the identity on N, E (and D); ``wind_n_mps`` is then a prior the state adds to.
    Turbulence the filter does not model is white to it: ``turbulence_sigma_mps`` (the gusts'
    std, taken isotropic: the larger of MIL-HDBK-1797's low-altitude intensities,
    :func:`navsim.flight.environment.turbulence_sigma_mps`) adds its variance to ``R`` on
    every axis a ``gust`` (``gust_down``) state does not carry. A gust state models them as
    coloured (Dryden's first-order form, :mod:`~navsim.navigation.estimators.error_model`):
    its columns are the identity too, and the wind state is then the steady wind.

    With a ``pitot_bias`` state in the filter (the dynamic pressure's per-run bias ``b``, Pa, a
    random constant whose initial std is the ADS model's), ``V = V_true + b / (rho V)``: its
    column is ``-C_nb u / (rho V)`` and ``R`` leaves the bias out. Without it, the bias is in
    ``R`` as if it were white. With an absolute pitot the static sensor's bias is in both
    ``pitot_bias`` and a ``baro`` state (their correlation is not in the initial covariance):
    the shipped ``p0_ads`` is differential.
    """

    sensor: str
    spec: AdsSpec                        #: the filter's model of the ADS
    angle_sigma_rad: float = 0.0         #: the unmeasured angles' std (an ADS model without vanes)
    wind_n_mps: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    turbulence_sigma_mps: float = 0.0    #: the gusts' std the filter takes as white, m/s
    SCHEMA = {"model": {"type": "string"}, "override": {"type": "object"}, "angle_sigma_deg": {"type": "number", "minimum": 0},
              "wind_n_mps": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
              "turbulence_sigma_mps": {"type": "number", "minimum": 0}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        sensor_of_kind(node, sensors, "ads")
        name = node.get("model", str)
        override = node.child("override", None)
        spec = _ads_spec(name, override.data if override else None, node)
        vanes = spec.velocity_axis == "air"
        given = node.data.get("angle_sigma_deg") is not None
        angle = node.get("angle_sigma_deg", float, 0.0, minimum=0.0)
        if vanes and given:
            raise node.error(f"the ADS model '{name}' has vanes: their noise is the angles' sigma", "angle_sigma_deg",
                             expected="no angle_sigma_deg with a vane-fitted ADS model (its vane_noise is used)")
        if not vanes and angle == 0.0:
            raise node.error(f"the ADS model '{name}' has no vanes: the angles it leaves out need a sigma",
                             "angle_sigma_deg", expected="a number > 0 (about 4 deg at a cruise angle of attack)")
        wind = node.data.get("wind_n_mps", [0.0, 0.0, 0.0])
        node._seen.add("wind_n_mps")
        wind = check_numbers(wind, 3, minimum=-MAX_WIND_MPS, maximum=MAX_WIND_MPS, error=lambda m, e: node.error(
            m, "wind_n_mps", expected=f"[north, east, down] in m/s ({e})"))
        return {"model": name, "override": override.data if override else None, "angle_sigma_deg": angle,
                "wind_n_mps": [float(w) for w in wind],
                "turbulence_sigma_mps": node.get("turbulence_sigma_mps", float, 0.0, minimum=0.0, maximum=MAX_WIND_MPS)}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], _ads_spec(entry["model"], entry["override"]),
                   math.radians(entry["angle_sigma_deg"]), np.asarray(entry["wind_n_mps"], float),
                   float(entry.get("turbulence_sigma_mps", 0.0)))

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        """The sensor values the model of ``entry`` reads: the vanes' angles when its ADS model
        has vanes, the air data always (checked against the sensor before anything runs)."""
        return _air_values(_ads_spec(entry["model"], entry["override"]).velocity_axis == "air")

    def axes_b(self, data, j: int) -> tuple:
        """The air axes in the body ``(B, 3)`` each (along the airspeed, the sideslip's and the
        angle of attack's directions) and their angles' std."""
        v = data.values
        if self.spec.velocity_axis == "air":
            a, b, sigma = v["alpha_rad"][:, j], v["beta_rad"][:, j], self.spec.vane_noise
        else:
            a = b = np.zeros(data.valid.shape[0])
            sigma = self.angle_sigma_rad
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        u = np.stack([ca * cb, sb, sa * cb], -1)
        e_b = np.stack([-ca * sb, cb, -sa * sb], -1)
        e_a = np.stack([-sa, np.zeros_like(a), ca], -1)
        return u, e_b, e_a, sigma

    @property
    def state_sigma(self) -> dict:
        """The initial std of the sensor-error state this model observes: ``pitot_bias``, the
        dynamic pressure's per-run bias by the filter's ADS model, Pa."""
        s = self.spec
        static = s.static_bias_sigma if s.pitot == "absolute" else 0.0
        return {"pitot_bias": np.array([math.hypot(s.total_bias_sigma, static)])}

    def airspeed_sigma(self, data, j: int, bias_state: bool) -> tuple:
        """The std of the ADS's true airspeed ``(B,)`` by the filter's model, m/s (the
        dynamic pressure's bias in it unless a ``bias_state`` carries it), and ``dV/dq_c =
        1 / (rho V)`` ``(B,)``, (m/s)/Pa."""
        s, v = self.spec, data.values
        V, ps, T = v["tas_mps"][:, j], v["p_static_pa"][:, j], v["temp_k"][:, j]
        dv_dqc = 1.0 / (ps / (atmosphere.R_AIR * T) * np.maximum(V, 1.0))
        var_ps, var_qc = self.pressure_variances(bias_state)
        density = 0.5 * V * np.sqrt(var_ps / ps ** 2 + (s.temperature_noise / T) ** 2)
        return np.hypot(np.sqrt(var_qc) * dv_dqc, density), dv_dqc

    def pressure_variances(self, bias_state: bool) -> tuple[float, float]:
        """The variances of the static pressure and of the dynamic pressure by the filter's
        ADS model, Pa^2 (the dynamic pressure's bias in it unless a ``bias_state`` carries it)."""
        s = self.spec
        var_ps = s.static_noise ** 2 + s.static_bias_sigma ** 2
        var_qc = s.total_noise ** 2 + (s.static_noise ** 2 if s.pitot == "absolute" else 0.0)
        if not bias_state:
            var_qc = var_qc + self.state_sigma["pitot_bias"][0] ** 2
        return var_ps, var_qc

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        V = data.values["tas_mps"][:, j]
        u, e_b, e_a, sigma = self.axes_b(data, j)
        u_n = np.einsum("bij,bj->bi", nav.C_nb, u)            # the airspeed's direction, NED
        air_n = u_n * V[:, None]
        z = nav.vel_n_mps - air_n - self.wind_n_mps
        H = np.zeros((B, 3, layout.n))
        s = layout.slice("vel").start
        H[:, [0, 1, 2], [s, s + 1, s + 2]] = 1.0
        H[:, :, layout.slice("att")] = -skew(air_n)
        bias_state = layout.has("pitot_bias")
        sv, dv_dqc = self.airspeed_sigma(data, j, bias_state)
        if bias_state:                   # V = V_true + b / (rho V): z = ... - C_nb u b / (rho V)
            H[:, :, layout.slice("pitot_bias").start] = -u_n * dv_dqc[:, None]
        white = np.full(3, self.turbulence_sigma_mps ** 2)   # the gusts no state carries
        for block, axes in AIR_MASS_AXES.items():    # the wind and gusts the filter estimates
            if layout.has(block):
                cols = layout.slice(block)
                H[:, list(axes), list(range(cols.start, cols.stop))] = 1.0
                if block in GUST_AXES:
                    white[list(axes)] = 0.0
        s_across = V * sigma
        R_b = (sv[:, None, None] ** 2 * np.einsum("bi,bj->bij", u, u)
               + s_across[:, None, None] ** 2 * (np.einsum("bi,bj->bij", e_b, e_b) + np.einsum("bi,bj->bij", e_a, e_a)))
        R = nav.C_nb @ R_b @ np.swapaxes(nav.C_nb, 1, 2) + np.diag(white)
        return Linearised(z, H, R, data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        """The compiled form (:func:`~navsim.navigation.estimators.compiled_models.air_velocity`)."""
        s, bias_state = self.spec, layout.has("pitot_bias")
        var_ps, var_qc = self.pressure_variances(bias_state)
        vanes = s.velocity_axis == "air"
        white = np.full(3, self.turbulence_sigma_mps ** 2)
        cols = [layout.slice("vel").start, layout.slice("att").start,
                layout.slice("pitot_bias").start if bias_state else -1] + [-1] * 6
        for k, group in enumerate((WIND_AXES, GUST_AXES)):
            for block, axes in group.items():
                if layout.has(block):
                    for a, col in zip(axes, range(layout.slice(block).start, layout.slice(block).stop)):
                        cols[3 + 3 * k + a] = col
                        white[a] = 0.0 if group is GUST_AXES else white[a]
        values = {"vanes": float(vanes), "angle_sigma": s.vane_noise if vanes else self.angle_sigma_rad,
                  "var_ps": var_ps, "var_qc": var_qc,
                  "temperature_noise": s.temperature_noise, "r_air": atmosphere.R_AIR,
                  **dict(zip(("wind_n", "wind_e", "wind_d"), np.asarray(self.wind_n_mps, float))),
                  **dict(zip(("white_n", "white_e", "white_d"), white))}
        keys = _air_values(vanes)

        def inputs(nav, data, j):
            inp = np.zeros((nav.lat_rad.shape[0], 5))
            inp[:, :len(keys)] = _columns(data, j, keys)
            return inp, _valid(data, j)
        return _compiled(compiled_models.air_velocity, 3, [values[k] for k in compiled_models.AIR_PARAMS], cols, inputs)


def _air_values(vanes: bool) -> tuple:
    """The ADS values the air-velocity model reads: airspeed, static pressure, temperature, and
    the vanes' angles where it has vanes."""
    return ("tas_mps", "p_static_pa", "temp_k") + (("alpha_rad", "beta_rad") if vanes else ())


def check_observed_states(node: Node, blocks, entries: list) -> None:
    """A ``pitot_bias`` state needs the one ``air_velocity`` model that observes it, with an
    ADS model whose bias is not zero (its initial std); a wind state an ``air_velocity`` model
    (nothing else observes the wind or the gusts)."""
    air = [e for e in entries if e["type"] == "air_velocity"]
    wind = [b for b in AIR_MASS_AXES if b in blocks]
    if wind and not air:
        raise node.error(f"the '{wind[0]}' state is observed by no measurement", "states",
                         expected="an air_velocity measurement with a wind or gust state (or no such state)")
    if wind and len({tuple(e["wind_n_mps"]) for e in air}) > 1:
        raise node.error("the air_velocity measurements give different wind_n_mps", "measurements",
                         expected="one wind prior for the one wind state they observe")
    if "pitot_bias" not in blocks:
        return
    if len(air) != 1:
        raise node.error(f"the 'pitot_bias' state is observed by {len(air)} air_velocity measurements", "states",
                         expected="exactly one air_velocity measurement with a pitot_bias state")
    if not AirVelocity.from_entry(air[0]).state_sigma["pitot_bias"][0] > 0:
        raise node.error(f"the ADS model '{air[0]['model']}' has no pitot bias for the 'pitot_bias' state", "states",
                         expected="an ADS model with total_bias_sigma > 0, or no pitot_bias state")


def reject_rotating_R(node: Node, entries: list, adapted, who: str) -> None:
    """An adaptive filter that estimates R in NED from the innovations cannot adapt
    ``air_velocity``'s, which turns with the attitude and grows with the airspeed."""
    for e in entries:
        if e["type"] == "air_velocity" and (adapted is None or e["sensor"] in adapted):
            raise node.error(f"{who} adapts the R of sensor '{e['sensor']}' in NED; air_velocity's R turns with "
                             "the attitude and the airspeed", "measurements",
                             expected="air_velocity on a sensor that is not adapted (or another filter)")


def _ads_spec(name: str, override, node: Node | None = None):
    """The filter's ADS model, catalog entry ``name`` with ``override``."""
    spec = load_spec(name, override, (), node.file if node else None, node.path if node else "")
    if not isinstance(spec, AdsSpec):
        if node is None:
            raise ValueError(f"'{name}' is not an ADS")
        raise node.error(f"'{name}' is not an ADS", "model", expected="an ads catalog entry")
    return spec


@measurement("gnss_horizontal")
@dataclass
class GnssHorizontal:
    """INS minus GNSS horizontal position, NED metres: ``[dL (R_M+h), dlambda (R_N+h) cos L]``
    (the height is left to a separate height channel, as in P2)."""

    sensor: str
    sigma_m: np.ndarray                  #: (2,) north, east
    SCHEMA = {"sigma_m": VEC3}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        return {"sigma_m": node.vector("sigma_m")[:2]}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], np.array(entry["sigma_m"]))

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return POSITION_VALUES

    def model(self, nav: NavState, layout: Layout, data, j: int):
        full = GnssPosition(self.sensor, np.r_[self.sigma_m, 1.0]).model(nav, layout, data, j)
        return Linearised(full.z[:, :2], full.H[:, :2], full.R[:, :2, :2], full.valid)

    def compiled(self, layout: Layout) -> CompiledModel:
        return _position_fix(np.asarray(self.sigma_m, float)[:2] ** 2, layout)


@measurement("landmark")
@dataclass
class LandmarkFix:
    """INS minus the aircraft position the landmark camera fixes from a recognised anchor point
    (P1, GNSS-denied), NED metres: the GNSS position model on the camera's fix, with the
    filter's own noise model, std ``sigma_m + ratio * range`` per axis, the range taken from the
    INS position to the anchor the camera reports (``values['landmark']``; the anchors'
    coordinates are known on board, ``meta['landmarks']``: that is the method)."""

    sensor: str
    sigma_m: float
    ratio: float = 0.0
    SCHEMA = {"sigma_m": VEC3, "ratio": {"type": "number", "minimum": 0}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        sensor_of_kind(node, sensors, "camera")
        return {"sigma_m": node.get("sigma_m", float, exclusive_minimum=0.0),
                "ratio": node.get("ratio", float, 0.0, minimum=0.0)}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], entry["sigma_m"], entry["ratio"])

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return POSITION_VALUES + ("landmark",)

    def model(self, nav: NavState, layout: Layout, data, j: int):
        fix = GnssPosition(self.sensor, np.ones(3)).model(nav, layout, data, j)
        idx = data.values["landmark"][:, j]
        anchors = np.asarray(data.meta.get("landmarks") or [(0.0, 0.0, 0.0)], float)
        a = anchors[np.clip(idx, 0, len(anchors) - 1)]
        r_m, r_n = earth.radii(nav.lat_rad)
        d = np.stack([(np.radians(a[:, 0]) - nav.lat_rad) * (r_m + nav.h_m),
                      (np.radians(a[:, 1]) - nav.lon_rad) * (r_n + nav.h_m) * np.cos(nav.lat_rad),
                      nav.h_m - a[:, 2]], -1)
        sigma = self.sigma_m + self.ratio * np.linalg.norm(d, axis=-1)
        R = sigma[:, None, None] ** 2 * np.eye(3)
        return Linearised(fix.z, fix.H, R, fix.valid & (idx >= 0))

    def compiled(self, layout: Layout) -> CompiledModel:
        def inputs(nav, data, j):
            idx = data.values["landmark"][:, j]
            anchors = np.asarray(data.meta.get("landmarks") or [(0.0, 0.0, 0.0)], float)
            fix = _columns(data, j, POSITION_VALUES)
            return np.concatenate([fix, anchors[np.clip(idx, 0, len(anchors) - 1)]], 1), _valid(data, j) & (idx >= 0)
        return _compiled(compiled_models.landmark_fix, 3, [self.sigma_m, self.ratio, 1.0, 1.0, 1.0],
                         [layout.slice("pos").start], inputs)


@measurement("mag_heading")
@dataclass
class MagneticHeading:
    """INS minus magnetic heading, rad, from the magnetometer calibrated online (P1).

    Every call feeds the magnetometer samples since the last one to a recursive least-squares
    ellipsoid fit (:class:`navsim.navigation.magcal.EllipsoidRLS`, its noise model ``noise_T`` the
    filter's own) and calibrates the current sample, ``m_c = S^-1 (m - b)``. Rotated to NED
    with the INS attitude, ``v = C_nb m_c``, its declination ``atan2(v_E, v_N)`` minus the
    declination of the filter's own field model (WMM at the INS position) is the measurement:
    identical to the tilt-compensated magnetic heading (the field levelled with the INS roll
    and pitch, plus the model declination) subtracted from the INS yaw. With
    ``C_nb_est = (I - [phi x]) C_nb``, ``v = m_n + [m_n x] phi`` and::

        z = (m_N m_D phi_N + m_E m_D phi_E) / H^2 - phi_D,   H^2 = m_N^2 + m_E^2

    (roll and pitch errors enter through the inclination, as in the tilt compensation). The
    measurement is used once the INS heading has turned ``min_turns`` full turns since the
    start (the calibration manoeuvre) and the fit is an ellipsoid.

    ``calibration: none`` takes the samples as calibrated already (a replayed autopilot's
    magnetometer) and uses them from the first epoch; ``field_uT`` (N, E, D) replaces the WMM as
    the filter's model of the Earth field (a field measured on the ground; ``navsim replay``
    gives the one of its coarse alignment).
    """

    sensor: str
    sigma_rad: float
    noise_T: float                       #: the filter's model of the magnetometer noise, per axis
    forgetting: float = 1.0
    min_turns: float = 2.0
    field_n_T: np.ndarray | None = None  #: (3,) the filter's Earth field, NED; None: the WMM
    online: bool = True                  #: calibrate online; False: the samples are calibrated
    _fit: object = dataclasses.field(default=None, init=False, repr=False)     #: the RLS fit, from the first call

    SCHEMA = {"sigma_deg": POS, "noise_uT": {"type": "number", "minimum": 0},
              "forgetting": {"type": "number", "exclusiveMinimum": 0, "maximum": 1},
              "min_turns": {"type": "number", "minimum": 0}, "calibration": {"enum": ["online", "none"]},
              "field_uT": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The heading's ``sigma_deg``, the filter's model of the magnetometer noise ``noise_uT``
        (per axis, for the online fit), the calibration (``online`` or ``none``), its
        ``forgetting`` and ``min_turns``, and the Earth field ``field_uT`` (None: the WMM)."""
        sensor_of_kind(node, sensors, "magnetometer")
        field = node.vector("field_uT", None, minimum=-math.inf) if node.data.get("field_uT") is not None else None
        calibration = node.get("calibration", str, "online", choices=["online", "none"])
        noise = (node.get("noise_uT", float, minimum=0.0) if calibration == "online"     # the fit's noise model
                 else node.get("noise_uT", float, 0.0, minimum=0.0))
        return {"sigma_deg": node.get("sigma_deg", float, exclusive_minimum=0.0), "noise_uT": noise,
                "calibration": calibration,
                "forgetting": node.get("forgetting", float, 1.0, exclusive_minimum=0.0, maximum=1.0),
                "min_turns": node.get("min_turns", float, 2.0, minimum=0.0), "field_uT": field}

    @classmethod
    def from_entry(cls, entry: dict):
        field = entry.get("field_uT")
        return cls(entry["sensor"], np.radians(entry["sigma_deg"]), entry["noise_uT"] * 1e-6,
                   forgetting=entry["forgetting"], min_turns=entry["min_turns"],
                   field_n_T=None if field is None else np.asarray(field, float) * 1e-6,
                   online=entry.get("calibration", "online") == "online")

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        return ("mag_b_T",)

    def _field_n_T(self, nav: NavState, date: str, grid: bool = True) -> np.ndarray:
        """The filter's Earth field at the INS position ``(B, 3)``."""
        if self.field_n_T is not None:
            return np.broadcast_to(self.field_n_T, (nav.lat_rad.shape[0], 3))
        return magcal.field_model_n_T(nav.lat_rad, nav.lon_rad, nav.h_m, date, grid=grid)

    def _calibrated(self, nav: NavState, data, j: int, date: str):
        """Sample ``j`` calibrated, and the runs whose calibration may be used."""
        B = nav.lat_rad.shape[0]
        mag = data.values["mag_b_T"]
        if not self.online:
            return mag[:, j], np.ones(B, bool)
        yaw = np.arctan2(nav.C_nb[:, 1, 0], nav.C_nb[:, 0, 0])
        if self._fit is None:
            field = self._field_n_T(nav, date, grid=False)
            self._fit = magcal.EllipsoidRLS(np.linalg.norm(field, axis=-1), self.noise_T, self.forgetting)
            self._fed, self._turns, self._yaw = 0, np.zeros(B), yaw
        self._fit.update(mag[:, self._fed:j + 1], data.valid[:, self._fed:j + 1])
        self._fed = j + 1
        self._turns += np.abs((yaw - self._yaw + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi)
        self._yaw = yaw
        hard, soft, ok = self._fit.estimate()
        return magcal.calibrate(mag[:, j], hard, soft), ok & (self._turns >= self.min_turns)

    def _sample(self, nav: NavState, data, j: int) -> tuple:
        """Sample ``j`` calibrated ``(B, 3)`` (body, T), the filter's Earth field ``(B, 3)``
        (NED, T) and the runs whose calibration is usable ``(B,)``."""
        date = data.meta.get("date", WMM_DATE)
        m_b, ok = self._calibrated(nav, data, j, date)
        return m_b, self._field_n_T(nav, date), ok

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        m_b, field_n, ok = self._sample(nav, data, j)
        z, h_att = magnetic_heading(nav.C_nb, m_b, field_n)
        valid = data.valid[:, j] & ok & np.isfinite(z)
        H = np.zeros((B, 1, layout.n))
        H[:, 0, layout.slice("att")] = h_att
        return Linearised(np.where(valid, z, 0.0)[:, None], H, np.full((B, 1, 1), float(self.sigma_rad) ** 2), valid)

    def compiled(self, layout: Layout) -> CompiledModel:
        """The heading's geometry compiled; the online calibration stays in Python (its fit is
        fed the samples since the last call)."""
        def inputs(nav, data, j):
            m_b, field_n, ok = self._sample(nav, data, j)
            return np.concatenate([m_b, field_n], 1), data.valid[:, j] & ok
        return _compiled(compiled_models.magnetic_heading, 1, [float(self.sigma_rad) ** 2],
                         [layout.slice("att").start], inputs)


def magnetic_heading(C_nb: np.ndarray, mag_cal_b: np.ndarray, field_n: np.ndarray):
    """INS minus magnetic heading ``z`` ``(B,)``, rad, and its row ``(B, 3)`` in the attitude
    error ``phi`` (NED): the declination of ``C_nb mag_cal_b`` minus that of ``field_n`` (see
    :class:`MagneticHeading`)."""
    v = np.einsum("bij,bj->bi", C_nb, mag_cal_b)
    z = (np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(field_n[:, 1], field_n[:, 0]) + np.pi) % (2 * np.pi) - np.pi
    h2 = field_n[:, 0] ** 2 + field_n[:, 1] ** 2
    H = np.stack([field_n[:, 0] * field_n[:, 2] / h2, field_n[:, 1] * field_n[:, 2] / h2,
                  -np.ones_like(h2)], -1)
    return z, H

