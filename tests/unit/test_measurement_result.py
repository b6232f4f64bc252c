"""A measurement model's result is one typed :class:`Linearised` (``z``, ``H``, ``R``, ``valid``),
returned by every built-in model with the documented shapes and read by attribute by the
filters; the former positional tuple still works from a plug-in, with a ``DeprecationWarning``."""

import dataclasses
import warnings

import numpy as np
import pytest

from navsim.navigation.estimators import Linearised, measurement
from navsim.navigation.estimators import measurements as meas
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.measurements import (
    LINEARISED_FIELDS,
    GnssPosition,
    build_measurements,
    measurement_class,
    measurement_types,
)
from navsim.navigation.strapdown import NavState
from navsim.sensors import load_spec
from navsim.sensors.base import Measurements

B = 2
LAYOUT = Layout(PRESETS["p3_15"] + ("pitot_bias",))
LAT, LON, H_M = np.radians(30.0), np.radians(114.0), 350.0
VEL = np.array([40.0, 5.0, -1.0])
FIELD_N_T = np.array([2.2e-5, -0.4e-5, 4.5e-5])


def nav_state() -> NavState:
    """``B`` runs at the nominal state, level and headed north."""
    return NavState(np.full(B, LAT), np.full(B, LON), np.full(B, H_M), np.tile(VEL, (B, 1)), np.tile(np.eye(3), (B, 1, 1)))


def data(**values) -> Measurements:
    """One sample (at t = 1 s) of each value for the ``B`` runs; the second run's invalid."""
    valid = np.array([[True], [False]])
    return Measurements("s", "any", np.array([1.0]), {k: np.broadcast_to(np.asarray(v), (B, 1) + np.shape(v)).copy()
                                                      for k, v in values.items()},
                        valid, {"landmarks": [(30.001, 114.001, 0.0)], "date": "2025-01-01"})


SAMPLE = data(lat_rad=LAT + 1e-6, lon_rad=LON, h_m=H_M + 2.0, vel_n_mps=VEL + 0.1, h_baro_m=H_M - 1.0,
              mag_b_T=FIELD_N_T, landmark=0, tas_mps=np.linalg.norm(VEL), p_static_pa=97000.0, temp_k=286.0)

#: an entry of each built-in type (``type`` and ``sensor`` added), as ``parse`` returns them
ENTRIES = {
    "gnss_position": {"sigma_m": [2.0, 2.0, 3.0]},
    "gnss_horizontal": {"sigma_m": [2.0, 2.0]},
    "velocity": {"sigma_mps": [0.1, 0.1, 0.2], "field": "vel_n_mps"},
    "height": {"sigma_m": 1.0, "field": "h_baro_m", "baro_state": False, "offset_m": 0.0},
    "zero_velocity": {"sigma_mps": [1.0, 1.0, 1.0], "axes": "ned"},
    "landmark": {"sigma_m": 3.0, "ratio": 0.01},
    "mag_heading": {"sigma_deg": 1.0, "noise_uT": 0.0, "calibration": "none", "forgetting": 1.0, "min_turns": 0.0,
                    "field_uT": list(FIELD_N_T * 1e6)},
    "air_velocity": {"model": "p0_ads", "override": None, "angle_sigma_deg": 4.0, "wind_n_mps": [0.0, 0.0, 0.0]},
}
#: the rows each one measures
ROWS = {"gnss_position": 3, "gnss_horizontal": 2, "velocity": 3, "height": 1, "zero_velocity": 3, "landmark": 3,
        "mag_heading": 1, "air_velocity": 3}


def built_in_types() -> list:
    return [t for t in measurement_types() if measurement_class(t).__module__.startswith("navsim.")]


def test_every_built_in_type_has_a_case():
    assert sorted(ENTRIES) == built_in_types()


@pytest.mark.parametrize("mtype", sorted(ENTRIES))
def test_every_built_in_model_returns_a_linearised_of_the_documented_shapes(mtype):
    model, = build_measurements([{"type": mtype, "sensor": "s", **ENTRIES[mtype]}])
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)        # no tuple left behind
        lin = model.model(nav_state(), LAYOUT, SAMPLE, 0)
    assert type(lin) is Linearised
    m = ROWS[mtype]
    assert lin.z.shape == (B, m) and lin.H.shape == (B, m, LAYOUT.n) and lin.R.shape == (B, m, m)
    assert lin.valid.dtype == bool and lin.valid.tolist() == [True, False]
    assert np.isfinite(lin.z[0]).all() and np.isfinite(lin.R[0]).all()


