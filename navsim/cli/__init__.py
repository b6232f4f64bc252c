"""The ``navsim`` command line: a module per command (``navsim.cli.run``, ``.fly``, ``.sensors``,
``.validate``, ``.sweep``, ``.replay``, ``.compare``, ``.budget``, ``.schema``, ``.list_``), each
giving its parser and its handler as one :class:`~navsim.cli.command.Command`, listed in the
table :data:`~navsim.cli.commands.COMMANDS` from which :func:`build_parser` builds the parser;
the options several commands share in :mod:`navsim.cli.options`, the tables, progress bars and
output folders in :mod:`navsim.cli.output`; :func:`main` (:mod:`navsim.cli.entry`) is the
``navsim`` executable.
"""

from navsim.cli.command import Command
from navsim.cli.commands import COMMANDS, register_command
from navsim.cli.compare import parse_margins
from navsim.cli.entry import build_parser, main
from navsim.cli.options import run_options

__all__ = ["COMMANDS", "Command", "build_parser", "main", "parse_margins", "register_command", "run_options"]
