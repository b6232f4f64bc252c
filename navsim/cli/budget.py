"""``navsim budget``: each error source's share of every estimator's errors, by Monte Carlo, by
one covariance analysis, or both; its what-if scalings predicted and checked."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

from navsim import api
from navsim.cli.command import Command
from navsim.cli.options import executor_options, monte_carlo_options, out_option, run_options, scenario_argument
from navsim.cli.options import scenario_of
from navsim.cli.output import open_folder, table
from navsim.experiment import resources
from navsim.experiment.budget import GROUPS as BUDGET_GROUP_NAMES, SCALE_RANGE, budget_sources, check_method
from navsim.experiment.budget import find_source, scale_ok
from navsim.foundations.errors import UsageError
from navsim.foundations.progress import Progress
from navsim.report.budget import check_text, chosen as budget_chosen, covariance_notes, left_out_rows, rank_notes
from navsim.report.budget import headers as budget_headers, text_rows as budget_text_rows, warn_unranked
from navsim.scoring.budget import METHODS as BUDGET_METHODS, check_metric as budget_metric
from navsim.scoring.verdicts import num


def arguments(p) -> None:
    """The scenario, the Monte Carlo numbers, the lines, the what-ifs, the metrics, the method,
    ``--out``, ``--resume`` and the executor."""
    scenario_argument(p)
    monte_carlo_options(p, runs="runs per Monte Carlo")
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
    out_option(p, "reports/<name>/budget")
    p.add_argument("--resume", action="store_true",
                   help="complete an interrupted budget in --out: each Monte Carlo it finished is read back "
                   "(budget_part_*.npz, kept for the same scenario, source, runs, seed and navsim version), "
                   "the others run")
    executor_options(p)


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


def handle(args) -> int:
    """Check every argument, run the budget into the output folder (its finished Monte Carlos
    kept for ``--resume``), print and write it; 130 when interrupted."""
    scenario = scenario_of(args)
    options = run_options(args)
    scales = parse_scales(args.scale)
    metrics = parse_budget_metrics(args.metric, [w[0] for w in scenario.windows])
    sources = budget_sources(scenario)           # checked before anything runs or is written
    for name, _ in scales:
        find_source(name, sources)
    check_method(scenario, args.method, BUDGET_METHODS, sources)
    carlos = (len(sources) + 2 if args.method != "covariance" else 0) + len(scales)
    if carlos:                                   # each Monte Carlo's runs are held in memory
        resources.check_held(scenario, scenario.runs if options.runs is None else options.runs,
                             workers=options.workers, held="budget")
    folder = open_folder(args, Path("reports") / scenario.name / "budget")
    todo = carlos + (args.method != "montecarlo")
    try:
        with Progress(todo, f"budget {scenario.name}", unit="step") as bar:
            result = api.budget(scenario, group=args.group, method=args.method, scales=scales, store=folder,
                                options=dataclasses.replace(options, progress=lambda *_: bar.update(1)))
    except KeyboardInterrupt:
        kept = len([p for p in folder.path.glob(api.BUDGET_PARTS) if p.name in folder.written()])
        print(f"interrupted: {kept} finished Monte Carlo(s) kept in {folder.path}/; the same command with "
              "--resume completes the budget", file=sys.stderr)
        return 130
    _print_budget(result, metrics)
    files = api.write_budget(result, folder, metrics)
    folder.clear_earlier()          # an earlier budget's files; this one's, its kept Monte Carlos among them, stay
    done = [f"{carlos} Monte Carlos of {result.runs} runs"] if carlos else []
    if result.method != "montecarlo":
        done.append(f"a covariance analysis in {result.covariance_s:.1f} s")
    print(f"\n{' and '.join(done)}: {result.wall_s:.1f} s; wrote {folder.path}/: " + ", ".join(f.name for f in files))
    return 0


def _print_budget(result, metrics) -> None:
    """Each metric shown (``metrics``, None: the default ones): its table, the linearity check,
    the ranking notes, then the what-ifs and the covariance analysis's notes."""
    shown = budget_chosen(result, metrics)
    if metrics and not shown:
        raise UsageError(f"--metric: none of {', '.join(':'.join(m) for m in metrics)} is scored; hint: "
                         "final.pos_m:horizontal, rms.att_deg:D, windows.<name>.height_m.rms")
    heads = budget_headers(result)
    runs_flown = result.runs if result.method != "covariance" else 0
    for m in shown:
        rows = budget_text_rows(m, heads) + left_out_rows(result, m, heads)
        print(f"\n{m.estimator}: {m.name}\n" + table(list(heads), rows) + "\n" + check_text(m))
        for note in rank_notes(m, runs_flown):
            print(note)
    warn_unranked(result, shown)
    for w in result.what_if:
        if (w.metric, w.component) in [(m.metric, m.component) for m in shown]:
            print(f"what if {w.source} x{w.factor:g}: {w.estimator} {w.metric} {w.component} {num(w.all_on)} -> "
                  f"predicted {num(w.predicted)}, run {num(w.measured)} ({100 * w.error:+.1f} %)")
    for line in covariance_notes(result):
        print(line)


COMMAND = Command(
    "budget", "error budget: each error source's share of the errors", usage="SCENARIO.yaml [--method M]",
    description="Run the scenario's Monte Carlo with every error source on, with none, and with each source "
    "alone (the same seeds: a source's realisation is the one it has with all on); print each source's "
    "contribution to the final and RMS errors, its share of the variance and the root-sum-square against the "
    "all-on value (the linearity check). Sources: every error term of the sensors' truth models that is on, "
    "each fault, the initial attitude, velocity and position errors. --method covariance: each source's "
    "contribution by one covariance analysis along the flight instead (no runs; the sources without a linear "
    "form, faults, quantization, saturation, vibration, latency and lever arm, are named and left to Monte "
    "Carlo); --method both: the Monte Carlo budget with the covariance analysis's figure beside each line. "
    "Writes budget.json, budget.csv and budget.pdf/.png.",
    arguments=arguments, handler=handle,
    kept="the finished Monte Carlos are kept (budget_part_*.npz) and --resume completes the budget")
