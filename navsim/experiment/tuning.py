"""What ``navsim tune`` varies: :class:`TuneParam`, read from ``--param PATH=LO:HI[:log]``
(:func:`parse_param`) or, without one, each noise term of the estimator's entry scaled by its
own factor (:func:`default_params`).

A parameter is a path into the scenario in the grammar of ``--set``
(:mod:`navsim.foundations.overrides`), relative to the tuned estimator's entry
(``measurements[0].sigma_m``; ``estimators[LABEL].`` is put in front) or whole
(``estimators[LABEL]....``), the entry addressed by its index. Its trial value is set there as a ``--set`` would set it: a number
between ``LO`` and ``HI`` (on a log scale with ``:log``), or, for a scaled term
(``PATH=xLO:HI``, and each noise term without ``--param``: 1/10 to 10, log), the entry's own
value (a number or a list) times the factor.

A path starting ``sensors.`` is a parameter of the truth model, not of the filter (the sensors'
errors the runs draw: ``sensors.gps.override.vertical_sigma``), set in the whole scenario: what
calibrating an unpublished sensor error against a paper's numbers varies (``--objective paper``).
Its LO and HI carry the datasheet's unit (``=5:30 m``, ``=20:300 ug/rtHz:log``), written with
the trial value.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from navsim.foundations.errors import UsageError
from navsim.foundations.overrides import value_at

#: the factor range a noise term is scaled over without ``--param``
SCALE_RANGE = (0.1, 10.0)
#: the start of a truth-model parameter's path (the scenario's sensors)
TRUTH_PREFIX = "sensors."
#: a range end: a number, and a datasheet unit after it
_END = re.compile(r"^\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z%/^0-9]*)\s*$")


@dataclass(frozen=True)
class TuneParam:
    """One tuned parameter: its name (the path in the entry), the scenario path it is set at,
    its range, whether it is searched on a log scale, and, for a scaled term, the value scaled."""

    name: str
    path: str
    lo: float
    hi: float
    log: bool = False
    base: object = None           #: None: the value is the parameter; else the factor's base
    integer: bool = False         #: LO and HI whole numbers: a whole number is searched (a window)
    unit: str = ""                #: a truth parameter's datasheet unit, written after the value

    @property
    def truth(self) -> bool:
        """A parameter of the truth model (the sensors' errors), not of the filter."""
        return self.path.startswith(TRUTH_PREFIX)

    def value(self, x: float):
        """The value set in the scenario for the trial value ``x``."""
        if self.unit:
            return f"{float(x):.6g} {self.unit}"
        if self.base is None:
            return int(round(x)) if self.integer else float(x)
        if isinstance(self.base, list):
            return [float(x) * float(b) for b in self.base]
        return float(x) * float(self.base)

    @property
    def what(self) -> str:
        """How the report names it: the path, ``(scale)`` for a scaled term."""
        return self.name + (" (scale)" if self.base is not None else "")


def entry_index(raw: dict, label: str) -> int:
    """The index of the estimator labelled ``label`` in the scenario mapping ``raw``; a
    :class:`UsageError` naming the labels where none is."""
    labels = [e.get("label") if isinstance(e, dict) else None for e in raw.get("estimators") or []]
    if label not in labels:
        raise UsageError(f"--estimator {label!r}: the scenario has no such estimator "
                         f"(its labels: {', '.join(map(str, labels))})")
    return labels.index(label)


def entry_path(label: str, path: str, index: int) -> str:
    """``path`` (relative to the estimator's entry, or starting ``estimators[LABEL].``) as a
    scenario path to the entry by its index (a label of digits would read as an index); a
    :class:`UsageError` for a path into another estimator."""
    own = f"estimators[{label}]."
    if path.startswith(own):
        path = path[len(own):]
    elif path.startswith("estimators["):
        raise UsageError(f"--param {path!r}: a parameter of another estimator than '{label}' (the one tuned)")
    return f"estimators[{index}].{path}"


def parse_param(text: str, label: str, raw: dict, check: bool = True) -> TuneParam:
    """``PATH=LO:HI[:log]`` for the estimator ``label`` of the scenario mapping ``raw``: a
    :class:`UsageError` for a malformed text, ``LO >= HI``, a log scale with ``LO <= 0``, a path
    of another estimator; a :class:`ScenarioError` (the closest key) for a path the entry lacks
    (``check``: False, not looked up: a log's estimator has no entry, its build checks it)."""
    path, sep, span = text.partition("=")
    scaled = span.strip().startswith("x")
    parts = span.strip().removeprefix("x").split(":")
    if not sep or not path.strip() or len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] != "log"):
        raise UsageError(f"--param {text!r}: expected PATH=LO:HI, PATH=LO:HI:log or PATH=xLO:HI[:log] (a factor)")
    ends = [_END.match(x) for x in parts[:2]]
    try:
        lo, hi = float(ends[0][1]), float(ends[1][1])
    except (TypeError, ValueError):                  # no match, or digits and dots that are no number
        raise UsageError(f"--param {text!r}: LO and HI must be numbers (a truth parameter's with its unit)") from None
    units = {m[2] for m in ends}
    whole = all(m[1].lstrip("+-").isdigit() for m in ends)
    log = len(parts) == 3
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise UsageError(f"--param {text!r}: LO ({lo:g}) must be below HI ({hi:g})")
    if log and lo <= 0:
        raise UsageError(f"--param {text!r}: a log scale needs LO above 0, not {lo:g}")
    if path.strip().startswith(TRUTH_PREFIX):
        return _truth_param(text, path.strip(), lo, hi, log, scaled, units)
    if units != {""}:
        raise UsageError(f"--param {text!r}: a filter's parameter is in SI, without a unit (a unit is for a "
                         f"sensor's datasheet value, {TRUTH_PREFIX}...)")
    index = entry_index(raw, label)
    full = entry_path(label, path.strip(), index)
    base = value_at(raw, full, f"--param {text}") if check else None
    name = full[len(f"estimators[{index}]."):]
    if scaled and not _numeric(base):
        raise UsageError(f"--param {text!r}: a factor scales a number or a list of numbers, and {name} is {base!r}")
    integer = whole and not scaled and isinstance(base, int) and not isinstance(base, bool)   # a window: 30
    return TuneParam(name, full, lo, hi, log, base if scaled else None, integer)


