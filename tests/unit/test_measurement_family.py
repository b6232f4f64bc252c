"""A measurement family added from outside navsim: this module declares a toy measurement type
(``north_fix``: the GNSS north position alone, one row), registers it, and a scenario's ES-KF
takes it by name like a built-in type; its ``H`` agrees with finite differences of its ``z``;
unregistered, it is unknown again. No file of navsim is edited for it (a built-in family is the
same class in a module of :mod:`navsim.navigation.estimators.measurements`)."""

import dataclasses

import numpy as np
import pytest

from navsim.experiment.driver import Batch, run_batch
from navsim.experiment.scenario import parse_scenario
from navsim.flight.truth import Pose, Truth
from navsim.foundations import earth
from navsim.foundations.errors import ScenarioError
from navsim.navigation.estimators import Linearised, measurement, measurement_types
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.factory import build
from navsim.navigation.estimators.measurements import MEASUREMENTS, measurements_schema, values_read
from navsim.navigation.strapdown import NavState
from navsim.sensors import emulate

LAT_DEG, LON_DEG, H_M = 30.0, 122.5, 150.0


@dataclasses.dataclass
class NorthFix:
    """INS minus GNSS north position, m: ``dL (R_M + h)``, one row, std ``sigma_m``."""

    #: its keys' JSON Schema (beside ``type`` and ``sensor``)
    SCHEMA = {"sigma_m": {"type": "number", "exclusiveMinimum": 0}}
    sensor: str
    sigma_m: float = 2.0                 #: the north position's std, m

    @classmethod
    def parse(cls, node, sensors):
        """Its one key, ``sigma_m`` (> 0, default 2 m)."""
        return {"sigma_m": node.get("sigma_m", float, 2.0, exclusive_minimum=0.0)}

    @classmethod
    def from_entry(cls, entry):
        """The model of a parsed entry."""
        return cls(entry["sensor"], float(entry["sigma_m"]))

    @classmethod
    def reads(cls, entry):
        """The one value of its GNSS sensor it reads."""
        return ("lat_rad",)

    def model(self, nav, layout, data, j):
        B = nav.lat_rad.shape[0]
        r_m, _ = earth.radii(nav.lat_rad)
        z = ((nav.lat_rad - data.values["lat_rad"][:, j]) * (r_m + nav.h_m))[:, None]
        H = np.zeros((B, 1, layout.n))
        H[:, 0, layout.slice("pos").start] = r_m + nav.h_m
        return Linearised(z, H, np.full((B, 1, 1), self.sigma_m ** 2), data.valid[:, j])


SCENARIO = {
    "name": "toy_north_fix",
    "aircraft": "survey10",
    "track": {"start": {"lat_deg": LAT_DEG, "lon_deg": LON_DEG, "alt_m": H_M, "speed_mps": 15, "heading_deg": 0},
              "segments": [{"type": "straight", "time_s": 20}]},
    "sensors": {"imu": {"model": "p3_imu"}, "gps": {"model": "p3_gps"}},
    "estimators": [{"label": "north fix", "type": "eskf", "states": "p3_15", "period_s": 1.0,
                    "noise": {"imu": "p3_imu"},
                    "measurements": [{"type": "north_fix", "sensor": "gps", "sigma_m": 2.0},
                                     {"type": "velocity", "sensor": "gps", "sigma_mps": 0.05}]}],
    "initial_errors": {"pos_m": [5, 5, 3], "vel_mps": 0.1, "att_arcsec": 60},
    "montecarlo": {"runs": 2, "seed": 1, "workers": 1},
}


@pytest.fixture
def north_fix():
    """The toy type registered for one test (as a plug-in's module registers at import), then
    unregistered: the registry is left as it was for the other tests."""
    yield measurement("north_fix")(NorthFix)
    MEASUREMENTS.unregister("north_fix")


def test_the_toy_type_is_known_everywhere_once_registered(north_fix):
    assert "north_fix" in measurement_types() and north_fix.name == "north_fix"
    assert "north_fix" in measurements_schema()["properties"]["type"]["enum"]
    assert "north_fix" not in measurements_schema(built_in=True)["properties"]["type"]["enum"]
    assert values_read({"type": "north_fix", "sensor": "gps", "sigma_m": 2.0}) == ("lat_rad",)


def test_its_H_matches_finite_differences_of_its_z(north_fix):
    """``z(dx) - z(0) = H dx`` for a position error of the INS (1e-7 rad, 1 m), at an INS
    position equal to the fix (where ``z``'s curvature in the radius drops out)."""
    layout = Layout(PRESETS["p3_15"])
    lat, h = np.radians([LAT_DEG]), np.array([H_M])
    data = type("Sample", (), {"values": {"lat_rad": lat[:, None]}, "valid": np.ones((1, 1), bool)})()

    def z_of(dlat=0.0, dlon=0.0, dh=0.0):
        nav = NavState(lat + dlat, np.radians([LON_DEG]) + dlon, h + dh, np.zeros((1, 3)), np.eye(3)[None])
        return north_fix("gps", 2.0).model(nav, layout, data, 0)

    lin = z_of()
    p = layout.slice("pos").start
    for col, step in ((p, 1e-7), (p + 1, 1e-7), (p + 2, 1.0)):
        kw = dict(zip(("dlat", "dlon", "dh"), np.eye(3)[col - p] * step))
        numeric = (z_of(**kw).z - z_of(**{k: -v for k, v in kw.items()}).z) / (2 * step)
        np.testing.assert_allclose(lin.H[:, :, col], numeric, rtol=1e-6, atol=1e-9)
    assert not np.delete(lin.H, range(p, p + 3), axis=2).any()


def test_a_scenario_s_eskf_takes_it_and_forgets_it_unregistered(north_fix):
    """The scenario mapping's ES-KF, on 20 s at rest with GNSS, updates with the toy model (its
    NIS recorded under ``north_fix:gps``) and holds the north position to the fix while
    the east one, which nothing observes, keeps its initial uncertainty; once the type is
    unregistered the same mapping is refused, naming the key."""
    scenario = parse_scenario(SCENARIO)
    spec = scenario.estimators[0]
    truth = Truth.static(20.0, pose=Pose(lat_deg=LAT_DEG, lon_deg=LON_DEG, h_m=H_M))
    data = {c.name: emulate(truth, c, scenario.seed, range(2)) for c in scenario.sensors}
    imu = data.pop("imu")
    est = build(spec)
    history = run_batch(truth, imu, data, {spec.label: est},
                        Batch(scenario.initial, scenario.seed, range(2)))[spec.label]
    nis = history.nis["north_fix:gps"]
    assert np.isfinite(nis).sum() >= 2 * 15
    p = est.layout.slice("pos").start
    r_m, r_n = earth.radii(np.radians(LAT_DEG))
    sigma_n, sigma_e = np.sqrt(est.P[:, p, p]) * (r_m + H_M), np.sqrt(est.P[:, p + 1, p + 1]) * (r_n + H_M)
    assert np.all(sigma_n < 2.0) and np.all(sigma_e > 4.0)
    assert np.all(np.abs(history.pos_err_m[:, -1, 0]) < 4 * sigma_n)
    MEASUREMENTS.unregister("north_fix")
    assert "north_fix" not in measurement_types()
    with pytest.raises(ScenarioError, match="north_fix"):
        parse_scenario(SCENARIO)
