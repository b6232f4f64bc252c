"""P1's return-to-land with navigation in the loop: miss distances and speed.

Runs ``scenarios/p1_return_to_land.yaml`` (or the file given) for N runs, prints the outcome,
CEP50/CEP95 of the true miss distance against the same flight guided on the truth, and the cost
per run and per simulated second, side by side with JSBSim alone flying the same flights: the
truth-guided flight's commands replayed into a fresh aircraft (JSBSim's step, the commands
written, the state read: what any flight of this aircraft costs), one aircraft after the other,
as many steps as the Monte Carlo's runs flew, on as many workers; and ``fly`` on the truth (the
autopilot included).

    python benchmarks/return_to_land.py [--runs 100] [--workers 2] [SCENARIO]
"""

import argparse
import time
from pathlib import Path

import numpy as np

from navsim.experiment.closed_loop import fly_batch
from navsim.experiment.runner import run_closed_loop
from navsim.experiment.scenario import load_scenario
from navsim.flight import fly
from navsim.flight.properties import JSBSimIO
from navsim.flight.simulator import Aircraft
from navsim.scoring.closed_loop import cep

ROOT = Path(__file__).resolve().parents[1]


def jsbsim_alone_us_per_step(scenario) -> float:
    """Microseconds per step of JSBSim alone: the truth-guided flight of ``scenario`` flown once
    to record its commands, which are then replayed into a fresh, identically started aircraft."""
    commands, original = [], JSBSimIO.set_controls
    JSBSimIO.set_controls = lambda io, *c: (commands.append(c), original(io, *c))[1]
    try:
        fly_batch(scenario, 1, [0], on_truth=True)
    finally:
        JSBSimIO.set_controls = original
    craft = Aircraft(scenario.flight)
    io, dt = craft.io, craft.dt
    changes = scenario.flight.environment.wind_changes
    t0 = time.perf_counter()
    for k, c in enumerate(commands):
        io.set_controls(*c)
        if changes:
            craft.set_wind_at((k + 1) * dt)
        io.run()
        io.read_row()
    return (time.perf_counter() - t0) / len(commands) * 1e6


def fly_us_per_step(scenario) -> float:
    """Microseconds per step of ``fly`` on the truth of the scenario's track (autopilot included)."""
    t0 = time.perf_counter()
    truth = fly(scenario.flight)
    return (time.perf_counter() - t0) / truth.n * 1e6


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
    outcome = [str(o) for o in loop.outcome]
    area = scenario.closed_loop.return_to_land.area_m
    miss = np.asarray(loop.miss_m, float)
    c, ce = cep(miss), cep(loop.miss_est_m)
    flown_s = np.nansum(loop.land_t_s)
    print(f"{args.runs} runs, seed {args.seed}, {args.workers} workers: "
          + ", ".join(f"{k} {outcome.count(k)}" for k in sorted(set(outcome)))
          + f"; failed: {len(result.failed)}")
    print(f"inside the {area:g} m recovery area: {(miss <= area).sum()} of {args.runs}")
    print(f"true miss distance     CEP50 {c['cep50_m']:.1f} m  CEP95 {c['cep95_m']:.1f} m  "
          f"mean {c['mean_m']:.1f} m  max {c['max_m']:.1f} m")
    print(f"solution's own miss    CEP50 {ce['cep50_m']:.2f} m  CEP95 {ce['cep95_m']:.2f} m")
    print(f"guided on the truth    miss {ref.miss_m[0]:.2f} m, parachute at {ref.land_t_s[0]:.1f} s")
    print(f"mission abandoned at {np.nanmean(loop.abort_t_s):.1f} s, parachute at "
          f"{np.nanmin(loop.land_t_s):.0f}-{np.nanmax(loop.land_t_s):.0f} s")
    print(f"wall {wall:.1f} s: {wall / args.runs:.2f} s per run (truth-guided flight included), "
          f"{flown_s / wall:.0f} simulated run-seconds per wall second")
    steps = flown_s * scenario.flight.rate_hz
    loop_us = wall * args.workers / steps * 1e6
    alone_us, fly_us = jsbsim_alone_us_per_step(scenario), fly_us_per_step(scenario)
    print(f"closed loop         {loop_us:5.2f} us per run and step ({args.workers} workers, {steps:.3g} steps)")
    print(f"JSBSim alone        {alone_us:5.2f} us per step (commands replayed, one aircraft): "
          f"{alone_us * steps / args.workers / 1e6:.1f} s for these flights on {args.workers} workers; "
          f"closed loop / JSBSim alone = {loop_us / alone_us:.2f} (target <= 1.3)")
    print(f"fly on the truth    {fly_us:5.2f} us per step (autopilot included); closed loop / fly = "
          f"{loop_us / fly_us:.2f}")


if __name__ == "__main__":
    main()
