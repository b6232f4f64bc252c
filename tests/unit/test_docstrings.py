"""Every public name has a docstring, and its numbers their units: the names ``import navsim``
exports (each parameter of a function documented in its numpydoc ``Parameters``), and the
contracts a plug-in reads and fills (the estimator's, the measurement model's, the sensor
kind's), whose fields each say their unit or shape (in the name, ``pos_m``, or in the field's
``#:`` comment or ``Attributes`` entry)."""

import dataclasses
import inspect
import re

import pytest

import navsim
from navsim.navigation.estimators import base, measurements
from navsim.navigation.strapdown import NavState
from navsim.records import metrics
from navsim.sensors import base as sensor_base, registry

API = [n for n in navsim.__all__ if n != "__version__"]
#: the contracts: what a plug-in implements, fills or is handed
CONTRACTS = [base.Estimator, base.Solution, base.Innovation, base.register, base.sample, measurements.measurement,
             measurements.Linearised, measurements.CompiledModel, registry.SensorKind, registry.register,
             sensor_base.SensorData, sensor_base.Measurements, sensor_base.Sampling, NavState]
#: the records whose numeric fields must each carry their unit or shape
UNIT_RECORDS = [base.Solution, base.Innovation, NavState, measurements.Linearised, metrics.ErrorStats,
                metrics.Nees, metrics.Nis, metrics.WindStats, metrics.HorizontalStats]
#: a name ending so carries its unit (``pos_m``, ``t_s``, ``vel_n_mps``, ``att_deg``, ...)
UNIT_SUFFIX = re.compile(r"_(m|s|mps|mps2|deg|rad|rad_s|rps|hz|pa|k|t|ut|dph|pct|us)$", re.I)
#: a field's text that gives a unit, a shape or says it has none
UNIT_WORDS = re.compile(r"(?<![\w'])(m|s|rad|deg|m/s|m/s\^2|rad/s|Pa|K|Hz|T|uT|dimensionless|fraction|"
                        r"measurement's units)(?![\w'])")


def _own_doc(obj) -> str:
    """``obj``'s own docstring (a dataclass without one gets its signature as ``__doc__``)."""
    doc = inspect.getdoc(obj) or ""
    return "" if doc.startswith(f"{getattr(obj, '__name__', '')}(") else doc


def _documented_parameters(doc: str) -> set:
    """The names a numpydoc ``Parameters`` section documents (``a, b : type`` lines too)."""
    m = re.search(r"^Parameters\n-+\n(.*?)(?=^\w[\w ]*\n-+\n|\Z)", doc, re.S | re.M)
    names = set()
    for line in (m.group(1).splitlines() if m else ()):
        if line and not line[0].isspace():
            names.update(n.strip().lstrip("*") for n in line.split(" : ")[0].split(","))
    return names


PUBLIC = {f"navsim.{n}": getattr(navsim, n) for n in API} | {f"{c.__module__}.{c.__name__}": c for c in CONTRACTS}


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_every_public_name_has_a_docstring(name):
    obj = PUBLIC[name]
    doc = _own_doc(obj)
    assert len(doc.split()) >= 5, f"{name}: no docstring of its own"
    if inspect.isclass(obj) and not dataclasses.is_dataclass(obj):
        for attr, member in vars(obj).items():
            if not attr.startswith("_") and inspect.isfunction(member):
                assert _own_doc(member), f"{name}.{attr}: no docstring"


@pytest.mark.parametrize("name", [n for n in API if inspect.isfunction(getattr(navsim, n))])
def test_every_parameter_of_the_api_is_documented(name):
    fn = getattr(navsim, name)
    params = [p.name for p in inspect.signature(fn).parameters.values()
              if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    missing = set(params) - _documented_parameters(inspect.getdoc(fn))
    if params == ["source"] or params == ["folder"]:   # one argument, described in the sentence
        assert params[0] in inspect.getdoc(fn) or "path" in inspect.getdoc(fn)
        return
    assert not missing, f"navsim.{name}: parameters not in its Parameters section: {sorted(missing)}"


def _field_docs(cls) -> dict:
    """Field -> its text: the ``#:`` comment on its line, else its ``Attributes`` entry."""
    src = inspect.getsource(cls)
    out = {f.name: "" for f in dataclasses.fields(cls)}
    for name in out:
        m = re.search(rf"^\s+{name}\s*:[^\n#]*#:\s*(.+)$", src, re.M)
        above = re.search(rf"((?:^\s+#:.*\n)+)\s+{name}\s*:", src, re.M)   # #: lines before it
        if m:
            out[name] = m.group(1)
        elif above:
            out[name] = above.group(1)
        else:
            m = re.search(rf"^\s*{name}\s*:\s*(.+?)\n(.*?)(?=^\s*\w+\s*:|\Z)", _own_doc(cls), re.S | re.M)
            out[name] = " ".join(m.groups()) if m else ""
    return out


@pytest.mark.parametrize("cls", UNIT_RECORDS, ids=lambda c: c.__name__)
def test_every_number_of_the_contracts_says_its_unit(cls):
    hints = {f.name: f.type for f in dataclasses.fields(cls)}
    for name, text in _field_docs(cls).items():
        numeric = any(t in str(hints[name]) for t in ("ndarray", "float", "list"))
        if not numeric:
            continue
        assert UNIT_SUFFIX.search(name) or UNIT_WORDS.search(text), \
            f"{cls.__name__}.{name}: no unit in its name nor in its documentation ({text!r})"
