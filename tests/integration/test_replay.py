"""``navsim replay`` on the shipped real PX4 log (tests/data/px4_quad_real_69s.ulg.gz): loading,
alignment, an end-to-end free-inertial replay, the estimator interface, the errors."""

import contextlib
import gzip
import json
import math

import numpy as np
import pytest

from navsim.cli import main
from navsim.navigation.estimators import base
from navsim.navigation.estimators.sins import FreeInertial
from navsim.replay.run import ReplayOptions, build_estimator, coarse_alignment, px4_euler_at, replay
from navsim.replay.ulog import load_ulog


@pytest.fixture(scope="module")
def log_path(repo_root):
    return repo_root / "tests" / "data" / "px4_quad_real_69s.ulg.gz"


@pytest.fixture(scope="module")
def log(log_path):
    return load_ulog(log_path)


def test_shipped_log_rates_and_units(log):
    assert 68.5 < log.duration_s < 69.5
    assert abs(log.imu_rate_hz - 250.0) < 1.0
    assert 90 < log.mag_rate_hz < 105
    assert 90 < (len(log.att_t_s) - 1) / np.ptp(log.att_t_s) < 98
    rest = log.imu_t_s > 10.0                      # the vehicle is still after 8 s
    g = np.linalg.norm(log.f_ib_b_mps2[rest], axis=1)
    assert 9.6 < g.mean() < 9.9 and g.std() < 0.05  # m/s^2: gravity, accelerometer in SI
    assert np.all(np.abs(log.omega_ib_b_rps[rest]) < 0.02)   # rad/s: at rest, bias ~2e-3
    m = np.linalg.norm(log.mag_b_T, axis=1)
    assert np.all((m > 2e-5) & (m < 6e-5))         # 0.45-0.51 gauss in tesla
    # the board had no barometer: PX4 logged its baro as invalid, the replay goes without
    assert len(log.baro_t_s) == 0 and any("no barometer" in n for n in log.notes)
    assert log.declination_source == "ATT_MAG_DECL" and log.declination_rad == 0.0
    assert log.lat_rad is None                     # no GNSS, no global position
    assert [round(d * 1e3) for _, d in log.gaps if d > 0.06] == [65]   # the 62 ms logger dropout
    np.testing.assert_allclose(np.linalg.norm(log.quat_nb_px4, axis=1), 1.0, atol=1e-12)


def test_coarse_alignment_agrees_with_px4_first_attitude(log):
    """PX4's attitude_estimator_q started from the same accelerometer and magnetometer: within
    0.3° in roll and pitch (accelerometer noise averaged over 1 s, 0.02 m/s^2, is 0.1°) and 1°
    in yaw (measured: 0.01°, 0.11°, 0.02°)."""
    a = coarse_alignment(log, 1.0)
    px4 = px4_euler_at(log, np.array([0.0]))[0]
    d = np.degrees(a.euler_rad - px4)
    assert abs(d[0]) < 0.3 and abs(d[1]) < 0.3 and abs(d[2]) < 1.0, d
    assert a.still
    # the field measured in the window: 0.48 gauss, dip 63.5° (a northern mid-latitude)
    assert 4.5e-5 < np.linalg.norm(a.field_n_T) < 5.1e-5
    assert 60 < math.degrees(math.atan2(a.field_n_T[2], a.field_n_T[0])) < 67
    assert a.field_n_T[1] == 0.0                   # declination 0


def test_cli_replay_writes_metrics_plot_and_report(log_path, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["replay", str(log_path), "--estimator", "sins", "--out", str(out)]) == 0
    for name in ("metrics.json", "attitude.png", "replay.pdf"):
        assert (out / name).stat().st_size > 10_000 or name == "metrics.json", name
    m = json.loads((out / "metrics.json").read_text())
    assert m["estimator"] == "sins" and m["settle_s"] == 10.0 and m["imu_grid_hz"] == 250.0
    assert m["provenance"]["git_revision"] and "pyulog" in m["provenance"]["versions"]
    assert m["resets"] == [] and m["cost"]["us_per_imu_cycle"] > 0
    text = capsys.readouterr()
    assert "roll" in text.out and "wrote" in text.out and "warning: no barometer" in text.err


