"""The coverage of navsim's 95 % intervals: for metrics of ``p3_sins_gps`` and
``p0_matched_ads``, a Monte Carlo of many runs gives the reference value; many independent
small Monte Carlos (seeds 1000, 1001, ...) each give an interval, and the share of them that
holds the reference is printed (95 % expected; with 200 Monte Carlos a share between 92 and
98 % is what chance gives a calibrated interval, 2 binomial sigmas).

    python benchmarks/interval_coverage.py [--reference-runs 2000] [--trials 200] [--runs 20]
                                           [--scenarios p3_sins_gps p0_matched_ads]

Every Monte Carlo runs in this process (``navsim.run`` with nothing written), the flight
flown or read from the cache once per scenario.
"""

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

import navsim
from navsim.experiment.runner import cached_flight

ROOT = Path(__file__).resolve().parents[1]
#: the metrics checked: dotted path and component (None: a scalar)
METRICS = (("rms.pos_m", 0), ("rms.pos_m", 2), ("rms.vel_mps", 0), ("final.pos_m", 0), ("p99.pos_m", 0),
           ("nees.average", None))
#: each scenario's estimator whose metrics are checked
ESTIMATOR = {"p3_sins_gps": "SINS/GPS 15-state", "p0_matched_ads": "ES-KF 17, matched ADS"}


def pick(m, path: str, j):
    v, iv = m.get(path), m.interval(path)
    if j is None:
        return float(v), (iv if iv is not None else [math.nan, math.nan])
    return float(v[j]), (iv[j] if iv is not None else [math.nan, math.nan])


def coverage(name: str, reference_runs: int, trials: int, runs: int, workers: int) -> None:
    scenario = navsim.load_scenario(ROOT / "scenarios" / f"{name}.yaml")
    label = ESTIMATOR.get(name) or next(iter(scenario.estimators)).label
    flight = cached_flight(scenario.flight)
    t0 = time.perf_counter()
    ref = navsim.run(scenario, runs=reference_runs, seed=1, workers=workers, flight=flight).metrics.estimators[label]
    print(f"{name} / {label}: reference from {reference_runs} runs (seed 1) in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    inside = {k: 0 for k in METRICS}
    width = {k: [] for k in METRICS}
    for i in range(trials):
        m = navsim.run(scenario, runs=runs, seed=1000 + i, workers=workers, flight=flight).metrics.estimators[label]
        for k in METRICS:
            _, (lo, hi) = pick(m, *k)
            inside[k] += bool(lo <= pick(ref, *k)[0] <= hi)
            width[k].append(hi - lo)
        if (i + 1) % 20 == 0:
            print(f"  {i + 1} of {trials} Monte Carlos", file=sys.stderr)
    for k in METRICS:
        value, (lo, hi) = pick(ref, *k)
        what = k[0] + ("" if k[1] is None else f"[{k[1]}]")
        print(f"| `{name}` | {label} | {what} | {value:.4g} [{lo:.4g}, {hi:.4g}] | {runs} runs x {trials} | "
              f"{inside[k]} of {trials} ({100 * inside[k] / trials:.1f} %) | {np.median(width[k]):.3g} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference-runs", type=int, default=2000, help="runs of the reference (default 2000)")
    parser.add_argument("--trials", type=int, default=200, help="small Monte Carlos (default 200)")
    parser.add_argument("--runs", type=int, default=20, help="runs of each small Monte Carlo (default 20)")
    parser.add_argument("--workers", type=int, default=1, help="worker processes per Monte Carlo (default 1)")
    parser.add_argument("--scenarios", nargs="*", default=["p3_sins_gps", "p0_matched_ads"])
    args = parser.parse_args()
    print("| scenario | estimator | metric | reference (its 95 % interval) | Monte Carlos | reference inside "
          "| median width |")
    print("|---|---|---|---|---|---|---|")
    for name in args.scenarios:
        coverage(name, args.reference_runs, args.trials, args.runs, args.workers)


if __name__ == "__main__":
    main()
