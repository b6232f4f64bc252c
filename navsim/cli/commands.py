"""The table of the ``navsim`` commands: :data:`COMMANDS`, the registry the parser is built from
(:func:`navsim.cli.build_parser`), in the order ``navsim --help`` and the README list them.

A new command is a module of :mod:`navsim.cli` giving its :class:`~navsim.cli.command.Command`
(``COMMAND``) and one line in :data:`BUILT_IN`. A test (or a program embedding the command
line) adds one with :func:`register_command` and takes it away with
``COMMANDS.unregister(name)``. The README's command list and ``docs/cli.md``'s are
:func:`command_list` (a test compares them).
"""

from __future__ import annotations

from navsim.cli import budget, compare, fly, list_, new, open_, replay, run, schema, sensors, sweep, tune, validate
from navsim.cli.command import Command
from navsim.foundations.registry import Registry

#: the commands navsim ships, in the order they are listed
BUILT_IN: tuple[Command, ...] = (
    run.COMMAND,
    open_.COMMAND,
    fly.COMMAND,
    sensors.COMMAND,
    validate.COMMAND,
    new.COMMAND,
    sweep.COMMAND,
    replay.COMMAND,
    compare.COMMAND,
    budget.COMMAND,
    tune.COMMAND,
    schema.COMMAND,
    list_.COMMAND,
)


def _checked(name: str, command: Command) -> Command:
    """``command`` if it is a :class:`Command` named ``name``, else a :class:`TypeError`."""
    if not isinstance(command, Command):
        raise TypeError(f"command '{name}': {command!r} is not a navsim.cli.command.Command")
    if command.name != name:
        raise TypeError(f"command '{name}': registered under another name than its own ('{command.name}')")
    return command


#: every command, by name: the built-in ones, then those registered since
COMMANDS: Registry[Command] = Registry("command", check=_checked)
for _command in BUILT_IN:
    COMMANDS.register(_command.name, _command)


def register_command(command: Command) -> Command:
    """Add ``command`` to the command line (after the built-in ones; one of the same name is
    replaced); returns it."""
    return COMMANDS.register(command.name, command)


def listed() -> list[Command]:
    """The commands in the order they are listed (registered), not sorted by name."""
    return list(COMMANDS.built().values())


def command_list() -> str:
    """The README's list of commands: a line each, ``navsim NAME USAGE`` then its help, aligned."""
    commands = listed()
    width = max(len(c.usage_line()) for c in commands) + 2
    return "\n".join(f"{c.usage_line():<{width}}{c.summary()}".rstrip() for c in commands)