def _truth_param(text: str, path: str, lo: float, hi: float, log: bool, scaled: bool, units: set) -> TuneParam:
    """A truth-model parameter: a datasheet value with its unit, set in the scenario's sensors."""
    if scaled:
        raise UsageError(f"--param {text!r}: a sensor's datasheet value carries its unit: give LO:HI with it "
                         "(=5:30 m), not a factor")
    units = units - {""}                          # the unit given once (after HI) or on both ends alike
    if len(units) != 1:
        raise UsageError(f"--param {text!r}: LO and HI of a sensor's value need one datasheet unit "
                         "(=5:30 m, =20:300 ug/rtHz:log)")
    return TuneParam(path, path, lo, hi, log, unit=units.pop())


def default_params(raw: dict, label: str) -> list[TuneParam]:
    """Each measurement noise of the estimator's entry (its ``sigma*`` keys) and its
    ``baro.sigma_m``, scaled by a factor in :data:`SCALE_RANGE` on a log scale."""
    index = entry_index(raw, label)
    entry = raw["estimators"][index]
    out = []
    for i, m in enumerate(entry.get("measurements") or []):
        for key, v in m.items():
            if key.startswith("sigma") and _numeric(v):
                out.append(_scaled(index, f"measurements[{i}].{key}", v))
    baro = entry.get("baro")
    if isinstance(baro, dict) and _numeric(baro.get("sigma_m")):
        out.append(_scaled(index, "baro.sigma_m", baro["sigma_m"]))
    if not out:
        raise UsageError(f"the estimator '{label}' declares no measurement noise to scale: name the parameters "
                         "with --param PATH=LO:HI")
    return out


def _numeric(v) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) or \
        (isinstance(v, list) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v))


def _scaled(index: int, path: str, base) -> TuneParam:
    return TuneParam(path, f"estimators[{index}].{path}", *SCALE_RANGE, log=True, base=base)
