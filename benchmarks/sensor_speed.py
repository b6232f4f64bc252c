"""Sensor emulation speed: all P0 sensors (SINS 100 Hz, BD-2, barometer, ADS) for 1000 runs of
the 500 s p0 track, in chunks of runs, against the time it takes to fly the track once
(the issue's target: emulation faster than one flight).

    python benchmarks/sensor_speed.py [--runs 1000] [--chunk 50]
"""

import argparse
import os
import time

from navsim.flight import fly, load_track
from navsim.sensors import emulate, parse_sensors

P0_SENSORS = {"imu": {"model": "p0_imu"}, "bd": {"model": "p0_bd2"},
              "baro": {"model": "p0_baro"}, "ads": {"model": "p0_ads"}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--chunk", type=int, default=50)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})   # one core
    track = load_track("p0")
    t0 = time.perf_counter()
    truth = fly(track)
    flight_s = time.perf_counter() - t0
    sensors = parse_sensors(P0_SENSORS)
    per_sensor = {c.name: 0.0 for c in sensors}
    samples = 0
    t0 = time.perf_counter()
    for start in range(0, args.runs, args.chunk):
        runs = range(start, min(start + args.chunk, args.runs))
        for c in sensors:
            t1 = time.perf_counter()
            data = emulate(truth, c, 1, runs)
            per_sensor[c.name] += time.perf_counter() - t1
            samples += sum(v.size for v in data.values.values())
            del data
    total = time.perf_counter() - t0
    print(f"flight p0 (500 s at 100 Hz): {flight_s:.2f} s wall")
    for name, sec in per_sensor.items():
        print(f"  {name:5s} {sec:7.2f} s for {args.runs} runs ({sec / args.runs * 1e3:.2f} ms/run)")
    print(f"all P0 sensors, {args.runs} runs x 500 s: {total:.2f} s on one core "
          f"({total / args.runs * 1e3:.2f} ms/run, {samples / total / 1e6:.0f} M values/s); "
          f"{total / flight_s:.1f}x the flight time (target < 1x)")


if __name__ == "__main__":
    main()
