"""P1's return-to-land with navigation in the loop: miss distances and speed.

Runs ``scenarios/p1_return_to_land.yaml`` (or the file given) for N runs, prints the outcome,
CEP50/CEP95 of the true miss distance against the same flight guided on the truth, and the cost
per run and per simulated second.

    python benchmarks/return_to_land.py [--runs 100] [--workers 2] [SCENARIO]
"""

import argparse
import time
from pathlib import Path

import numpy as np

from navsim.experiment.runner import run_closed_loop
from navsim.experiment.scenario import load_scenario
from navsim.scoring.closed_loop import cep

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "p1_return_to_land.yaml"))
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    scenario = load_scenario(args.scenario)
    t0 = time.perf_counter()
    result, loop, ref = run_closed_loop(scenario, args.runs, args.seed, args.workers)
    wall = time.perf_counter() - t0
    outcome = [str(o) for o in loop["outcome"]]
    area = scenario.closed_loop.return_to_land.area_m
    miss = np.asarray(loop["miss_m"], float)
    c, ce = cep(miss), cep(loop["miss_est_m"])
    flown_s = np.nansum(loop["land_t_s"])
    print(f"{args.runs} runs, seed {args.seed}, {args.workers} workers: "
          + ", ".join(f"{k} {outcome.count(k)}" for k in sorted(set(outcome)))
          + f"; failed: {len(result.failed)}")
    print(f"inside the {area:g} m recovery area: {(miss <= area).sum()} of {args.runs}")
    print(f"true miss distance     CEP50 {c['cep50_m']:.1f} m  CEP95 {c['cep95_m']:.1f} m  "
          f"mean {c['mean_m']:.1f} m  max {c['max_m']:.1f} m")
    print(f"solution's own miss    CEP50 {ce['cep50_m']:.2f} m  CEP95 {ce['cep95_m']:.2f} m")
    print(f"guided on the truth    miss {ref.miss_m[0]:.2f} m, parachute at {ref.land_t_s[0]:.1f} s")
    print(f"mission abandoned at {np.nanmean(loop['abort_t_s']):.1f} s, parachute at "
          f"{np.nanmin(loop['land_t_s']):.0f}-{np.nanmax(loop['land_t_s']):.0f} s")
    print(f"wall {wall:.1f} s: {wall / args.runs:.2f} s per run (truth-guided flight included), "
          f"{flown_s / wall:.0f} simulated run-seconds per wall second")


if __name__ == "__main__":
    main()
