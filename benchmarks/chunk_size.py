"""The default chunk size, by measurement: wall time of ``navsim run`` (P0, 1000 runs, 2
workers, flight and kernels cached, report included) and the peak resident memory of its
largest process, for several ``--chunk-runs``. A chunk's filter epochs cost the same Python
work whatever its number of runs, so bigger chunks are cheaper per run and dearer in memory.

    python benchmarks/chunk_size.py [--runs 1000] [--workers 2] [--sizes 125 250 500]
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(args, size: int, env: dict, out: Path) -> tuple[float, float]:
    """Wall time (s) and the largest peak resident memory (MB) of the run's processes."""
    code = (f"import resource, subprocess, sys; subprocess.run({[sys.executable, '-m', 'navsim', 'run', args.scenario, '--runs', str(args.runs), '--workers', str(args.workers), '--chunk-runs', str(size), '--out', str(out)]!r}, check=True, capture_output=True); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, int(proc.stdout.split()[-1]) / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--sizes", type=int, nargs="+", default=[125, 250, 500])
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "p0_bd_sins_ads.yaml"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NAVSIM_CACHE=str(Path(tmp) / "cache"))
        env.pop("NUMBA_CACHE_DIR", None)
        run(args, args.sizes[0], env, Path(tmp) / "out")          # fly and compile once
        print(f"navsim run {Path(args.scenario).name} --runs {args.runs} --workers {args.workers}, cached:")
        for size in args.sizes:
            wall, peak = run(args, size, env, Path(tmp) / "out")
            print(f"  --chunk-runs {size:4d}: {wall:5.1f} s wall, largest process peak {peak:5.0f} MB")


if __name__ == "__main__":
    main()
