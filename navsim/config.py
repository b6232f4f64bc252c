"""Reading YAML configuration with errors that name the key path, what was expected and a hint.

YAML is read with a ``yaml.SafeLoader`` subclass (YAML 1.2 booleans) and nothing in it is evaluated.
"""

from __future__ import annotations

import difflib
import math
import re
from pathlib import Path
from typing import Any

import yaml

from navsim.errors import ScenarioError

_MISSING = object()
_TYPE_NAMES = {float: "a number", int: "an integer", str: "a string", bool: "true or false",
               dict: "a mapping", list: "a list"}


class SafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` with YAML 1.2 booleans: only ``true``/``false`` are booleans, so that
    keys and values such as ``off`` (a sensor's switched-off error sources), ``on``, ``yes``,
    ``no`` stay strings (PyYAML's YAML 1.1 default reads ``off:`` as the key ``False``)."""


SafeLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:bool"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
SafeLoader.add_implicit_resolver("tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"),
                                 list("tTfF"))


def load_yaml(path: str | Path) -> Any:
    """Read a YAML file with the safe loader (:class:`SafeLoader`: no object construction, YAML
    1.2 booleans); syntax errors become :class:`ScenarioError`."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError(f"cannot read the file: {exc.strerror}", file=str(path)) from None
    try:
        return yaml.load(text, Loader=SafeLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        raise ScenarioError(f"not valid YAML: {getattr(exc, 'problem', exc)}", file=str(path),
                            key=where, hint="check indentation and the ':' after each key") from None


def close_match(word: str, choices) -> str | None:
    """A hint naming the closest of ``choices`` to ``word``, or listing them."""
    choices = sorted(str(c) for c in choices)
    best = difflib.get_close_matches(str(word), choices, n=1, cutoff=0.5)
    if best:
        return f"did you mean '{best[0]}'?"
    return "one of: " + ", ".join(choices) if choices else None


class Node:
    """A mapping from YAML being read key by key, remembering its key path.

    Call :meth:`done` at the end: any key that was not read is reported as unknown.
    """

    def __init__(self, data: Any, path: str, file: str | None = None):
        if not isinstance(data, dict):
            raise ScenarioError(f"is {_describe(data)}", file=file, key=path or None,
                                expected="a mapping of keys to values")
        self.data, self.path, self.file = data, path, file
        self._seen: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def error(self, message: str, name: str | None = None, expected: str | None = None,
              hint: str | None = None) -> ScenarioError:
        return ScenarioError(message, file=self.file, key=self.key(name) if name else self.path,
                             expected=expected, hint=hint)

    def has(self, name: str) -> bool:
        return name in self.data

    def get(self, name: str, kind: type = float, default: Any = _MISSING, *,
            minimum: float | None = None, maximum: float | None = None,
            exclusive_minimum: float | None = None, choices=None) -> Any:
        """Read ``name`` as ``kind`` with range checks; missing and no default is an error."""
        self._seen.add(name)
        if name not in self.data or self.data[name] is None:
            if default is _MISSING:
                raise self.error("is missing", name, expected=_TYPE_NAMES.get(kind, str(kind)))
            return default
        value = self.data[name]
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise self.error(f"is {_describe(value)}", name, expected="a number")
            value = float(value)
            if not math.isfinite(value):
                raise self.error(f"is {value}", name, expected="a finite number")
        elif kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise self.error(f"is {_describe(value)}", name, expected="an integer")
        elif kind is bool:
            if not isinstance(value, bool):
                raise self.error(f"is {_describe(value)}", name, expected="true or false")
        elif not isinstance(value, kind):
            raise self.error(f"is {_describe(value)}", name, expected=_TYPE_NAMES.get(kind))
        if choices is not None and value not in choices:
            raise self.error(f"is '{value}'", name, expected="one of " + ", ".join(map(str, choices)),
                             hint=close_match(value, choices))
        if minimum is not None and value < minimum:
            raise self.error(f"is {value}", name, expected=f"a value >= {minimum}")
        if exclusive_minimum is not None and value <= exclusive_minimum:
            raise self.error(f"is {value}", name, expected=f"a value > {exclusive_minimum}")
        if maximum is not None and value > maximum:
            raise self.error(f"is {value}", name, expected=f"a value <= {maximum}")
        return value

    def child(self, name: str, default: Any = _MISSING) -> "Node | None":
        """The mapping under ``name`` as a :class:`Node`."""
        self._seen.add(name)
        if name not in self.data or self.data[name] is None:
            if default is _MISSING:
                raise self.error("is missing", name, expected="a mapping")
            return default
        return Node(self.data[name], self.key(name), self.file)

    def done(self) -> None:
        """Raise on the first key that was never read."""
        for name in self.data:
            if name not in self._seen:
                raise self.error("is not a known key", str(name), hint=close_match(name, self._seen))


def _describe(value: Any) -> str:
    if value is None:
        return "empty"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {value}"
    if isinstance(value, str):
        return f"the string '{value}'"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return type(value).__name__
