"""The sensor registry: each kind declared once, in its own module, and everything else read
from that declaration (catalog fields, outputs, error sources, faults, emulator, plot)."""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

import navsim.sensors
from navsim.flight import FlightConfig, fly, parse_track
from navsim.flight.environment import parse_environment
from navsim.flight.truth import Pose, Truth
from navsim.foundations import plugins
from navsim.foundations.errors import ScenarioError, UsageError
from navsim.sensors import SensorConfig, emulate, load_spec, output_fields, registry
from navsim.sensors.base import check_faults, parse_faults
from navsim.sensors.catalog import available as catalog, spec_from_datasheet
from navsim.sensors.plots import channels
from navsim.sensors.registry import ErrorTerm, Field, LoopSample, Output, SensorKind

SENSORS = Path(navsim.sensors.__file__).parent
BUILT_IN = {"imu": "imu", "gnss": "gnss", "baro": "airdata", "ads": "airdata", "radar_altimeter": "radar",
            "magnetometer": "magnetometer", "camera": "camera"}


def test_each_built_in_kind_is_registered_by_its_own_module():
    assert set(BUILT_IN) <= set(registry.available())
    for kind, module in BUILT_IN.items():
        declared = registry.get(kind)
        assert declared.emulate.__module__ == f"navsim.sensors.{module}"
        assert declared.spec.__module__ == f"navsim.sensors.{module}"
    assert set(catalog().values()) <= set(registry.available())       # every datasheet's kind is known


def test_no_other_module_of_the_sensors_names_a_kind():
    """The lookup tables keyed by kind are gone: a kind's name appears as a string only in the
    module that declares it."""
    for path in SENSORS.glob("*.py"):
        text = path.read_text()
        for kind, module in BUILT_IN.items():
            if path.stem != module:
                assert not re.search(rf"[\"']{kind}[\"']", text), f"{path.name} names the kind '{kind}'"


@pytest.fixture(scope="module")
def static():
    return Truth.static(30.0, rate_hz=100.0, h_agl_m=120.0)


@pytest.mark.parametrize("model", sorted(catalog()))
def test_declared_outputs_units_and_channels_are_what_the_emulator_gives(static, model):
    spec = load_spec(model)
    kind = registry.of(spec)
    data = emulate(static, SensorConfig(model, model, spec), 1, range(2))
    assert set(output_fields(spec)) == set(data.values)
    assert all(o.unit for o in kind.outputs)
    for label, unit, t, meas, true in channels(data, static, 1):
        assert meas.shape == true.shape == t.shape, (model, label)


@pytest.mark.parametrize("model", sorted(catalog()))
def test_each_error_term_is_a_field_of_the_spec_and_switches_off(model):
    """``off: [term]`` sets exactly that attribute (to its declared off value); ``off: all`` is
    every term off."""
    spec = load_spec(model)
    kind = registry.of(spec)
    everything = load_spec(model, off="all")
    assert _same(everything, kind.ideal(spec)) and _same(everything, kind.disable(spec, kind.error_names()))
    for term in kind.errors:
        one = load_spec(model, off=[term.name])
        head, _, rest = term.name.partition(".")
        value = getattr(getattr(one, head), rest) if rest else getattr(one, head)
        if term.off is not None:
            assert value == term.off
        elif isinstance(value, np.ndarray) and value.shape == (3, 3):
            assert np.array_equal(value, np.eye(3))
        else:
            assert not np.any(value), (model, term.name)


def _same(a, b) -> bool:
    """Two specs field by field (nested dataclasses too)."""
    if dataclasses.is_dataclass(a):
        return type(a) is type(b) and all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return np.array_equal(a, b)


def test_an_unknown_error_source_names_the_kinds_own():
    with pytest.raises(ScenarioError, match="not an error source of a radar_altimeter") as exc:
        load_spec("p2_radar", off=["noise_ration"])
    assert "noise_ratio" in str(exc.value) and "beam_half_width" in str(exc.value)


def test_faults_are_those_the_kind_declares():
    """A magnetometer may have a disturbance, a GNSS receiver an interference, an IMU none at all
    (its emulator reads no fault window: an IMU outage was accepted and silently ignored)."""
    disturbance = parse_faults([{"type": "disturbance", "start_s": 1, "hard_iron_uT": [1, 2, 3]}], "f")
    check_faults(disturbance, "magnetometer", 10.0, "mag")
    with pytest.raises(ScenarioError, match="a gnss cannot have a 'disturbance' fault"):
        check_faults(disturbance, "gnss", 10.0, "gps")
    outage = parse_faults([{"type": "outage", "start_s": 1, "end_s": 2}], "f")
    with pytest.raises(ScenarioError, match="a imu cannot have a 'outage' fault") as exc:
        check_faults(outage, "imu", 10.0, "imu")
    assert "no fault windows" in str(exc.value)


def test_height_and_velocity_fields_come_from_the_declared_roles():
    assert set(navsim.sensors.height_fields()) == {"h_m", "h_baro_m", "h_pressure_m", "h_agl_m"}
    assert navsim.sensors.velocity_fields() == ("vel_n_mps",)
    assert [registry.default_output(k, "height") for k in ("gnss", "baro", "ads", "radar_altimeter", "camera")] \
        == ["h_m", "h_baro_m", "h_pressure_m", "h_agl_m", "h_m"]
    assert registry.default_output("magnetometer", "height") is None


