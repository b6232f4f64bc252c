"""P0's two-step (two-stage, bias-separated) adaptive Kalman filter."""

import numpy as np
import pytest

from navsim.experiment.driver import ARCSEC, Batch, InitialErrors, run_batch
from navsim.flight import fly, load_track
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.eskf import ErrorStateKF, ExtraStates
from navsim.navigation.estimators.measurements import GnssPosition, Height, Velocity
from navsim.navigation.estimators.two_stage import TwoStageAdaptiveKF
from navsim.scoring.stats import chi2_band
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
    kw = dict(extra_states=ExtraStates(baro_sigma_m=3.0, baro_tau_s=600.0))
    full = ErrorStateKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, models(2.0), **kw)
    two = TwoStageAdaptiveKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, models(2.0), adaptive=False, **kw)
    r = run_batch(truth, imu, data, {"full": full, "two": two}, Batch(P0_INITIAL, 1, range(3)))
    for key in ("pos_err_m", "vel_err_mps", "att_err_rad", "sigma"):
        np.testing.assert_allclose(getattr(r["two"], key), getattr(r["full"], key), rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["two"].nees, r["full"].nees, rtol=1e-9)


def p0_models(bd_sigma):
    return [GnssPosition("bd", np.full(3, bd_sigma)), Velocity("ads", np.array([1.0, 1.0, 1.5])),
            Height("ads", 1.0, field="h_pressure_m", use_baro_state=True)]


def test_adaptive_filter_stays_consistent_when_R_is_ten_times_too_small(p0):
    """P0's BD/SINS/ADS set-up, both filters told the BD noise is 8/sqrt(10) m instead of 8 m."""
    truth = p0.slice(0, 30001)
    runs = range(30)
    spec = load_spec("p0_imu")
    imu = emulate(truth, SensorConfig("imu", "p0_imu", spec), 1, runs)
    data = {name: emulate(truth, SensorConfig(name, model, load_spec(model)), 1, runs)
            for name, model in (("bd", "p0_bd2"), ("ads", "p0_ads"))}
    kw = dict(extra_states=ExtraStates(baro_sigma_m=3.0, baro_tau_s=600.0))
    right, wrong = 8.0, 8.0 / np.sqrt(10.0)
    est = {"std": ErrorStateKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, p0_models(right), **kw),
           "std_wrong": ErrorStateKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, p0_models(wrong), **kw),
           "ada_wrong": TwoStageAdaptiveKF.from_imu_spec(Layout(PRESETS["p0_16"]), spec, p0_models(wrong), **kw)}
    r = run_batch(truth, imu, data, est, Batch(P0_INITIAL, 1, runs))
    lo, hi = chi2_band(9, 30)
    after = r["std"].t_s >= 60
    nees = {k: h.nees.mean(axis=0)[after] for k, h in r.items()}
    # measured (seed 1, 60-300 s): average NEES 8.0 (right model), 54.7 (R/10), 9.1 (adaptive,
    # R/10, 100 % of the epochs inside); band 7.55-10.58
    assert lo < np.mean(nees["std"]) < hi                  # the model is right: consistent
    assert np.mean(nees["std_wrong"] > hi) > 0.9           # R/10: overconfident
    assert lo < np.mean(nees["ada_wrong"]) < hi            # the adaptive filter re-learns R
    assert np.mean((nees["ada_wrong"] > lo) & (nees["ada_wrong"] < hi)) > 0.5
    # all converge from P0's initial errors
    for h in r.values():
        assert np.sqrt((h.pos_err_m[:, after] ** 2).mean()) < 3.0
