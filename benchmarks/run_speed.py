"""Wall time of ``navsim run scenarios/p0_bd_sins_ads.yaml --runs 1000`` including the flight
(flown, not cached) and the report (target <= 60 s on the 2-core machine).

    python benchmarks/run_speed.py [--runs 1000] [--workers 2]
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "p0_bd_sins_ads.yaml"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NAVSIM_CACHE=str(Path(tmp) / "cache"))      # fly, do not reuse
        cmd = [sys.executable, "-m", "navsim", "run", args.scenario, "--runs", str(args.runs),
               "--workers", str(args.workers), "--out", str(Path(tmp) / "out")]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
    print(proc.stdout[-1500:])
    if proc.returncode:
        print(proc.stderr[-2000:])
    print(f"navsim run {Path(args.scenario).name} --runs {args.runs} --workers {args.workers}: "
          f"{wall:.1f} s wall including flight and report (target <= 60 s)")


if __name__ == "__main__":
    main()
