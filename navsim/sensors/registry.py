"""The sensor kinds, registered by name: everything navsim knows of a kind, declared once.

A sensor kind is one :class:`SensorKind` object, built and passed to :func:`register` by the
module that emulates it (``navsim/sensors/imu.py``, ``gnss.py``, ``airdata.py`` (``baro`` and
``ads``), ``radar.py``, ``magnetometer.py``, ``camera.py``). It names

* the kind (a catalog entry's ``kind:``) and its spec dataclass (the truth model, SI);
* the catalog's field table: each datasheet key, the spec attribute it fills, its unit dimension
  (:mod:`navsim.sensors.units`) and shape (:class:`Field`);
* its outputs (``SensorData.values`` keys) with their units, which of them a ``height`` or a
  ``velocity`` measurement may read (``role``) and which truth field each one measures
  (:class:`Output`);
* its error terms, each a named source a scenario's ``off:`` switches off (:class:`ErrorTerm`);
* the fault windows it can have (:data:`FAULT_TYPES`);
* its emulator and, where the default (each output with a ``truth`` against that truth field)
  does not do, its plot channels;
* whether and how it flies in the closed loop (:class:`InLoop`: each sample filled from the
  runs' true state as they fly, and the configurations refused).

The catalog (:mod:`navsim.sensors.catalog`), :func:`navsim.sensors.emulate`, the fault checks
(:func:`navsim.sensors.base.check_faults`), the scenario's field checks and ``navsim sensors``'
plots all read the registry; there is no other table of sensor kinds. Every module of the
package is imported by ``navsim/sensors/__init__.py``, so a new built-in kind is one new module
(and its catalog datasheets); a user's module registers its own kind the same way, and a
package registers one through the ``navsim.sensors`` entry-point group (``name =
"package.module:KIND"``, the object a :class:`SensorKind` named ``name``). ``docs/sensors.md``
is the worked example.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from navsim.foundations.config import plain_name
from navsim.foundations.registry import Registry

ENTRY_POINT_GROUP = "navsim.sensors"
#: the fault windows a scenario may give a sensor (:class:`navsim.sensors.base.Fault`); each kind
#: names those it can have
FAULT_TYPES = ("outage", "bias", "degraded", "interference", "disturbance")
#: the shapes of a catalog field (see :class:`Field`)
SHAPES = ("1", "3", "h", "v", "33", "plain", "str", "bool", "pair", "landmarks", "group", "list")
#: what an output may be read as by a measurement (``height``, ``velocity``), besides by name
ROLES = ("height", "velocity")
#: what a kind is to the navigation (:attr:`SensorKind.role`): the ``inertial`` one drives the
#: strapdown (the scenario's IMU), the others aid it
KIND_ROLES = ("inertial", "position_fix", "landmark_fix", "altimeter", "air_data", "heading")
#: the role of the sensor that drives the strapdown (a scenario with estimators has one)
INERTIAL = "inertial"

_ENTRY_POINTS_READ: list[bool] = []          #: non-empty once the entry points were read


class Group(NamedTuple):
    """A nested datasheet mapping (``shape`` ``group``) or list of them (``list``): its field
    table and the dataclass it is read into."""

    table: dict
    cls: type


class Field(NamedTuple):
    """One datasheet key of a catalog entry.

    ``attr`` the spec attribute it fills; ``dim`` the unit dimension of its value
    (:mod:`navsim.sensors.units`; None for unit-less shapes), a :class:`Group` for ``group`` and
    ``list``, or the allowed strings for ``str``; ``shape``: ``1`` one value, ``3`` three axes (a
    scalar broadcast), ``h`` / ``v`` the horizontal / vertical part of a NED triple, ``33`` a
    dimensionless 3x3 matrix, ``plain`` a positive unit-less number (a rate, Hz), ``str``,
    ``bool``, ``pair`` ``[low, high]`` Hz, ``landmarks`` ``[lat_deg, lon_deg, h_m]`` points;
    ``signed``: a negative value is allowed (else refused)."""

    attr: str
    dim: object = None
    shape: str = "1"
    signed: bool = False


@dataclass(frozen=True)
class Output:
    """One ``SensorData.values`` key of a kind.

    ``unit`` its SI unit; ``role`` ``height`` or ``velocity`` if a measurement of that type may
    read it (``field:``); ``when(spec)`` true when the spec makes the emulator produce it (None:
    always); ``truth`` the :class:`~navsim.flight.truth.Truth` field it measures (the default
    plot draws the output against it), ``label`` the plot's name of it, ``axes`` the names of
    its components (a vector output)."""

    name: str
    unit: str
    role: str | None = None
    when: Callable | None = None
    truth: str | None = None
    label: str | None = None
    axes: tuple[str, ...] = ()


#: the quantities a :class:`LinearError` adds its error to: the IMU's body rate and specific
#: force (they drive the strapdown error dynamics), a position (NED, m) and a velocity (NED, m/s)
#: fix (they enter the measurements that read them)
LINEAR_QUANTITIES = ("rate_b", "force_b", "pos_n", "vel_n")


class Motion(NamedTuple):
    """The true motion over one step of a covariance analysis, what a time-varying
    :class:`LinearError` coupling reads (a scale factor multiplies the true rate)."""

    omega_ib_b_rps: np.ndarray      #: (3,) body rate, rad/s
    f_b_mps2: np.ndarray            #: (3,) specific force, body, m/s^2


@dataclass(frozen=True)
class LinearError:
    """The linear form of one error term, for covariance analysis (``navsim budget --method
    covariance``): the error it adds to ``quantity`` (one of :data:`LINEAR_QUANTITIES`),

        e(t) = C(t) s(t) + w(t),      s' = -s / tau + q^(1/2) n(t),

    with ``n`` states ``s`` whose second moment at the start is ``P0`` ``(n, n)`` (a random
    constant: its variance; a fixed error: its outer product, a mean being a second moment
    too), ``tau_s`` ``(n,)`` their correlation times (``inf``: a constant or a random walk),
    ``q`` ``(n,)`` their driving noise's density squared (per s), ``C = coupling(Motion)``
    ``(3, n)`` (None: the identity) and ``w`` white noise of ``white`` ``(3,)``: the density
    squared (unit^2 s) for the IMU's quantities, the variance of one sample for a fix's."""

    quantity: str
    P0: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    tau_s: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    q: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    coupling: Callable | None = None
    white: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))

    @property
    def n(self) -> int:
        """The number of states."""
        return int(np.shape(self.P0)[0])


@dataclass(frozen=True)
class ErrorTerm:
    """One error source of a kind: the dotted path of the spec attribute that sets it (its name,
    as ``off:`` lists it), the value that switches it off (None: the zero of its type, the
    identity for a 3x3 matrix, no entries for a tuple) and its linear form ``linear(spec) ->``
    :class:`LinearError` (None: it has none, a covariance analysis leaves it to Monte Carlo:
    quantization, saturation, vibration, faults)."""

    name: str
    off: object = None
    linear: Callable | None = None


class LoopSample(NamedTuple):
    """The runs' true state at one step of the closed loop: what an in-loop sensor measures
    (arrays over the runs ``B``: views of the loop's buffer, valid during the ``fill`` call
    only; a sensor that keeps one copies it)."""

    lat_rad: np.ndarray          #: (B,) geodetic latitude
    lon_rad: np.ndarray          #: (B,)
    h_m: np.ndarray              #: (B,) height above the ellipsoid
    vel_n_mps: np.ndarray        #: (B, 3) velocity, north-east-down
    euler_rad: np.ndarray        #: (B, 3) roll, pitch, yaw
    p_static_pa: np.ndarray      #: (B,) static pressure
    p_total_pa: np.ndarray       #: (B,) total (pitot) pressure
    temp_k: np.ndarray           #: (B,) static air temperature
    alpha_rad: np.ndarray        #: (B,) angle of attack
    beta_rad: np.ndarray         #: (B,) sideslip


class Refusal(NamedTuple):
    """Why a sensor's configuration cannot fly in the closed loop: ``what`` it has (its errors
    depend on the trajectory), ``expected`` what would fly, ``hint`` the override that does."""

    what: str
    expected: str
    hint: str


@dataclass(frozen=True)
class InLoop:
    """How a kind is emulated inside the closed loop (:mod:`navsim.experiment.closed_loop`).
    Its errors are drawn as in open loop by the kind's ``emulate``, on a static record (so they
    must not depend on the trajectory), and added to the runs' true state as it is flown:
    ``fill(data, j, sample)`` writes sample ``j`` of every output of ``data`` (a
    :class:`~navsim.sensors.base.SensorData`) from the :class:`LoopSample` ``sample`` plus
    ``data.errors``; ``refuse(config) -> Refusal | None`` names a configuration (a
    :class:`~navsim.sensors.base.SensorConfig`) whose errors do depend on the trajectory;
    ``prepare(data, static)``, where the outputs are not the truth plus ``errors`` (an ADS
    computes them from its sensors), keeps what ``fill`` adds, from the static record
    ``static`` they were emulated on."""

    fill: Callable
    refuse: Callable | None = None
    prepare: Callable | None = None


@dataclass(frozen=True)
class SensorKind:
    """Everything navsim knows of one sensor kind (see the module docstring).

    ``emulate(truth, spec, seed, runs, faults=(), name=...) -> SensorData``;
    ``channels(data, truth, run) -> [(label, unit, t, measured, true), ...]`` (None: each output
    with a ``truth`` against it); ``vector_bias``: a ``bias`` fault is a NED vector (``value_m:
    [n, e, d]``); ``in_loop``: how it flies in the closed loop (:class:`InLoop`; None: it cannot);
    ``role``: what it is to the navigation, one of :data:`KIND_ROLES` (None: not declared; the
    experiment asks the role, never the name, for the scenario's inertial sensor)."""

    name: str
    spec: type
    fields: dict
    outputs: tuple[Output, ...]
    errors: tuple[ErrorTerm, ...]
    emulate: Callable
    faults: tuple[str, ...] = ("outage",)
    channels: Callable | None = None
    vector_bias: bool = False
    description: str = ""
    in_loop: InLoop | None = None
    role: str | None = None

    def output_fields(self, spec) -> tuple[str, ...]:
        """The ``values`` keys the emulator produces for ``spec``, in declared order."""
        return tuple(o.name for o in self.outputs if o.when is None or o.when(spec))

    def output(self, name: str) -> Output:
        """The declared output ``name``."""
        return next(o for o in self.outputs if o.name == name)

    def error_names(self) -> list[str]:
        """The names of the kind's error sources (what ``off:`` may list)."""
        return [e.name for e in self.errors]

    def disable(self, spec, names):
        """A copy of ``spec`` with the error sources ``names`` switched off."""
        terms = {e.name: e for e in self.errors}
        for name in names:
            spec = _set_off(spec, name.split("."), terms[name].off)
        return spec

    def ideal(self, spec):
        """``spec`` with every error source off: the sensor reproduces the truth."""
        return self.disable(spec, self.error_names())


def _set_off(spec, path: list, off):
    """``spec`` with the attribute at ``path`` set to ``off`` (None: its type's zero)."""
    head = path[0]
    current = getattr(spec, head)
    if len(path) > 1:
        return dataclasses.replace(spec, **{head: _set_off(current, path[1:], off)})
    return dataclasses.replace(spec, **{head: _zero_of(current) if off is None else off})


def _zero_of(current):
    """The value that switches off an error source now at ``current``."""
    if isinstance(current, tuple):
        return ()
    if isinstance(current, np.ndarray):
        return np.eye(3) if current.shape == (3, 3) else np.zeros_like(current)
    if isinstance(current, float) and math.isinf(current):
        return math.inf
    return 0.0


def _checked(name: str, kind: SensorKind) -> SensorKind:
    """``kind`` registered as ``name``: a :class:`SensorKind` of that name whose declaration is
    sound (:func:`_problems`)."""
    if not isinstance(kind, SensorKind) or kind.name != name:
        raise TypeError(f"it is not a SensorKind named '{name}'")
    problems = _problems(kind)
    if problems:
        raise TypeError(f"sensor kind '{kind.name}': " + "; ".join(problems))
    return kind


class _Kinds(Registry[SensorKind]):
    """The sensor kinds' registry: the ``navsim.sensors`` entry points are read once per
    process (the kinds are looked up at every emulation)."""

    def _read_entry_points(self) -> None:
        if _ENTRY_POINTS_READ:
            return
        _ENTRY_POINTS_READ.append(True)
        super()._read_entry_points()


#: the sensor kinds by name: the built-in ones, a user's module's and the entry points'
KINDS: Registry[SensorKind] = _Kinds("sensor kind", ENTRY_POINT_GROUP, _checked)
#: what is registered now
_REGISTRY = KINDS.built()


def register(kind: SensorKind, replace: bool = False) -> SensorKind:
    """Make ``kind`` known by its name (its declaration checked: a plain name, a spec
    dataclass whose attributes its fields, outputs' roles, error terms and faults name).
    Returns ``kind``. ``replace``: a kind of that name may be registered again (a reloaded
    module)."""
    earlier = _REGISTRY.get(kind.name)
    if earlier is not None and not replace and earlier is not kind:
        _checked(kind.name, kind)
        raise TypeError(f"sensor kind '{kind.name}' is registered already (by {earlier.emulate.__module__})")
    return KINDS.register(kind.name, kind)


#: forget the kind ``name`` (a test's toy kind)
unregister = KINDS.unregister


def _problems(kind: SensorKind) -> list[str]:
    """What is wrong with a kind's declaration (empty: nothing)."""
    out = []
    if not (isinstance(kind.name, str) and plain_name(kind.name)):
        out.append("its name is not a plain name")
    if not dataclasses.is_dataclass(kind.spec):
        return out + [f"its spec {kind.spec!r} is not a dataclass"]
    attrs = {f.name for f in dataclasses.fields(kind.spec)}
    out += [f"field '{k}' fills '{f.attr}', not an attribute of {kind.spec.__name__}"
            for k, f in kind.fields.items() if f.attr not in attrs]
    out += [f"field '{k}' has the shape '{f.shape}'" for k, f in kind.fields.items() if f.shape not in SHAPES]
    out += [f"error term '{e.name}' is not an attribute of {kind.spec.__name__}"
            for e in kind.errors if e.name.split(".")[0] not in attrs]
    out += [f"output '{o.name}' has the role '{o.role}'" for o in kind.outputs if o.role not in (None, *ROLES)]
    if kind.role not in (None, *KIND_ROLES):
        out.append(f"its role '{kind.role}' is not one of {', '.join(KIND_ROLES)}")
    out += [f"fault '{f}' is not one of {', '.join(FAULT_TYPES)}" for f in kind.faults if f not in FAULT_TYPES]
    if "rate_hz" not in attrs:
        out.append(f"{kind.spec.__name__} has no rate_hz")
    if not callable(kind.emulate):
        out.append("its emulator is not callable")
    return out


#: whether ``name`` is a registered kind; the entry points are read once, for the first name
#: not registered
known = KINDS.known
#: the kind registered as ``name`` (built-in, a user's module's, or an entry point's); a
#: :class:`KeyError` naming the closest one
get = KINDS.get


def available() -> list[str]:
    """The registered kinds' names, sorted."""
    return KINDS.names()


def kinds() -> list[SensorKind]:
    """The registered kinds."""
    return KINDS.values()


def kind_of(spec) -> str:
    """The name of the kind whose spec ``spec`` is."""
    for kind in kinds():
        if isinstance(spec, kind.spec):
            return kind.name
    raise TypeError(type(spec))


def of(spec) -> SensorKind:
    """The kind whose spec ``spec`` is."""
    return get(kind_of(spec))


def fields_of_role(role: str) -> tuple[str, ...]:
    """Every registered kind's outputs of ``role`` (``height``, ``velocity``), each once."""
    return tuple(dict.fromkeys(o.name for k in kinds() for o in k.outputs if o.role == role))


def default_output(kind: str, role: str) -> str | None:
    """The first output of ``role`` kind ``kind`` declares (what a measurement of that type reads
    without a ``field``), None without one."""
    return next((o.name for o in get(kind).outputs if o.role == role), None)


class View(Mapping):
    """A read-only mapping kind name -> ``pick(kind)`` over the registered kinds, always current
    (``OUTPUTS``, ``ERROR_FIELDS``: the registry seen as the tables it replaced)."""

    def __init__(self, pick: Callable):
        self._pick = pick

    def __getitem__(self, name):
        if name not in _REGISTRY:
            raise KeyError(name)
        return self._pick(_REGISTRY[name])

    def __iter__(self):
        return iter(available())

    def __len__(self):
        return len(available())
