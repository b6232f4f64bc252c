"""The fixed cost of a Monte Carlo in a process that runs many (a budget's, a sweep's, a
tuning's): ``navsim.run`` of P0 (``scenarios/p0_bd_sins_ads.yaml``) with 2 workers at 2, 10 and
50 runs, each three times, flight cached, nothing written; once starting a pool of workers for
each Monte Carlo (``navsim.run`` alone) and once inside ``lend_pool`` (one pool for them all, as
``navsim budget``, ``sweep`` and ``tune`` run). The fixed cost is the intercept of the least
squares line of the best wall time against the runs (issue 56's target: <= 0.1 s).

    python benchmarks/fixed_cost.py [--workers 2] [--repeat 3]
"""

import argparse
import time
from pathlib import Path

import numpy as np

import navsim
from navsim.experiment.executors import lend_pool
from navsim.experiment.runner import cached_flight

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "p0_bd_sins_ads.yaml"
RUNS = (2, 10, 50)


def walls(scenario, flight, workers: int, repeat: int) -> dict:
    """Runs -> the wall times of ``repeat`` Monte Carlos of that many runs."""
    out = {}
    for runs in RUNS:
        out[runs] = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            navsim.run(scenario, runs=runs, workers=workers, flight=flight)
            out[runs].append(time.perf_counter() - t0)
    return out


def fixed(w: dict) -> tuple[float, float]:
    """The intercept and slope (s per run) of the best wall time of each number of runs against
    the runs (the best: a collection or another process's burst only ever adds)."""
    slope, intercept = np.polyfit(list(w), [min(v) for v in w.values()], 1)
    return float(intercept), float(slope)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    scenario = navsim.load_scenario(SCENARIO)
    flight = cached_flight(scenario.flight)
    navsim.run(scenario, runs=2, workers=args.workers, flight=flight)           # kernels compiled or cached
    alone = walls(scenario, flight, args.workers, args.repeat)
    with lend_pool():
        lent = walls(scenario, flight, args.workers, args.repeat)
    for name, w in (("a pool for each Monte Carlo", alone), ("one pool lent to them all", lent)):
        a, b = fixed(w)
        cells = ", ".join(f"{r} runs {min(v):.2f} s" for r, v in w.items())
        print(f"{name}: {cells} (best of {args.repeat}; all: "
              f"{', '.join(f'{x:.2f}' for v in w.values() for x in v)}); fixed cost {a:.2f} s, {b * 1e3:.1f} ms per run")


if __name__ == "__main__":
    main()
