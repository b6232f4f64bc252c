"""Free-inertial strapdown of B runs on one core: the numpy reference ``Strapdown`` of the tests
(``tests/reference_strapdown.py``, one call per IMU sample; navsim's own until issue 18) against the compiled :class:`~navsim.navigation.strapdown.BlockStrapdown` (one
call per block of samples), and the kernel's compile time (first call, cold and cached).

    python benchmarks/strapdown_speed.py [--runs 250] [--seconds 50] [--block 100]
"""

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from navsim.flight import fly, load_track
from navsim.navigation.strapdown import BlockStrapdown, state_from_truth
from navsim.sensors.catalog import load_spec
from navsim.sensors.imu import emulate_imu

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference_strapdown import Strapdown  # noqa: E402

FIRST_CALL = ("import time, numpy as np; t = time.perf_counter(); from navsim.navigation.strapdown import BlockStrapdown, "
              "NavState; s = NavState(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros((1, 3)), "
              "np.eye(3)[None].copy()); BlockStrapdown(s).block(np.zeros((1, 2, 3)), np.zeros((1, 2, 3)), 0.01); "
              "print(time.perf_counter() - t)")


def first_call_s(env: dict) -> float:
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=250)
    parser.add_argument("--seconds", type=float, default=50.0, help="stretch of the p0 track integrated")
    parser.add_argument("--block", type=int, default=100, help="IMU samples per compiled call")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(os.environ.get("TMPDIR", "/tmp"), "navsim-bench-numba"))
    subprocess.run(["rm", "-rf", env["NUMBA_CACHE_DIR"]], check=True)
    cold, warm = first_call_s(env), first_call_s(env)
    truth = fly(load_track("p0"))
    imu = emulate_imu(truth, load_spec("p0_imu"), 1, range(args.runs), keep_rates=False)
    dt = imu.meta["dt_s"]
    n = int(args.seconds / dt) + 1
    dth, dv = imu.values["dtheta_b_rad"][:, :n], imu.values["dv_b_mps"][:, :n]

    sd = Strapdown(state_from_truth(truth, 0, args.runs))
    t0 = time.perf_counter()
    for i in range(1, n):
        sd.step(dth[:, i], dv[:, i], dt)
    t_numpy = time.perf_counter() - t0

    bs = BlockStrapdown(state_from_truth(truth, 0, args.runs))
    bs.block(dth[:, 1:2], dv[:, 1:2], dt)            # compiled (or loaded from the cache) here
    bs = BlockStrapdown(state_from_truth(truth, 0, args.runs))
    t0 = time.perf_counter()
    for a in range(1, n, args.block):
        bs.block(dth[:, a:a + args.block], dv[:, a:a + args.block], dt)
    t_kernel = time.perf_counter() - t0
    diff = np.abs(bs.state.vel_n_mps - sd.state.vel_n_mps).max()

    per = lambda t: t / args.runs / ((n - 1) * dt) * 500.0 * 1e3
    print(f"B = {args.runs} runs, {n - 1} IMU intervals ({(n - 1) * dt:.0f} s of the p0 track), one core")
    print(f"numpy Strapdown.step      : {t_numpy:8.3f} s = {per(t_numpy):8.2f} ms per run per 500 s")
    print(f"BlockStrapdown ({args.block:3d}/call) : {t_kernel:8.3f} s = {per(t_kernel):8.2f} ms per run per 500 s "
          f"(x{t_numpy / t_kernel:.0f})")
    print(f"largest velocity difference: {diff:.2e} m/s")
    print(f"first call in a fresh process: {cold:.2f} s compiling, {warm:.2f} s from numba's cache")


if __name__ == "__main__":
    main()
