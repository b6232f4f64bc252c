"""Reading YAML configuration with errors that name the key path, what was expected and a hint.

YAML is read with a ``yaml.SafeLoader`` subclass (YAML 1.2 booleans) and nothing in it is evaluated.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from pathlib import Path
from typing import Any

import yaml

from navsim.foundations.errors import ScenarioError

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


#: the deepest nesting of mappings and lists a configuration file may have
MAX_DEPTH = 40
#: the most values (mapping entries and list items, counted as if every alias were written out)
#: a configuration file may expand to: far above any scenario, far below a YAML "alias bomb"
MAX_VALUES = 200_000
#: the largest configuration file read, bytes
MAX_BYTES = 4_000_000


def _construct_mapping(loader, node, deep=False):
    """A mapping whose keys are unique: a duplicated key is an error, not a silent overwrite
    (keys merged in by ``<<: *anchor`` may be overridden, as YAML intends)."""
    seen = {}
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(None, None, "a list or mapping used as a key",
                                                    key_node.start_mark) from None
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {seen[key] + 1})", key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return yaml.SafeLoader.construct_mapping(loader, node, deep)


SafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def _check_size(root, path: str) -> None:
    """Refuse a document nested deeper than :data:`MAX_DEPTH` or expanding (aliases written
    out) to more than :data:`MAX_VALUES` values. Each shared node is walked once; its size and
    height are counted again at each use, so aliases can neither hide depth nor multiply work."""
    seen: dict[int, tuple[int, int]] = {}     # id -> (values, height)

    def deep():
        return ScenarioError(f"is nested more than {MAX_DEPTH} levels deep", file=path,
                             expected="a scenario, track or datasheet file")

    def walk(x, depth):
        if not isinstance(x, (dict, list)):
            return 1, 0
        if depth > MAX_DEPTH:
            raise deep()
        if id(x) not in seen:
            total, height = 1, 0
            for v in (x.values() if isinstance(x, dict) else x):
                n, h = walk(v, depth + 1)
                total, height = total + n, max(height, h + 1)
                if total > MAX_VALUES:
                    raise ScenarioError(f"expands to more than {MAX_VALUES} values (aliases written out)",
                                        file=path, expected="a scenario, track or datasheet file",
                                        hint="an alias used inside the anchor it names, or aliases of aliases")
            seen[id(x)] = total, height
        if depth + seen[id(x)][1] > MAX_DEPTH:
            raise deep()
        return seen[id(x)]
    walk(root, 0)


def load_yaml(path: str | Path) -> Any:
    """Read a YAML file with the safe loader (:class:`SafeLoader`: no object construction, YAML
    1.2 booleans, unique keys); a file that cannot be read, is not UTF-8 text, is not valid
    YAML, is nested deeper than :data:`MAX_DEPTH` or expands to more than :data:`MAX_VALUES`
    values raises :class:`ScenarioError`."""
    path = Path(path)
    try:
        if path.is_dir():
            raise ScenarioError("is a folder", file=str(path), expected="a YAML file")
        if path.stat().st_size > MAX_BYTES:
            raise ScenarioError(f"is larger than {MAX_BYTES // 1_000_000} MB", file=str(path),
                                expected="a YAML file")
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise ScenarioError(f"cannot read the file: {exc.strerror}", file=str(path)) from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"is not UTF-8 text (byte {exc.start})", file=str(path),
                            expected="a YAML text file") from None
    try:
        data = yaml.load(text, Loader=SafeLoader)  # noqa: S506 (a SafeLoader subclass)
    except RecursionError:
        raise ScenarioError(f"is nested more than {MAX_DEPTH} levels deep", file=str(path),
                            expected="a scenario, track or datasheet file") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = str(getattr(exc, "problem", exc))
        hint = ("write each key once in a mapping" if problem.startswith("duplicate key")
                else "check indentation and the ':' after each key")
        raise ScenarioError(f"not valid YAML: {problem}", file=str(path), key=where, hint=hint) from None
    _check_size(data, str(path))
    return data


#: a name that may become a file or folder name: letters, digits, '.', '_', '-', not starting with '.'
PLAIN_NAME_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9._-]{0,99}$"
_PLAIN_NAME = re.compile(PLAIN_NAME_PATTERN)


def plain_name(value: str) -> bool:
    """Whether ``value`` is a plain file name: no separator, no ``..``, not absolute, not hidden."""
    return bool(_PLAIN_NAME.fullmatch(value))


def resolve_file(ref: str, *, catalog: Path, file: str | None, key: str, what: str,
                 choices=()) -> Path:
    """The YAML file a scenario names at ``key``: a plain name is an entry of ``catalog``
    (``<catalog>/<name>.yaml``); anything else is a ``.yaml``/``.yml`` path relative to the
    folder of the scenario ``file`` that must stay inside that folder (beside or below it).

    Raises :class:`ScenarioError` for an absolute path, a path leaving the scenario's folder,
    another suffix or a missing file; the file's content is never read here nor echoed.
    """
    if "/" not in ref and "\\" not in ref and Path(ref).suffix.lower() not in (".yaml", ".yml"):
        path = catalog / f"{ref}.yaml"
        if plain_name(ref) and path.is_file():
            return path
        raise ScenarioError(f"'{ref}' is not {what}", file=file, key=key,
                            expected=f"a name of {catalog.name}/ or a .yaml file beside the scenario",
                            hint=close_match(ref, choices))
    base = Path(file).resolve().parent if file else Path.cwd().resolve()
    expected = "a .yaml file beside or below the scenario's folder, as a relative path"
    if Path(ref).is_absolute() or Path(ref).suffix.lower() not in (".yaml", ".yml"):
        raise ScenarioError(f"'{ref}' is not allowed", file=file, key=key, expected=expected)
    path = (base / ref).resolve()
    if not path.is_relative_to(base):
        raise ScenarioError(f"'{ref}' leaves the scenario's folder", file=file, key=key, expected=expected)
    if not path.is_file():
        raise ScenarioError(f"'{ref}' does not exist beside the scenario", file=file, key=key,
                            expected=expected)
    return path


def cache_dir() -> Path:
    """navsim's cache folder: ``$NAVSIM_CACHE``, default ``~/.cache/navsim`` (flown flights,
    compiled kernels)."""
    return Path(os.environ.get("NAVSIM_CACHE", Path.home() / ".cache" / "navsim"))


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

    def vector(self, name: str, default: Any = _MISSING, minimum: float = 0.0) -> list[float]:
        """Read ``name`` as three numbers above ``minimum``: ``[x, y, z]``, or one number for all
        three."""
        self._seen.add(name)
        v = self.data.get(name)
        if v is None:
            if default is _MISSING:
                raise self.error("is missing", name, expected="a number or [x, y, z]")
            v = default
        ok = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > minimum
        if ok(v):
            return [float(v)] * 3
        if isinstance(v, list) and len(v) == 3 and all(ok(x) for x in v):
            return [float(x) for x in v]
        above = "a positive number" if minimum == 0 else f"a number above {minimum:g}"
        raise self.error(f"is {v!r}", name, expected=f"{above} or a list of three")

    def items(self, name: str, minimum: int, expected: str, hint: str | None = None) -> list:
        """Read ``name`` as a list of at least ``minimum`` entries."""
        self._seen.add(name)
        raw = self.data.get(name)
        if not isinstance(raw, list) or len(raw) < minimum:
            raise self.error("is missing or too short", name, expected=expected, hint=hint)
        return raw

    def section(self, name: str, read) -> dict:
        """``read(node)`` of the optional mapping ``name``, its keys checked (unknown ones
        reported); ``{}`` without it."""
        sub = self.child(name, None)
        if sub is None:
            return {}
        out = read(sub)
        sub.done()
        return out

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
