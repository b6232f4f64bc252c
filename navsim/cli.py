"""The ``navsim`` command line.

``navsim run SCENARIO``   Monte Carlo of the scenario's estimators, report.pdf and metrics.
``navsim sweep SWEEP``    a grid of scenario variants, one metric compared.
``navsim fly SCENARIO``   fly the scenario's track, write PNGs, the truth and a summary.
``navsim sensors SCENARIO``  emulate the scenario's sensors, plot them against the truth.
``navsim replay LOG.ulg``  replay a real PX4 log through an estimator, compare with PX4's attitude.
``navsim validate FILE``  check a scenario without running it.
``navsim list``           aircraft and tracks shipped.

Over 600 lines (every subcommand's parser and handler in one file): issue 51 splits it into a package, one
module per verb, its long keyword chains into options objects.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import logging
import math
import shutil
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import yaml

from navsim import api
from navsim.experiment.chunkstore import listed_runs
from navsim.experiment.executors import TERMINATED_EXIT, Terminated, stop_on_sigterm
from navsim.experiment.runner import cached_flight
from navsim.experiment import resources
from navsim.experiment.scenario import (
    MAX_WORKERS,
    RATE_HZ,
    available_aircraft,
    check_scenario,
    load_scenario,
)
from navsim.experiment.schema import schema_text
from navsim.experiment.sweep import parse_sweep
from navsim.flight.plots import plot_flight
from navsim.flight.simulator import fly
from navsim.flight.track import available_tracks, load_track, nominal_duration_s
from navsim.foundations.config import Argument
from navsim.foundations.errors import FlightError, NavsimError, OutputError, UsageError
from navsim.experiment.budget import GROUPS as BUDGET_GROUP_NAMES, budget_sources, check_method, find_source
from navsim.experiment.budget import SCALE_RANGE, scale_ok
from navsim.scoring.budget import METHODS as BUDGET_METHODS, check_metric as budget_metric
from navsim.report.budget import check_text, chosen as budget_chosen, covariance_notes, left_out_rows, rank_notes
from navsim.report.budget import headers as budget_headers, text_rows as budget_text_rows, warn_unranked
from navsim.report.compare import HEADERS as COMPARE_HEADERS, headline, text_rows
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.progress import Progress
from navsim.foundations.provenance import provenance
from navsim.navigation.estimators import base, measurement_types
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.measurements import measurement_class
from navsim.replay import load_ulog, replay, replay_metrics
from navsim.replay.run import IMU_RATE_HZ
from navsim.report.replay import difference_table, write_replay_report
from navsim.report.summary import sections as summary_sections, text_table
from navsim.report.sweep import short_key, write_sweep_figure
from navsim.scoring.compare import DEFAULT_MARGIN_PCT, check_margin
from navsim.scoring.verdicts import num, with_interval
from navsim.sensors import emulate
from navsim.sensors.catalog import entries as catalog_entries
from navsim.sensors.plots import channels, plot_allan, plot_sensor
from navsim.version import __version__


def _numeric(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _table(headers: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.rjust(w) if _numeric(c) else c.ljust(w) for c, w in zip(r, widths))
            for r in rows]
    return "\n".join(out)


def flight_summary(truth) -> str:
    rows = []
    for _, label, a, b in truth.segment_spans():
        m = (truth.t_s >= a) & (truth.t_s <= b)
        rows.append([label, f"{a:.1f}", f"{b:.1f}", f"{truth.h_m[m].min():.1f}",
                     f"{truth.h_m[m].max():.1f}", f"{truth.tas_mps[m].mean():.2f}",
                     f"{np.degrees(np.abs(truth.euler_rad[m, 0])).max():.1f}"])
    return _table(["segment", "t0 s", "t1 s", "h min m", "h max m", "TAS m/s", "|bank| max°"], rows)


def _progress(desc: str):
    """A :class:`Progress` in percent and ``update(t_s, nominal_s)`` for work measured in
    simulated seconds (a flight, a replay)."""
    bar = Progress(100, desc, unit="%", leave=False)

    def update(t_s, nominal_s):
        target = min(int(100 * t_s / max(nominal_s, 1.0)), 99)
        if target > bar.n:
            bar.update(target - bar.n)
    return bar, update


#: the output folders the command being run holds (closed by :func:`main` however it ends)
_OPEN: list = []


def _open_folder(args, default: Path) -> OutputFolder:
    """The command's output folder (``--out``, else ``default``), locked until the command
    ends; ``--force`` writes into a folder that is not navsim's."""
    folder = OutputFolder(Path(args.out) if args.out else default, command=args.command, force=args.force)
    _OPEN.append(folder)
    return folder


def cmd_fly(args) -> int:
    scenario = load_scenario(args.scenario)
    if args.rate_hz is not None:
        scenario.flight.rate_hz = args.rate_hz
    resources.check_flight(scenario)
    out = _open_folder(args, Path("reports") / scenario.name / "flight")
    out.clear_earlier()
    bar, update = _progress(f"flying {scenario.flight.track.name}")
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


