"""``navsim tune``: an estimator's parameters searched for the lowest objective over Monte Carlo
runs, and the best checked against the original on runs the tuning never saw."""

from __future__ import annotations

from pathlib import Path

from navsim.api.tuning import TuneOptions, tune, tune_log
from navsim.cli.command import Command
from navsim.cli.options import RUNS_TYPE, SEED_TYPE, executor_options, load_plugins, number, out_option, plugin_option
from navsim.cli.options import set_option, workers_option
from navsim.cli.output import open_folder, table
from navsim.foundations.errors import UsageError
from navsim.foundations.progress import Progress
from navsim.report.tuning import consistency_rows, paper_check_tables, value_text
from navsim.scoring.tuning import DEFAULT_METRIC, OBJECTIVES
from navsim.scoring.verdicts import VERDICT_HEADERS, num


#: the options a log's tuning (--replay) does not take
REPLAY_REFUSED = ("overrides", "runs", "check_runs", "workers", "seed", "metric", "shape")


def arguments(p) -> None:
    """The scenario, the estimator, the parameters, the objective, the trials and runs, --out."""
    p.add_argument("scenario", nargs="?", help="scenario YAML file (none with --replay)")
    p.add_argument("--estimator", required=True, metavar="LABEL",
                   help="the label of the estimator tuned (with --replay: a registered estimator, cpf_ekf)")
    p.add_argument("--replay", metavar="LOG", help="tune on a PX4 log instead, by its innovations (--objective "
                   "nis or nis-band; --param paths into the estimator's parameters, sigma.mag_uT=0.5:20:log), "
                   "the attitude against PX4's compared before and after")
    p.add_argument("--param", action="append", default=[], metavar="PATH=LO:HI[:log]",
                   help="a parameter and its range, repeatable: a --set path into the estimator's entry "
                   "(measurements[0].sigma_m=1:20:log), or a factor on its value with x (measurements[1].sigma_mps="
                   "x0.1:10:log, a list scaled as a whole); a path starting sensors. is the truth model's, a "
                   "datasheet value with its unit (sensors.gps.override.vertical_sigma=5:30 m): what --objective "
                   "paper calibrates; default: each measurement sigma and the baro sigma scaled by a factor in "
                   "0.1-10 (log)")
    p.add_argument("--objective", choices=OBJECTIVES,
                   help="what is minimised: rms (of --metric), nees (the distance of ln(NEES/dim) from 0), nees-band (the share of "
                   "epochs outside the NEES band), nis and nis-band (the same on each NIS, no truth needed), "
                   "rms+consistent (the RMS, penalised outside the NEES band), paper (the distance of the runs' "
                   "median from the paper's single-flight numbers of the estimator, in log); default nees, "
                   "with --replay nis")
    p.add_argument("--shape", type=number(float, minimum=0.0), metavar="W",
                   help="add W times the Kolmogorov-Smirnov distance of the NEES (NIS for nis objectives) "
                   "samples from their chi-square (Chen et al. 2023): right in shape, not only on average")
    p.add_argument("--metric", help=f"the rms objectives' metric (default {DEFAULT_METRIC})")
    p.add_argument("--trials", type=number(int, minimum=1), help=f"trials (default {TuneOptions.trials})")
    p.add_argument("--runs", type=RUNS_TYPE, help=f"runs per trial, every trial the same (default {TuneOptions.runs})")
    p.add_argument("--check-runs", type=RUNS_TYPE, help="runs of each check of the best (default --runs)")
    p.add_argument("--seed", type=SEED_TYPE, help="the tuning seed (default montecarlo.seed); the held-out check "
                   "flies another")
    workers_option(p)
    executor_options(p)
    out_option(p, "reports/tune_<name>_<estimator>")
    p.add_argument("--resume", action="store_true", help="continue the tuning in --out to --trials trials "
                   "(the same trials as uninterrupted)")
    set_option(p)
    plugin_option(p)


