"""P1's federated Kalman filter (Liang): optimality of fusion-reset, no-reset, fault isolation."""

import numpy as np
import pytest

from navsim.experiment.driver import ARCSEC, Batch, InitialErrors, run_batch
from navsim.flight import fly, load_track
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.eskf import ErrorStateKF, ExtraStates
from navsim.navigation.estimators.federated import FederatedKF
from navsim.navigation.estimators.measurements import GnssPosition, Height
from navsim.sensors import SensorConfig, emulate, load_spec
from navsim.sensors.base import Fault

INIT = InitialErrors(pos_m=np.array([5.0, 5.0, 10.0]), vel_mps=np.full(3, 0.1),
                     att_rad=np.array([20.0, 20.0, 50.0]) * ARCSEC)
KW = dict(extra_states=ExtraStates(baro_sigma_m=3.0, baro_tau_s=600.0))


@pytest.fixture(scope="module")
def p0():
    return fly(load_track("p0")).slice(0, 20001)


def data(truth, runs, baro_faults=()):
    spec = load_spec("p0_imu")
    imu = emulate(truth, SensorConfig("imu", "p0_imu", spec), 1, runs)
    gps = emulate(truth, SensorConfig("gps", "p0_bd2", load_spec("p0_bd2")), 1, runs)
    baro = emulate(truth, SensorConfig("baro", "p0_baro", load_spec("p0_baro"), faults=baro_faults), 1, runs)
    return spec, imu, {"gps": gps, "baro": baro}


def gps_models():
    return [GnssPosition("gps", np.full(3, 8.0))]


def baro_models():
    return [Height("baro", 0.5, field="h_baro_m", use_baro_state=True)]


def locals_(betas=(0.5, 0.5)):
    return [{"name": "SINS/GPS", "beta": betas[0], "measurements": gps_models()},
            {"name": "SINS/baro", "beta": betas[1], "measurements": baro_models()}]


def test_fusion_reset_every_epoch_is_the_centralized_filter(p0):
    runs = range(3)
    spec, imu, d = data(p0, runs)
    central = ErrorStateKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, gps_models() + baro_models(), **KW)
    fed = FederatedKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, locals_((0.3, 0.7)), reset=True, **KW)
    r = run_batch(p0, imu, d, {"c": central, "f": fed}, Batch(INIT, 1, runs))
    for key in ("pos_err_m", "vel_err_mps", "att_err_rad"):
        a, b = getattr(r["f"], key), getattr(r["c"], key)
        assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(b))
    np.testing.assert_allclose(r["f"].sigma, r["c"].sigma, rtol=1e-6)


def test_no_reset_is_conservative_and_a_baro_step_is_isolated(p0):
    runs = range(20)
    step = (Fault(type="bias", start_s=100.0, end_s=150.0, value=30.0),)
    spec, imu, d = data(p0, runs, step)
    iso = {"window": 3, "p": 0.999}
    est = {"reset": FederatedKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, locals_(), reset=True, **KW),
           "no_reset": FederatedKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, locals_(), reset=False, **KW),
           "isolating": FederatedKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, locals_(), reset=True,
                                                  isolation=iso, **KW)}
    r = run_batch(p0, imu, d, est, Batch(INIT, 1, runs))
    t = r["reset"].t_s
    fault = (t >= 100) & (t <= 150)
    before = (t >= 40) & (t < 100)
    dh = {k: np.sqrt(np.mean(h.pos_err_m[:, :, 2] ** 2, axis=0)) for k, h in r.items()}
    # no-reset counts the common process noise once per local filter: its fused sigma is wider
    assert np.mean(r["no_reset"].sigma[:, before, 8]) > np.mean(r["reset"].sigma[:, before, 8])
    # a 30 m baro step drags the fused height of the plain filter; isolation drops the baro filter
    assert np.max(dh["reset"][fault]) > 5.0
    assert np.max(dh["isolating"][fault]) < 0.3 * np.max(dh["reset"][fault])
    assert np.mean(dh["isolating"][before]) < 1.5 * np.mean(dh["reset"][before])
    active = est["isolating"].active
    assert active.shape == (2, 20) and active[0].all()      # the GPS filter never leaves
