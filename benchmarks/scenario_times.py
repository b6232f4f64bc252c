"""Wall time of each shipped scenario's Monte Carlo through ``navsim.run`` (its own ``workers``,
the flight cached first and not timed, nothing written), and each estimator's epoch cost per run
(``cost.epoch_us_per_run``); printed as the markdown rows of ``docs/performance.md``'s table.

    python benchmarks/scenario_times.py [--scenarios p0_bd_sins_ads p3_sins_gps ...] [--runs N]

Without ``--runs`` each scenario runs its own ``montecarlo.runs``; the kernels are loaded from
navsim's cache (a fresh cache compiles them first, once: ``docs/performance.md``).
"""

import argparse
import time
from pathlib import Path

import navsim
from navsim.experiment.runner import cached_flight

ROOT = Path(__file__).resolve().parents[1]


def measure(name: str, runs: int | None) -> tuple[str, str]:
    """The table row of scenario ``name`` and its estimators' epoch costs."""
    scenario = navsim.load_scenario(ROOT / "scenarios" / f"{name}.yaml")
    flight = cached_flight(scenario.flight)
    t0 = time.perf_counter()
    result = navsim.run(scenario, runs=runs, flight=flight)
    wall = time.perf_counter() - t0
    n = len(result.runs)
    costs = ", ".join(f"{label} {m.cost.epoch_us_per_run:.0f}" for label, m in result.metrics.estimators.items()
                      if m.cost is not None)
    workers = result.record.workers
    return (f"| `scenarios/{name}.yaml` | {n} runs in {wall:.1f} s ({workers} worker{'s' if workers > 1 else ''}) "
            f"| `navsim run scenarios/{name}.yaml{f' --runs {runs}' if runs else ''}` |"), costs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", help="names in scenarios/ (default: every one with estimators)")
    parser.add_argument("--runs", type=int, help="runs of each (default: the scenario's own)")
    args = parser.parse_args()
    names = args.scenarios or sorted(p.stem for p in (ROOT / "scenarios").glob("*.yaml")
                                     if navsim.load_scenario(p).estimators)
    print("| scenario | Monte Carlo, flight cached | command |\n|---|---|---|")
    costs = {}
    for name in names:
        row, costs[name] = measure(name, args.runs)
        print(row, flush=True)
    print("\nepoch cost per run, us (cost.epoch_us_per_run):")
    for name, c in costs.items():
        print(f"  {name}: {c}")


if __name__ == "__main__":
    main()
