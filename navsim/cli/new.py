"""``navsim new``: a scenario copied from a shipped one with its comments, or a filter in one file
from the template with its scenario and its test, to change into one's own.

``navsim new scenario NAME --from SHIPPED`` writes ``NAME.yaml`` (the shipped file's text, its
``name:`` made ``NAME``), checked as ``navsim validate`` would. ``navsim new estimator NAME`` writes
``NAME.py`` (a single-vehicle 15-state ES-KF registered as ``NAME``, docs/plugins.md),
``NAME_p3.yaml`` (P3's flight with it beside navsim's ES-KF) and ``test_NAME.py`` (it follows the
shipped filter on 4 runs). Into ``--out`` (default the working folder); a file that is there
already is never replaced (exit 2, nothing written).
"""

from __future__ import annotations

import importlib.util
import keyword
import re
from pathlib import Path
from string import Template

import yaml

from navsim import plugin

from navsim.cli.command import Command
from navsim.experiment.scenario import parse_scenario
from navsim.foundations.config import close_match, parse_yaml, plain_name
from navsim.foundations.errors import UsageError
from navsim.foundations.resources import data_folder
from navsim.navigation.estimators import base

#: the files ``navsim new estimator NAME`` writes: template -> file name (``$name`` the name)
ESTIMATOR_FILES = {"estimator.py.txt": "${name}.py", "estimator_p3.yaml.txt": "${name}_p3.yaml",
                   "test_estimator.py.txt": "test_${name}.py"}
_NAME_LINE = re.compile(r"^name:.*$", re.MULTILINE)


def arguments(p) -> None:
    """What to make, its name, ``--from`` and ``--out``."""
    p.add_argument("what", choices=("scenario", "estimator"), help="a scenario, or a filter in one file")
    p.add_argument("name", help="its name: the scenario's (a plain file name) or the filter's type (a Python "
                   "identifier)")
    p.add_argument("--from", dest="source", metavar="SHIPPED",
                   help="the shipped scenario to copy (navsim list names them; default p0_bd_sins_ads)")
    p.add_argument("--out", default=".", help="the folder written into (default: the working folder)")


def shipped_scenarios() -> list[str]:
    """The shipped scenarios' names."""
    return sorted(p.stem for p in data_folder("scenarios").glob("*.yaml"))


def scenario_text(name: str, source: str) -> str:
    """The text of the shipped scenario ``source`` with its ``name:`` made ``name``."""
    shipped = shipped_scenarios()
    if source not in shipped:
        raise UsageError(f"--from {source}: no shipped scenario of that name "
                         f"({close_match(source, shipped) or 'the shipped ones: ' + ', '.join(shipped)})")
    text = (data_folder("scenarios") / f"{source}.yaml").read_text()
    return _NAME_LINE.sub(f"name: {name}", text, count=1)


def estimator_texts(name: str) -> dict[str, str]:
    """File name -> text of the files ``navsim new estimator name`` writes."""
    values = {"name": name, "Class": "".join(w[:1].upper() + w[1:] for w in name.split("_") if w)}
    folder = data_folder("templates")
    return {Template(target).substitute(values): Template((folder / template).read_text()).substitute(values)
            for template, target in ESTIMATOR_FILES.items()}


def _files(args) -> dict[str, str]:
    """File name -> text of what the command writes, its name checked."""
    if args.what == "scenario":
        if not plain_name(args.name):
            raise UsageError(f"{args.name!r}: not a plain file name (expected letters, digits, '.', '_', '-')")
        return {f"{args.name}.yaml": scenario_text(args.name, args.source or "p0_bd_sins_ads")}
    if args.source:
        raise UsageError("--from: only for navsim new scenario")
    check_estimator_name(args.name)
    return estimator_texts(args.name)


def check_estimator_name(name: str) -> None:
    """Refuse (:class:`UsageError`) a filter name that would not make working files: not a
    lower-case identifier, one whose class name is not an identifier or is a keyword, a YAML
    word (``true``, ``null``, ...), a registered estimator type, a name of :mod:`navsim.plugin`
    the template imports, or a module Python finds already (the file would hide it)."""
    cls = "".join(w[:1].upper() + w[1:] for w in name.split("_") if w)
    why = None
    if not (name.isidentifier() and name.isascii() and name == name.lower()) or keyword.iskeyword(name):
        why = "is not a lower-case Python identifier"
    elif not cls.isidentifier() or keyword.iskeyword(cls) or cls in plugin.__all__:
        why = f"makes the class name {cls!r}, which Python or the template cannot use"
    elif not isinstance(yaml.safe_load(name), str):
        why = "is a YAML word (true, false, null, ...), not a string in the scenario"
    elif name in base.available() and not getattr(base.get(name), "source_sha256", None):
        why = "is a registered estimator type already"      # shipped or installed (not a --plugin file's)
    elif importlib.util.find_spec(name) is not None:
        why = "is the name of a module Python finds already (the file would hide it)"
    if why:
        raise UsageError(f"{name!r} {why} (expected a name of your own, as my_filter: the module, the class "
                         "MyFilter and the scenario's type)")


def handle(args) -> int:
    """Write the files, none of which may be there already; a scenario is checked first."""
    out = Path(args.out)
    files = _files(args)
    there = [n for n in files if (out / n).exists()]
    if there:
        raise UsageError(f"{out}: {', '.join(there)} exists already; nothing written (hint: another name, or "
                         "another --out)")
    if args.what == "scenario":
        name = next(iter(files))
        parse_scenario(parse_yaml(files[name], out / name), str(out / name))   # a ScenarioError: exit 2
    out.mkdir(parents=True, exist_ok=True)
    written = []
    try:
        for n, text in files.items():
            with open(out / n, "x") as f:          # never over a file made meanwhile
                written.append(out / n)
                f.write(text)
    except OSError:
        for path in written:                       # all three files or none
            path.unlink(missing_ok=True)
        raise
    for path in written:
        print(f"wrote {path}")
    if args.what == "estimator":
        print(f"run it: navsim run {out / (args.name + '_p3.yaml')} --plugin {out / (args.name + '.py')}\n"
              f"test it: python -m pytest {out / ('test_' + args.name + '.py')}")
    return 0


COMMAND = Command(
    "new", "start a scenario from a shipped one, or a filter in one file", usage="scenario|estimator NAME",
    description="Write NAME.yaml, a shipped scenario (--from, default p0_bd_sins_ads) with its comments; or "
    "NAME.py, a filter in one file for one vehicle (P3's 15-state ES-KF), with NAME_p3.yaml and its test "
    "test_NAME.py. A file that exists already is not replaced.",
    arguments=arguments, handler=handle)
