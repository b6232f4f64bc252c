"""A sensor kind added from outside navsim: this module declares a sonar (range to the ground,
one output, one white-noise error term) as one registered :class:`SensorKind`, its datasheet is
a YAML file beside a scenario, and ``navsim run``, ``navsim sensors`` and ``navsim validate``
take it like a built-in kind. No file of navsim is edited for it (``docs/sensors.md`` walks
through the same steps)."""

import dataclasses
import inspect
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from navsim.cli import main
from navsim.sensors import SensorConfig, emulate, load_spec, output_fields, registry
from navsim.sensors.base import SensorData, apply_outages, normals, sampling
from navsim.sensors.registry import ErrorTerm, Field, Output, SensorKind


@dataclass(frozen=True)
class SonarSpec:
    """A downward sonar: the range to the ground with white noise, m."""

    rate_hz: float = 10.0
    noise: float = 0.0                        #: white range noise std, m


def emulate_sonar(truth, spec: SonarSpec, seed: int, runs, faults=(), name: str = "sonar") -> SensorData:
    """The range to the ground at the sonar's rate, plus white noise; no output in outages."""
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    err = normals(smp.rng("noise"), (smp.M,)) * spec.noise
    valid = np.ones((smp.B, smp.M), bool)
    apply_outages(valid, smp.t, faults)
    return SensorData(name=name, kind="sonar", t_s=smp.t, values={"range_m": truth.h_agl_m[::smp.step][None] + err},
                      valid=valid, errors={"range_error_m": err}, meta={"rate_hz": spec.rate_hz, "runs": smp.runs})


SONAR = SensorKind(
    name="sonar", spec=SonarSpec, description="downward sonar: range to the ground",
    fields={"rate_hz": Field("rate_hz", None, "plain"), "noise": Field("noise", "length", "1")},
    outputs=(Output("range_m", "m", role="height", truth="h_agl_m", label="range to ground"),),
    errors=(ErrorTerm("noise"),), emulate=emulate_sonar, faults=("outage",))

DATASHEET = """
kind: sonar
description: a toy downward sonar (docs/sensors.md)
source: made up
rate_hz: 10
noise: 0.05 m
"""

SCENARIO = """
name: toy_sonar
description: a 10 s straight flight with a toy sonar
aircraft: survey10
track:
  start: {lat_deg: 30.0, lon_deg: 122.5, alt_m: 150, speed_mps: 15, heading_deg: 0}
  segments:
    - {type: straight, time_s: 10}
sensors:
  imu: {model: p0_imu}
  sonar: {model: sonar_x1.yaml, faults: [{type: outage, start_s: 4, end_s: 6}]}
estimators:
  - {label: free SINS, type: sins}
initial_errors: {pos_m: [5, 5, 10], vel_mps: 0.1, att_arcsec: [20, 20, 50]}
montecarlo: {runs: 2, seed: 1, workers: 1}
metrics:
  settle_s: 1
report: {formats: [pdf]}
"""


#: the run indices each call of the emulator was asked for (the runs are in this process)
CALLS = []


def _counted(*args, **kwargs):
    CALLS.append(list(args[3]))
    return emulate_sonar(*args, **kwargs)


@pytest.fixture(scope="module")
def sonar():
    """The sonar registered for this module's tests only (a plug-in registers at import, as
    docs/sensors.md shows; here the registry is left as it was for the other tests), its
    emulator's calls counted."""
    kind = registry.register(dataclasses.replace(SONAR, emulate=_counted))
    yield kind
    registry.unregister("sonar")


@pytest.fixture
def scenario(tmp_path, sonar):
    (tmp_path / "sonar_x1.yaml").write_text(DATASHEET)
    path = tmp_path / "toy.yaml"
    path.write_text(SCENARIO)
    return path


def test_the_sonar_is_known_everywhere_once_registered(sonar, scenario):
    assert "sonar" in registry.available()
    spec = load_spec("sonar_x1.yaml", file=str(scenario))
    assert spec == SonarSpec(rate_hz=10.0, noise=0.05)
    assert output_fields(spec) == ("range_m",)
    assert load_spec("sonar_x1.yaml", off=["noise"], file=str(scenario)).noise == 0.0
    assert "range_m" in registry.fields_of_role("height")
    assert registry.default_output("sonar", "height") == "range_m"


def test_navsim_run_flies_and_scores_with_the_sonar(scenario, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["validate", str(scenario)]) == 0
    CALLS.clear()
    assert main(["run", str(scenario), "--out", str(out)]) == 0, capsys.readouterr().err
    assert sorted(r for call in CALLS for r in call) == [0, 1]        # both runs' sonar data emulated
    metrics = json.loads((out / "metrics.json").read_text())
    assert "free SINS" in metrics["estimators"]
    assert "sonar_x1.yaml" in (out / "scenario.resolved.yaml").read_text()


