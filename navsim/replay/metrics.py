"""A replay scored: the estimator's roll, pitch and yaw against PX4's own estimate."""

from __future__ import annotations

import math

import numpy as np

from navsim.replay.run import ReplayResult
from navsim.scoring.metrics import EULER_AXES as AXES


def replay_metrics(result: ReplayResult) -> dict:
    """RMS, max and 95th percentile of |estimator - PX4| per axis (degrees) over the records
    after ``settle_s``; the alignment, the log's rates and notes, resets and the CPU cost."""
    r, log = result, result.log
    keep = (r.t_s >= r.settle_s) & np.all(np.isfinite(r.euler_px4_rad), axis=1)
    d = np.degrees(np.abs(r.diff_rad[keep]))
    diff = {ax: ({"rms": float(np.sqrt(np.mean(d[:, j] ** 2))), "max": float(d[:, j].max()),
                  "p95": float(np.percentile(d[:, j], 95))} if len(d) else None)
            for j, ax in enumerate(AXES)}
    c = r.cost
    a = r.alignment
    return {
        "log": {"file": str(log.path), "duration_s": log.duration_s, **log.info,
                "imu_rate_hz": log.imu_rate_hz, "mag_rate_hz": log.mag_rate_hz,
                "baro_rate_hz": log.baro_rate_hz, "px4_attitude_rate_hz":
                float((len(log.att_t_s) - 1) / np.ptp(log.att_t_s)),
                "declination_deg": math.degrees(log.declination_rad),
                "declination_source": log.declination_source,
                "imu_gaps": [{"t_s": t, "duration_s": g} for t, g in log.gaps], "notes": list(log.notes)},
        "estimator": r.estimator,
        "params": {k: v for k, v in r.params.items()},
        "imu_grid_hz": r.imu_rate_hz, "period_s": r.period_s, "sensors": r.sensors,
        "alignment": {"window_s": a.window_s, "euler_deg": np.degrees(a.euler_rad).tolist(),
                      "px4_euler_deg": np.degrees(r.euler_px4_rad[0]).tolist(),
                      "field_n_T": a.field_n_T.tolist(), "gyro_max_rps": a.gyro_max_rps, "still": a.still},
        "settle_s": r.settle_s, "samples_scored": int(keep.sum()),
        "record_s": float(np.median(np.diff(r.t_s))) if len(r.t_s) > 1 else None,
        "attitude_diff_deg": diff,
        "resets": [{"t_s": t, "cause": cause} for t, cause in r.resets],
        "cost": {"us_per_imu_step_propagated": 1e6 * c["propagate_s"] / max(c["steps"], 1),
                 "us_per_epoch": 1e6 * c["epoch_s"] / max(c["epochs"], 1),
                 "us_per_imu_cycle": 1e6 * (c["propagate_s"] + c["epoch_s"]) / max(c["steps"], 1),
                 "real_time_factor": log.duration_s / max(c["propagate_s"] + c["epoch_s"], 1e-9)},
    }
