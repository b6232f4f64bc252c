"""``navsim validate``: check scenario files without running them."""

from __future__ import annotations

from navsim.cli.command import Command
from navsim.cli.options import load_plugins, overrides_given, plugin_option, set_option
from navsim.experiment.scenario import load_scenario


def arguments(p) -> None:
    """The scenario files and ``--set``."""
    p.add_argument("files", nargs="+", help="scenario YAML files")
    set_option(p, "each file")
    plugin_option(p)


def handle(args) -> int:
    """Load each file (a malformed one raises its :class:`ScenarioError`, exit 2) and say what it holds."""
    load_plugins(args)
    overrides = overrides_given(args)
    for path in args.files:
        s = load_scenario(path, overrides)
        print(f"{path}: ok ({s.name}: track {s.flight.track.name}, "
              f"{len(s.flight.track.segments)} segments)")
    return 0


COMMAND = Command("validate", "check scenario files without running them", usage="FILE...",
                  description="Check scenario files; exit 2 on the first malformed one.",
                  arguments=arguments, handler=handle)