def save_flight(out: OutputFolder, truth, scenario_file, scenario, wall_s: float, failure=None) -> list[Path]:
    """Write a flight (or the part flown before ``failure``) into ``out``: ``truth.npz``, the
    flight PNGs, ``scenario.yaml`` (a copy) and ``run.json``; returns the files written."""
    files = [out.write("scenario.yaml", lambda p: shutil.copyfile(scenario_file, p))]
    record = {"scenario": str(scenario_file), "name": scenario.name, **provenance(),
              "wall_s": wall_s, "failure": str(failure) if failure else None}
    if truth is not None:
        files.append(out.write("truth.npz", truth.save))
        plots = plot_flight(truth, out.path)
        out.record(plots)
        files += plots
        record.update(duration_s=truth.duration_s, samples=truth.n,
                      real_time_factor=truth.duration_s / max(wall_s, 1e-9))
    files.append(out.json("run.json", record))
    return files


def _fly_or_save(scenario, scenario_file, out: OutputFolder):
    """The scenario's flight from the cache or flown; a flight that fails saves the part flown
    in ``out/flight`` (as ``navsim fly`` does) before its :class:`FlightError` goes on."""
    bar, update = _progress(f"flight {scenario.flight.track.name}")
    t0 = time.perf_counter()
    try:
        return cached_flight(scenario.flight, progress=update)
    except FlightError as exc:
        out.clear_earlier()               # an earlier run's results do not stand beside this failure
        with OutputFolder(out.path / "flight", command="fly", force=True) as folder:    # inside the locked folder
            folder.clear_earlier()
            save_flight(folder, getattr(exc, "truth", None), scenario_file, scenario, time.perf_counter() - t0, exc)
        print(f"the part flown is saved in {folder.path}/", file=sys.stderr)
        raise
    finally:
        bar.close()


def cmd_run(args) -> int:
    scenario = load_scenario(args.scenario)
    runs = scenario.runs if args.runs is None else args.runs
    resources.check_run(scenario, runs, args.chunk_runs, Path(args.out) if args.out else Path("reports"),
                        args.workers)
    folder = _open_folder(args, Path("reports") / scenario.name)
    print(resources.estimate_line(scenario, runs, folder.path, args.workers, args.chunk_runs), flush=True)
    todo, desc, flight = runs, f"{runs} runs", None
    if scenario.closed_loop is not None:
        desc += ", navigation in the loop"
    else:
        flight = _fly_or_save(scenario, args.scenario, folder)   # cached, or flown with its progress bar
        if args.resume:
            todo -= len(listed_runs(folder.path / "chunks"))
            desc += f", {todo} left"
    with Progress(todo, f"{scenario.name}: {desc}", unit="run") as pbar:
        result = api.run(scenario, runs, args.seed, args.workers, out=folder.path, executor=args.executor,
                         scheduler=args.scheduler, chunk_runs=args.chunk_runs, resume=args.resume,
                         progress=pbar.update, flight=flight)
    files = api.write_report(result)
    print_run_summary(result)
    note = " (interrupted: partial results)" if result.interrupted else ""
    if result.failed:
        run, why = min(result.failed.items())
        note += f"; {len(result.failed)} run(s) failed, the first (run {run}): {why}"
    out = folder.path
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
    names = [f.name for f in files if f.suffix == ".pdf"] + ([f"{len(pngs)} PNGs"] if pngs else [])
    names += [n for n in ("metrics.json", "run.json", "scenario.resolved.yaml", "samples.npz", "runs.npz") if (out / n).exists()]
    if (out / "chunks" / "index.json").exists():
        names.append(f"chunks/ (per-run data, {len(listed_runs(out / 'chunks'))} runs)")
    return ", ".join(names)


def print_run_summary(result) -> None:
    """The summary of a run, section by section as the report's first page has it (results,
    paper checks, consistency findings, diverged runs, attitude, landmarks, closed loop),
    then the magnetometer calibration."""
    for j, section in enumerate(summary_sections(result.metrics, result.scenario)):
        print(("\n" if j else "") + text_table(section, _table))
    _print_calibration(result.metrics)


def _print_calibration(metrics) -> None:
    pct = lambda d: "/".join("-" if v is None else f"{v:.2f}" for v in (d.mean, d.p95, d.max))
    for name, c in (metrics.calibration or {}).items():
        for when, v in ((f"after {c.turns:g} turns", c.after_turns), ("final", c.final)):
            if v is not None:
                print(f"\nmagnetometer '{name}' calibration, {when} ({v.t_s:.0f} s), mean/p95/max: hard iron "
                      f"{pct(v.hard_iron_pct)} % of |m|, soft iron {pct(v.soft_iron_pct)} %", end="")
        print()


