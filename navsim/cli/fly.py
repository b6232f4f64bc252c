"""``navsim fly``: fly a scenario's track, write the truth, its plots and a summary."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from navsim.cli.command import Command
from navsim.cli.flights import flight_summary, save_flight
from navsim.cli.options import NOTHING_RESUMED, number, out_option, scenario_argument, scenario_of
from navsim.cli.output import open_folder, progress
from navsim.experiment import resources
from navsim.experiment.scenario import RATE_HZ
from navsim.flight.simulator import fly
from navsim.foundations.errors import FlightError


def arguments(p) -> None:
    """The scenario, ``--out`` and ``--rate-hz``."""
    scenario_argument(p)
    out_option(p, "reports/<name>/flight")
    p.add_argument("--rate-hz", type=number(float, minimum=RATE_HZ[0], maximum=RATE_HZ[1]),
                   help=f"simulation and truth rate, {RATE_HZ[0]:g}-{RATE_HZ[1]:g} Hz (default: scenario's, 100)")


def handle(args) -> int:
    """Fly (no cache: the flight is what is shown), save and summarise; exit 3 for a track that
    cannot be flown (the part flown is saved)."""
    scenario = scenario_of(args)
    if args.rate_hz is not None:
        scenario.flight.rate_hz = args.rate_hz
    resources.check_flight(scenario)
    out = open_folder(args, Path("reports") / scenario.name / "flight")
    out.clear_earlier()
    bar, update = progress(f"flying {scenario.flight.track.name}")
    t0 = time.perf_counter()
    failure = None
    try:
        truth = fly(scenario.flight, progress=update)
    except FlightError as exc:
        failure, truth = exc, getattr(exc, "truth", None)
    finally:
        bar.close()
    wall = time.perf_counter() - t0
    files = save_flight(out, truth, args.scenario, scenario, wall, failure)
    if truth is not None:
        print(flight_summary(truth))
        print(f"\nflew {truth.duration_s:.1f} s in {wall:.2f} s wall "
              f"({truth.duration_s / max(wall, 1e-9):.0f}x real time); wrote {out.path}/ "
              f"({', '.join(f.name for f in files)})")
    if failure:
        print(f"error: {failure}", file=sys.stderr)
        return failure.exit_code
    return 0


COMMAND = Command(
    "fly", "fly a scenario's track and plot it", usage="SCENARIO.yaml [--out DIR]",
    description="Fly the scenario's track in JSBSim under the autopilot; write the truth (truth.npz), PNG "
    "plots, run.json and print a summary.",
    arguments=arguments, handler=handle, kept=NOTHING_RESUMED)