def test_free_inertial_attitude_difference_is_the_integrated_gyro_bias(log):
    """At rest (after 8 s) PX4's attitude holds still and free inertial turns at the gyro bias,
    so their difference must change by ``b (t - 10)``: b is measured as the mean rate over the
    rest, 0.073°/s in roll and 0.122°/s in pitch. Allowed: 10 % (the bias drifts as the sensor
    warms up) and 0.3° (Earth rate, 0.004°/s, at the log's unknown latitude)."""
    r = replay(log, "sins", options=ReplayOptions(imu_rate_hz=125.0))
    rest = log.imu_t_s > 10.0
    bias_dps = np.degrees(log.omega_ib_b_rps[rest].mean(axis=0))
    d = np.degrees(r.diff_rad)
    k10 = np.searchsorted(r.t_s, 10.0)
    span = r.t_s[-1] - r.t_s[k10]
    for j, name in ((0, "roll"), (1, "pitch")):
        predicted = bias_dps[j] * span
        change = d[-1, j] - d[k10, j]
        assert abs(change - predicted) < 0.1 * abs(predicted) + 0.3, (name, change, predicted)
    assert abs(d[k10, 0]) < 1.5 and abs(d[k10, 1]) < 2.0     # 10 s of bias plus the handling


class _AttitudeProbe:
    """Free inertial with an attitude estimator's constructor and no ``parse`` (a plain-keyword
    third-party estimator): records what the replay gives."""

    seen: dict = {}

    def __init__(self, mag="mag", baro="baro", gnss=None, field_n_T=None, period_s=0.1):
        self.inner, self.period_s = FreeInertial(period_s), period_s
        type(self).seen.update(mag=mag, baro=baro, gnss=gnss, field_n_T=field_n_T, epochs=0, mag_hits=0)

    def initialize(self, nav0, sigma0):
        self.inner.initialize(nav0, sigma0)

    def propagate(self, dtheta_b, dv_b, dt):
        self.inner.propagate(dtheta_b, dv_b, dt)

    def epoch(self, t, sensors):
        data = sensors[self.seen["mag"]]
        j = int(np.searchsorted(data.t_s, t - 1e-6))
        self.seen["epochs"] += 1
        self.seen["mag_hits"] += int(j < len(data.t_s) and abs(data.t_s[j] - t) <= 1e-6)
        assert data.kind == "magnetometer" and data.values["mag_b_T"].shape == (1, len(data.t_s), 3)
        return []

    def solution(self):
        sol = self.inner.solution()
        sol.extra["resets"] = [[(20.0, "probe reset")]]
        return sol


def test_attitude_estimator_gets_sensor_names_field_and_resets(log_path, tmp_path, monkeypatch):
    monkeypatch.setitem(base._REGISTRY, "probe", _AttitudeProbe)
    out = tmp_path / "probe"
    assert main(["replay", str(log_path), "--estimator", "probe", "--out", str(out),
                 "--imu-rate", "50", "--set", "period_s=0.02"]) == 0
    seen = _AttitudeProbe.seen
    assert seen["mag"] == "mag" and seen["baro"] is None and seen["gnss"] is None
    assert 4.5e-5 < np.linalg.norm(seen["field_n_T"]) < 5.1e-5
    # a 98 Hz magnetometer on a 50 Hz grid: a sample at (nearly) every 50 Hz epoch
    assert seen["mag_hits"] > 0.95 * seen["epochs"] > 3000
    m = json.loads((out / "metrics.json").read_text())
    assert m["resets"] == [{"t_s": 20.0, "cause": "probe reset"}]
    assert m["params"]["period_s"] == 0.02 and m["period_s"] == pytest.approx(0.02)


