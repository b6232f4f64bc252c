"""``navsim sensors``: emulate a scenario's sensors over its runs and plot them against the truth."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from navsim.cli import flights
from navsim.cli.command import Command
from navsim.cli.options import NOTHING_RESUMED, monte_carlo_options, out_option, scenario_argument, scenario_of
from navsim.cli.output import open_folder, table
from navsim.experiment import resources
from navsim.experiment.scenario import check_scenario
from navsim.foundations.errors import UsageError
from navsim.replay.export import EXPORTED, WRITERS, emulated_log
from navsim.sensors import emulate
from navsim.sensors.plots import MARKED_ORDERS, channels, plot_allan, plot_sensor, plot_spectrum
from navsim.sensors.registry import INERTIAL


def arguments(p) -> None:
    """The scenario, ``--runs``, ``--seed`` and ``--out``."""
    scenario_argument(p)
    monte_carlo_options(p, runs="runs emulated", workers=False)
    out_option(p, "reports/<name>/sensors")
    p.add_argument("--export", choices=sorted(WRITERS), action="append",
                   help="also write run 0 as a log navsim replay reads (its IMU increments, GNSS fixes, the "
                   "truth as reference and its start): kfgins (imu.txt, gnss.txt, truth.nav, kf-gins.yaml) or csv "
                   "(imu.csv, gnss.csv, reference.csv, start.yaml); repeatable")


def handle(args) -> int:
    """Emulate every sensor over the runs, plot run 0 (and the IMUs' Allan deviation), print the
    error statistics over all runs."""
    scenario = scenario_of(args)
    if not scenario.sensors:
        print(f"error: {args.scenario} has no 'sensors'", file=sys.stderr)
        return 2
    runs = scenario.runs if args.runs is None else args.runs
    resources.check_sensors(scenario, runs)
    seed = scenario.seed if args.seed is None else args.seed
    if args.export and not any(c.kind == "gnss" for c in scenario.sensors):
        raise UsageError(f"--export: {args.scenario} has no GNSS receiver, and a log is an IMU and a GNSS")
    folder = open_folder(args, Path("reports") / scenario.name / "sensors")
    out = folder.path
    truth, _, _ = flights.fly_or_save(scenario, args.scenario, folder)
    check_scenario(scenario, truth.duration_s)
    folder.clear_earlier()
    rows, allan = [], []
    for cfg in scenario.sensors:
        data = emulate(truth, cfg, seed, range(runs))
        folder.record([plot_sensor(data, truth, out / f"sensor_{cfg.name}.png", run=0)])
        if cfg.role == INERTIAL:
            orders = [t.order for v in cfg.spec.vibration if v.type == "rotor" for t in v.tones] or MARKED_ORDERS
            folder.record([plot_spectrum(data, truth, out / f"spectrum_{cfg.name}.png", sorted(set(orders)))])
            folder.record([out / f"allan_{cfg.name}.png"])
            _, ratios = plot_allan(f"{cfg.name} ({cfg.model})", cfg.spec, seed, out / f"allan_{cfg.name}.png")
            allan.append(f"{cfg.name}: white noise read from its Allan deviation at the shortest tau, over the "
                         "datasheet's: " + ", ".join(f"{k} {v:.3f}" for k, v in ratios.items()))
        rows += _error_rows(cfg, data, truth, runs)
    for fmt in dict.fromkeys(args.export or []):
        folder.record([out / name for name in EXPORTED[fmt]])      # listed before they are written
        written = WRITERS[fmt](out, emulated_log(scenario, truth, seed, 0))
        print(f"run 0 as a {fmt} log: " + ", ".join(p.name for p in written.values())
              + f" (navsim replay {written.get('config', written['imu'])} ...; docs/data.md)")
    print(table(["sensor", "model", "channel", "unit", "error mean", "error std", "|error| 95%",
                 "output %"], rows))
    print("\n".join([""] + allan))
    print(f"\n{runs} run(s), seed {seed}; wrote {out}/: sensor_<name>.png (run 0)"
          + (", spectrum_<imu>.png (run 0), allan_<imu>.png (at rest)" if allan else ""))
    return 0


def _error_rows(cfg, data, truth, runs: int) -> list[list[str]]:
    """A row per channel of the sensor ``cfg``: its errors over every run's valid outputs."""
    rows = []
    for label, unit, _, _, _ in channels(data, truth, 0):
        errs = np.concatenate([np.where(data.valid[r], c[3] - c[4], np.nan)
                               for r in range(runs) for c in channels(data, truth, r) if c[0] == label])
        errs = errs[np.isfinite(errs)]
        rows.append([cfg.name, cfg.model, label, unit, f"{errs.mean():.4g}", f"{errs.std():.4g}",
                     f"{np.percentile(np.abs(errs), 95):.4g}", f"{data.valid.mean() * 100:.1f}"])
    return rows


COMMAND = Command(
    "sensors", "emulate a scenario's sensors, plot them against the truth", usage="SCENARIO.yaml [--runs N]",
    description="Fly the scenario's track, emulate its sensors for the Monte Carlo runs, write one PNG per "
    "sensor (output against truth, error) and print error statistics over all runs.",
    arguments=arguments, handler=handle, kept=NOTHING_RESUMED)