def cmd_sensors(args) -> int:
    scenario = load_scenario(args.scenario)
    if not scenario.sensors:
        print(f"error: {args.scenario} has no 'sensors'", file=sys.stderr)
        return 2
    runs = scenario.runs if args.runs is None else args.runs
    resources.check_sensors(scenario, runs)
    seed = scenario.seed if args.seed is None else args.seed
    folder = _open_folder(args, Path("reports") / scenario.name / "sensors")
    out = folder.path
    truth, _, _ = _fly_or_save(scenario, args.scenario, folder)
    check_scenario(scenario, truth.duration_s)
    folder.clear_earlier()
    rows, allan = [], []
    for cfg in scenario.sensors:
        data = emulate(truth, cfg, seed, range(runs))
        folder.record([plot_sensor(data, truth, out / f"sensor_{cfg.name}.png", run=0)])
        if cfg.kind == "imu":
            folder.record([out / f"allan_{cfg.name}.png"])
            _, ratios = plot_allan(f"{cfg.name} ({cfg.model})", cfg.spec, seed, out / f"allan_{cfg.name}.png")
            allan.append(f"{cfg.name}: white noise read from its Allan deviation at the shortest tau, over the "
                         "datasheet's: " + ", ".join(f"{k} {v:.3f}" for k, v in ratios.items()))
        for label, unit, _, _, _ in channels(data, truth, 0):
            errs = np.concatenate([np.where(data.valid[r], c[3] - c[4], np.nan)
                                   for r in range(runs) for c in channels(data, truth, r) if c[0] == label])
            errs = errs[np.isfinite(errs)]
            rows.append([cfg.name, cfg.model, label, unit, f"{errs.mean():.4g}", f"{errs.std():.4g}",
                         f"{np.percentile(np.abs(errs), 95):.4g}", f"{data.valid.mean() * 100:.1f}"])
    print(_table(["sensor", "model", "channel", "unit", "error mean", "error std", "|error| 95%",
                  "output %"], rows))
    print("\n".join([""] + allan))
    print(f"\n{runs} run(s), seed {seed}; wrote {out}/: sensor_<name>.png (run 0)"
          + (", allan_<imu>.png (at rest)" if allan else ""))
    return 0


def _point_name(n: int, total: int, point: dict) -> str:
    """``point 2/3 (key=value, ...)``: the point of index ``n``, numbered from 1 as everywhere
    the user reads it (progress, errors, sweep.csv)."""
    return f"point {n + 1}/{total} (" + ", ".join(f"{short_key(k)}={v}" for k, v in point.items()) + ")"


def _point_line(n: int, total: int, point: dict, values: dict, res) -> str:
    if res is None:
        return f"{_point_name(n, total, point)}: the flight cannot be flown"
    got = ", ".join(f"{lb} {num(v)}" for lb, v in values.items())
    return f"{_point_name(n, total, point)}: {got} [{len(res.runs)} runs, {res.record.wall_s:.1f} s]"


def cmd_sweep(args) -> int:
    _, _, _, points = parse_sweep(args.sweep)
    folder = _open_folder(args, Path("reports") / Path(args.sweep).stem)
    with Progress(len(points), f"sweep {Path(args.sweep).stem}", unit="point") as bar:
        sweep = api.sweep(args.sweep, args.workers, progress=bar.update, executor=args.executor,
                          scheduler=args.scheduler,
                          on_point=lambda i, p, v, r: print(_point_line(i, len(points), p, v, r), flush=True))
    labels = list(sweep.rows[0][1]) if sweep.rows else []
    ci = lambda n, lb: [sweep.interval(n, lb)] if sweep.interval(n, lb) else None
    table = [[", ".join(f"{short_key(k)}={v}" for k, v in p.items())]
             + [with_interval(vals.get(lb), ci(n, lb)) for lb in labels] for n, (p, vals) in enumerate(sweep.rows)]
    print("\n" + _table(["point"] + [f"{lb}: {sweep.metric}" for lb in labels], table))
    folder.clear_earlier()                 # only now: a sweep that cannot start leaves the earlier one
    write_sweep_files(folder, sweep)
    write_sweep_figure(folder, sweep, f"sweep {Path(args.sweep).name}: {sweep.metric} (vectors by their norm), 95 % intervals over the runs")
    print(f"\nwrote {folder.path}/: sweep.json (every point's metrics), sweep.csv, sweep.png")
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


def cmd_compare(args) -> int:
    comparisons = api.compare(args.a, args.b, args.estimators, partial=args.partial, unpaired=args.unpaired,
                              margin=parse_margins(args.margin))
    name = lambda p: Path(p).resolve().name
    default = Path("reports") / (f"compare_{name(args.a)}" + (f"_vs_{name(args.b)}" if args.b else ""))
    out = (Path(args.out) if args.out else default).resolve()
    for given in filter(None, (args.a, args.b)):
        held = Path(given).resolve()
        if out == held or held in out.parents or out in held.parents:
            raise UsageError(f"--out {out}: inside or holding the result {given} it compares; hint: write the "
                             "comparison to a folder of its own (default reports/compare_<A>_vs_<B>)")
    folder = _open_folder(args, default)     # only now: a refused comparison writes nothing
    for j, c in enumerate(comparisons):
        print(("\n" if j else "") + headline(c) + "\n\n" + _table(list(COMPARE_HEADERS), text_rows(c)))
    folder.clear_earlier()
    files = api.write_comparison(comparisons, folder)
    print(f"\nwrote {folder.path}/: " + ", ".join(f.name for f in files))
    return 0


