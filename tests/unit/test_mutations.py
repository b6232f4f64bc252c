"""A property-based pass over every shipped scenario: random mutations (numbers at their limits,
wrong types, keys dropped or duplicated) end in a valid parse or one ScenarioError (exit 2),
never in another exception, and nothing is flown.

Seeded (``derandomize=True``) with a bounded example count, so the pass is the same on every
machine and stays in the default suite.
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
import re
import tempfile
from pathlib import Path
from unittest import mock

import pytest
import yaml
from hypothesis import HealthCheck, Phase, given, settings, strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

from navsim import cli
from navsim.experiment import resources
from navsim.experiment.scenario import load_scenario, parse_scenario
from navsim.foundations.config import load_yaml
from navsim.foundations.errors import NavsimError

set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "navsim-hypothesis")   # never .hypothesis/ in the checkout
SCENARIOS = sorted((Path(__file__).resolve().parents[2] / "scenarios").glob("*.yaml"))
DATA = {p.name: load_yaml(p) for p in SCENARIOS}
#: the values a mutation puts in place of a value
HOSTILE = [0, 0.0, -0.0, -1, -1.5, math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-308, -1e-308,
           10**30, 2**64, -(2**64), 10**400, "x", "1e308 m", "1e-308 s", "0 s", "nan", [], [1, 2], [1e308] * 3,
           {"a": 1}, {}, True, False, None]
EXAMPLES = 2000
#: seeded, no example database and no patch files written (nothing into the checkout)
SETTINGS = dict(derandomize=True, deadline=None, database=None,
                phases=(Phase.explicit, Phase.generate, Phase.shrink),
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def _paths(node, prefix=()):
    """Every path into ``node`` (mapping keys and list indices), leaves and inner nodes."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from _paths(v, prefix + (k,))


PATHS = {name: list(_paths(data)) for name, data in DATA.items()}


def _mutate(data, path, how, value):
    """``data`` with the value at ``path`` replaced by ``value`` (``how == "set"``), scaled
    (``"neg"``: negated, ``"tiny"``: times 1e-300) or its key dropped (``"drop"``)."""
    out = copy.deepcopy(data)
    parent = out
    for k in path[:-1]:
        parent = parent[k]
    last = path[-1]
    old = parent[last]
    if how == "drop":
        del parent[last]
    elif how == "neg" and isinstance(old, (int, float)) and not isinstance(old, bool):
        parent[last] = -old
    elif how == "tiny" and isinstance(old, (int, float)) and not isinstance(old, bool):
        parent[last] = old * 1e-300
    else:
        parent[last] = value
    return out


def _check(call):
    """``call()`` ends in a result or a NavsimError of exit code 2 with one message."""
    try:
        call()
    except NavsimError as exc:
        assert exc.exit_code == 2, exc
        assert str(exc).strip(), "an empty message"
        assert "Traceback" not in str(exc)


def _no_flight(*args, **kwargs):
    raise AssertionError("a flight was flown while validating")


#: every name a flight can be flown through (each module's own binding)
FLY_BINDINGS = ("navsim.flight.simulator.fly", "navsim.cli.fly.fly", "navsim.experiment.runner.fly",
                "navsim.experiment.runner.cached_flight", "navsim.api.runs.cached_flight", "navsim.api.budgets.cached_flight",
                "navsim.api.results.cached_flight", "navsim.cli.flights.cached_flight",
                "navsim.cli.flights.fly_or_save")


@contextlib.contextmanager
def _nothing_flown():
    with contextlib.ExitStack() as stack:
        for name in FLY_BINDINGS:
            stack.enter_context(mock.patch(name, _no_flight))
        yield


def _parse_and_plan(data, file):
    """What ``navsim run`` does before it flies: parse (with the check at the nominal duration),
    then plan the run's memory and disk (:func:`navsim.experiment.resources.check_run`) for a
    scenario with estimators, so a number that only overflows later is caught here too."""
    scenario = parse_scenario(data, file)
    if scenario.estimators:
        resources.check_run(scenario, scenario.runs, None, None, scenario.workers)


MUTATION = st.tuples(st.sampled_from(sorted(DATA)), st.integers(0, 10**6),
                     st.sampled_from(["set", "set", "set", "neg", "tiny", "drop"]), st.sampled_from(HOSTILE))


@settings(max_examples=EXAMPLES, **SETTINGS)
@given(MUTATION)
def test_a_mutated_scenario_parses_or_is_refused(mutation):
    name, i, how, value = mutation
    paths = PATHS[name]
    path = paths[i % len(paths)]
    data = _mutate(DATA[name], path, how, value)
    with _nothing_flown():
        _check(lambda: _parse_and_plan(data, f"scenarios/{name}"))


def _one_line(node):
    """``node`` with every text on one line (so each key is on a line of its own)."""
    if isinstance(node, dict):
        return {k: _one_line(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_one_line(v) for v in node]
    return " ".join(node.split()) if isinstance(node, str) else node


class _NoAliases(yaml.SafeDumper):
    """One line per key: no anchors and aliases."""

    def ignore_aliases(self, data):
        return True


def _duplicated(text: str, i: int) -> str:
    """``text`` (block-style YAML) with its ``i``-th ``key: value`` line written twice."""
    lines = text.splitlines()
    keyed = [j for j, line in enumerate(lines) if re.match(r"^\s*(- )?[A-Za-z_][\w]*: \S", line)]
    j = keyed[i % len(keyed)]
    line = lines[j]
    indent = re.match(r"^(\s*)(- )?", line)
    copy_line = indent.group(1) + ("  " if indent.group(2) else "") + line[indent.end():]
    return "\n".join(lines[:j + 1] + [copy_line] + lines[j + 1:]) + "\n"


@settings(max_examples=60, **SETTINGS)
@given(st.sampled_from(sorted(DATA)), st.integers(0, 10**6))
def test_a_duplicated_key_is_refused(tmp_path_factory, name, i):
    text = _duplicated(yaml.dump(_one_line(DATA[name]), Dumper=_NoAliases, sort_keys=False, default_flow_style=False,
                                 width=math.inf), i)
    path = tmp_path_factory.mktemp("dup") / name
    path.write_text(text)
    with _nothing_flown(), pytest.raises(NavsimError, match="duplicate key") as exc:
        load_scenario(path)
    assert exc.value.exit_code == 2


@settings(max_examples=100, **SETTINGS)
@given(MUTATION)
def test_navsim_validate_of_a_mutated_scenario(tmp_path_factory, mutation):
    name, i, how, value = mutation
    paths = PATHS[name]
    data = _mutate(DATA[name], paths[i % len(paths)], how, value)
    path = tmp_path_factory.mktemp("mut") / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    err = io.StringIO()
    with _nothing_flown(), contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli.main(["validate", str(path)])
    assert code in (0, 2), err.getvalue()
    assert "Traceback" not in err.getvalue()
    if code == 2:
        assert err.getvalue().startswith("error: "), err.getvalue()
