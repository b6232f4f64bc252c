"""Cost per run of P0's scenario (``scenarios/p0_bd_sins_ads.yaml``) on one core, batched over B
runs: its sensors (the IMU generated block by block as in a chunk, and whole), its 16-state
ES-KF and its free SINS, each timed on its own over the 500 s p0 track (on the IMU blocks as a
chunk hands them over, contiguous, cut before the timing: :class:`ChunkBlocks`), and the peak
resident memory of a worker running one chunk of B runs (sensors, both estimators, records) in
a fresh process. Targets (issue 36, B = 250): ES-KF <= 6 ms per run, free SINS <= 2 ms,
sensors <= 3 ms; a chunk worker <= 400 MB (issue 56: the 300 MB goal retired).

    python benchmarks/filter_speed.py [--runs 250]

The first call of a compiled kernel in a process compiles it or loads it from navsim's cache;
one short warm-up batch runs first, so the figures are those of a worker in steady state.
"""

import argparse
import os
import resource
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from navsim.experiment.driver import Batch, run_batch
from navsim.experiment.runner import _chunk_work, cached_flight
from navsim.experiment.scenario import load_scenario
from navsim.navigation.estimators.factory import build
from navsim.sensors import emulate
from navsim.sensors.imu import ImuStream, emulate_imu

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "p0_bd_sins_ads.yaml"


def sensors(truth, scenario, runs):
    """The IMU whole (for the estimators' timing) and the other sensors."""
    imu_cfg = next(c for c in scenario.sensors if c.kind == "imu")
    imu = emulate_imu(truth, imu_cfg.spec, scenario.seed, runs, name=imu_cfg.name, keep_rates=False)
    return imu, {c.name: emulate(truth, c, scenario.seed, runs) for c in scenario.sensors if c.kind != "imu"}


def streamed_sensors(truth, scenario, runs, every: int = 100):
    """The sensors as a chunk emulates them: the IMU generated a block of ``every`` samples at
    a time (:class:`~navsim.sensors.imu.ImuStream`, blocks dropped), the others whole."""
    imu_cfg = next(c for c in scenario.sensors if c.kind == "imu")
    stream = ImuStream(truth, imu_cfg.spec, scenario.seed, runs, name=imu_cfg.name)
    for i in range(1, stream.n, every):
        stream.block(i, min(i + every, stream.n))
    return {c.name: emulate(truth, c, scenario.seed, runs) for c in scenario.sensors if c.kind != "imu"}


class ChunkBlocks:
    """The IMU record ``imu`` handed to the estimators as a chunk's stream hands it: one
    contiguous ``(B, K, 3)`` block per request (a view of a whole record puts each run's block
    megabytes apart, and the strapdown would copy it first). The blocks are cut by a first,
    untimed pass; ``block`` then returns them as they are."""

    def __init__(self, imu):
        self.t_s, self.meta, self.values = imu.t_s, imu.meta, imu.values
        self.cut = {}

    def block(self, a: int, b: int):
        if (a, b) not in self.cut:
            self.cut[a, b] = tuple(np.ascontiguousarray(self.values[k][:, a:b]) for k in ("dtheta_b_rad", "dv_b_mps"))
        return self.cut[a, b], None


def timed(f, *a):
    t0 = time.perf_counter()
    out = f(*a)
    return time.perf_counter() - t0, out


def chunk_peak_mb(path: str, runs: int) -> float:
    """Peak resident memory (MB) of a fresh process that runs one chunk of ``runs`` runs."""
    scenario = load_scenario(SCENARIO)
    _chunk_work(path, scenario, scenario.seed, range(runs))
    try:      # this process's own high-water mark (ru_maxrss may be the forking parent's)
        status = Path("/proc/self/status").read_text()
        return next(int(line.split()[1]) for line in status.splitlines() if line.startswith("VmHWM")) / 1024.0
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=250, help="batch size B (default 250)")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    scenario = load_scenario(SCENARIO)
    truth, path, _ = cached_flight(scenario.flight)
    B = args.runs
    per = lambda s: s / B * 1e3
    warm = truth.slice(0, 2001)
    imu, others = sensors(warm, scenario, range(2))
    streamed_sensors(warm, scenario, range(2))
    for e in scenario.estimators:
        run_batch(warm, imu, others, {e.label: build(e)}, Batch(scenario.initial, scenario.seed, range(2)))
    t_sensors, _ = timed(streamed_sensors, truth, scenario, range(B))
    t_whole, (imu, others) = timed(sensors, truth, scenario, range(B))
    print(f"P0 ({SCENARIO.name}), p0 track {truth.t_s[-1]:.0f} s, IMU 100 Hz, B = {B}, one core:")
    print(f"  sensors, IMU streamed     {t_sensors:6.2f} s = {per(t_sensors):6.1f} ms per run (target <= 3)")
    print(f"  sensors, IMU whole        {t_whole:6.2f} s = {per(t_whole):6.1f} ms per run ((B, n, 3) arrays)")
    imu = ChunkBlocks(imu)
    for e in scenario.estimators:
        run_batch(truth, imu, others, {e.label: build(e)}, Batch(scenario.initial, scenario.seed, range(B)))
        wall, h = timed(run_batch, truth, imu, others, {e.label: build(e)},
                        Batch(scenario.initial, scenario.seed, range(B)))
        h = h[e.label]
        target = 2 if e.type == "sins" else 6
        print(f"  {e.label:<25} {wall:6.2f} s = {per(wall):6.1f} ms per run (target <= {target}); "
              f"final horizontal error RMS {((h.pos_err_m[:, -1, :2] ** 2).sum(-1).mean()) ** 0.5:.1f} m, "
              f"{int(h.diverged.sum())} diverged")
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
        wall, peak = timed(lambda: pool.submit(chunk_peak_mb, str(path), B).result())
    print(f"  one chunk of {B} runs in a fresh worker: {wall:.1f} s wall (start-up and compile or "
          f"cache load included), peak resident memory {peak:.0f} MB (bound <= 400)")


if __name__ == "__main__":
    main()
