"""Cost per run of P0's 16-state error-state Kalman filter on the 500 s p0 track, batched over
B runs (target <= 30 ms per run at B = 1000 on one core of the 2-core machine).

    python benchmarks/filter_speed.py [--runs 1000]
"""

import argparse
import os
import time

import numpy as np

from navsim.estimators.error_model import PRESETS, Layout
from navsim.estimators.eskf import ErrorStateKF
from navsim.estimators.measurements import GnssPosition, Height, Velocity
from navsim.flight import fly, load_track
from navsim.montecarlo import ARCSEC, InitialErrors, run_batch
from navsim.sensors import SensorConfig, emulate, load_spec
from navsim.sensors.imu import emulate_imu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--discretization", default="series", choices=("series", "van_loan"))
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    truth = fly(load_track("p0"))
    runs = range(args.runs)
    imu_spec = load_spec("p0_imu")
    t0 = time.perf_counter()
    imu = emulate_imu(truth, imu_spec, 1, runs, keep_rates=False)
    bd = emulate(truth, SensorConfig("bd", "p0_bd2", load_spec("p0_bd2")), 1, runs)
    ads = emulate(truth, SensorConfig("ads", "p0_ads", load_spec("p0_ads")), 1, runs)
    t_sensors = time.perf_counter() - t0
    kf = ErrorStateKF.from_imu_spec(
        Layout(PRESETS["p0_16"]), imu_spec,
        [GnssPosition("bd", np.full(3, 8.0)), Velocity("ads", np.full(3, 1.0)),
         Height("ads", 3.0, field="h_pressure_m", use_baro_state=True)],
        baro_sigma_m=3.0, baro_tau_s=600.0, discretization=args.discretization)
    init = InitialErrors(pos_m=np.array([5.0, 5.0, 10.0]), vel_mps=np.full(3, 0.1),
                         att_rad=np.array([20.0, 20.0, 50.0]) * ARCSEC)
    t0 = time.perf_counter()
    h = run_batch(truth, imu, {"bd": bd, "ads": ads}, {"kf": kf}, init, 1, runs)["kf"]
    wall = time.perf_counter() - t0
    print(f"16-state ES-KF (P0), p0 track 500 s, IMU 100 Hz, filter 1 Hz, B = {args.runs}:")
    print(f"  filter {wall:.1f} s -> {wall / args.runs * 1e3:.1f} ms per run (target <= 30 ms)")
    print(f"  sensors {t_sensors:.1f} s ({t_sensors / args.runs * 1e3:.1f} ms per run)")
    print(f"  final horizontal error RMS {np.sqrt((h.pos_err_m[:, -1, :2] ** 2).sum(-1).mean()):.2f} m, "
          f"diverged runs {int(h.diverged.sum())}")


if __name__ == "__main__":
    main()
