"""A command of the ``navsim`` command line, declared as one object: :class:`Command`, its name,
its help, the usage line the README shows, its arguments and its handler.

Each command is a module of :mod:`navsim.cli` giving its ``COMMAND``; the table
:data:`navsim.cli.commands.COMMANDS` lists them, and the parser is built from it.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Command:
    """A subcommand: ``navsim NAME ...``.

    ``arguments(parser)`` adds its arguments to its subparser; ``handler(args)`` runs it and
    returns the exit code (a :class:`~navsim.foundations.errors.NavsimError` it raises is
    printed and exits with its code, :func:`navsim.cli.main`). A command that writes an output
    folder says what an interrupt leaves there (``kept``): its parser gets ``--force`` and the
    epilog on locks and signals after its own arguments.
    """

    name: str                                           #: the word after ``navsim``
    help: str                                           #: one line: ``navsim --help``'s list, the README's
    description: str                                    #: the paragraph of ``navsim NAME --help``
    usage: str                                          #: the arguments as the README's command list shows them
    handler: Callable[[argparse.Namespace], int]        #: runs the command: parsed arguments -> exit code
    arguments: Callable[[argparse.ArgumentParser], None] | None = None   #: adds its arguments to its parser
    kept: str | None = None                             #: what an interrupt leaves in its output folder; None: writes none

    def usage_line(self) -> str:
        """``navsim NAME USAGE``, the left column of the README's command list."""
        return " ".join(filter(None, ("navsim", self.name, self.usage)))

    def summary(self) -> str:
        """The help as printed (argparse's ``%%`` as ``%``)."""
        return self.help.replace("%%", "%")
