"""What the API's verbs are given, checked before any work: a path argument
(:func:`checked_path`) and a scenario (:func:`load_scenario`, from a file or a mapping). How the
runs are made is a :class:`~navsim.experiment.options.RunOptions`, checked there."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from navsim.experiment.options import shown
from navsim.experiment.scenario import Scenario, parse_scenario
from navsim.experiment.scenario import load_scenario as _load_file
from navsim.foundations.errors import UsageError


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


def load_scenario(source) -> Scenario:
    """A scenario from a YAML file (path) or from a mapping with the file's keys (relative
    paths then resolve from the working directory).

    Parameters
    ----------
    source : path or mapping
        The scenario file, or its content.

    Returns
    -------
    Scenario
        Parsed and checked (:func:`navsim.experiment.scenario.parse_scenario`).
    """
    if isinstance(source, Mapping):
        return parse_scenario(dict(source), None)
    return _load_file(checked_path("scenario", source, "scenario file"))