@pytest.mark.parametrize("make, args, words", [
    (None, [], ["nowhere.ulg", "no such file"]),
    ("truncate", [], ["is truncated", "last message", "--allow-damaged"]),
    ("truncate5", ["--allow-damaged"], ["holds 2.86 s of IMU data", "needs 5 s"]),
    ("garbage", [], ["not a ULog"]),
    ("corrupt", [], ["is corrupt"]),
])
def test_unreplayable_logs_exit_2_naming_the_problem(log_path, tmp_path, capsys, make, args, words):
    raw = gzip.decompress(log_path.read_bytes())          # the shipped log is gzip-compressed
    path = tmp_path / "nowhere.ulg"
    if make == "truncate":
        path.write_bytes(raw[: int(0.3 * len(raw))])
    elif make == "truncate5":
        path.write_bytes(raw[: int(0.05 * len(raw))])
    elif make == "garbage":
        path.write_bytes(b"not a log at all" * 100)
    elif make == "corrupt":
        b = bytearray(raw)
        b[len(b) // 2: len(b) // 2 + 5000] = b"\xff" * 5000
        path.write_bytes(bytes(b))
    code = main(["replay", str(path), "--estimator", "sins", "--out", str(tmp_path / "o")] + args)
    err = capsys.readouterr().err
    assert code == 2, err
    for w in words:
        assert w in err, (w, err)
    assert "Traceback" not in err and not (tmp_path / "o" / "metrics.json").exists()


def test_missing_topic_exits_2_without_traceback(log_path, tmp_path, monkeypatch, capsys):
    import navsim.replay.ulog as rp
    real = rp.topics_of
    monkeypatch.setattr(rp, "topics_of", lambda u: {k: v for k, v in real(u).items() if k != "vehicle_attitude"})
    assert main(["replay", str(log_path), "--estimator", "sins", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "has no 'vehicle_attitude' messages" in err and "sensor_combined" in err


def test_cli_usage_errors_exit_2(log_path, tmp_path, capsys):
    assert main(["replay", str(log_path), "--estimator", "nonesuch", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no estimator 'nonesuch'" in err and "sins" in err and "Traceback" not in err
    assert main(["replay", str(log_path), "--estimator", "sins", "--set", "gain=1",
                 "--out", str(tmp_path)]) == 2
    with pytest.raises(SystemExit) as done:
        main(["replay", "--help"])
    assert done.value.code == 0 and "--settle" in (out := capsys.readouterr().out) and "--set" in out


@pytest.mark.parametrize("estimator, bounds", [("cpf_ekf", (2.0, 2.0, 5.0)), ("cpf", (2.0, 2.0, 5.0))])
def test_p4_attitude_estimators_follow_px4_on_the_real_log(log, estimator, bounds):
    """The issue's acceptance: RMS difference from PX4's attitude under 2 deg in roll and pitch,
    5 deg in yaw, after the 10 s settling (measured: cpf_ekf 0.91/1.14/0.55 deg -- slower to
    re-level after the hand tilting than PX4's complementary filter, as it levels on a zero
    horizontal velocity of 1 m/s sigma without GNSS; cpf 0.02/0.03/0.45 deg). No reset."""
    from navsim.replay.metrics import replay_metrics
    m = replay_metrics(replay(log, estimator, options=ReplayOptions(imu_rate_hz=125.0)))
    rms = [m.attitude_diff_deg.axis(ax).rms for ax in ("roll", "pitch", "yaw")]
    assert np.all(np.array(rms) < bounds), rms
    assert m.resets == []


def test_the_replay_defaults_go_where_the_estimator_reads_them():
    """An estimator that reads its entry gets the replay's defaults it names, with the type it
    expects: ``baro`` is the CPF-EKF's barometer's name but the ES-KF's baro model, a mapping."""
    defaults = {"mag": "mag", "baro": "baro", "gnss": None, "field_uT": [21.4, 0.0, 43.0],
                "sigma": {"no_gnss_mps": 1.0}, "latest_sample": True}
    kinds = {"mag": "magnetometer", "baro": "baro"}
    kf, entry = build_estimator("eskf", {"noise": {"imu": "mpu6050"}, "measurements": [
        {"type": "height", "sensor": "baro", "sigma_m": 2.0}]}, defaults, kinds)
    assert "baro" not in entry and entry["latest_sample"] is True and kf.latest_sample
    ekf, entry = build_estimator("cpf_ekf", {"sigma": {"mag_uT": 1.0}}, defaults, kinds)
    assert ekf.baro == "baro" and ekf.no_gnss_sigma_mps == 1.0 and ekf.mag_sigma_uT == 1.0   # the mapping completed
    assert np.allclose(ekf.field_n_T, [21.4e-6, 0.0, 43.0e-6])


@pytest.mark.parametrize("args, words", [
    (["--settle", "1e308"], ["--settle", "1e+308 s", "end of the log (68.9 s)"]),
    (["--settle", "70"], ["--settle", "70 s"]),
    (["--align", "100"], ["--align", "100 s", "end of the log"]),
    (["--imu-rate", "0.001"], ["--imu-rate", "below 10"]),
])
def test_replay_windows_and_rates_outside_the_log_exit_2(log_path, tmp_path, capsys, args, words):
    """A settling time or an alignment window that does not end inside the 68.9 s log, or an
    IMU grid too coarse to integrate, is refused before anything runs (today: exit 0 with
    nothing scored, or a traceback for the rate); the folder is left as it was (not created)."""
    out = tmp_path / "o"
    with pytest.raises(SystemExit) if args[0] == "--imu-rate" else contextlib.nullcontext() as stop:
        code = main(["replay", str(log_path), "--estimator", "sins", "--out", str(out)] + args)
    code = stop.value.code if args[0] == "--imu-rate" else code
    err = capsys.readouterr().err
    assert code == 2, err
    assert all(w in err for w in words), err
    assert "Traceback" not in err and not out.exists()