def parse_margins(items: list[str] | None):
    """``--margin`` strings (``PCT`` or ``PATH=PCT``) as :func:`navsim.compare`'s ``margin``: one
    number, or a mapping of metric path -> per cent (``""`` the default)."""
    out = {}
    for item in items or []:
        path, sep, value = item.rpartition("=")
        try:
            out[path.strip()] = float(value)
        except ValueError:
            raise UsageError(f"--margin {item!r}: expected PCT or PATH=PCT, a number of per cent "
                             "(--margin 2, --margin rms.pos_m=5)") from None
    margin = DEFAULT_MARGIN_PCT if not out else out[""] if list(out) == [""] else out
    try:
        return check_margin(margin)
    except UsageError as exc:                   # in the option's words: margin[...] -> --margin[...]
        raise UsageError(f"--{exc}") from None


def parse_scales(items: list[str] | None) -> list[tuple[str, float]]:
    """``SOURCE=K`` strings to ``(source, factor)``; a factor that is not a number from 0 to
    :data:`~navsim.experiment.budget.MAX_SCALE` is a :class:`UsageError`."""
    out = []
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            factor = float(value)
        except ValueError:
            factor = math.nan
        if not sep or not name or not scale_ok(factor):
            raise UsageError(f"--scale {item!r}: expected SOURCE=K with {SCALE_RANGE} (a budget's what-if "
                             "is linear in the squared errors; far larger factors overflow them); hint: "
                             "--scale imu.gyro.noise_density=0.5")
        out.append((name, factor))
    return out


def parse_budget_metrics(items: list[str] | None, windows=()):
    """``PATH[:COMPONENT]`` strings (``final.pos_m:horizontal``) to pairs, each checked against
    what a budget of a scenario with the metric windows ``windows`` (names) can score; None:
    the default."""
    return None if not items else [budget_metric(x, windows) for x in items]


def cmd_budget(args) -> int:
    scenario = load_scenario(args.scenario)
    scales = parse_scales(args.scale)
    metrics = parse_budget_metrics(args.metric, [w[0] for w in scenario.windows])
    sources = budget_sources(scenario)           # checked before anything runs or is written
    for name, _ in scales:
        find_source(name, sources)
    check_method(scenario, args.method, BUDGET_METHODS, sources)
    carlos = (len(sources) + 2 if args.method != "covariance" else 0) + len(scales)
    if carlos:                                   # each Monte Carlo's runs are held in memory
        resources.check_held(scenario, scenario.runs if args.runs is None else args.runs, workers=args.workers,
                             held="budget")
    folder = _open_folder(args, Path("reports") / scenario.name / "budget")
    todo = carlos + (args.method != "montecarlo")
    try:
        with Progress(todo, f"budget {scenario.name}", unit="step") as bar:
            result = api.budget(scenario, args.runs, args.seed, args.workers, group=args.group, scales=scales,
                                method=args.method, executor=args.executor, scheduler=args.scheduler,
                                progress=lambda *_: bar.update(1), store=folder, resume=args.resume)
    except KeyboardInterrupt:
        kept = len([p for p in folder.path.glob(api.BUDGET_PARTS) if p.name in folder.written()])
        print(f"interrupted: {kept} finished Monte Carlo(s) kept in {folder.path}/; the same command with "
              "--resume completes the budget", file=sys.stderr)
        return 130
    shown = budget_chosen(result, metrics)
    if metrics and not shown:
        raise UsageError(f"--metric: none of {', '.join(':'.join(m) for m in metrics)} is scored; hint: "
                         "final.pos_m:horizontal, rms.att_deg:D, windows.<name>.height_m.rms")
    heads = budget_headers(result)
    runs_flown = result.runs if result.method != "covariance" else 0
    for m in shown:
        rows = budget_text_rows(m, heads) + left_out_rows(result, m, heads)
        print(f"\n{m.estimator}: {m.name}\n" + _table(list(heads), rows) + "\n" + check_text(m))
        for note in rank_notes(m, runs_flown):
            print(note)
    warn_unranked(result, shown)
    for w in result.what_if:
        if (w.metric, w.component) in [(m.metric, m.component) for m in shown]:
            print(f"what if {w.source} x{w.factor:g}: {w.estimator} {w.metric} {w.component} {num(w.all_on)} -> "
                  f"predicted {num(w.predicted)}, run {num(w.measured)} ({100 * w.error:+.1f} %)")
    for line in covariance_notes(result):
        print(line)
    files = api.write_budget(result, folder, metrics)
    folder.clear_earlier()          # an earlier budget's files; this one's, its kept Monte Carlos among them, stay
    done = [f"{carlos} Monte Carlos of {result.runs} runs"] if carlos else []
    if result.method != "montecarlo":
        done.append(f"a covariance analysis in {result.covariance_s:.1f} s")
    print(f"\n{' and '.join(done)}: {result.wall_s:.1f} s; wrote {folder.path}/: " + ", ".join(f.name for f in files))
    return 0


