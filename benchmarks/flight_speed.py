"""Flight real-time factor: simulated seconds per wall second on one core of the 2-core CI
machine (target >= 150x), for both classes: the fixed wing (survey10) on a shipped track and
the multirotors (octo25, and the jsbsim package's F450 as aircraft/f450) on a hover, a goto and
two circles.

    python benchmarks/flight_speed.py [--repeat 3] [--track p0]
"""

import argparse
import os
import time

from navsim.flight import FlightConfig, fly, load_track, parse_track

#: the multirotors' benchmark track: 60 s hover at 20 m, 100 m out at 5 m/s, two laps of a 30 m circle
OCTO_TRACK = {"name": "octo_bench",
              "start": {"type": "hover", "lat_deg": 30.0, "lon_deg": 120.0, "alt_m": 20.0, "heading_deg": 0.0},
              "segments": [{"type": "hover", "time_s": 60.0}, {"type": "goto", "north_m": 100.0, "east_m": 0.0},
                           {"type": "circle", "radius_m": 30.0, "laps": 2, "yaw": "center"}]}


def factors(config: FlightConfig, repeat: int) -> list[float]:
    """Real-time factors of ``repeat`` flights of ``config`` (after one to warm up), each printed."""
    fly(config)
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        truth = fly(config)
        wall = time.perf_counter() - t0
        out.append(truth.duration_s / wall)
        print(f"{config.aircraft} on {config.track.name}: {truth.duration_s:.0f} s simulated ({truth.n} steps at "
              f"{truth.meta['rate_hz']:g} Hz) in {wall:.3f} s wall -> {out[-1]:.0f}x real time")
    return sorted(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--track", default="p0", help="the fixed wing's shipped track")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})   # one core
    for config in (FlightConfig(track=load_track(args.track)),
                   FlightConfig(track=parse_track(OCTO_TRACK), aircraft="octo25"),
                   FlightConfig(track=parse_track(OCTO_TRACK), aircraft="f450")):
        f = factors(config, args.repeat)
        print(f"{config.aircraft}: real-time factor median {f[len(f) // 2]:.0f}x, best {f[-1]:.0f}x (target >= 150x)")


if __name__ == "__main__":
    main()
