"""What the API's verbs are given, checked before any work: a path argument
(:func:`checked_path`) and a scenario (:func:`load_scenario`, from a file or a mapping). How the
runs are made is a :class:`~navsim.experiment.options.RunOptions`, checked there."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from navsim.experiment.options import shown
from navsim.experiment.scenario import Scenario, parse_changed
from navsim.experiment.scenario import load_scenario as _load_file
from navsim.foundations.errors import UsageError
from navsim.foundations.overrides import make_override, parse_override


def checked_path(name: str, value, what: str) -> Path:
    """``value`` as the path of a ``what``; :class:`UsageError` naming ``name`` for anything else.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : str or os.PathLike
        What the caller gave: a non-empty path without NUL characters.
    what : str
        What the path is of (``"output folder"``), for the message.

    Returns
    -------
    Path
    """
    text = os.fspath(value) if isinstance(value, (str, os.PathLike)) else None
    if not isinstance(text, str) or not text or "\0" in text:
        why = "has a NUL character" if isinstance(text, str) and text else "is not a path"
        raise UsageError(f"{name}: {shown(value)} {why} (expected the {what}'s path: a non-empty str or "
                         "os.PathLike without NUL characters)")
    return Path(text)


def load_scenario(source, set=None) -> Scenario:     # noqa: A002 -- the command line's --set
    """A scenario from a YAML file (path) or from a mapping with the file's keys (relative
    paths then resolve from the working directory), changed by ``set``.

    Parameters
    ----------
    source : path or mapping
        The scenario file, or its content.
    set : mapping or sequence of str, optional
        The command line's ``--set``: ``{"montecarlo.runs": 200, "estimators[ES-KF 16].period_s":
        0.5}`` (the values as YAML would give them: ``"3 m"``, ``[1, 2, 3]``), or
        ``["montecarlo.runs=200", ...]`` (each value read as YAML). The grammar is
        :mod:`navsim.foundations.overrides`'s; the changed mapping is validated as a file is,
        an error naming the change.

    Returns
    -------
    Scenario
        Parsed and checked (:func:`navsim.experiment.scenario.parse_scenario`); its
        ``overrides`` are the changes as ``PATH=VALUE``.
    """
    overrides = overrides_of(set)
    if isinstance(source, Mapping):
        return parse_changed(dict(source), None, overrides)
    return _load_file(checked_path("scenario", source, "scenario file"), overrides)


def overrides_of(given) -> list:
    """``set=`` as :class:`~navsim.foundations.overrides.Override`: a mapping of paths to values,
    or a sequence of ``PATH=VALUE`` strings; :class:`UsageError` for anything else."""
    if given is None:
        return []
    if isinstance(given, Mapping) and all(isinstance(k, str) for k in given):
        return [make_override(k, v) for k, v in given.items()]
    if isinstance(given, (list, tuple)) and all(isinstance(x, str) for x in given):
        return [parse_override(x) for x in given]
    raise UsageError(f"set: {shown(given)} is not a mapping of paths to values nor a list of 'PATH=VALUE' "
                     "strings (expected {'montecarlo.runs': 200} or ['montecarlo.runs=200'])")