def write_sweep_files(folder: OutputFolder, sweep) -> None:
    """``sweep.json``: each point with its values, their 95 % intervals and its whole
    ``metrics.json``; ``sweep.csv``: one row per point (numbered from 1), the swept parameters
    then the metric of each estimator and its interval's ends (empty where there is none)."""
    folder.json("sweep.json", {"metric": sweep.metric, "points": [
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


def parse_settings(items: list[str] | None) -> dict:
    """``key=value`` strings (values read as YAML) to a dict."""

    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--set {item!r}: expected key=value")
        try:
            out[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise UsageError(f"--set {item!r}: the value is not valid YAML ({exc})") from exc
    return out


DEFAULT_REPLAY_ESTIMATOR = "cpf_ekf"


def cmd_replay(args) -> int:
    name = args.estimator or DEFAULT_REPLAY_ESTIMATOR
    if name not in base.available():
        raise UsageError(f"no estimator '{name}' registered; choose one with --estimator: "
                          + ", ".join(base.available()))
    params = parse_settings(args.set)
    folder = _open_folder(args, Path("reports") / f"replay_{Path(args.log).name.split('.')[0]}_{name}")
    log = load_ulog(args.log, allow_damaged=args.allow_damaged)
    for note in log.notes:
        print(f"warning: {note}", file=sys.stderr)
    bar, update = _progress(f"replaying {Path(args.log).name} through {name}")
    t0 = time.perf_counter()
    try:
        result = replay(log, name, params, imu_rate_hz=args.imu_rate, settle_s=args.settle,
                        align_s=args.align, progress=update)
    finally:
        bar.close()
    folder.clear_earlier()
    out = folder.path
    record = provenance()
    metrics = dataclasses.replace(replay_metrics(result), wall_s=time.perf_counter() - t0, provenance=record)
    folder.json("metrics.json", metrics.to_dict())
    folder.record(write_replay_report(out, result, metrics, record))
    print(f"{name} against PX4's vehicle_attitude, after {args.settle:g} s:")
    print(_table(*difference_table(metrics)))
    for reset in metrics.resets:
        print(f"reset at {reset.t_s:.2f} s: {reset.cause}")
    c = metrics.cost
    print(f"\n{log.duration_s:.1f} s of log replayed {c.real_time_factor:.0f}x faster than real time "
          f"({c.us_per_imu_cycle:.0f} us per IMU cycle); wrote {out}/ "
          "(metrics.json, attitude.png, replay.pdf)")
    return 0


def cmd_schema(args) -> int:
    sys.stdout.write(schema_text())
    return 0


def cmd_validate(args) -> int:
    for path in args.files:
        s = load_scenario(path)
        print(f"{path}: ok ({s.name}: track {s.flight.track.name}, "
              f"{len(s.flight.track.segments)} segments)")
    return 0


def _first_sentence(text: str) -> str:
    """The first sentence of a text, its whitespace collapsed."""
    para = " ".join((text or "").strip().split("\n\n")[0].split())
    end = para.find(". ")
    return para if end < 0 else para[:end + 1]


def _summary(obj) -> str:
    """The first sentence of a class's docstring, or of its module's where the class's has no
    summary of its own (it starts with its parameters, or sends the reader to the module)."""
    doc = (obj.__doc__ or "").strip()
    if not doc or doc.startswith("Parameters") or "see the module docstring" in _first_sentence(doc):
        doc = sys.modules[obj.__module__].__doc__ or ""
    return _first_sentence(doc)


def _listing(title: str, rows: list) -> str:
    """``title:`` then ``name  tag  text`` per row, the columns aligned and the text wrapped
    to the terminal under itself (never cut)."""
    width = max(60, shutil.get_terminal_size((100, 24)).columns)
    w0, w1 = (max((len(r[k]) for r in rows), default=0) for k in (0, 1))
    indent = 2 + w0 + 2 + (w1 + 2 if w1 else 0)
    out = [f"{title}:"]
    for name, tag, text in rows:
        lines = textwrap.wrap(text, max(width - indent, 30)) or [""]
        head = f"  {name:<{w0}}  " + (f"{tag:<{w1}}  " if w1 else "")
        out += [head + lines[0]] + [" " * indent + ln for ln in lines[1:]]
    return "\n".join(out)


def cmd_list(args) -> int:
    print(_listing("aircraft", [(a, "", "") for a in available_aircraft()]))
    print(_listing("sensors (catalog entries)", [(n, k, d) for n, (k, d) in catalog_entries().items()]))
    tracks = [(n, load_track(n)) for n in available_tracks()]
    print(_listing("tracks", [(n, f"{nominal_duration_s(t):.0f} s", _first_sentence(t.description)) for n, t in tracks]))
    print(_listing("estimators (type:)", [(n, "" if base.get(n).__module__.startswith("navsim.") else "plug-in",
                                           _summary(base.get(n))) for n in base.available()]))
    print(_listing("state presets (states:)", [(n, f"{Layout(b).n} states", ", ".join(b)) for n, b in PRESETS.items()]))
    print(_listing("measurement types (measurements: - type:)",
                   [(n, "", _summary(measurement_class(n))) for n in measurement_types()]))
    return 0


def option_type(argument: Argument):
    """An argparse ``type`` reading ``argument``'s option (:meth:`Argument.parse`): a value
    refused is a usage error (exit 2) in the words the API uses."""
    def read(text: str):
        try:
            return argument.parse(text)
        except UsageError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    read.__name__ = argument.kind.__name__
    return read


def _number(kind, minimum=None, maximum=None, exclusive_minimum=None):
    """An argparse ``type`` reading ``kind`` within bounds (an option of the command line only)."""
    return option_type(Argument("", kind, minimum, maximum, exclusive_minimum))


RUNS, CHUNK_RUNS = option_type(api.RUNS), option_type(api.CHUNK_RUNS)
SEED, WORKERS = option_type(api.SEED), option_type(api.WORKERS)


def scheduler_address(text: str) -> str:
    """A Dask scheduler address (argparse ``type``; :func:`navsim.api.check_scheduler`)."""
    try:
        return api.check_scheduler(text, "")
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


#: the end of the --help of every command that writes an output folder; ``{kept}``: what an
#: interrupt leaves, as the command has it (:data:`KEPT`)
WRITER_EPILOG = ("The output folder is locked while the command writes it: a second command writing "
                 "there is refused (exit 2) with the holder's pid and start time; a lock left by a "
                 "killed command is taken over. A non-empty folder that is not a navsim result is "
                 "refused (exit 2, its files named) unless --force; a folder holding another command's "
                 "result is refused (exit 2), even with --force. Ctrl-C or SIGTERM (how Slurm, "
                 "Kubernetes and Dask stop a job) stops it as an interrupt: {kept}, exit 130 for Ctrl-C, "
                 "143 for SIGTERM ('terminated'); the worker processes end with it, also when it is killed.")
#: what an interrupt leaves, per command (the others: :data:`NOTHING_RESUMED`)
KEPT = {"run": "the finished chunks are kept and --resume completes the run",
        "budget": "the finished Monte Carlos are kept (budget_part_*.npz) and --resume completes the budget",
        "sweep": "the finished points are written (sweep.json, sweep.csv, sweep.png; nothing completes "
                 "the rest later: run the sweep again)"}
NOTHING_RESUMED = "what it wrote stays (nothing completes it later: run it again)"


def _writer_options(p, command: str = "") -> None:
    """--force, and the epilog on locks and signals, of a command that writes a folder
    (``command``: its key of :data:`KEPT`, if it has one)."""
    p.add_argument("--force", action="store_true",
                   help="write into --out even when it is a non-empty folder that is not a navsim "
                   "result (its files of the same names are replaced)")
    p.epilog = WRITER_EPILOG.format(kept=KEPT.get(command, NOTHING_RESUMED))


def _executor_options(p) -> None:
    p.add_argument("--executor", choices=api.EXECUTORS, default="local",
                   help="where the chunks of runs go: a process pool here (local, default) or Dask "
                   "distributed tasks (dask; needs pip install 'navsim[dask]')")
    p.add_argument("--scheduler", metavar="ADDRESS", type=scheduler_address,
                   help="with --executor dask: a running scheduler (tcp://host:8786); without it a "
                   "LocalCluster of --workers processes is started")


def _budget_parser(sub) -> None:
    p = sub.add_parser("budget", help="error budget: each error source's share of every estimator's errors",
                       description="Run the scenario's Monte Carlo with every error source on, with none, and "
                       "with each source alone (the same seeds: a source's realisation is the one it has with "
                       "all on); print each source's contribution to the final and RMS errors, its share of "
                       "the variance and the root-sum-square against the all-on value (the linearity check). "
                       "Sources: every error term of the sensors' truth models that is on, each fault, the "
                       "initial attitude, velocity and position errors. --method covariance: each source's "
                       "contribution by one covariance analysis along the flight instead (no runs; the sources "
                       "without a linear form, faults, quantization, saturation, vibration, latency and lever "
                       "arm, are named and left to Monte Carlo); --method both: the Monte Carlo budget with the "
                       "covariance analysis's figure beside each line. Writes budget.json, budget.csv and "
                       "budget.pdf/.png.")
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--runs", type=RUNS, help="runs per Monte Carlo (default: montecarlo.runs)")
    p.add_argument("--seed", type=SEED, help="seed (default: montecarlo.seed)")
    p.add_argument("--workers", type=WORKERS, help="worker processes (default: montecarlo.workers)")
    p.add_argument("--group", choices=BUDGET_GROUP_NAMES, default="source",
                   help="the budget's lines: each source (default), each sensor, each sensor's kind of term")
    p.add_argument("--scale", action="append", metavar="SOURCE=K",
                   help=f"what if: the source scaled by K ({SCALE_RANGE}), predicted from the budget and "
                   "checked by a run (repeatable)")
    p.add_argument("--metric", action="append", metavar="PATH[:COMPONENT]",
                   help="a metric to print and draw (repeatable; default final.pos_m:horizontal, "
                   "final.att_deg:D, rms.pos_m:horizontal, rms.att_deg:D); budget.json has every RMS metric")
    p.add_argument("--method", choices=BUDGET_METHODS, default="montecarlo",
                   help="montecarlo (default): a Monte Carlo per source; covariance: one covariance analysis "
                   "(ES-KF and free inertial, seconds); both: Monte Carlo with the covariance figures beside")
    p.add_argument("--out", help="output folder (default reports/<name>/budget)")
    p.add_argument("--resume", action="store_true",
                   help="complete an interrupted budget in --out: each Monte Carlo it finished is read back "
                   "(budget_part_*.npz, kept for the same scenario, source, runs, seed and navsim version), "
                   "the others run")
    _executor_options(p)
    _writer_options(p, "budget")
    p.set_defaults(func=cmd_budget)


def _compare_parser(sub) -> None:
    p = sub.add_parser("compare", help="compare two estimators' metrics: B - A with 95 %% intervals",
                       description="Compare the metrics of two results (navsim run's folders), or of two "
                       "estimators of one result: for each metric A, B, B - A with its 95 % interval and a "
                       "verdict (better / worse / no significant difference at N runs, with the runs that "
                       "would resolve it; NEES: higher / lower). When both flew the same flights and sensor "
                       "data (the resolved scenarios equal but for their estimators and run counts, the same "
                       "seed and flight) the runs are paired by number, which cancels the noise they share; "
                       "else side against side. Writes compare.json, compare.csv and compare.pdf/.png. "
                       "Refused with exit 2, nothing written: a folder that is not a result, damaged, or that an "
                       "older or newer navsim wrote, two different tracks or metric settings, an interrupted result "
                       "(unless --partial).")
    p.add_argument("a", help="result folder A")
    p.add_argument("b", nargs="?", help="result folder B (default: A, comparing two of its estimators)")
    p.add_argument("--estimators", nargs="+", metavar="LABEL",
                   help="the estimator of A and of B (one label: the same on both; default: every label both "
                   "have, or each one's only estimator)")
    p.add_argument("--partial", action="store_true",
                   help="compare an interrupted result's finished runs (each side's count is printed)")
    p.add_argument("--unpaired", action="store_true",
                   help="compare side against side even where the runs pair (to see what pairing gains)")
    p.add_argument("--margin", action="append", metavar="[PATH=]PCT",
                   help="the practical-equivalence margin, per cent of the larger value: a difference whose "
                   f"95 %% interval lies within it is 'negligible', and none within it is offered a run count "
                   f"(default {DEFAULT_MARGIN_PCT:g}); PATH=PCT sets it for a metric path (rms.pos_m=5); repeatable")
    p.add_argument("--out", help="output folder (default reports/compare_<A>_vs_<B>)")
    _writer_options(p)
    p.set_defaults(func=cmd_compare)


def _replay_parser(sub) -> None:
    p = sub.add_parser("replay", help="replay a real PX4 flight log through an estimator",
                       description="Read a PX4 ULog (pyulog), feed its IMU, magnetometer and baro "
                       "to an estimator from a coarse alignment on the first second, and compare "
                       "its roll, pitch and yaw with PX4's own vehicle_attitude; write "
                       "metrics.json, attitude.png and replay.pdf, print the differences. An "
                       "ES-KF-family estimator gets a zero velocity (it levels) and the heading "
                       "of PX4's calibrated magnetometer unless --set measurements=... says "
                       "otherwise; it needs the filter's IMU model: --set 'noise={imu: mpu6050}'. "
                       "Exit 2 for a log that cannot be replayed.")
    p.add_argument("log", help="PX4 .ulg file (example: tests/data/px4_quad_real_69s.ulg.gz)")
    p.add_argument("--estimator", help=f"registered estimator (default {DEFAULT_REPLAY_ESTIMATOR})")
    p.add_argument("--out", help="output folder (default reports/replay_<log>_<estimator>)")
    p.add_argument("--settle", type=_number(float, minimum=0.0), default=10.0,
                   help="seconds left out of the metrics while the estimator converges (default 10)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="estimator parameter (YAML value), repeatable: --set period_s=0.02")
    p.add_argument("--imu-rate", type=_number(float, minimum=IMU_RATE_HZ[0], maximum=IMU_RATE_HZ[1]),
                   help="IMU grid rate, Hz (default: the log's, 250 Hz for PX4's sensor_combined)")
    p.add_argument("--align", type=_number(float, exclusive_minimum=0.0), default=1.0,
                   help="coarse-alignment window from the first sample, s (default 1)")
    p.add_argument("--allow-damaged", action="store_true",
                   help="replay what a truncated or corrupt log still holds instead of refusing it")
    _writer_options(p)
    p.set_defaults(func=cmd_replay)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="navsim", description="UAV integrated-navigation testbed: JSBSim flights, sensor "
        "emulators, estimators, Monte Carlo reports.")
    parser.add_argument("--version", action="version", version=f"navsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    p = sub.add_parser("fly", help="fly a scenario's track and plot it",
                       description="Fly the scenario's track in JSBSim under the autopilot; write "
                       "the truth (truth.npz), PNG plots, run.json and print a summary.")
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--out", help="output folder (default reports/<name>/flight)")
    p.add_argument("--rate-hz", type=_number(float, minimum=RATE_HZ[0], maximum=RATE_HZ[1]),
                   help=f"simulation and truth rate, {RATE_HZ[0]:g}-{RATE_HZ[1]:g} Hz (default: scenario's, 100)")
    _writer_options(p)
    p.set_defaults(func=cmd_fly)
    p = sub.add_parser("run", help="run a scenario's Monte Carlo and write its report",
                       description="Fly the track (cached), emulate the sensors and run every "
                       "estimator over the Monte Carlo runs; write report.pdf, PNGs, metrics.json, "
                       "scenario.resolved.yaml and the per-run data (chunks/); print a summary table.")
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--runs", type=RUNS, help="Monte Carlo runs, >= 1 (default: montecarlo.runs)")
    p.add_argument("--seed", type=SEED, help="seed, >= 0 (default: montecarlo.seed)")
    p.add_argument("--workers", type=WORKERS, help=f"worker processes, 1-{MAX_WORKERS} (default: montecarlo.workers)")
    p.add_argument("--out", help="output folder (default reports/<name>)")
    _executor_options(p)
    p.add_argument("--chunk-runs", type=CHUNK_RUNS, metavar="N",
                   help="runs per chunk, the unit of work streamed to <out>/chunks (default 250; "
                   "the numbers do not depend on it)")
    p.add_argument("--resume", action="store_true",
                   help="complete an interrupted run in --out: run only the chunks missing from "
                   "<out>/chunks (same scenario, seed and runs, else exit 2)")
    _writer_options(p, "run")
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("sensors", help="emulate a scenario's sensors and plot them against the truth",
                       description="Fly the scenario's track, emulate its sensors for the Monte "
                       "Carlo runs, write one PNG per sensor (output against truth, error) and print "
                       "error statistics over all runs.")
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--runs", type=RUNS, help="number of runs (default: the scenario's montecarlo.runs)")
    p.add_argument("--seed", type=SEED, help="seed (default: the scenario's montecarlo.seed)")
    p.add_argument("--out", help="output folder (default reports/<name>/sensors)")
    _writer_options(p)
    p.set_defaults(func=cmd_sensors)
    p = sub.add_parser("validate", help="check scenario files without running them",
                       description="Check scenario files; exit 2 on the first malformed one.")
    p.add_argument("files", nargs="+", help="scenario YAML files")
    p.set_defaults(func=cmd_validate)
    p = sub.add_parser("sweep", help="run a grid of scenario variants and compare a metric",
                       description="Run every point of a sweep file (a grid or a list of changes "
                       "to a scenario), each a Monte Carlo; print a table and plot the chosen metric.")
    p.add_argument("sweep", help="sweep YAML file")
    p.add_argument("--workers", type=WORKERS, help="worker processes (default: the scenario's)")
    p.add_argument("--out", help="output folder (default reports/<sweep name>)")
    _executor_options(p)
    _writer_options(p, "sweep")
    p.set_defaults(func=cmd_sweep)
    _replay_parser(sub)
    _compare_parser(sub)
    _budget_parser(sub)
    p = sub.add_parser("schema", help="print the JSON Schema of scenario files",
                       description="Print the JSON Schema of scenario files for editors, with the "
                       "estimators and measurement types of installed plug-ins (docs/scenario.schema.json "
                       "holds navsim's own); navsim's own validation is stricter.")
    p.set_defaults(func=cmd_schema)
    p = sub.add_parser("list", help="list the shipped aircraft, sensors, tracks, estimators and measurements",
                       description="List the shipped aircraft, sensor catalog entries and tracks, and the "
                       "registered estimators and measurement types (installed plug-ins' included).")
    p.set_defaults(func=cmd_list)
    return parser


class _ToStderr(logging.Handler):
    """Log records as plain lines on the current ``sys.stderr`` (the progress of long work)."""

    def emit(self, record) -> None:
        print(self.format(record), file=sys.stderr, flush=True)


def _show_progress() -> None:
    """Send the library's progress lines (logger ``navsim.progress``) to stderr, once."""
    log = logging.getLogger("navsim.progress")
    if not any(isinstance(h, _ToStderr) for h in log.handlers):
        log.addHandler(_ToStderr())
        log.setLevel(logging.INFO)


def main(argv: list[str] | None = None) -> int:
    _show_progress()
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with stop_on_sigterm() as stop:
            code = _run_command(args)
    except Terminated:                        # a SIGTERM while the command's folders were closed
        code = TERMINATED_EXIT
    if stop.terminated and code in (130, TERMINATED_EXIT):
        print("terminated (SIGTERM): what finished is kept", file=sys.stderr)
        return TERMINATED_EXIT
    return code


def _run_command(args) -> int:
    """``args.func(args)``, its errors as messages and exit codes; the folders it held closed."""
    try:
        return args.func(args)
    except NavsimError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:                     # the disk, a permission: the environment, not a bug
        print(f"error: {OutputError(exc.filename or '?', exc)}", file=sys.stderr)
        return OutputError.exit_code
    except Terminated:
        return TERMINATED_EXIT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        while _OPEN:
            _OPEN.pop().close()


if __name__ == "__main__":
    sys.exit(main())
