"""P4's CPF-EKF on its shipped scenarios: the static test against P4's accuracy, and the
divergence of the EKF alone under the magnetic disturbance against the CPF-EKF's reset.

Whole-scenario figures (20 runs, ``navsim run``) are in the README; these tests run a few runs
(and the divergence flight up to 560 s) to stay inside the CI budget."""

import dataclasses

import numpy as np
import pytest

from navsim.experiment.options import RunOptions
from navsim.experiment.runner import run_monte_carlo
from navsim.scoring.scorer import score


@pytest.fixture(scope="module")
def static(shipped_flight):
    scenario, truth, _ = shipped_flight("p4_static")
    return run_monte_carlo(scenario, truth, None, RunOptions(runs=4, seed=scenario.seed, workers=1)), scenario


def test_static_attitude_reaches_p4s_accuracy(static):
    res, scenario = static
    h = res.histories["CPF-EKF"]
    a = score(h, scenario.settle_s).attitude
    # P4: +/-0.05 deg roll/pitch, +/-0.2 deg yaw against the MTi: the spread about each run's
    # own mean (4 runs, 95th percentile; 20 runs in the README)
    assert np.all(np.array(a.p95_about_run_mean_deg) < [0.05, 0.05, 0.2])
    # against the truth the calibration residuals add a constant per run: tilt b/g (0.5 mg ->
    # 0.029 deg, 1 sigma) and misalignment (0.1 mrad -> 0.006 deg): below 3 sigma of that floor
    assert np.all(np.array(a.p95_deg[:2]) < 3 * (0.029 + 0.006) + 0.03)
    assert len(h.resets) == 4 and not any(h.resets), "a static vehicle with a calibrated magnetometer must not be reset"


def test_without_gnss_a_zero_velocity_levels_the_eskf_to_the_accelerometer_floor(static):
    """navsim's ES-KF on the parked vehicle with no GNSS: the zero velocity (0.05 m/s) makes the
    tilt observable through the accelerometers, so roll and pitch reach the same floor as the
    CPF-EKF's (b/g of the 0.5 mg residual bias, 0.029 deg, and the 0.1 mrad misalignment), and
    the calibrated magnetometer's heading holds yaw at hard iron / horizontal field (0.05 uT /
    ~23 uT, 0.12 deg 1 sigma) plus the heading noise; the position it is never told stays at
    its initial error, the velocity at the pseudo-measurement's level."""
    res, scenario = static
    h = res.histories["ES-KF, no GNSS"]
    a = score(h, scenario.settle_s).attitude
    assert np.all(np.array(a.p95_deg[:2]) < 3 * (0.029 + 0.006) + 0.03), a.p95_deg
    assert a.p95_deg[2] < 3 * 0.12 + 0.2, a.p95_deg
    late = h.t_s > scenario.settle_s
    assert np.sqrt(np.mean(h.vel_err_mps[:, late] ** 2)) < 0.05
    # one entry per run, each None: no run flagged diverged
    assert h.divergence is not None and len(h.divergence) == h.pos_err_m.shape[0] == 4, h.divergence
    assert all(d is None for d in h.divergence) and not h.diverged.any(), h.divergence


def test_the_complementary_filter_alone_is_coarser(static):
    res, scenario = static
    ekf, cpf = (score(res.histories[k], scenario.settle_s).attitude for k in ("CPF-EKF", "CPF"))
    assert np.all(np.array(ekf.p95_deg) < np.array(cpf.p95_deg))


@pytest.fixture(scope="module")
def divergence(shipped_flight):
    scenario, truth, _ = shipped_flight("p4_divergence")
    truth = truth.slice(0, 560 * 100 + 1)          # the disturbance at 320 s, the reset ~390 s
    return run_monte_carlo(scenario, truth, None, RunOptions(runs=2, seed=scenario.seed, workers=1)), scenario


