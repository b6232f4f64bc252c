"""The out-of-tree plug-in ``examples/ukf_plugin`` (an error-state unscented Kalman filter),
installed as its own package (``.ci/run`` installs it): found through its entry point, run on
P3's experiment beside the built-in ES-KF on the same registered measurement models, its
configuration errors in navsim's format."""

import copy
import json
import os

import numpy as np
import pytest
import yaml

import navsim
from navsim.cli import main
from navsim.navigation.estimators import available, get

pytestmark = pytest.mark.plugin      # .ci/run runs these with the plug-in installed


@pytest.fixture(scope="module")
def plugin():
    """The plug-in module; skipped where it is not installed, except in CI
    (``NAVSIM_REQUIRE_PLUGIN=1``), where that fails."""
    try:
        import navsim_ukf
    except ImportError:
        if os.environ.get("NAVSIM_REQUIRE_PLUGIN") == "1":
            pytest.fail("NAVSIM_REQUIRE_PLUGIN=1 but examples/ukf_plugin is not installed")
        pytest.skip("the plug-in tests need pip install -e examples/ukf_plugin")
    return navsim_ukf


def p3_with_ukf(repo_root) -> dict:
    """P3's scenario with the UKF beside its ES-KF, on the same keys and measurement models."""
    data = yaml.safe_load((repo_root / "scenarios" / "p3_sins_gps.yaml").read_text())
    kf = next(e for e in data["estimators"] if e["type"] == "eskf")
    data["estimators"] = [kf, {**copy.deepcopy(kf), "label": "SINS/GPS UKF", "type": "eskf_ukf"}]
    data.pop("reference", None)
    return data


def test_the_plugin_is_found_through_its_entry_point(plugin, capsys):
    assert "eskf_ukf" in available() and get("eskf_ukf") is plugin.ErrorStateUKF
    assert main(["list"]) == 0
    listed = capsys.readouterr().out.split("estimators (type:):\n")[1].splitlines()
    assert any(line.split()[:2] == ["eskf_ukf", "plug-in"] for line in listed)
    # the unscented weights: the mean of the sigma points is x, their covariance P, exactly
    rng = np.random.default_rng(2)
    A = rng.normal(size=(3, 5, 5))
    P, x = A @ np.swapaxes(A, 1, 2) + np.eye(5), rng.normal(size=(3, 5))
    lam, wm, wc = plugin.weights(5, 0.5, 2.0, 1.0)
    X = plugin.sigma_points(x, P, 5 + lam)
    mean = np.einsum("s,sbn->bn", wm, X)
    cov = np.einsum("s,sbn,sbm->bnm", wm, X - mean, X - mean)
    np.testing.assert_allclose(mean, x, atol=1e-12)
    np.testing.assert_allclose(cov, P, rtol=1e-10)
    # the covariance weights: the centre point's carries 1 - alpha^2 + beta more (Gaussian prior)
    assert wc[0] == pytest.approx(wm[0] + 1 - 0.25 + 2.0) and np.array_equal(wc[1:], wm[1:])
    assert sum(wm) == pytest.approx(1.0)
    # a run whose innovation covariance is singular gets NaN alone
    S = np.stack([np.eye(2), np.zeros((2, 2)), 2 * np.eye(2)])
    out = plugin.solve(S, np.ones((3, 2, 1)))
    assert np.isnan(out[1]).all() and np.allclose(out[0], 1.0) and np.allclose(out[2], 0.5)


def test_the_ukf_on_p3_beside_the_eskf(plugin, repo_root):
    """10 runs of P3 (3000 s, GPS 1 Hz): the UKF's position RMS within 10 % of the ES-KF's on
    every axis, its NEES average inside the chi-square band of the 10 runs."""
    result = navsim.run(p3_with_ukf(repo_root), runs=10, seed=3, workers=2)
    kf, ukf = (result.metrics.estimators[k] for k in ("SINS/GPS 15-state", "SINS/GPS UKF"))
    assert ukf.diverged_runs == 0 and kf.diverged_runs == 0
    rms_kf, rms_ukf = np.array(kf.rms.pos_m), np.array(ukf.rms.pos_m)
    assert np.all(np.abs(rms_ukf - rms_kf) <= 0.10 * rms_kf), (rms_kf, rms_ukf)
    lo, hi = ukf.nees.band
    assert lo < ukf.nees.average < hi, (ukf.nees, kf.nees)
    assert set(ukf.nis) == set(kf.nis) == {"gnss_position:gps", "velocity:gps"}
    # its own update, not the ES-KF's, and GNSS position and velocity nearly linear in the
    # errors: the two solutions differ, by micrometres (measured: 6 um at most, 2026-12-06)
    d = np.abs(result.histories["SINS/GPS UKF"].pos_err_m - result.histories["SINS/GPS 15-state"].pos_err_m)
    assert 0.0 < np.nanmax(d) < 1e-3


@pytest.mark.parametrize("change, key, words", [
    (lambda e: e.update(unscented={"alpha": -1}), "estimators[1].unscented.alpha", "expected a value > 0.0"),
    (lambda e: e.update(unscented={"alpa": 1}), "estimators[1].unscented.alpa", "did you mean 'alpha'"),
    (lambda e: e["measurements"][0].update(sensor="gsp"), "estimators[1].measurements[0].sensor",
     "did you mean 'gps'"),
])
def test_the_plugins_config_errors_read_as_navsims(plugin, repo_root, tmp_path, capsys, change, key, words):
    data = p3_with_ukf(repo_root)
    change(data["estimators"][1])
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: {key}:" in err and words in err and "Traceback" not in err, err


def test_the_ukf_replays_a_px4_log(plugin, repo_root, tmp_path):
    """``navsim replay --estimator eskf_ukf`` on the shipped PX4 log, which has no GNSS and no
    barometer: the replay gives the ES-KF family its measurements for such a log (the velocity
    held near zero, which levels, and the heading of PX4's calibrated magnetometer against the
    aligned field), and the UKF follows PX4's EKF2 as the built-in ES-KF does, at a tenth of the
    free strapdown's difference or less."""
    log = str(repo_root / "tests" / "data" / "px4_quad_real_69s.ulg.gz")
    common = ["--set", "noise={imu: mpu6050}", "--set", "period_s=0.1"]
    for name in ("eskf_ukf", "eskf"):
        assert main(["replay", log, "--estimator", name, "--out", str(tmp_path / name), *common]) == 0
    assert main(["replay", log, "--estimator", "sins", "--out", str(tmp_path / "sins")]) == 0
    ukf, eskf, sins = (json.loads((tmp_path / k / "metrics.json").read_text()) for k in ("eskf_ukf", "eskf", "sins"))
    assert ukf["params"]["latest_sample"] is True             # the log's sensors are not on its epochs
    assert [m["type"] for m in ukf["params"]["measurements"]] == ["zero_velocity", "mag_heading"]
    for axis, bound in (("roll", 0.1), ("pitch", 0.1), ("yaw", 0.5)):
        rms = ukf["attitude_diff_deg"][axis]["rms"]
        assert rms < bound and rms < 0.1 * sins["attitude_diff_deg"][axis]["rms"], (axis, rms)
        assert abs(rms - eskf["attitude_diff_deg"][axis]["rms"]) < 0.01, axis