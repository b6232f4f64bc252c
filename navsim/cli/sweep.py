"""``navsim sweep``: every point of a sweep file, each a Monte Carlo; a table, sweep.json,
sweep.csv and a figure of the chosen metric."""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import sys
from pathlib import Path

from navsim import api, report
from navsim.cli.command import Command
from navsim.cli.options import RUNS_TYPE, SEED_TYPE, executor_options, out_option, run_options, set_option
from navsim.cli.options import load_plugins, overrides_given, plugin_option, workers_option
from navsim.cli.output import open_folder, table
from navsim.experiment.sweep import parse_sweep
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.progress import Progress
from navsim.report.sweep import short_key, write_sweep_figure
from navsim.scoring.verdicts import num, with_interval


def arguments(p) -> None:
    """The sweep file, ``--set``, ``--runs``, ``--seed``, ``--workers``, ``--out`` and the executor."""
    p.add_argument("sweep", help="sweep YAML file")
    set_option(p, "the sweep's scenario (before each point's changes)")
    plugin_option(p)
    p.add_argument("--runs", type=RUNS_TYPE, help="runs per point, >= 1 (default: the sweep file's runs, "
                   "else montecarlo.runs)")
    p.add_argument("--seed", type=SEED_TYPE, help="every point's seed, >= 0 (default: montecarlo.seed)")
    workers_option(p)
    out_option(p, "reports/<sweep name>")
    executor_options(p)


def _point_name(n: int, total: int, point: dict) -> str:
    """``point 2/3 (key=value, ...)``: the point of index ``n``, numbered from 1 as everywhere
    the user reads it (progress, errors, sweep.csv)."""
    return f"point {n + 1}/{total} (" + ", ".join(f"{short_key(k)}={v}" for k, v in point.items()) + ")"


def _point_line(n: int, total: int, point: dict, values: dict, res) -> str:
    if res is None:
        return f"{_point_name(n, total, point)}: the flight cannot be flown"
    got = ", ".join(f"{lb} {num(v)}" for lb, v in values.items())
    return f"{_point_name(n, total, point)}: {got} [{len(res.runs)} runs, {res.record.wall_s:.1f} s]"


def handle(args) -> int:
    """Run the points (a line each as it ends), print the table, write the files; exit 1 for a
    point not flown or without a run, 130 when interrupted (the finished points written)."""
    load_plugins(args)
    _, _, _, points = parse_sweep(args.sweep, overrides_given(args))      # a bad --set: before any file
    folder = open_folder(args, Path("reports") / Path(args.sweep).stem)
    options = run_options(args)
    with Progress(len(points), f"sweep {Path(args.sweep).stem}", unit="point") as bar:
        sweep = api.sweep(args.sweep, options=dataclasses.replace(options, progress=bar.update), set=args.overrides,
                          on_point=lambda i, p, v, r: print(_point_line(i, len(points), p, v, r), flush=True))
    labels = list(sweep.rows[0][1]) if sweep.rows else []
    ci = lambda n, lb: [sweep.interval(n, lb)] if sweep.interval(n, lb) else None
    rows = [[", ".join(f"{short_key(k)}={v}" for k, v in p.items())]
            + [with_interval(vals.get(lb), ci(n, lb)) for lb in labels] for n, (p, vals) in enumerate(sweep.rows)]
    print("\n" + table(["point"] + [f"{lb}: {sweep.metric}" for lb in labels], rows))
    folder.clear_earlier()                 # only now: a sweep that cannot start leaves the earlier one
    write_sweep_files(folder, sweep)
    write_sweep_figure(folder, sweep, f"sweep {Path(args.sweep).name}: {sweep.metric} (vectors by their norm), 95 % intervals over the runs")
    folder.write("sweep.html", lambda p: p.write_text(report.html.sweep_html(sweep), encoding="utf-8"))
    print(f"\nwrote {folder.path}/: sweep.json (every point's metrics), sweep.csv, sweep.png, sweep.html")
    for i, why in sweep.failed_points.items():
        name = _point_name(i, len(points), points[i])
        print(f"error: {name}: {why}" if i in sweep.unflown else f"error: no run of {name} succeeded: {why}",
              file=sys.stderr)
    if sweep.interrupted:
        print(f"interrupted after {len(sweep.rows)} of {len(points)} points", file=sys.stderr)
        return 130
    if sweep.failed_points:                # exit 1: a point not flown or without a run (the others written)
        print(f"{len(sweep.failed_points)} of {len(points)} points failed", file=sys.stderr)
        return 1
    return 0


def write_sweep_files(folder: OutputFolder, sweep) -> None:
    """``sweep.json``: each point with its values, their 95 % intervals and its whole
    ``metrics.json``; ``sweep.csv``: one row per point (numbered from 1), the swept parameters
    then the metric of each estimator and its interval's ends (empty where there is none)."""
    folder.json("sweep.json", {"metric": sweep.metric, "overrides": list(sweep.overrides), "points": [
        {"point": p, "values": v, "ci95": sweep.intervals[i] if i < len(sweep.intervals) else {},
         "metrics": None if m is None else m.to_dict()} for i, ((p, v), m) in enumerate(zip(sweep.rows, sweep.metrics))],
        "failed_points": sweep.failed_points, "interrupted": sweep.interrupted})
    keys = list(sweep.axes())
    labels = list(sweep.rows[0][1]) if sweep.rows else []
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["point", *keys, *(f"{lb}: {sweep.metric}{end}" for lb in labels for end in ("", " ci95_lo", " ci95_hi"))])
    cell = lambda v: "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else repr(v)
    for n, (p, vals) in enumerate(sweep.rows):          # numbered from 1, as the progress and errors
        ends = lambda lb: sweep.interval(n, lb) or [None, None]
        w.writerow([n + 1, *(p.get(k) for k in keys), *(cell(x) for lb in labels for x in (vals.get(lb), *ends(lb)))])
    folder.text("sweep.csv", buf.getvalue())


COMMAND = Command(
    "sweep", "run a grid of scenario variants and compare a metric", usage="SWEEP.yaml [--workers W]",
    description="Run every point of a sweep file (a grid or a list of changes to a scenario), each a Monte "
    "Carlo; print a table and plot the chosen metric.",
    arguments=arguments, handler=handle,
    kept="the finished points are written (sweep.json, sweep.csv, sweep.png; nothing completes the rest "
    "later: run the sweep again)")
