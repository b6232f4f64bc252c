"""The consistency of every shipped scenario's filters: for each estimator that reports a
covariance, the share of epochs (from the settling time on) whose NEES averaged over the runs is
inside its 95 % chi-square band, the mean (error/sigma)^2 of each navigation error, and each
measurement's NIS likewise; printed as the markdown table of ``docs/consistency.md``.

    python benchmarks/consistency.py [--runs N] [--seed S] [--scenarios p0_matched_ads p3_sins_gps ...]

Without ``--runs`` each scenario runs its own ``montecarlo.runs`` (and ``--seed``, its own seed).
"""

import argparse
import sys
import time
from pathlib import Path

import navsim
from navsim.records.states import SIGMA_STATES

ROOT = Path(__file__).resolve().parents[1]


def rows_of(name: str, runs, seed) -> list[str]:
    scenario = navsim.load_scenario(ROOT / "scenarios" / f"{name}.yaml")
    if not scenario.estimators:
        return []
    t0 = time.perf_counter()
    result = navsim.run(scenario, runs=runs, seed=seed)
    wall = time.perf_counter() - t0
    out = []
    for label, m in result.metrics.estimators.items():
        if m.nees is None:
            continue
        per = m.nees.per_state or [float("nan")]
        worst = sorted(zip(SIGMA_STATES, per), key=lambda kv: abs(kv[1] - 1.0), reverse=True)[:2]
        nis = "; ".join(f"{k} {v.average:.2f} ({100 * v.fraction_inside:.0f} %)" for k, v in (m.nis or {}).items())
        out.append(f"| `{name}` | {label} | {result.record.runs} / {result.record.seed} | "
                   f"{m.nees.average:.2f} ({m.nees.band[0]:.2f}-{m.nees.band[1]:.2f}) | "
                   f"{100 * m.nees.fraction_inside:.0f} % | {min(per):.2f}-{max(per):.2f} "
                   f"({', '.join(f'{k} {v:.2f}' for k, v in worst)}) | {nis} |")
    print(f"{name}: {wall:.0f} s", file=sys.stderr)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=None, help="runs per scenario (default: its own)")
    parser.add_argument("--seed", type=int, default=None, help="seed (default: each scenario's own)")
    parser.add_argument("--scenarios", nargs="*", default=None, help="scenario names (default: every shipped one)")
    args = parser.parse_args()
    names = args.scenarios or sorted(p.stem for p in (ROOT / "scenarios").glob("*.yaml"))
    print("| scenario | estimator | runs / seed | NEES avg (95 % band) | epochs inside | (e/σ)² range (furthest from 1) "
          "| NIS avg (epochs inside) |")
    print("|---|---|---|---|---|---|---|")
    for name in names:
        for row in rows_of(name, args.runs, args.seed):
            print(row, flush=True)


if __name__ == "__main__":
    main()
