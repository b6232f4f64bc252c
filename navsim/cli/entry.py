"""The command line's entry point: :func:`build_parser`, the parser built from the table of
commands (:data:`~navsim.cli.commands.COMMANDS`), and :func:`main`, which runs the command
chosen and turns its errors, interrupts and signals into messages and exit codes."""

from __future__ import annotations

import argparse
import logging
import sys

from navsim.cli.commands import listed
from navsim.cli.options import writer_options
from navsim.cli.output import close_folders
from navsim.experiment.executors import TERMINATED_EXIT, Terminated, stop_on_sigterm
from navsim.foundations.errors import NavsimError, OutputError
from navsim.version import __version__


def build_parser() -> argparse.ArgumentParser:
    """The ``navsim`` parser: a subparser per command of the table, its arguments then, for a
    command that writes an output folder, ``--force`` and the epilog on locks and signals."""
    parser = argparse.ArgumentParser(
        prog="navsim", description="UAV integrated-navigation testbed: JSBSim flights, sensor "
        "emulators, estimators, Monte Carlo reports.")
    parser.add_argument("--version", action="version", version=f"navsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in listed():
        p = sub.add_parser(command.name, help=command.help, description=command.description)
        if command.arguments is not None:
            command.arguments(p)
        if command.kept is not None:
            writer_options(p, command.kept)
        p.set_defaults(func=command.handler)
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
    """Run ``navsim ARGV`` (default: the process's arguments); returns the exit code."""
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
        close_folders()
