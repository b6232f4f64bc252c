"""An error budget's sources and the scenarios that run each one alone.

A scenario's error sources are every error term its sensors' truth models apply (the terms each
sensor kind declares, :attr:`navsim.sensors.registry.SensorKind.errors`, that are not already
off), each fault window of a sensor, and each block of the initial errors (attitude, velocity,
position) that is not zero. :func:`alone` is the scenario with one source on and every other
off, in the truth only: the estimators, their noise models and initial covariances are the
scenario's own, and the seeds are the same, so a source's realisation is the one it has with
all on (the initial errors draw every block and zero the others; a sensor's random stream is
its own, by its name).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations.errors import UsageError
from navsim.experiment.driver import DRAWN_FIELDS
from navsim.navigation.covariance import CovarianceAnalysis, SourceModel
from navsim.navigation.estimators import factory
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.sins import FreeInertial
from navsim.sensors import emulate, registry
from navsim.sensors.registry import INERTIAL

#: the initial errors' blocks as sources, and the label of their group
INITIAL = "initial"
#: the groupings ``--group`` offers: each source alone, per sensor, per sensor and kind of term
GROUPS = ("source", "sensor", "kind")
#: the magnitude a source switched off for a budget keeps (times its unit; its square is still a
#: normal double, as a white noise density needs): every random number
#: it draws is still drawn, so the other sources' streams are where they are with it on, and its
#: effect is below any double's resolution beside the truth (an emulator that draws only for a
#: non-zero term would otherwise hand the next term the stream this one had)
HELD = 1e-150
#: terms that are not held but switched off: they draw nothing, and a held value would be wrong
#: (a quantization step divides, a range bounds)
NOT_HELD = ("quantization", "range")
#: the largest factor a what-if (``--scale SOURCE=K``) scales a source by: a budget's prediction
#: is linear in the squared errors, which a thousandfold source leaves far behind, and factors
#: much larger overflow them (1e200 squared is no double: NaN predictions)
MAX_SCALE = 1000.0
#: the factors a what-if takes, as messages and the help say them
SCALE_RANGE = f"a factor K >= 0, at most {MAX_SCALE:g}"


def scale_ok(factor: float) -> bool:
    """Whether ``factor`` is one a what-if takes: finite, 0 to :data:`MAX_SCALE`."""
    return math.isfinite(factor) and 0.0 <= factor <= MAX_SCALE


@dataclass(frozen=True)
class Source:
    """One error source: its name (``imu.gyro.bias_instability``, ``gnss.fault[0]``,
    ``initial.att``), the sensor it belongs to (``initial`` for the initial errors), the error
    term or fault it is, and the kind group it reports under (``imu gyro``)."""

    name: str
    sensor: str
    term: str
    group: str

    def group_of(self, how: str) -> str:
        """The name it is summed under for ``how`` (one of :data:`GROUPS`)."""
        return {"source": self.name, "sensor": self.sensor, "kind": self.group}[how]


def _value(spec, path: str):
    node = spec
    for part in path.split("."):
        node = getattr(node, part)
    return node


def _on(spec, kind, term) -> bool:
    """Whether the error term is on in ``spec`` (its value is not the one that switches it off)."""
    off = kind.disable(spec, [term.name])
    now, then = _value(spec, term.name), _value(off, term.name)
    if isinstance(now, tuple):
        return len(now) > 0
    return not np.array_equal(np.asarray(now, float), np.asarray(then, float))


def error_sources(scenario) -> list[Source]:
    """Every error source of ``scenario`` that is on, sensors first (in their order, each
    kind's declared terms in order, then its faults), then the initial errors."""
    out = []
    for c in scenario.sensors:
        kind = registry.of(c.spec)
        for term in kind.errors:
            if _on(c.spec, kind, term):
                head = term.name.split(".")[0]
                group = f"{c.name} {head}" if "." in term.name else c.name
                out.append(Source(f"{c.name}.{term.name}", c.name, term.name, group))
        for i, f in enumerate(c.faults):
            out.append(Source(f"{c.name}.fault[{i}]", c.name, f"fault[{i}]", f"{c.name} faults ({f.type})"))
    init = scenario.initial
    if init is not None:
        for block, fld in DRAWN_FIELDS.items():
            if np.any(np.asarray(getattr(init, fld), float) != 0):
                out.append(Source(f"{INITIAL}.{block}", INITIAL, block, f"{INITIAL} errors"))
    return out


def held(spec, kind, term: str):
    """``spec`` with the error term ``term`` off for a budget: held at :data:`HELD` where it is
    a magnitude that switches off at 0 (its draws kept), else switched off."""
    off = kind.disable(spec, [term])
    now, then = _value(spec, term), _value(off, term)
    magnitude = isinstance(now, (float, int, np.ndarray)) and np.ndim(now) <= 1
    if term.split(".")[-1] in NOT_HELD or not magnitude or np.any(np.asarray(then, float) != 0):
        return off
    value = np.full(np.shape(now), HELD) if isinstance(now, np.ndarray) else HELD
    return _replace_at(spec, term.split("."), value)


def _replace_at(spec, path: list, value):
    head = path[0]
    if len(path) > 1:
        return dataclasses.replace(spec, **{head: _replace_at(getattr(spec, head), path[1:], value)})
    return dataclasses.replace(spec, **{head: value})


def budget_sources(scenario) -> list[Source]:
    """:func:`error_sources`, or a :class:`UsageError` when there is none to budget."""
    out = error_sources(scenario)
    if not out:
        raise UsageError(f"{scenario.name}: no error source is on (every sensor ideal, no fault, no initial "
                         "error): nothing to budget; hint: remove 'off: all' or give initial_errors")
    return out


def alone(scenario, source: Source | None, sources: list[Source]):
    """``scenario`` with only ``source`` on in the truth (None: every source off), every other
    of ``sources`` off (:func:`held`); its name suffixed with the source."""
    sensors = []
    for c in scenario.sensors:
        kind = registry.of(c.spec)
        spec = c.spec
        for s in sources:
            if s.sensor == c.name and not s.term.startswith("fault[") and (source is None or s.name != source.name):
                spec = held(spec, kind, s.term)
        faults = tuple(f for i, f in enumerate(c.faults)
                       if source is not None and source.name == f"{c.name}.fault[{i}]")
        sensors.append(dataclasses.replace(c, spec=spec, faults=faults))
    init = scenario.initial
    if init is not None:
        keep = (source.term,) if source is not None and source.sensor == INITIAL else ()
        init = dataclasses.replace(init, drawn=keep)
    suffix = "none" if source is None else source.name
    return dataclasses.replace(scenario, name=f"{scenario.name} [{suffix}]", sensors=tuple(sensors), initial=init)


def scaled(scenario, source: Source, factor: float):
    """``scenario`` with one source's magnitude times ``factor`` (a sensor's error term: its
    value; an initial error block: its sigma in the truth and in the filters' covariances alike,
    as a better alignment would give)."""
    if not scale_ok(factor):
        raise UsageError(f"--scale {source.name}={factor}: expected {SCALE_RANGE}")
    if source.sensor == INITIAL:
        fld = DRAWN_FIELDS[source.term]
        init = dataclasses.replace(scenario.initial, **{fld: np.asarray(getattr(scenario.initial, fld)) * factor})
        return dataclasses.replace(scenario, initial=init)
    if source.term.startswith("fault["):
        raise UsageError(f"--scale {source.name}: a fault has no magnitude to scale; hint: scale an error term")
    sensors = []
    for c in scenario.sensors:
        if c.name == source.sensor:
            c = dataclasses.replace(c, spec=_times(c.spec, source.term.split("."), factor))
        sensors.append(c)
    return dataclasses.replace(scenario, sensors=tuple(sensors))


def _times(spec, path: list, factor: float):
    head = path[0]
    current = getattr(spec, head)
    if len(path) > 1:
        return dataclasses.replace(spec, **{head: _times(current, path[1:], factor)})
    if isinstance(current, np.ndarray) and current.shape == (3, 3):     # a matrix about the identity
        return dataclasses.replace(spec, **{head: np.eye(3) + factor * (current - np.eye(3))})
    if isinstance(current, tuple):
        raise UsageError(f"--scale: '{head}' is a list of terms, not a magnitude")
    return dataclasses.replace(spec, **{head: np.asarray(current, float) * factor
                                        if isinstance(current, np.ndarray) else float(current) * factor})


def find_source(name: str, sources: list[Source]) -> Source:
    """The source called ``name``; :class:`UsageError` naming those there are."""
    for s in sources:
        if s.name == name:
            return s
    raise UsageError(f"no error source '{name}' in this scenario; its sources: " + ", ".join(s.name for s in sources))



# --- covariance analysis ----------------------------------------------------------------------------
#: the estimator types a covariance analysis takes: linear in the errors, their gains set by the
#: trajectory alone (an adaptive or federated filter's gains follow the data)
ANALYSABLE = (ErrorStateKF, FreeInertial)


def check_method(scenario, method: str, methods, sources: list[Source]) -> None:
    """:class:`UsageError` for a method not in ``methods``, or a covariance analysis that cannot
    be had: of a closed loop (its flight is not known before the runs), of sources none of which
    has a linear form, of estimators none of which it takes (:data:`ANALYSABLE`)."""
    if method not in methods:
        raise UsageError(f"--method {method!r}: expected one of {', '.join(methods)}")
    if method == "montecarlo":
        return
    if scenario.closed_loop is not None:
        raise UsageError(f"{scenario.name}: a closed loop flies on the filter's solution, so its flight is not known "
                         "before the runs: no covariance analysis; hint: --method montecarlo")
    if not any(s.sensor == INITIAL or _linear(scenario, s) is not None for s in sources):
        raise UsageError(f"{scenario.name}: none of its sources has a linear form (" + ", ".join(s.name for s in sources)
                         + "): no covariance analysis; hint: --method montecarlo")
    kinds = {c.label: c.type for c in scenario.estimators if type(factory.build(c)) not in ANALYSABLE}
    if len(kinds) == len(scenario.estimators):
        raise UsageError(f"{scenario.name}: no estimator a covariance analysis takes (" + ", ".join(
            f"{k}: {v}" for k, v in kinds.items()) + "; it takes eskf and sins); hint: --method montecarlo")


def _linear(scenario, s: Source):
    """The linear form of a sensor's source, None where it has none."""
    spec = next(c.spec for c in scenario.sensors if c.name == s.sensor)
    term = next((t for t in registry.of(spec).errors if t.name == s.term), None)
    return term.linear(spec) if term is not None and term.linear is not None else None


def linear_sources(scenario, sources: list[Source], truth) -> tuple[list[SourceModel], list[str]]:
    """The linear forms of ``sources`` (:class:`~navsim.navigation.covariance.SourceModel`),
    and the names of those that have none (faults, quantization, saturation, vibration, a
    latency, a lever arm: left to Monte Carlo)."""
    models, left = [], []
    for s in sources:
        if s.sensor == INITIAL:
            sig = np.asarray(scenario.initial.sigma_blocks(float(truth.lat_rad[0]), float(truth.h_m[0]))[s.term], float)
            P0 = np.zeros((9, 9))
            i = list(DRAWN_FIELDS).index(s.term)          # fixed errors: their outer product, a second moment
            P0[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.outer(sig, sig) if scenario.initial.fixed else np.diag(sig ** 2)
            models.append(SourceModel(s.name, P0_nav=P0))
            continue
        form = _linear(scenario, s)
        if form is None:
            left.append(s.name)
        else:
            models.append(SourceModel(s.name, s.sensor, form))
    return models, left


#: why a term (the last part of its name) has no linear form
NOT_LINEAR = {"quantization": "rounding to a step is not linear in the errors",
              "range": "clipping at the range (saturation) is not linear in the errors",
              "vibration": "a vibration's error is set by the motion's spectrum, not a linear error process",
              "latency_s": "a latency's error is set by the trajectory (the motion over the delay)",
              "lever_arm_b": "a lever arm's error is set by the trajectory (the attitude and body rate)"}
#: why a sensor kind none of whose terms has a linear form has none (the rest: said generically)
NOT_LINEAR_KINDS = {"ads": "its errors are its raw sensors' (static and total pressure in Pa, temperature in K, "
                           "vane angles); they reach its height (h_pressure_m, not a fix's h) and its velocity "
                           "(along the airspeed's direction: correlated across N, E, D and turning with the "
                           "attitude) through the air-data formulas, which a linear form (an error of the body rate, "
                           "the specific force or a NED fix, white per axis) does not express"}


def left_out_reasons(scenario, sources: list[Source], left: list[str]) -> dict[str, str]:
    """Each source of ``left`` (:func:`linear_sources`' names) -> why a covariance analysis
    leaves it to Monte Carlo, said in the budget's table."""
    out = {}
    for s in sources:
        if s.name not in left:
            continue
        config = next(c for c in scenario.sensors if c.name == s.sensor)
        kind = registry.of(config.spec)
        if s.term.startswith("fault["):
            why = f"a fault window ({config.faults[int(s.term[6:-1])].type}) switches its errors in time: not linear"
        elif s.term.split(".")[-1] in NOT_LINEAR:
            why = NOT_LINEAR[s.term.split(".")[-1]]
        elif not any(t.linear is not None for t in kind.errors):
            why = (f"the {kind.name} kind declares no linear form of its error terms"
                   + (f": {NOT_LINEAR_KINDS[kind.name]}" if kind.name in NOT_LINEAR_KINDS else ""))
        else:
            why = f"the {kind.name} kind declares no linear form of '{s.term}'"
        out[s.name] = why + "; Monte Carlo only (--method montecarlo or both)"
    return out


def _ideal(truth, config, seed: int):
    """The sensor without its errors and faults, one run: the samples each source alone has in
    the Monte Carlo budget (:func:`alone` flies every source but a fault without the faults)."""
    spec = registry.of(config.spec).ideal(config.spec)
    return emulate(truth, dataclasses.replace(config, spec=spec, faults=()), seed, [0])


def covariance_contributions(scenario, truth, models: list[SourceModel]) -> tuple[dict, dict]:
    """Each estimator's :class:`~navsim.navigation.covariance.Contributions` of ``models``
    (label -> it), and the estimators not analysed (label -> why)."""
    imu = next(c for c in scenario.sensors if c.role == INERTIAL)
    others = {c.name: _ideal(truth, c, scenario.seed) for c in scenario.sensors if c.role != INERTIAL}
    sigma_nav = scenario.initial.sigma_blocks(float(truth.lat_rad[0]), float(truth.h_m[0]))
    out, skipped = {}, {}
    for config in scenario.estimators:
        est = factory.build(config)
        if type(est) not in ANALYSABLE:
            skipped[config.label] = (f"a {config.type} filter's gains follow its data, not the trajectory alone: "
                                     "no covariance analysis (its budget needs --method montecarlo)")
            continue
        sigma0 = {**sigma_nav, **est.noise_sigma0()} if hasattr(est, "noise_sigma0") else sigma_nav
        out[config.label] = CovarianceAnalysis(truth, est, 1.0 / imu.spec.rate_hz, others, sigma0).run(models)
    return out, skipped

