"""Wall time of ``navsim run scenarios/p0_bd_sins_ads.yaml --runs 1000 --workers 2``, report
included, in a fresh navsim cache: first with nothing cached (the flight flown, the compiled
kernels compiled), then with the flight flown again and the kernels cached, then with both cached
(targets, issue 18: <= 15 s flown, <= 12 s cached, on the 2-core machine).

    python benchmarks/run_speed.py [--runs 1000] [--workers 2]
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(args, env, out: Path) -> tuple[float, str]:
    cmd = [sys.executable, "-m", "navsim", "run", args.scenario, "--runs", str(args.runs),
           "--workers", str(args.workers), "--out", str(out)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode:
        print(proc.stdout[-1500:], proc.stderr[-2000:])
        raise SystemExit(f"navsim run exited {proc.returncode}")
    return wall, proc.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "p0_bd_sins_ads.yaml"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "cache"
        env = dict(os.environ, NAVSIM_CACHE=str(cache))      # an empty cache: fly and compile
        env.pop("NUMBA_CACHE_DIR", None)
        cold, _ = run(args, env, Path(tmp) / "out")
        shutil.rmtree(cache / "flights")
        flown, _ = run(args, env, Path(tmp) / "out")
        cached, stdout = run(args, env, Path(tmp) / "out")
    print(stdout[-1500:])
    what = f"navsim run {Path(args.scenario).name} --runs {args.runs} --workers {args.workers}, report included"
    print(f"{what}:")
    print(f"  empty cache (flight flown, kernels compiled): {cold:6.1f} s")
    print(f"  flight flown, kernels cached                : {flown:6.1f} s (target <= 15 s)")
    print(f"  flight and kernels cached                   : {cached:6.1f} s (target <= 10 s)")

if __name__ == "__main__":
    main()
