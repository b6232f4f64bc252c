"""``--set PATH=VALUE``: the path grammar, what a change may add, and what it refuses, each
refusal naming the ``--set``."""

import copy

import pytest
from hypothesis import given, settings, strategies as st

from navsim.foundations.errors import ScenarioError
from navsim.foundations.overrides import apply_overrides, blame, make_override, parse_override

DATA = {"sensors": {"gps": {"model": "p3_gps"}, "imu": "p3_imu"},
        "estimators": [{"label": "free SINS", "type": "sins"}, {"label": "ES-KF 16", "period_s": 1.0}],
        "montecarlo": {"runs": 6}}


@pytest.mark.parametrize("text, parts, value", [
    ("montecarlo.runs=200", ("montecarlo", "runs"), 200),
    ("sensors.gps.override.position_sigma=3 m", ("sensors", "gps", "override", "position_sigma"), "3 m"),
    ("estimators[ES-KF 16].period_s=0.5", ("estimators", ("ES-KF 16",), "period_s"), 0.5),
    ("estimators[1].noise={imu: p3_imu}", ("estimators", (1,), "noise"), {"imu": "p3_imu"}),
    ("estimators[a.b c].x=[1, 2, 3]", ("estimators", ("a.b c",), "x"), [1, 2, 3]),
    ("metrics.windows[0]=", ("metrics", "windows", (0,)), None),
    ("description=a=b", ("description",), "a=b"),
    ("estimators[a=b].x=1", ("estimators", ("a=b",), "x"), 1),
    ("estimators[a[b]c][0]=1", ("estimators", ("a[b]c",), (0,)), 1),
    ("estimators[²]=1", ("estimators", ("²",)), 1),
])
def test_a_path_splits_into_keys_and_selectors_and_the_value_is_yaml(text, parts, value):
    o = parse_override(text)
    assert o.parts == parts and o.value == value and o.origin == f"--set {text}"


@pytest.mark.parametrize("text, words", [
    ("montecarlo.runs", "is not PATH=VALUE"), ("=3", "is not PATH=VALUE"), ("a[=1", "is not PATH=VALUE"),
    ("a..b=1", "empty or malformed key"), ("a.=1", "after a key"), ("a[0]..b=1", "empty or malformed key"),
    ("a.[0]=1", "empty or malformed key"), ("a[0].=1", "after a key"), ("a[0]b=1", "after a key"),
    ("a[]=1", "unclosed or empty"), ("a[0=1]", "is not PATH=VALUE"), ("[0].a=1", "empty or malformed key"),
    ("a]=1", "empty or malformed key"),
    ("a=[1, 2", "not valid YAML"), ("a={b: }}", "not valid YAML"), ("a=" + "[" * 200 + "]" * 200, "nested"),
])
def test_a_malformed_set_is_refused_naming_it(text, words):
    with pytest.raises(ScenarioError) as exc:
        parse_override(text)
    assert str(exc.value).startswith(f"--set {text}: ") and words in str(exc.value), str(exc.value)


def test_changes_apply_in_order_add_missing_keys_and_leave_the_input_alone():
    before = copy.deepcopy(DATA)
    out, written = apply_overrides(DATA, [parse_override("sensors.gps.override.position_sigma=4 m"),
                                          parse_override("estimators[ES-KF 16].period_s=0.5"),
                                          parse_override("montecarlo.runs=20"),
                                          parse_override("montecarlo.runs=30")])
    assert DATA == before
    assert out["sensors"]["gps"] == {"model": "p3_gps", "override": {"position_sigma": "4 m"}}
    assert out["estimators"][1]["period_s"] == 0.5 and out["montecarlo"]["runs"] == 30
    # validation names list entries by index: the label is resolved to it
    assert list(written) == ["sensors.gps.override.position_sigma", "estimators[1].period_s", "montecarlo.runs"]
    assert written["sensors.gps.override.position_sigma"][1] == [("sensors.gps", "override", ["model"])]


@pytest.mark.parametrize("text, words", [
    ("estimators[ES-KF 61].period_s=1", "no entry labelled 'ES-KF 61'"),
    ("estimators[2].period_s=1", "has 2 entries, no [2]"),
    ("sensors.imu.override.x=1", "sensors.imu is str 'p3_imu', not a mapping with 'override'"),
    ("montecarlo[0]=1", "montecarlo is dict"),
])
def test_a_path_that_does_not_fit_the_mapping_is_refused(text, words):
    with pytest.raises(ScenarioError) as exc:
        apply_overrides(DATA, [parse_override(text)])
    assert f"--set {text}" in str(exc.value) and words in str(exc.value), str(exc.value)


def test_a_value_is_copied_where_it_is_set_and_recorded_as_given():
    """Two changes on one value do not write into each other, nor into the caller's object."""
    given = {"model": "p3_gps"}
    first, second = make_override("sensors.gps", given), parse_override("sensors.gps.override.position_sigma=4 m")
    out, _ = apply_overrides(DATA, [first, second])
    assert given == {"model": "p3_gps"} and first.as_text() == "sensors.gps={model: p3_gps}"
    assert out["sensors"]["gps"] == {"model": "p3_gps", "override": {"position_sigma": "4 m"}}
    assert second.as_text() == "sensors.gps.override.position_sigma=4 m"
    with pytest.raises(ScenarioError, match="is not a YAML value"):
        make_override("a", object())


def test_an_error_is_blamed_on_the_set_at_or_above_its_key():
    _, written = apply_overrides(DATA, [parse_override("sensors.gps={model: x}"),
                                        parse_override("sensors.gps.override.position_sigma=4 m")])
    err = blame(ScenarioError("no sensor model 'x'", file="s.yaml", key="sensors.gps.model"), written)
    assert err.origin == "--set sensors.gps={model: x}", err.origin
    err = blame(ScenarioError("is not a mapping", file="s.yaml", key="sensors"), written)
    assert err.origin == "--set sensors.gps={model: x}", err.origin


def test_a_misspelt_label_gets_the_closest_one():
    with pytest.raises(ScenarioError) as exc:
        apply_overrides(DATA, [parse_override("estimators[ES-KF 61].period_s=1")])
    assert exc.value.hint == "did you mean 'ES-KF 16'?", exc.value.hint


def test_an_error_at_a_written_path_names_the_set_and_the_closest_existing_path():
    _, written = apply_overrides(DATA, [parse_override("sensors.gsp.override.position_sigma=4 m")])
    err = ScenarioError("is missing", file="s.yaml", key="sensors.gsp.model")
    blamed = blame(err, written)
    assert blamed.origin == "--set sensors.gsp.override.position_sigma=4 m"
    assert "the closest existing path: sensors.gps" in blamed.hint
    assert str(blamed).startswith("s.yaml (--set sensors.gsp.override.position_sigma=4 m): sensors.gsp.model: ")
    # an error elsewhere is left as it is
    other = ScenarioError("is missing", file="s.yaml", key="track")
    assert blame(other, written) is other


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.integers(-10**6, 10**6), st.floats(allow_nan=False, allow_infinity=False),
                 st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=20), st.booleans(),
                 st.lists(st.integers(0, 9), max_size=3)))
def test_a_value_recorded_as_text_reads_back_as_itself(value):
    """run.json records each change as ``PATH=VALUE``; read as a ``--set`` again it is the same
    change."""
    o = make_override("a.b", value)
    again = parse_override(o.as_text())
    assert again.parts == o.parts and again.value == value, o.as_text()
