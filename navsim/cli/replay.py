"""``navsim replay``: a flight log through navsim's estimators: a PX4 ULog's attitude compared
with PX4's own, or an INS/GNSS text log (KF-GINS, CSV) scored as one Monte Carlo run."""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import yaml

from navsim import api
from navsim.api.replays import DEFAULT_LOG_SCENARIO, LOG_FORMATS, log_format
from navsim.cli.command import Command
from navsim.cli.options import NOTHING_RESUMED, load_plugins, number, out_option, plugin_option
from navsim.cli.output import open_folder, progress, table
from navsim.cli.run import artifacts, print_run_summary
from navsim.foundations.errors import UsageError
from navsim.foundations.progress import Progress
from navsim.foundations.provenance import provenance
from navsim.navigation.estimators import base
from navsim.replay import ReplayOptions, load_ulog, replay, replay_metrics
from navsim.replay.run import ALIGN_S, IMU_RATE_HZ
from navsim.replay.ulog_nav import ulog_navlog
from navsim.report.replay import difference_table, write_replay_report

DEFAULT_REPLAY_ESTIMATOR = "cpf_ekf"


def arguments(p) -> None:
    """The log and its companion files, the estimator or scenario and its settings, ``--out``,
    the settling and alignment times, the IMU rate and whether a damaged log is read."""
    p.add_argument("log", help="a PX4 .ulg (example: tests/data/px4_quad_real_69s.ulg.gz), a KF-GINS IMU file or "
                   "configuration (.txt, .yaml), or an IMU CSV (.csv); docs/data.md has the formats")
    p.add_argument("--format", choices=FORMATS, help="the log's format (default: by its name: .ulg ulog, .csv csv, "
                   "else kfgins)")
    p.add_argument("--gnss", metavar="FILE", help="text logs: the GNSS fixes (KF-GINS: default the configuration's)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--reference", metavar="FILE", help="text logs: the reference trajectory the estimators are "
                       "scored against (KF-GINS truth.nav or a reference CSV)")
    group.add_argument("--solution", metavar="FILE", help="text logs: the log's own navigation solution (the same "
                       "layout); the scores are differences from it, not errors")
    p.add_argument("--start", metavar="FILE", help="text logs: a YAML with KF-GINS's start keys (starttime, initpos, "
                   "initvel, initatt and their std; default: the reference's first state and the scenario's "
                   "initial_errors)")
    p.add_argument("--scenario", metavar="FILE", help="the scenario whose estimators run (text logs: default the "
                   f"shipped {DEFAULT_LOG_SCENARIO}; a PX4 log with GNSS: its position and velocity compared with "
                   "EKF2's); its IMU and first GNSS receiver take the log's data")
    p.add_argument("--estimator", help=f"PX4 logs: registered estimator (default {DEFAULT_REPLAY_ESTIMATOR})")
    out_option(p, "reports/replay_<log>_<estimator or scenario>")
    p.add_argument("--settle", type=number(float, minimum=0.0),
                   help="seconds left out of the metrics while the estimator converges (PX4 logs: default 10; "
                   "text logs: the scenario's metrics.settle_s)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="PX4 logs: an estimator parameter (YAML value), --set period_s=0.02; text logs: a scenario "
                   "path, as navsim run's --set; repeatable")
    p.add_argument("--imu-rate", type=number(float, minimum=IMU_RATE_HZ[0], maximum=IMU_RATE_HZ[1]),
                   help="PX4 logs: IMU grid rate, Hz (default: the log's, 250 Hz for PX4's sensor_combined)")
    p.add_argument("--align", type=number(float, exclusive_minimum=0.0),
                   help="PX4 logs: coarse-alignment window from the first sample, s (default 1)")
    p.add_argument("--allow-damaged", action="store_true",
                   help="PX4 logs: replay what a truncated or corrupt log still holds instead of refusing it")
    plugin_option(p)


#: the formats ``navsim replay`` reads
FORMATS = LOG_FORMATS
#: the options each kind of replay takes of those not every one takes
OPTIONS = {"attitude": ("estimator", "imu_rate", "align", "allow_damaged"),
           "position": ("gnss", "reference", "solution", "start", "scenario"),
           "ulog position": ("scenario", "imu_rate", "allow_damaged")}


def format_of(args) -> str:
    """The log's format: ``--format``, else its name's."""
    return args.format or log_format(args.log)


def kind_of(args, fmt: str) -> str:
    """What the replay is: a PX4 log's ``attitude`` against PX4's, or a scenario's estimators
    over a text log (``position``) or over a PX4 log with GNSS (``ulog position``: ``--scenario``)."""
    if fmt != "ulog":
        return "position"
    return "ulog position" if args.scenario else "attitude"


def check_options(args, kind: str) -> None:
    """Refuse an option this kind of replay does not take."""
    others = {o for opts in OPTIONS.values() for o in opts} - set(OPTIONS[kind])
    given = [o for o in sorted(others) if getattr(args, o) not in (None, False)]
    if given:
        what = {"attitude": "a PX4 log's attitude replay (without --scenario)", "position": "a text log's replay",
                "ulog position": "a PX4 log's replay through a scenario (--scenario)"}[kind]
        raise UsageError(f"{', '.join('--' + o.replace('_', '-') for o in given)}: not an option of {what}")


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


