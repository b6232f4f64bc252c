"""Streaming and Dask scaling on P0: the driver's peak memory for a small and a large number of
runs (the whole ``navsim run``: chunks streamed to disk, metrics from the stored chunks, report
from the first chunks; issue target: less than 2x from 1000 to 10000 runs), and the wall time of the Monte Carlo on a LocalCluster of 1 and of 2 Dask
workers and on the local executor's process pool (targets on the 2-core machine: speed-up
>= 1.7x from 1 to 2 Dask workers, 2 Dask workers within 10 % of the local executor).

    python benchmarks/dask_scaling.py [--runs 1000 10000] [--speed-runs 1000] [--workers 2]

Each measurement runs in a fresh process (its own peak resident memory, ``ru_maxrss``); the
flight is flown and the kernels compiled once into a shared temporary cache first. The wall
times include starting and closing the cluster.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "p0_bd_sins_ads.yaml"
sys.path.insert(0, str(ROOT))            # this checkout's navsim, not another installed one


def measure(runs: int, workers: int, executor: str, out: Path) -> dict:
    """``navsim run`` of P0 in this process (flight cached, Monte Carlo, metrics, report):
    wall time, peak resident memory of this driver process, RMS position errors."""
    import contextlib
    import io
    import resource

    from navsim.cli import main
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        rc = main(["run", str(SCENARIO), "--runs", str(runs), "--workers", str(workers), "--executor", executor,
                   "--out", str(out)])
    wall = time.perf_counter() - t0
    m = json.loads((out / "metrics.json").read_text())
    return {"runs": runs, "workers": workers, "executor": executor, "wall_s": wall, "rc": rc,
            "runs_done": m["runs_done"], "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "rms_pos_m": {k: e["rms"]["pos_m"] for k, e in m["estimators"].items()}}


def measure_speed(runs: int, workers: int, executor: str, out: Path) -> dict:
    """The Monte Carlo alone (chunks streamed; cluster start and close included): wall time."""
    from navsim.experiment.chunkstore import ChunkStore
    from navsim.experiment.options import RunOptions
    from navsim.experiment.runner import CHUNK_RUNS, cached_flight, run_monte_carlo, scenario_hash
    from navsim.experiment.scenario import load_scenario
    from navsim.scoring.scorer import score_parts
    sc = load_scenario(SCENARIO)
    truth, path, _ = cached_flight(sc.flight)
    key = {"scenario_hash": scenario_hash(sc), "seed": sc.seed, "runs": runs, "chunk_runs": CHUNK_RUNS}
    store = ChunkStore(out, key, mode="new")
    t0 = time.perf_counter()
    res = run_monte_carlo(sc, truth, path, RunOptions(runs=runs, seed=sc.seed, workers=workers, executor=executor),
                          store=store, keep_runs=0)
    wall = time.perf_counter() - t0
    m = score_parts(store.parts, sc.settle_s, sc.windows)
    return {"runs": runs, "workers": workers, "executor": executor, "wall_s": wall, "runs_done": len(res.runs),
            "rms_pos_m": {k: e.rms.pos_m for k, e in m.items()}}


def child(mode: str, runs: int, workers: int, executor: str, tmp: Path) -> dict:
    cmd = [sys.executable, __file__, "--child", mode, str(runs), str(workers), executor, str(tmp)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if proc.returncode:
        raise SystemExit(proc.stderr[-3000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, nargs=2, default=[1000, 10000], metavar=("SMALL", "LARGE"))
    parser.add_argument("--speed-runs", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--only", choices=("memory", "speed"), help="one of the two measurements")
    parser.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        mode, runs, workers, executor, tmp = args.child
        fn = measure if mode == "memory" else measure_speed
        print(json.dumps(fn(int(runs), int(workers), executor, Path(tmp) / f"{mode}_{runs}_{workers}")))
        return
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["NAVSIM_CACHE"] = str(Path(tmp) / "cache")
        from navsim.experiment.runner import cached_flight
        from navsim.experiment.scenario import load_scenario
        cached_flight(load_scenario(SCENARIO).flight)
        if args.only != "speed":
            memory(args, Path(tmp))
        if args.only != "memory":
            speed(args, Path(tmp))


def memory(args, tmp: Path) -> None:
    mem = [child("memory", n, args.workers, "local", tmp) for n in args.runs]
    for m in mem:
        print(f"{m['runs']:6d} runs, local executor, {m['workers']} workers, streamed: "
              f"driver peak RSS {m['peak_rss_mb']:.0f} MB, {m['wall_s']:.1f} s")
    print(f"peak memory {mem[0]['runs']} -> {mem[1]['runs']} runs: x{mem[1]['peak_rss_mb'] / mem[0]['peak_rss_mb']:.2f} "
          "(target < 2)")


def speed(args, tmp: Path) -> None:
    child("speed", 2, 1, "local", tmp)        # the compiled kernels into the cache, for all
    speed = [child("speed", args.speed_runs, w, "dask", tmp) for w in (1, args.workers)]
    local = child("speed", args.speed_runs, args.workers, "local", tmp)
    for s in speed:
        print(f"{s['runs']:6d} runs, Dask LocalCluster of {s['workers']} worker(s): {s['wall_s']:.1f} s")
    print(f"{local['runs']:6d} runs, local executor, {local['workers']} workers: {local['wall_s']:.1f} s")
    print(f"speed-up 1 -> {args.workers} Dask workers: x{speed[0]['wall_s'] / speed[1]['wall_s']:.2f} "
          "(target >= 1.7)")
    print(f"Dask / local with {args.workers} workers: x{speed[1]['wall_s'] / local['wall_s']:.2f} (target <= 1.10)")
    same = speed[0]["rms_pos_m"] == speed[1]["rms_pos_m"] == local["rms_pos_m"]
    print(f"RMS position errors identical across worker counts and executors: {same}")

if __name__ == "__main__":
    main()