# the divergence pair: 27 s of CPF-EKF epochs in numpy (the fixture), slow for the default suite's
# 5 min until issue 56 compiles them; the figures are docs/papers.md's (20 runs)
@pytest.mark.slow
def test_the_ekf_alone_diverges_under_the_magnetic_disturbance(divergence):
    res, _ = divergence
    h = res.histories["EKF alone"]
    yaw = np.degrees(np.abs(h.euler_err_rad[..., 2]))
    assert np.all(yaw[:, (h.t_s > 60) & (h.t_s < 320)].max(axis=1) < 1.0)      # fine before
    assert np.all(yaw[:, h.t_s > 320].max(axis=1) > 10.0)                         # P4: diverged
    assert len(h.resets) == 2 and not any(h.resets)


@pytest.mark.slow
def test_the_cpf_ekf_is_reset_and_tracks_again(divergence):
    res, _ = divergence
    h = res.histories["CPF-EKF"]
    assert len(h.resets) == 2, h.resets
    for run in h.resets:
        assert run, "every run is reset"
        t, cause = run[0]
        assert 320.0 < t < 420.0 and cause == "cpf"
    late_s = max(r[-1][0] for r in h.resets) + 120.0
    assert (h.t_s > late_s).sum() > 100
    a = score(h, late_s).attitude
    # within P4's dynamic accuracy again two minutes after the reset
    assert np.all(np.array(a.p95_deg) < [0.1, 0.1, 0.5])
    # and the CPF it was reset from stayed with the truth through the disturbance
    cpf = np.degrees(np.abs(res.histories["CPF"].euler_err_rad[:, res.histories["CPF"].t_s > 60]))
    assert cpf.max() < 2.0


@pytest.mark.slow       # 13 s of CPF-EKF epochs in numpy: the default suite's 5 min (issue 56 compiles them)
def test_three_switches_of_the_pump_reset_the_cpf_ekf_at_p4s_times(shipped_flight):
    """P4's three resets (320, 780, 960 s): the pump's field on, off and on again, one reset
    after each, from the CPF (one run, the CPF-EKF alone: the numbers are the scenario's). The
    first comes 40-97 s after the switch at 230 s: at 326.5-327.3 s in most runs, at 279-281 s
    in about a fifth of them (a magnetometer sample accepted during the field's ramp makes the
    CPF a trusted reference early: 4 of 20 runs at the scenario's seed 6, run 0 among them; 3 of
    12 at seed 5); the other two fall on P4's times."""
    scenario, truth, _ = shipped_flight("p4_three_resets")
    scenario = dataclasses.replace(scenario, estimators=[e for e in scenario.estimators if e.label == "CPF-EKF"])
    res = run_monte_carlo(scenario, truth, None, RunOptions(runs=1, seed=scenario.seed, workers=1))
    (resets,) = res.histories["CPF-EKF"].resets
    assert [cause for _, cause in resets] == ["cpf"] * 3
    assert 230.0 + 40.0 <= resets[0][0] <= 230.0 + 97.0
    np.testing.assert_allclose([t for t, _ in resets[1:]], [780.0, 960.0], atol=20.0)


@pytest.mark.slow
def test_on_its_octocopter_a_cpf_without_the_gnss_course_resets_the_ekf_more_often(shipped_flight):
    """p4_octo_divergence: P4's vehicle circling with its nose on the centre, so the CPF has
    only the magnetometer for its heading. The EKF alone diverges as on the fixed-wing; the
    CPF-EKF is reset within a minute of the onset at 320 s (at 341-343 s in 100 runs, 21-23 s
    after it), but the CPF, coasting on its gyros once it rejects every magnetometer sample, is
    no steady reference: more than one reset a run (3.03 a run at 100 runs, docs/papers.md)
    where the fixed-wing, steered by its GNSS course, has one."""
    scenario, truth, _ = shipped_flight("p4_octo_divergence")
    res = run_monte_carlo(scenario, truth, None, RunOptions(runs=4, seed=scenario.seed, workers=1))
    ekf = res.histories["EKF alone"]
    assert np.all(np.degrees(np.abs(ekf.euler_err_rad[..., 2]))[:, ekf.t_s > 320].max(axis=1) > 10.0)
    resets = res.histories["CPF-EKF"].resets
    assert all(run and run[0][1] == "cpf" and 320.0 < run[0][0] < 380.0 for run in resets), resets
    assert np.mean([len(run) for run in resets]) > 1.5, resets
