"""An error budget by covariance analysis against the same budget by Monte Carlo, and what each
costs: for a scenario (default ``p3_sins_gps``), ``navsim.budget(method="both")`` at ``--runs``
runs per source, then every line of the default metrics with its Monte Carlo and covariance
contributions, their ratio, and whether a source above 5 % of the variance is within 15 %
(issue 34's acceptance); the wall time of the Monte Carlo budget and of the covariance
analysis, and their ratio. ``--scale SOURCE=K`` adds a what-if (the budget's prediction against
a run with the source scaled).

    python benchmarks/budget_covariance.py [--scenario scenarios/p3_sins_gps.yaml] [--runs 200]
                                           [--workers 2] [--scale gps.position_sigma=0.5]

The flight is flown or read from the cache first (not counted); each Monte Carlo runs in this
process's worker pool, nothing written.
"""

import argparse
import time
from pathlib import Path

import navsim
from navsim.experiment.runner import cached_flight
from navsim.scoring.budget import DEFAULT_METRICS

ROOT = Path(__file__).resolve().parents[1]
#: a source is checked when its share is above this, and passes within this relative tolerance
SHARE, TOLERANCE = 0.05, 0.15


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default=str(ROOT / "scenarios" / "p3_sins_gps.yaml"))
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scale", action="append", default=[], metavar="SOURCE=K")
    args = ap.parse_args()
    scenario = navsim.load_scenario(args.scenario)
    cached_flight(scenario.flight)
    scales = [(s.split("=")[0], float(s.split("=")[1])) for s in args.scale]
    t0 = time.perf_counter()
    b = navsim.budget(scenario, args.runs, args.seed, args.workers, method="both", scales=scales)
    wall = time.perf_counter() - t0
    checked = passed = 0
    for m in b.metrics:
        if (m.metric, m.component) not in DEFAULT_METRICS:
            continue
        print(f"\n{m.estimator}: {m.name}: Monte Carlo all on {m.all_on:.4g} (ratio {m.ratio:.3f}), "
              f"covariance {sum(x.covariance ** 2 for x in m.lines) ** 0.5:.4g}")
        for x in m.lines:
            ratio = x.covariance / x.contribution if x.contribution > 0 else float("nan")
            mark = ""
            if x.share > SHARE:
                checked += 1
                ok = abs(ratio - 1) <= TOLERANCE
                passed += ok
                mark = "  within 15 %" if ok else "  OUT of 15 %"
            print(f"  {x.source:28s} MC {x.contribution:10.4g} ({100 * x.share:5.1f} %)  covariance "
                  f"{x.covariance:10.4g}  ratio {ratio:6.3f}{mark}")
    for w in b.what_if:
        if (w.metric, w.component) in DEFAULT_METRICS:
            print(f"what if {w.source} x{w.factor:g}: {w.estimator} {w.metric} {w.component}: {w.all_on:.4g} -> "
                  f"predicted {w.predicted:.4g}, run {w.measured:.4g} ({100 * w.error:+.1f} %)")
    monte_carlo_s = wall - b.covariance_s
    print(f"\nsources above {100 * SHARE:.0f} % within {100 * TOLERANCE:.0f} %: {passed} of {checked}")
    print(f"Monte Carlo budget ({len(b.sources) + 2 + len(scales)} Monte Carlos of {b.runs} runs, "
          f"{args.workers} workers): {monte_carlo_s:.1f} s; covariance analysis: {b.covariance_s:.2f} s; "
          f"ratio {monte_carlo_s / b.covariance_s:.0f}x")
    if b.monte_carlo_only:
        print("left to Monte Carlo (no linear form): " + ", ".join(b.monte_carlo_only))


if __name__ == "__main__":
    main()