def test_linearised_is_a_frozen_dataclass_of_the_four_fields():
    assert tuple(f.name for f in dataclasses.fields(Linearised)) == LINEARISED_FIELDS
    lin = GnssPosition("s", np.ones(3)).model(nav_state(), LAYOUT, SAMPLE, 0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        lin.R = lin.R * 2.0


def test_unpacking_or_indexing_it_as_the_former_tuple_still_works_and_warns():
    lin = GnssPosition("s", np.ones(3)).model(nav_state(), LAYOUT, SAMPLE, 0)
    with pytest.warns(DeprecationWarning, match="read .z, .H, .R, .valid"):
        z, H, R, valid = lin
    assert z is lin.z and H is lin.H and R is lin.R and valid is lin.valid
    with pytest.warns(DeprecationWarning):
        assert lin[1] is lin.H


@pytest.fixture
def registry():
    """The measurement registry, restored after the test (its plug-in types dropped)."""
    before = set(meas.MEASUREMENTS.built())
    yield meas.MEASUREMENTS
    for name in set(meas.MEASUREMENTS.built()) - before:
        meas.MEASUREMENTS.unregister(name)


def _plugin(name: str, result):
    """A plug-in type registered as ``name`` whose ``model`` returns ``result(lin)``, ``lin`` the
    GNSS position model's."""
    @measurement(name)
    @dataclasses.dataclass
    class Plugin:
        sensor: str
        SCHEMA = {}

        @classmethod
        def parse(cls, node, sensors):
            return {}

        @classmethod
        def from_entry(cls, entry):
            return cls(entry["sensor"])

        def model(self, nav, layout, data, j):
            lin = GnssPosition(self.sensor, np.ones(3)).model(nav, layout, data, j)
            return result(lin)
    return Plugin("s")


def _updated(model):
    """The covariance ``P`` and the corrected position ``(lat, lon, h)`` of a 15-state ES-KF
    after one epoch with ``model`` alone."""
    kf = ErrorStateKF.from_imu_spec(Layout(PRESETS["p3_15"]), load_spec("p3_imu"), [model])
    kf.initialize(nav_state(), {"att": np.full(3, 1e-3), "vel": np.full(3, 0.1), "pos": np.array([1e-6, 1e-6, 3.0])})
    kf.epoch(1.0, {"s": SAMPLE})
    s = kf.sd.state
    return kf.P, np.stack([s.lat_rad, s.lon_rad, s.h_m], -1)


def test_a_plugin_model_returning_the_former_tuple_is_wrapped_with_a_warning(registry):
    old = _plugin("old_style", lambda lin: (lin.z, lin.H, lin.R, lin.valid))
    with pytest.warns(DeprecationWarning, match="'old_style': model\\(\\) returns a tuple"):
        lin = old.model(nav_state(), LAYOUT, SAMPLE, 0)
    assert type(lin) is Linearised
    with pytest.warns(DeprecationWarning):
        P_old, pos_old = _updated(old)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)         # the filter reads attributes
        P_new, pos_new = _updated(_plugin("new_style", lambda lin: lin))
        P_shipped, pos_shipped = _updated(GnssPosition("s", np.ones(3)))    # its compiled form
    assert P_new[0, 8, 8] < P_new[1, 8, 8] == 9.0 and pos_new[0, 2] != pos_new[1, 2] == H_M   # run 1 has no sample
    np.testing.assert_array_equal(P_old, P_new)
    np.testing.assert_array_equal(pos_old, pos_new)
    np.testing.assert_allclose(P_shipped, P_new, rtol=1e-12, atol=0)
    np.testing.assert_allclose(pos_shipped, pos_new, rtol=1e-14, atol=0)


def test_a_plugin_model_returning_anything_else_is_a_type_error_naming_its_type(registry):
    bad = _plugin("bad_style", lambda lin: [lin.z, lin.H])
    with pytest.raises(TypeError, match="measurement 'bad_style': model\\(\\) returned list, expected a Linearised"):
        bad.model(nav_state(), LAYOUT, SAMPLE, 0)