def test_navsim_sensors_plots_the_sonar(scenario, tmp_path, capsys):
    out = tmp_path / "plots"
    assert main(["sensors", str(scenario), "--runs", "2", "--out", str(out)]) == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert (out / "sensor_sonar.png").stat().st_size > 0
    assert "range to ground" in printed


def test_the_sonar_emulates_its_declared_error_and_faults(sonar, scenario):
    """The emulated range is the truth's height above ground plus noise of the datasheet's std,
    with no output in the outage; a fault the sonar does not declare is refused."""
    from navsim.flight import fly, parse_track
    from navsim.foundations.errors import ScenarioError
    from navsim.sensors.base import parse_faults
    truth = fly(parse_track({"start": {"lat_deg": 30.0, "lon_deg": 122.5, "alt_m": 150, "speed_mps": 15,
                                       "heading_deg": 0}, "segments": [{"type": "straight", "time_s": 10}]}))
    spec = load_spec("sonar_x1.yaml", file=str(scenario))
    cfg = SensorConfig("sonar", "sonar_x1.yaml", spec,
                       parse_faults([{"type": "outage", "start_s": 4, "end_s": 6}], "faults"))
    data = emulate(truth, cfg, 3, range(200))
    err = data.values["range_m"] - truth.h_agl_m[::10][None]
    assert abs(err.std() / 0.05 - 1) < 0.03
    assert not data.valid[:, (data.t_s >= 4) & (data.t_s < 6)].any() and data.valid[:, data.t_s < 4].all()
    biased = SensorConfig("sonar", "x", spec, parse_faults([{"type": "bias", "start_s": 1, "value_m": 2}], "f"))
    with pytest.raises(ScenarioError, match="a sonar cannot have a 'bias' fault"):
        emulate(truth, biased, 3, range(1))


def test_docs_show_this_module_s_sonar():
    """docs/sensors.md's worked example is this module's code, word for word."""
    docs = (Path(__file__).parents[2] / "docs" / "sensors.md").read_text()
    for obj in (SonarSpec, emulate_sonar):
        assert inspect.getsource(obj) in docs, obj.__name__
    declaration = Path(__file__).read_text().split("SONAR = SensorKind(")[1].split("\n\n")[0]
    assert "SONAR = SensorKind(" + declaration in docs
    assert DATASHEET.strip() in docs


#: the sonar flown in a closed loop on its true height (flat ground at 0 m), a sample filled
#: each time the loop steps past one
CLOSED_LOOP = SCENARIO.replace("start: {", "start: {type: air, ").replace(
    "report: {formats: [pdf]}", "closed_loop: {fly_on: truth, time_limit_s: 12}\nreport: {formats: [pdf]}")


def _fill_sonar(data, j, sample):
    FILLED.append((j, sample.h_m.copy()))
    data.values["range_m"][:, j] = sample.h_m + data.errors["range_error_m"][:, j]


FILLED = []


@pytest.mark.parametrize("in_loop, code", [(None, 2), (registry.InLoop(_fill_sonar), 0)])
def test_a_closed_loop_flies_the_sensors_that_declare_how(in_loop, code, sonar, scenario, tmp_path, capsys):
    """Without an :class:`InLoop` the sonar is refused in a closed loop (naming the kinds that
    fly there, the sonar not among them); with one its every sample is filled from the runs' true
    state as they fly (the kind's own fill, through the registry: no table in navsim)."""
    registry.register(dataclasses.replace(sonar, in_loop=in_loop), replace=True)
    try:
        path = tmp_path / "loop.yaml"
        path.write_text(CLOSED_LOOP)
        (tmp_path / "sonar_x1.yaml").write_text(DATASHEET)
        FILLED.clear()
        assert main(["run", str(path), "--workers", "1", "--out", str(tmp_path / "out")]) == code
        err = capsys.readouterr().err
    finally:
        registry.register(sonar, replace=True)
    if in_loop is None:
        assert "sensors.sonar" in err and "kinds imu, " in err and "sonar" not in err.split("kinds ")[1]
        return
    # two flights: the reference on truth (run 0 alone), then the Monte Carlo's two runs; in each
    # sample 0 is the static record's (the start), then 10 Hz over 10-12 s, each once, in order
    flights = [[(j, h) for j, h in FILLED if h.shape == (n,)] for n in (1, 2)]
    assert len(flights[0]) + len(flights[1]) == len(FILLED)
    for flight in flights:
        js = [j for j, _ in flight]
        assert js == list(range(1, len(js) + 1)) and 100 <= len(js) <= 120
    heights = np.array([h for _, h in flights[1]])
    assert heights.shape[1] == 2 and np.all(np.abs(heights - 150.0) < 30.0)
