"""The command line is a table of commands (issue 51): a new command is a module giving its
:class:`~navsim.cli.command.Command` and one line of :data:`~navsim.cli.commands.COMMANDS`; a
toy command registered from here runs through ``navsim.cli.main`` with its ``--help``; the
README's and ``docs/cli.md``'s command lists are the table's usage lines; the options a command
parses make one :class:`~navsim.experiment.options.RunOptions`."""

import re
from pathlib import Path

import pytest

import navsim.cli
from navsim.cli import COMMANDS, Command, build_parser, register_command, run_options
from navsim.cli.commands import BUILT_IN, command_list, listed
from navsim.experiment.options import RunOptions
from navsim.foundations.errors import UsageError

ROOT = Path(__file__).resolve().parents[2]


def _toy_arguments(p) -> None:
    p.add_argument("word", help="the word echoed")
    p.add_argument("--times", type=int, default=1, help="how often")


def _toy(args) -> int:
    """Echo the word; a word 'bad' is a usage error (exit 2, as any command's)."""
    if args.word == "bad":
        raise UsageError("toy: 'bad' is not a word")
    print(" ".join([args.word] * args.times))
    return 0


TOY = Command("toy", "echo a word (a test's command)", usage="WORD [--times N]",
              description="Echo WORD --times times: a command registered by a test.",
              arguments=_toy_arguments, handler=_toy)


@pytest.fixture
def toy():
    register_command(TOY)
    try:
        yield TOY
    finally:
        COMMANDS.unregister("toy")


def test_a_command_registered_from_outside_runs_with_its_help(toy, capsys):
    assert "toy" in COMMANDS and listed()[-1] is toy
    assert navsim.cli.main(["toy", "hello", "--times", "2"]) == 0
    assert capsys.readouterr().out == "hello hello\n"
    assert navsim.cli.main(["toy", "bad"]) == 2
    assert "error: toy: 'bad' is not a word" in capsys.readouterr().err
    with pytest.raises(SystemExit) as done:
        navsim.cli.main(["toy", "--help"])
    out = capsys.readouterr().out
    assert done.value.code == 0 and "usage: navsim toy" in out and "Echo WORD --times times" in out
    assert "--force" not in out                       # it writes no folder
    with pytest.raises(SystemExit):
        navsim.cli.main(["--help"])
    assert "echo a word (a test's command)" in capsys.readouterr().out
    assert "navsim toy WORD [--times N]" in command_list()


def test_an_unregistered_command_is_gone(toy, capsys):
    COMMANDS.unregister("toy")
    assert "toy" not in COMMANDS
    with pytest.raises(SystemExit) as done:
        navsim.cli.main(["toy", "hello"])
    assert done.value.code == 2 and "invalid choice: 'toy'" in capsys.readouterr().err
    with pytest.raises(KeyError, match="no command 'tyo'"):
        COMMANDS.get("tyo")


def test_the_table_holds_commands_only():
    with pytest.raises(TypeError, match="is not a"):
        COMMANDS.register("nothing", object())
    with pytest.raises(TypeError, match="another name"):
        COMMANDS.register("other", TOY)
    assert "nothing" not in COMMANDS.built() and "other" not in COMMANDS.built()


def test_the_parser_is_the_table():
    """One subparser per command, in the table's order; each module's ``COMMAND``."""
    choices = build_parser()._subparsers._group_actions[0].choices
    assert list(choices) == [c.name for c in BUILT_IN] == [c.name for c in listed()]
    for command in BUILT_IN:
        module = getattr(navsim.cli, {"list": "list_", "open": "open_"}.get(command.name, command.name))   # builtins' names
        assert module.COMMAND is command and command.handler.__module__ == module.__name__
        assert (choices[command.name].epilog is not None) == (command.kept is not None), command.name


def _listed_in(path: Path) -> str:
    """The command list of a Markdown file: the code block after its ``## Commands`` heading."""
    m = re.search(r"^## Commands\n\n```\n(.*?)```$", path.read_text(), re.S | re.M)
    assert m, f"{path.name}: no code block after '## Commands'"
    return m.group(1).rstrip("\n")


@pytest.mark.parametrize("name", ["README.md", "docs/cli.md"])
def test_the_documented_command_lists_are_the_table(name):
    """Where a list differs, paste ``python -c 'from navsim.cli.commands import command_list;
    print(command_list())'`` into it."""
    assert _listed_in(ROOT / name) == command_list(), f"{name}: its command list is not the table's"
    assert len((ROOT / "README.md").read_text().splitlines()) <= 250


def test_the_options_of_a_run_are_built_once():
    args = build_parser().parse_args(["run", "s.yaml", "--runs", "3", "--seed", "7", "--chunk-runs", "2",
                                      "--executor", "dask", "--scheduler", "tcp://h:8786", "--resume"])
    assert run_options(args) == RunOptions(runs=3, seed=7, executor="dask", scheduler="tcp://h:8786",
                                           chunk_runs=2, resume=True)
    assert run_options(build_parser().parse_args(["sweep", "w.yaml", "--workers", "2"])) == RunOptions(workers=2)
    assert run_options(build_parser().parse_args(["sensors", "s.yaml"])) == RunOptions()
