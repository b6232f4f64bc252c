"""The replay's scores as typed objects (:class:`navsim.replay.metrics.ReplayMetrics`): the
mapping of ``metrics.json`` keeps its keys and their order, and reads back to the same object."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from navsim.foundations.outputs import strict_json
from navsim.replay.metrics import AttitudeDiff, AxisDiff, ReplayMetrics, ResetEvent, replay_metrics
from navsim.replay.run import Alignment, ReplayResult
from navsim.replay.ulog import ReplayLog
from navsim.report.replay import difference_table

#: the keys of a replay's metrics.json, in their order (``wall_s`` and ``provenance`` follow,
#: set by ``navsim replay``)
TOP_KEYS = ["log", "estimator", "params", "imu_grid_hz", "period_s", "sensors", "alignment", "settle_s",
            "samples_scored", "record_s", "attitude_diff_deg", "resets", "cost"]
LOG_KEYS = ["file", "duration_s", "sys_name", "ver_hw", "ver_sw", "SYS_MC_EST_GROUP", "imu_rate_hz",
            "mag_rate_hz", "baro_rate_hz", "px4_attitude_rate_hz", "declination_deg", "declination_source",
            "imu_gaps", "notes"]
ALIGNMENT_KEYS = ["window_s", "euler_deg", "px4_euler_deg", "field_n_T", "gyro_max_rps", "still"]
COST_KEYS = ["us_per_imu_step_propagated", "us_per_epoch", "us_per_imu_cycle", "real_time_factor"]


def _result(settle_s=10.0, records=41) -> ReplayResult:
    """A 20 s replay recorded every 0.5 s: the estimator 1, 2, 3 deg off PX4 in roll, pitch,
    yaw; PX4's last record missing (NaN); one reset."""
    imu_t = np.arange(0.0, 20.0 + 1e-9, 0.004)
    att_t = np.arange(0.0, 20.0 + 1e-9, 0.01)
    log = ReplayLog(Path("flight.ulg"), 0, imu_t, np.zeros((imu_t.size, 3)), np.zeros((imu_t.size, 3)),
                    att_t[::2], np.zeros((att_t[::2].size, 3)), np.array([]), np.array([]), att_t,
                    np.tile([1.0, 0.0, 0.0, 0.0], (att_t.size, 1)), declination_rad=np.radians(4.0),
                    declination_source="EKF2_MAG_DECL", gaps=[(5.0, 0.05)], notes=["a note"],
                    info={"sys_name": "PX4", "ver_hw": "FMU", "ver_sw": "abc", "SYS_MC_EST_GROUP": None})
    t = np.linspace(0.0, 20.0, records)
    px4 = np.zeros((records, 3))
    px4[-1] = np.nan
    align = Alignment(np.radians([1.0, -2.0, 90.0]), np.array([2e-5, 1e-6, 4e-5]), 2.0, 0.01, True)
    return ReplayResult(log, "cpf_ekf", {"gain": 1.0}, align, 250.0, 0.02, t, np.tile(np.radians([1.0, -2.0, 3.0]), (records, 1)),
                        px4, settle_s, [(12.5, "nis")], {"propagate_s": 2.0, "epoch_s": 1.0, "steps": 5000, "epochs": 1000},
                        {"mag": {"samples": 1000, "rate_hz": 50.0}})


def test_the_typed_metrics_give_the_mapping_of_metrics_json():
    m = replay_metrics(_result())
    assert isinstance(m, ReplayMetrics)
    d = m.to_dict()
    assert list(d) == TOP_KEYS
    assert list(d["log"]) == LOG_KEYS and d["log"]["SYS_MC_EST_GROUP"] is None
    assert d["log"]["imu_gaps"] == [{"t_s": 5.0, "duration_s": 0.05}] and d["log"]["notes"] == ["a note"]
    assert d["log"]["declination_deg"] == pytest.approx(4.0) and d["log"]["px4_attitude_rate_hz"] == pytest.approx(100.0)
    assert list(d["alignment"]) == ALIGNMENT_KEYS and list(d["cost"]) == COST_KEYS
    assert d["sensors"] == {"mag": {"samples": 1000, "rate_hz": 50.0}}
    assert d["samples_scored"] == 20 and d["record_s"] == 0.5           # 10 s on, PX4's last one left out
    assert list(d["attitude_diff_deg"]) == ["roll", "pitch", "yaw"]
    for ax, deg in zip(("roll", "pitch", "yaw"), (1.0, 2.0, 3.0)):
        assert list(d["attitude_diff_deg"][ax]) == ["rms", "max", "p95"]
        assert d["attitude_diff_deg"][ax] == pytest.approx({"rms": deg, "max": deg, "p95": deg})
    assert d["resets"] == [{"t_s": 12.5, "cause": "nis"}]
    assert d["cost"] == pytest.approx({"us_per_imu_step_propagated": 400.0, "us_per_epoch": 1000.0,
                                       "us_per_imu_cycle": 600.0, "real_time_factor": 20.0 / 3.0}, rel=1e-3)
    assert m.attitude_diff_deg.axis("pitch") == m.attitude_diff_deg.pitch and m.resets == [ResetEvent(12.5, "nis")]
    assert difference_table(m)[1][2] == ["yaw", "3.000", "3.000", "3.000"]


def test_the_typed_metrics_read_back_from_their_json():
    """Through strict JSON and back: the same object, the same text; ``wall_s`` and
    ``provenance`` last where set, left out where not."""
    m = dataclasses.replace(replay_metrics(_result()), wall_s=1.5, provenance={"git_revision": "x"})
    text = strict_json(m.to_dict())
    back = ReplayMetrics.from_dict(json.loads(text))
    assert back == m and strict_json(back.to_dict()) == text
    assert list(json.loads(text)) == TOP_KEYS + ["wall_s", "provenance"]
    assert back.log.info == {"sys_name": "PX4", "ver_hw": "FMU", "ver_sw": "abc", "SYS_MC_EST_GROUP": None}
    assert isinstance(back.attitude_diff_deg.roll, AxisDiff) and isinstance(back.resets[0], ResetEvent)


def test_nothing_scored_keeps_its_nulls():
    """No record after ``settle_s`` and a single record: each axis and ``record_s`` are null
    in the mapping (not left out), None when read back; the table shows dashes."""
    m = replay_metrics(_result(settle_s=30.0, records=1))
    d = m.to_dict()
    assert d["attitude_diff_deg"] == {"roll": None, "pitch": None, "yaw": None} and d["record_s"] is None
    assert d["samples_scored"] == 0
    back = ReplayMetrics.from_dict(json.loads(strict_json(d)))    # PX4's only record NaN: null
    assert strict_json(back.to_dict()) == strict_json(d) and back.attitude_diff_deg == AttitudeDiff(None, None, None) and back.record_s is None
    assert difference_table(back)[1][0] == ["roll", "-", "-", "-"]
