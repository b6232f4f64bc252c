"""The options several commands share, each declared once: the scenario argument and its
``--set`` changes, the Monte
Carlo numbers (read with the words the API checks them in), the executor, the output folder and
what a command writing one says about locks and signals; and :func:`run_options`, the one
:class:`~navsim.experiment.options.RunOptions` a command builds from its parsed arguments."""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing

from navsim.experiment.options import CHUNK_RUNS, EXECUTORS, RUNS, SEED, WORKERS, RunOptions, check_scheduler
from navsim.experiment.scenario import MAX_WORKERS, Scenario, load_scenario
from navsim.foundations.config import Argument
from navsim.foundations.errors import UsageError
from navsim.foundations.overrides import parse_override
from navsim.plugin import load


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


def number(kind, minimum=None, maximum=None, exclusive_minimum=None):
    """An argparse ``type`` reading ``kind`` within bounds (an option of the command line only)."""
    return option_type(Argument("", kind, minimum, maximum, exclusive_minimum))


#: the argparse types of ``--runs``, ``--seed``, ``--workers`` and ``--chunk-runs``
RUNS_TYPE, SEED_TYPE = option_type(RUNS), option_type(SEED)
WORKERS_TYPE, CHUNK_RUNS_TYPE = option_type(WORKERS), option_type(CHUNK_RUNS)


def scheduler_address(text: str) -> str:
    """A Dask scheduler address (argparse ``type``;
    :func:`navsim.experiment.options.check_scheduler`)."""
    try:
        return check_scheduler(text, "")
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


#: the end of the --help of every command that writes an output folder; ``{kept}``: what an
#: interrupt leaves, as the command has it (its :attr:`~navsim.cli.command.Command.kept`)
WRITER_EPILOG = ("The output folder is locked while the command writes it: a second command writing "
                 "there is refused (exit 2) with the holder's pid and start time; a lock left by a "
                 "killed command is taken over. A non-empty folder that is not a navsim result is "
                 "refused (exit 2, its files named) unless --force; a folder holding another command's "
                 "result is refused (exit 2), even with --force. Ctrl-C or SIGTERM (how Slurm, "
                 "Kubernetes and Dask stop a job) stops it as an interrupt: {kept}, exit 130 for Ctrl-C, "
                 "143 for SIGTERM ('terminated'); the worker processes end with it, also when it is killed.")
#: what an interrupt leaves of a command that completes nothing later
NOTHING_RESUMED = "what it wrote stays (nothing completes it later: run it again)"


def writer_options(p, kept: str) -> None:
    """--force, and the epilog on locks and signals, of a command that writes a folder
    (``kept``: what an interrupt leaves there)."""
    p.add_argument("--force", action="store_true",
                   help="write into --out even when it is a non-empty folder that is not a navsim "
                   "result (its files of the same names are replaced)")
    p.epilog = WRITER_EPILOG.format(kept=kept)


def scenario_argument(p) -> None:
    """The scenario file, a command's first argument, ``--set`` and ``--plugin``."""
    p.add_argument("scenario", help="scenario YAML file")
    set_option(p)
    plugin_option(p)


def plugin_option(p) -> None:
    """``--plugin FILE.py``, repeatable: a filter in one file, imported before anything is read."""
    p.add_argument("--plugin", dest="plugins", action="append", default=[], metavar="FILE.py",
                   help="import this Python file first, whose classes register filters with "
                   "navsim.plugin.register (a scenario names them by type); repeatable")


def load_plugins(args) -> list[str]:
    """Import the command's ``--plugin`` files (:func:`navsim.foundations.plugins.load_file`);
    returns what they registered. Refused with ``--executor dask``, whose workers would not
    import them."""
    files = getattr(args, "plugins", None) or []
    if files and getattr(args, "executor", "local") == "dask":
        raise UsageError("--plugin with --executor dask: the Dask workers do not import the file (hint: run it "
                         "on the local executor, or package it as a plug-in with an entry point: docs/plugins.md)")
    if files and "fork" not in multiprocessing.get_all_start_methods() and getattr(args, "workers", None) not in (None, 1):
        raise UsageError("--plugin: the worker processes of this system do not inherit the file (they are not "
                         "forked; hint: --workers 1, or package it as a plug-in with an entry point)")
    return [item for f in files for item in load(f)]


def set_option(p, what: str = "the scenario") -> None:
    """``--set PATH=VALUE``, repeatable: a change to ``what`` (:mod:`navsim.foundations.overrides`)."""
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="PATH=VALUE",
                   help=f"change {what}, repeatable, validated as the file is: a dotted key path, a list "
                   "entry by [index] or [label], a YAML value (--set montecarlo.runs=200 --set "
                   "sensors.gps.override.position_sigma='3 m' --set 'estimators[ES-KF 16].period_s=0.5'); "
                   "recorded in scenario.resolved.yaml and run.json")


def overrides_given(args) -> list:
    """The command's ``--set`` as :class:`~navsim.foundations.overrides.Override` (a malformed
    one: :class:`ScenarioError`, exit 2)."""
    return [parse_override(text) for text in getattr(args, "overrides", None) or []]


def scenario_of(args) -> Scenario:
    """The command's scenario file with its ``--set`` changes, validated (its ``--plugin``
    files imported first)."""
    load_plugins(args)
    return load_scenario(args.scenario, overrides_given(args))


def out_option(p, default: str) -> None:
    """``--out``, the output folder (``default`` as the help names it)."""
    p.add_argument("--out", help=f"output folder (default {default})")


def monte_carlo_options(p, runs: str = "Monte Carlo runs", workers: bool = True) -> None:
    """``--runs`` (``runs``: what they are), ``--seed`` and, with ``workers``, ``--workers``:
    the scenario's ``montecarlo`` settings by default."""
    p.add_argument("--runs", type=RUNS_TYPE, help=f"{runs}, >= 1 (default: montecarlo.runs)")
    p.add_argument("--seed", type=SEED_TYPE, help="seed, >= 0 (default: montecarlo.seed)")
    if workers:
        workers_option(p)


def workers_option(p) -> None:
    """``--workers``, the scenario's ``montecarlo.workers`` by default."""
    p.add_argument("--workers", type=WORKERS_TYPE,
                   help=f"worker processes, 1-{MAX_WORKERS} (default: montecarlo.workers)")


def executor_options(p) -> None:
    """``--executor`` and ``--scheduler``: where the chunks of runs go."""
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="where the chunks of runs go: a process pool here (local, default) or Dask "
                   "distributed tasks (dask; needs pip install 'navsim[dask]')")
    p.add_argument("--scheduler", metavar="ADDRESS", type=scheduler_address,
                   help="with --executor dask: a running scheduler (tcp://host:8786); without it a "
                   "LocalCluster of --workers processes is started")


def run_options(args) -> RunOptions:
    """The :class:`RunOptions` of a command's parsed arguments: each field the value of its
    option where the command has one (``--runs``, ``--chunk-runs``...), else its default."""
    given = vars(args)
    return RunOptions(**{f.name: given[f.name] for f in dataclasses.fields(RunOptions) if f.name in given})