def handle(args) -> int:
    """Replay the log (a PX4 ULog: attitude against PX4's; a text log: a scenario's estimators
    scored against its reference), write metrics.json and the report, print the summary."""
    fmt = format_of(args)
    kind = kind_of(args, fmt)
    check_options(args, kind)
    load_plugins(args)
    return _ulog(args) if kind == "attitude" else _position(args, fmt)


def _position(args, fmt: str) -> int:
    """A log (KF-GINS, CSV, a PX4 log with GNSS) through a scenario's estimators, scored as one run."""
    if fmt == "ulog":
        log = ulog_navlog(args.log, allow_damaged=args.allow_damaged, rate_hz=args.imu_rate)
    else:
        log = api.read_log(args.log, args.gnss, args.reference or args.solution, args.start, format=fmt,
                           solution=args.solution is not None)
    changes = list(args.set or []) + ([f"metrics.settle_s={args.settle!r}"] if args.settle is not None else [])
    name = Path(args.scenario).stem if args.scenario else DEFAULT_LOG_SCENARIO
    folder = open_folder(args, Path("reports") / f"replay_{log.name}_{name}")
    with Progress(int(log.imu.t_s.size), f"replaying {log.name} through {name}", unit="sample") as bar:
        result = api.replay_log(log, args.scenario, set=changes, out=folder.path,
                                progress=lambda i, n: bar.update(i - bar.n))
    files = api.write_report(result)
    against = result.record.log["scored_against"]
    print(f"{log.name} ({fmt}, {log.duration_s:.1f} s): "
          + ("differences from the log's own solution, not errors" if against == "solution"
             else "errors against the log's reference"))
    for note in result.record.log["notes"]:
        print(f"note: {note}")
    print_run_summary(result)
    print(f"\nreplayed in {result.record.wall_s:.1f} s; wrote {folder.path}/: {artifacts(folder.path, files)}")
    return 0


def _ulog(args) -> int:
    """A PX4 log's attitude through an estimator, against PX4's own."""
    name = args.estimator or DEFAULT_REPLAY_ESTIMATOR
    if name not in base.available():
        raise UsageError(f"no estimator '{name}' registered; choose one with --estimator: "
                         + ", ".join(base.available()))
    params = parse_settings(args.set)
    settle = 10.0 if args.settle is None else args.settle
    folder = open_folder(args, Path("reports") / f"replay_{Path(args.log).name.split('.')[0]}_{name}")
    log = load_ulog(args.log, allow_damaged=args.allow_damaged)
    for note in log.notes:
        print(f"warning: {note}", file=sys.stderr)
    bar, update = progress(f"replaying {Path(args.log).name} through {name}")
    t0 = time.perf_counter()
    try:
        options = ReplayOptions(imu_rate_hz=args.imu_rate, settle_s=settle, align_s=args.align or ALIGN_S)
        result = replay(log, name, params, options, progress=update)
    finally:
        bar.close()
    folder.clear_earlier()
    out = folder.path
    record = provenance()
    metrics = dataclasses.replace(replay_metrics(result), wall_s=time.perf_counter() - t0, provenance=record)
    folder.json("metrics.json", metrics.to_dict())
    folder.record(write_replay_report(out, result, metrics, record))
    print(f"{name} against PX4's vehicle_attitude, after {settle:g} s:")
    print(table(*difference_table(metrics)))
    for reset in metrics.resets:
        print(f"reset at {reset.t_s:.2f} s: {reset.cause}")
    for key, n in (metrics.nis or {}).items():
        print(f"NIS {key}: average {n.average:.3g} (band of the average {n.band[0]:.3g}-{n.band[1]:.3g}), "
              f"{100 * n.fraction_inside:.0f} % of epochs inside their band")
    c = metrics.cost
    print(f"\n{log.duration_s:.1f} s of log replayed {c.real_time_factor:.0f}x faster than real time "
          f"({c.us_per_imu_cycle:.0f} us per IMU cycle); wrote {out}/ "
          "(metrics.json, attitude.png, replay.pdf)")
    return 0


COMMAND = Command(
    "replay", "replay a flight log through navsim's estimators", usage="LOG [--gnss F --reference F]",
    description="A PX4 ULog: feed its IMU, magnetometer and baro to an estimator from a coarse alignment on the "
    "first second and compare its roll, pitch and yaw with PX4's vehicle_attitude (metrics.json, attitude.png, "
    "replay.pdf); an ES-KF-family estimator gets a zero velocity and the heading of PX4's calibrated magnetometer "
    "unless --set measurements=... says otherwise, and needs the filter's IMU model: --set 'noise={imu: mpu6050}'. "
    "A text log (KF-GINS's IMU, GNSS and truth.nav files, or CSV files whose header names each column and unit): "
    "run a scenario's estimators over it as one Monte Carlo run, scored against its reference (or the "
    "difference from its own solution) with every metric, interval and report page of navsim run; a PX4 log "
    "with GNSS given --scenario: the same, its position, velocity and attitude compared with EKF2's. Exit 2 for "
    "a log that cannot be replayed, naming the file and line.",
    arguments=arguments, handler=handle, kept=NOTHING_RESUMED)
