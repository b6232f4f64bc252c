"""``navsim run``: a scenario's Monte Carlo with its progress, its report and a summary."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from navsim import api
from navsim.cli import flights
from navsim.cli.command import Command
from navsim.cli.options import CHUNK_RUNS_TYPE, executor_options, monte_carlo_options, out_option, run_options
from navsim.cli.options import scenario_argument, scenario_of
from navsim.cli.output import open_folder, table
from navsim.experiment import resources
from navsim.experiment.chunkstore import listed_runs
from navsim.foundations.progress import Progress
from navsim.report.summary import sections as summary_sections, text_table


def arguments(p) -> None:
    """The scenario, the Monte Carlo numbers, ``--out``, the executor, the chunks and ``--resume``."""
    scenario_argument(p)
    monte_carlo_options(p)
    out_option(p, "reports/<name>")
    executor_options(p)
    p.add_argument("--chunk-runs", type=CHUNK_RUNS_TYPE, metavar="N",
                   help="runs per chunk, the unit of work streamed to <out>/chunks (default 250, or "
                   "runs/workers where that is fewer; the numbers do not depend on it)")
    p.add_argument("--resume", action="store_true",
                   help="complete an interrupted run in --out: run only the chunks missing from "
                   "<out>/chunks (same scenario, seed and runs, else exit 2)")


def handle(args) -> int:
    """Run the Monte Carlo into the output folder, write its report, print its summary; exit
    1 when no run succeeded, 130 when interrupted (the finished chunks kept)."""
    scenario = scenario_of(args)
    options = run_options(args)
    runs = scenario.runs if options.runs is None else options.runs
    resources.check_run(scenario, runs, options.chunk_runs, Path(args.out) if args.out else Path("reports"),
                        options.workers)
    folder = open_folder(args, Path("reports") / scenario.name)
    print(resources.estimate_line(scenario, runs, folder.path, options.workers, options.chunk_runs), flush=True)
    todo, desc, flight = runs, f"{runs} runs", None
    if scenario.closed_loop is not None:
        desc += ", navigation in the loop"
    else:
        flight = flights.fly_or_save(scenario, args.scenario, folder)   # cached, or flown with its progress bar
        if options.resume:
            todo -= len(listed_runs(folder.path / "chunks"))
            desc += f", {todo} left"
    with Progress(todo, f"{scenario.name}: {desc}", unit="run") as pbar:
        result = api.run(scenario, out=folder.path, flight=flight,
                         options=dataclasses.replace(options, progress=pbar.update))
    files = api.write_report(result)
    print_run_summary(result)
    return _ending(result, runs, folder.path, files)


def _ending(result, runs: int, out: Path, files) -> int:
    """The run's last line (its runs, time, failures and files) and its exit code."""
    note = " (interrupted: partial results)" if result.interrupted else ""
    if result.failed:
        run, why = min(result.failed.items())
        note += f"; {len(result.failed)} run(s) failed, the first (run {run}): {why}"
    print(f"\n{len(result.runs)}/{runs} runs in {result.record.wall_s:.1f} s{note}; wrote {out}/: "
          + artifacts(out, files))
    if result.interrupted:
        return 130
    if not len(result.runs):
        print(f"error: no run succeeded (see {out}/run.json)", file=sys.stderr)
        return 1
    return 0


def artifacts(out: Path, files) -> str:
    """Every file a run wrote into ``out``: the report's and the run's own."""
    pngs = [f for f in files if f.suffix == ".png"]
    names = [f.name for f in files if f.suffix in (".html", ".pdf")] + ([f"{len(pngs)} PNGs"] if pngs else [])
    names += [n for n in ("metrics.json", "run.json", "scenario.resolved.yaml", "samples.npz", "runs.npz") if (out / n).exists()]
    if (out / "chunks" / "index.json").exists():
        names.append(f"chunks/ (per-run data, {len(listed_runs(out / 'chunks'))} runs)")
    return ", ".join(names)


def print_run_summary(result) -> None:
    """The summary of a run, section by section as the report's first page has it (results,
    paper checks, consistency findings, diverged runs, attitude, landmarks, closed loop),
    then the magnetometer calibration."""
    for j, section in enumerate(summary_sections(result.metrics, result.scenario)):
        print(("\n" if j else "") + text_table(section, table))
    _print_calibration(result.metrics)


def _print_calibration(metrics) -> None:
    pct = lambda d: "/".join("-" if v is None else f"{v:.2f}" for v in (d.mean, d.p95, d.max))
    for name, c in (metrics.calibration or {}).items():
        for when, v in ((f"after {c.turns:g} turns", c.after_turns), ("final", c.final)):
            if v is not None:
                print(f"\nmagnetometer '{name}' calibration, {when} ({v.t_s:.0f} s), mean/p95/max: hard iron "
                      f"{pct(v.hard_iron_pct)} % of |m|, soft iron {pct(v.soft_iron_pct)} %", end="")
        print()


COMMAND = Command(
    "run", "run a scenario's Monte Carlo and write its report", usage="SCENARIO.yaml [--runs N] [--out DIR]",
    description="Fly the track (cached), emulate the sensors and run every estimator over the Monte Carlo "
    "runs; write report.html (navsim open), report.pdf, PNGs, metrics.json, scenario.resolved.yaml and the "
    "per-run data (chunks/); print a summary table.",
    arguments=arguments, handler=handle, kept="the finished chunks are kept and --resume completes the run")