def handle(args) -> int:
    """Tune, write tune.json, tune.csv, tuned.yaml and tune.pdf, print the best and the checks."""
    load_plugins(args)
    if args.replay:
        given = [f"--{o.replace('_', '-')}" for o in REPLAY_REFUSED if getattr(args, o) not in (None, [])]
        if given:
            raise UsageError(f"{', '.join(given)}: not an option of --replay (one log: no runs, seeds or scenario)")
    objective = args.objective or ("nis" if args.replay else "nees")
    given = {"metric": args.metric, "trials": args.trials, "runs": args.runs}
    options = TuneOptions(objective=objective, seed=args.seed, workers=args.workers, check_runs=args.check_runs,
                          params=tuple(args.param), set=tuple(args.overrides), executor=args.executor,
                          scheduler=args.scheduler, shape=args.shape or 0.0,
                          **{k: v for k, v in given.items() if v is not None})
    if (args.scenario is None) == (args.replay is None):
        raise UsageError("give a scenario file, or --replay LOG, not both" if args.scenario else
                         "give the scenario file to tune on (or --replay LOG)")
    label = "".join(c if c.isalnum() else "_" for c in args.estimator)
    source = Path(args.scenario or args.replay).name.split(".")[0]
    folder = open_folder(args, Path("reports") / f"tune_{source}_{label}")
    with Progress(options.trials, f"tuning {args.estimator} ({objective})", unit="trial") as bar:
        def step(trial):
            bar.update(1)
        how = dict(out=folder.path, resume=args.resume, progress=step)
        result = (tune_log(args.replay, args.estimator, options, **how) if args.replay
                  else tune(args.scenario, args.estimator, options, **how))
    r = result.record
    best = r.best_trial
    print(f"\n{len(r.trials)} trials of {r.runs} runs in {r.wall_s:.0f} s; best trial {r.best}: {objective} "
          f"{num(best.objective)}")
    print(table(["parameter", "best", "value set"],
                [[p.what, num(best.values[p.name]), value_text(p.value(best.values[p.name]))] for p in result.params]))
    for name, c in r.checks.items():
        where = "the log" if name == "log" else f"{name.replace('_', '-')} seed {c.seed} ({c.runs} runs)"
        print(f"\n{where}: {objective} {num(c.objective_original)} original, {num(c.objective_tuned)} tuned")
        if c.differences:
            print(table(["metric", "original", "tuned", "tuned - original [95 %]", "verdict"],
                        [[d["metric"] + (f" {d['component']}" if d["component"] else ""), num(d["a"]), num(d["b"]),
                          f"{num(d['diff'])} [{num(d['ci95'][0])}, {num(d['ci95'][1])}]", d["verdict"]]
                         for d in c.differences]))
        print(table(["consistency", "original: average [band], inside", "tuned: average [band], inside"],
                    consistency_rows(c.consistency)))
        for title, rows in paper_check_tables(c):
            print(f"\n{title}")
            print(table(VERDICT_HEADERS, rows))
    if r.improved is False:
        print("\nno trial beat the original (trial 0): keep it, or widen the ranges and add trials")
    elif r.improved is None:
        print("\nthe original was not a trial (its value outside a range, a list of unequal values, a log's "
              "defaults, a sensor's datasheet value): compare the checks above before taking the tuned values")
    what = "parameters" if args.replay else "sensors" if r.tuned_sensors is not None else "entry"
    print(f"\nwrote {folder.path}/: tuned.yaml (the {what} to paste), "
          "tune.json, tune.csv, tune.pdf and its PNGs")
    return 0


COMMAND = Command(
    "tune", "tune an estimator's noise against the truth over Monte Carlo runs",
    usage="SCENARIO.yaml --estimator LABEL",
    description="Search the estimator's parameters (--param, default: each measurement noise scaled) with "
    "Optuna's TPE sampler for the lowest objective over --runs runs per trial, every trial on the same seed; "
    "then run the best and the original side by side on the tuning seed and on a seed the tuning never saw, "
    "compared paired (B - A with 95 % intervals and verdicts: a held-out gain smaller than the tuning one is "
    "over-fitting). With truth parameters (sensors.) and --objective paper, the sensors' unpublished errors "
    "are calibrated against the paper's numbers, and the checks fly the whole scenario with the original and the "
    "fitted truth, its paper checks judged (the fit's prediction of the other estimators). With --replay LOG, a PX4 log instead, by its innovations, the attitude against PX4's before "
    "and after. Writes tuned.yaml, tune.json, tune.csv, tune.pdf; --resume continues an interrupted tuning "
    "from its journal.",
    arguments=arguments, handler=handle, kept="the finished trials are kept and --resume completes the tuning")
