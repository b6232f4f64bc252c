"""P0's two-step (two-stage, bias-separated) adaptive Kalman filter."""

import numpy as np
import pytest

from navsim.estimators.error_model import PRESETS, Layout
from navsim.estimators.eskf import ErrorStateKF
from navsim.estimators.measurements import GnssPosition, Height, Velocity
from navsim.estimators.two_stage import TwoStageAdaptiveKF
from navsim.flight import fly, load_track
from navsim.metrics import chi2_band
from navsim.montecarlo import ARCSEC, InitialErrors, run_batch
from navsim.sensors import SensorConfig, emulate, load_spec

P0_INITIAL = InitialErrors(pos_m=np.array([5.0, 5.0, 10.0]), vel_mps=np.full(3, 0.1),
                           att_rad=np.array([20.0, 20.0, 50.0]) * ARCSEC)


@pytest.fixture(scope="module")
def p0():
    return fly(load_track("p0"))


def sensors(truth, runs, gps_model="p3_gps"):
    spec = load_spec("p0_imu")
    imu = emulate(truth, SensorConfig("imu", "p0_imu", spec), 1, runs)
    gps = emulate(truth, SensorConfig("gps", gps_model, load_spec(gps_model)), 1, runs)
    baro = emulate(truth, SensorConfig("baro", "p0_baro", load_spec("p0_baro")), 1, runs)
    return spec, imu, {"gps": gps, "baro": baro}


def models(pos_sigma):
    return [GnssPosition("gps", np.full(3, pos_sigma)), Velocity("gps", np.full(3, 0.05)),
            Height("baro", 0.5, field="h_baro_m", use_baro_state=True)]


def test_two_stage_equals_the_augmented_filter(p0):
    truth = p0.slice(0, 20001)
    spec, imu, data = sensors(truth, range(3))
    kw = dict(baro_sigma_m=3.0, baro_tau_s=600.0)
    full = ErrorStateKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, models(2.0), **kw)
    two = TwoStageAdaptiveKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, models(2.0), adaptive=False, **kw)
    r = run_batch(truth, imu, data, {"full": full, "two": two}, P0_INITIAL, 1, range(3))
    for key in ("pos_err_m", "vel_err_mps", "att_err_rad", "sigma"):
        np.testing.assert_allclose(getattr(r["two"], key), getattr(r["full"], key), rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["two"].nees, r["full"].nees, rtol=1e-9)


def test_adaptive_filter_stays_consistent_when_R_is_ten_times_too_small(p0):
    truth = p0.slice(0, 30001)
    runs = range(30)
    spec, imu, data = sensors(truth, runs)
    kw = dict(baro_sigma_m=3.0, baro_tau_s=600.0)
    wrong = 2.0 / np.sqrt(10.0)                     # the GPS truth has 2, 2, 1 m
    std = ErrorStateKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, models(wrong), **kw)
    ada = TwoStageAdaptiveKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, models(wrong), **kw)
    r = run_batch(truth, imu, data, {"std": std, "ada": ada}, P0_INITIAL, 1, runs)
    lo, hi = chi2_band(9, 30)
    after = r["std"].t_s >= 60
    nees_std = r["std"].nees.mean(axis=0)[after]
    nees_ada = r["ada"].nees.mean(axis=0)[after]
    assert np.mean(nees_std > hi) > 0.9                       # the standard filter is overconfident
    # the adaptive one learns R over its 30-epoch window: measured, its average NEES falls from
    # 16 at 60 s to 10.8 at 300 s (band upper edge 10.6) while the standard's stays near 40
    late = r["std"].t_s[after] >= 240
    assert np.mean(nees_ada[late]) < 1.1 * hi
    assert np.mean(nees_ada) < 0.5 * np.mean(nees_std)
    # both converge from P0's initial errors
    for h in r.values():
        assert np.sqrt((h.pos_err_m[:, after] ** 2).mean()) < 3.0
