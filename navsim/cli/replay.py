"""``navsim replay``: a real PX4 flight log through an estimator, its attitude compared with
PX4's own."""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import yaml

from navsim.cli.command import Command
from navsim.cli.options import NOTHING_RESUMED, load_plugins, number, out_option, plugin_option
from navsim.cli.output import open_folder, progress, table
from navsim.foundations.errors import UsageError
from navsim.foundations.provenance import provenance
from navsim.navigation.estimators import base
from navsim.replay import ReplayOptions, load_ulog, replay, replay_metrics
from navsim.replay.run import IMU_RATE_HZ
from navsim.report.replay import difference_table, write_replay_report

DEFAULT_REPLAY_ESTIMATOR = "cpf_ekf"


def arguments(p) -> None:
    """The log, the estimator and its settings, ``--out``, the settling and alignment times,
    the IMU rate and whether a damaged log is read."""
    p.add_argument("log", help="PX4 .ulg file (example: tests/data/px4_quad_real_69s.ulg.gz)")
    p.add_argument("--estimator", help=f"registered estimator (default {DEFAULT_REPLAY_ESTIMATOR})")
    out_option(p, "reports/replay_<log>_<estimator>")
    p.add_argument("--settle", type=number(float, minimum=0.0), default=10.0,
                   help="seconds left out of the metrics while the estimator converges (default 10)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="estimator parameter (YAML value), repeatable: --set period_s=0.02")
    p.add_argument("--imu-rate", type=number(float, minimum=IMU_RATE_HZ[0], maximum=IMU_RATE_HZ[1]),
                   help="IMU grid rate, Hz (default: the log's, 250 Hz for PX4's sensor_combined)")
    p.add_argument("--align", type=number(float, exclusive_minimum=0.0), default=1.0,
                   help="coarse-alignment window from the first sample, s (default 1)")
    p.add_argument("--allow-damaged", action="store_true",
                   help="replay what a truncated or corrupt log still holds instead of refusing it")
    plugin_option(p)


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
    """Replay the log, write metrics.json and the report, print the differences from PX4's
    attitude and the cost."""
    load_plugins(args)
    name = args.estimator or DEFAULT_REPLAY_ESTIMATOR
    if name not in base.available():
        raise UsageError(f"no estimator '{name}' registered; choose one with --estimator: "
                         + ", ".join(base.available()))
    params = parse_settings(args.set)
    folder = open_folder(args, Path("reports") / f"replay_{Path(args.log).name.split('.')[0]}_{name}")
    log = load_ulog(args.log, allow_damaged=args.allow_damaged)
    for note in log.notes:
        print(f"warning: {note}", file=sys.stderr)
    bar, update = progress(f"replaying {Path(args.log).name} through {name}")
    t0 = time.perf_counter()
    try:
        options = ReplayOptions(imu_rate_hz=args.imu_rate, settle_s=args.settle, align_s=args.align)
        result = replay(log, name, params, options, progress=update)
    finally:
        bar.close()
    folder.clear_earlier()
    out = folder.path
    record = provenance()
    metrics = dataclasses.replace(replay_metrics(result), wall_s=time.perf_counter() - t0, provenance=record)
    folder.json("metrics.json", metrics.to_dict())
    folder.record(write_replay_report(out, result, metrics, record))
    print(f"{name} against PX4's vehicle_attitude, after {args.settle:g} s:")
    print(table(*difference_table(metrics)))
    for reset in metrics.resets:
        print(f"reset at {reset.t_s:.2f} s: {reset.cause}")
    c = metrics.cost
    print(f"\n{log.duration_s:.1f} s of log replayed {c.real_time_factor:.0f}x faster than real time "
          f"({c.us_per_imu_cycle:.0f} us per IMU cycle); wrote {out}/ "
          "(metrics.json, attitude.png, replay.pdf)")
    return 0


COMMAND = Command(
    "replay", "replay a real PX4 flight log through an estimator", usage="LOG.ulg [--estimator NAME]",
    description="Read a PX4 ULog (pyulog), feed its IMU, magnetometer and baro to an estimator from a coarse "
    "alignment on the first second, and compare its roll, pitch and yaw with PX4's own vehicle_attitude; write "
    "metrics.json, attitude.png and replay.pdf, print the differences. An ES-KF-family estimator gets a zero "
    "velocity (it levels) and the heading of PX4's calibrated magnetometer unless --set measurements=... says "
    "otherwise; it needs the filter's IMU model: --set 'noise={imu: mpu6050}'. Exit 2 for a log that cannot be "
    "replayed.",
    arguments=arguments, handler=handle, kept=NOTHING_RESUMED)
