"""Cost of P4's CPF-EKF cycle, batched over B runs, on one core (P4: 15 ms per cycle on an
STM32F429, one vehicle).

A cycle is one IMU sample (50 Hz): the quaternion Runge-Kutta step, velocity and position, the
complementary filter beside it; plus the filter epoch (covariance prediction of the 20 states,
three sequential magnetometer updates, the GNSS/baro linear update, the divergence test) every
``period_s`` (0.1 s: the magnetometer rate; ``--period 0.02`` runs it at every IMU sample as
P4's STM32 did).

    python benchmarks/attitude_speed.py [--runs 1 10 100 1000] [--seconds 60] [--period 0.1]
"""

import argparse
import os
import time

import numpy as np

from navsim.experiment.driver import Batch, InitialErrors, run_batch
from navsim.flight.truth import Pose, Truth
from navsim.navigation.estimators.attitude_config import imu_noise
from navsim.navigation.estimators.cpf_ekf import CpfEkf, CpfEkfConfig
from navsim.sensors.catalog import load_spec
from navsim.sensors.gnss import emulate_gnss
from navsim.sensors.imu import emulate_imu
from navsim.sensors.magnetometer import emulate_magnetometer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, nargs="+", default=[1, 10, 100, 1000])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--period", type=float, default=0.1)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    truth = Truth.static(args.seconds, 100.0, Pose(43.88, 125.35, 220.0, 63.0))
    spec = load_spec("mpu6050")
    noise, initial = imu_noise(spec)
    print(f"CPF-EKF (P4, 20 states + CPF), {args.seconds:g} s at rest, IMU 50 Hz, magnetometer 10 Hz, "
          f"GNSS 5 Hz, filter epoch every {args.period:g} s, one core:")
    print(f"{'B':>6} {'us/cycle/run':>13} {'us/cycle (batch)':>17} {'propagate us':>13} {'epoch us':>9}")
    for B in args.runs:
        runs = range(B)
        imu = emulate_imu(truth, spec, 1, runs, keep_rates=False)
        sensors = {"mag": emulate_magnetometer(truth, load_spec("lsm303d"), 1, runs, name="mag"),
                   "gps": emulate_gnss(truth, load_spec("neo_m8n"), 1, runs, name="gps")}
        est = CpfEkf(CpfEkfConfig(mag="mag", gnss="gps", period_s=args.period, noise=noise, initial=initial))
        init = InitialErrors(np.full(3, 2.0), np.full(3, 0.1), np.radians([1.0, 1.0, 2.0]))
        t0 = time.perf_counter()
        h = run_batch(truth, imu, sensors, {"ekf": est}, Batch(init, 1, runs))["ekf"]
        wall = time.perf_counter() - t0
        cycles = imu.values["dtheta_b_rad"].shape[1] - 1
        c = h.cost
        print(f"{B:>6} {wall / cycles / B * 1e6:>13.1f} {wall / cycles * 1e6:>17.0f} "
              f"{c['propagate_s'] / cycles * 1e6:>13.0f} {c['epoch_s'] / max(c['epochs'], 1) * 1e6:>9.0f}")
    print("P4: 15 ms per cycle for one vehicle on an STM32F429 (180 MHz Cortex-M4F).")


if __name__ == "__main__":
    main()
