"""Flight real-time factor: simulated seconds per wall second for the p0 track (target >= 150x
on one core of the 2-core CI machine).

    python benchmarks/flight_speed.py [--repeat 3] [--track p0]
"""

import argparse
import os
import time

from navsim.flight import fly, load_track


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--track", default="p0")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})   # one core
    track = load_track(args.track)
    fly(track)                                                             # warm-up
    factors = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        truth = fly(track)
        wall = time.perf_counter() - t0
        factors.append(truth.duration_s / wall)
        print(f"{args.track}: {truth.duration_s:.0f} s simulated ({truth.n} steps at "
              f"{truth.meta['rate_hz']:g} Hz) in {wall:.3f} s wall -> {factors[-1]:.0f}x real time")
    factors.sort()
    print(f"real-time factor: median {factors[len(factors) // 2]:.0f}x, best {factors[-1]:.0f}x "
          f"(target >= 150x)")


if __name__ == "__main__":
    main()