@dataclasses.dataclass(frozen=True)
class _Spec:
    rate_hz: float = 1.0
    noise: float = 0.0


def _kind(**changes) -> SensorKind:
    base = dict(name="toy", spec=_Spec, fields={"rate_hz": Field("rate_hz", None, "plain"),
                                                 "noise": Field("noise", "length", "1")},
                outputs=(Output("x_m", "m"),), errors=(ErrorTerm("noise"),), emulate=lambda *a, **k: None)
    return SensorKind(**{**base, **changes})


@pytest.mark.parametrize("changes, words", [
    ({"fields": {"noise": Field("nosie", "length", "1")}}, "fills 'nosie'"),
    ({"errors": (ErrorTerm("noise_sigma"),)}, "error term 'noise_sigma'"),
    ({"faults": ("outages",)}, "fault 'outages'"),
    ({"outputs": (Output("x_m", "m", role="altitude"),)}, "role 'altitude'"),
    ({"name": "a toy"}, "not a plain name"),
    ({"fields": {"noise": Field("noise", "length", "scalar")}}, "shape 'scalar'"),
])
def test_a_malformed_declaration_is_refused_at_registration(changes, words):
    with pytest.raises(TypeError, match=words):
        registry.register(_kind(**changes))
    assert "toy" not in registry.available()


def test_a_kind_registers_once_and_reads_its_datasheets():
    kind = registry.register(_kind())
    try:
        with pytest.raises(TypeError, match="registered already"):
            registry.register(_kind())
        assert spec_from_datasheet({"kind": "toy", "rate_hz": 2, "noise": "3 m"}) == _Spec(2.0, 3.0)
        with pytest.raises(ScenarioError, match="is negative"):
            spec_from_datasheet({"kind": "toy", "noise": "-3 m"})
        assert registry.get("toy") is kind and "toy" in navsim.sensors.OUTPUTS
    finally:
        registry.unregister("toy")
    with pytest.raises(ScenarioError, match="is 'toy'"):
        spec_from_datasheet({"kind": "toy"})


def test_an_entry_point_registers_its_kind(monkeypatch):
    class EntryPoint:
        name, value = "toy", "pkg.mod:KIND"

        def __init__(self, obj):
            self.obj = obj

        def load(self):
            return self.obj

    monkeypatch.setattr(registry, "_ENTRY_POINTS_READ", [])
    monkeypatch.setattr(plugins.metadata, "entry_points", lambda group: [EntryPoint(_kind())])
    try:
        assert registry.get("toy").name == "toy"
    finally:
        registry.unregister("toy")
    monkeypatch.setattr(registry, "_ENTRY_POINTS_READ", [])
    monkeypatch.setattr(plugins.metadata, "entry_points", lambda group: [EntryPoint(object())])
    with pytest.raises(UsageError, match="is not a SensorKind named 'toy'"):
        registry.available()


@pytest.mark.parametrize("override", [{}, {"velocity_axis": "air", "vane_noise": "0.5 deg"},
                                      {"pitot": "absolute", "formula": "p0"}])
def test_an_ads_in_the_loop_reads_what_it_reads_open_loop(override):
    """An ADS emulated on the closed loop's static record, its errors kept (``prepare``) and its
    samples filled from the flown state one by one, gives what it gives emulated on the flight:
    the same errors drawn, the same air data computed from them."""
    track = parse_track({"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 200, "speed_mps": 14},
                         "segments": [{"type": "turn", "by_deg": 60, "bank_deg": 25}]})
    env = parse_environment({"wind": {"force": 3, "from_deg": 200},
                             "turbulence": {"type": "milspec", "wind20_mps": 10, "severity": 3, "seed": 2}})
    truth = fly(FlightConfig(track=track, environment=env))
    spec = load_spec("p0_ads", override)
    config = SensorConfig("ads", "ads", spec)
    flown = emulate(truth, config, 3, range(4))
    static = Truth.static(truth.duration_s, 1.0 / truth.dt_s, Pose(37.0, 118.0, 200.0))
    loop = emulate(static, config, 3, range(4))
    kind = registry.get("ads").in_loop
    kind.prepare(loop, static)
    step = int(round(1.0 / (spec.rate_hz * truth.dt_s)))
    for j in range(loop.t_s.size):
        k = j * step
        one = lambda x: np.broadcast_to(x[k], (4, *np.shape(x[k])))
        kind.fill(loop, j, LoopSample(one(truth.lat_rad), one(truth.lon_rad), one(truth.h_m), one(truth.vel_n_mps),
                                      one(truth.euler_rad), one(truth.p_static_pa), one(truth.p_total_pa),
                                      one(truth.temp_k), one(truth.alpha_rad), one(truth.beta_rad)))
    assert set(loop.values) == set(flown.values)
    for name, v in flown.values.items():
        np.testing.assert_allclose(loop.values[name], v, rtol=1e-9, atol=1e-9, err_msg=name)
    assert np.ptp(flown.values["tas_mps"]) > 0.5           # a flight, not a rest: the fill follows it
