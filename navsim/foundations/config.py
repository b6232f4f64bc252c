"""Reading YAML configuration with errors that name the key path, what was expected and a hint.

YAML is read with a ``yaml.SafeLoader`` subclass (YAML 1.2 booleans) and nothing in it is evaluated.
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import logging
import math
import numbers
import os
import re
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from navsim.foundations.errors import ScenarioError, UsageError

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

# --- the ranges of numbers, declared once ---------------------------------------------------------
#: the largest magnitude of a number a configuration takes where its key declares no bound of its
#: own: far above any physical quantity in a scenario's units, far below a float's overflow
MAX_FLOAT = 1e12
#: the smallest magnitude of a non-zero number: its square is still a normal float (a 1e-308 sigma
#: squares to zero, a 1e-308 period divides to infinity); far below any physical quantity in SI
#: (a navigation-grade gyro's bias walk is about 1e-13 rad/s/sqrt(s), a wind north component
#: written as 5 cos(90 deg) is 3e-16 m/s)
MIN_FLOAT = 1e-150
#: the largest magnitude of an integer where its key declares no bound of its own (a float holds
#: every integer up to it exactly)
MAX_INT = 2**53
#: the longest flight, time window or time constant of a scenario, s (about 11.6 days)
MAX_DURATION_S = 1e6
#: the longest time constant (a Gauss-Markov tau; 1e7 s and more model a random constant), s
MAX_TIME_CONSTANT_S = 1e10
#: the highest rate of a simulation or a sensor, Hz
MAX_RATE_HZ = 1000.0
#: the strongest wind a scenario may set or an estimator may assume, m/s (Beaufort 12, a
#: hurricane, starts at 32.7 m/s)
MAX_WIND_MPS = 40.0
#: the most Monte Carlo runs of a scenario or a command line
MAX_RUNS = 1_000_000
#: the longest averaging window of an adaptive filter, epochs; the most rules of a fuzzy one
MAX_WINDOW = 1_000_000
MAX_RULES = 1_000
#: how close an unread key must be to a missing one to be named as its misspelling
TYPO_CUTOFF = 0.8


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


#: parsed texts by their digest: a scenario's parse reads the same datasheets and track files
#: again for each sensor and check, and PyYAML's pure-Python parser takes 3 ms a datasheet; a
#: copy is handed out, so a caller may change what it gets. At most 256 texts, each of at most
#: 64 kB (the largest shipped file is 4 kB).
_PARSED: dict[bytes, Any] = {}
_PARSED_MAX, _PARSED_MAX_BYTES = 256, 65_536
_PARSED_LOCK = threading.Lock()             # a notebook's threads may parse at once


def load_yaml(path: str | Path) -> Any:
    """Read a YAML file with the safe loader (:class:`SafeLoader`: no object construction, YAML
    1.2 booleans, unique keys); a file that cannot be read, is not UTF-8 text, is not valid
    YAML, is nested deeper than :data:`MAX_DEPTH` or expands to more than :data:`MAX_VALUES`
    values raises :class:`ScenarioError`. A text parsed before (the same bytes) is not parsed
    again."""
    path = Path(path)
    try:
        if path.is_dir():
            raise ScenarioError("is a folder", file=str(path), expected="a YAML file")
        with path.open("rb") as f:        # the read itself bounded: a device or a growing file too
            raw = f.read(MAX_BYTES + 1)
        if len(raw) > MAX_BYTES:
            raise ScenarioError(f"is larger than {MAX_BYTES // 1_000_000} MB", file=str(path),
                                expected="a YAML file")
        text = raw.decode("utf-8")
    except OSError as exc:
        raise ScenarioError(f"cannot read the file: {exc.strerror}", file=str(path)) from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"is not UTF-8 text (byte {exc.start})", file=str(path),
                            expected="a YAML text file") from None
    if len(raw) > _PARSED_MAX_BYTES:
        return parse_yaml(text, path)
    key = hashlib.blake2b(raw, digest_size=20).digest()
    with _PARSED_LOCK:
        data = _PARSED.get(key)
    if data is None:
        data = parse_yaml(text, path)
        with _PARSED_LOCK:
            if len(_PARSED) >= _PARSED_MAX:
                _PARSED.pop(next(iter(_PARSED)))
            _PARSED[key] = data
    return copy.deepcopy(data)


def parse_yaml(text: str, path: Path) -> Any:
    """:func:`load_yaml`'s parse and checks of ``text`` (read from ``path``; a ``--set``'s value
    too): the depth and size bounded, a :class:`ScenarioError` for what is not YAML."""
    try:
        data = yaml.load(text, Loader=SafeLoader)  # noqa: S506 (a SafeLoader subclass)
    except RecursionError:
        raise ScenarioError(f"is nested more than {MAX_DEPTH} levels deep", file=str(path),
                            expected="a scenario, track or datasheet file") from None
    except ValueError as exc:             # an integer of more digits than Python converts
        raise ScenarioError(f"not valid YAML: {exc}", file=str(path),
                            hint=f"numbers of at most {len(str(MAX_INT))} digits") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = str(getattr(exc, "problem", None) or exc)
        if getattr(exc, "context", None):     # e.g. "found duplicate anchor 'a'; first occurrence"
            problem = f"{problem} ({exc.context})"
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

    ``choices``: the catalog's names for the hint, or a function returning them (called only for
    the error). Raises :class:`ScenarioError` for an absolute path, a path leaving the scenario's
    folder, another suffix or a missing file; the file's content is never read here nor echoed.
    """
    if "/" not in ref and "\\" not in ref and Path(ref).suffix.lower() not in (".yaml", ".yml"):
        path = catalog / f"{ref}.yaml"
        if plain_name(ref) and path.is_file():
            return path
        raise ScenarioError(f"'{ref}' is not {what}", file=file, key=key,
                            expected=f"a name of {catalog.name}/ or a .yaml file beside the scenario",
                            hint=close_match(ref, choices() if callable(choices) else choices))
    expected = "a .yaml file beside or below the scenario's folder, as a relative path"
    if Path(ref).suffix.lower() not in (".yaml", ".yml"):
        raise ScenarioError(f"'{ref}' is not allowed", file=file, key=key, expected=expected)
    path = _beside(ref, file=file, key=key, expected=expected)
    if not path.is_file():
        raise ScenarioError(f"'{ref}' does not exist beside the scenario", file=file, key=key,
                            expected=expected)
    return path


def resolve_folder(ref: str, *, file: str | None, key: str, what: str) -> Path:
    """The folder a scenario names at ``key`` by the relative path ``ref``: beside or below the
    folder of the scenario ``file`` (the working folder without a file), never leaving it, never
    that folder itself; the same rules as :func:`resolve_file`'s paths.

    Raises
    ------
    ScenarioError
        For an absolute path, a path leaving the scenario's folder or naming it, a missing folder.
    """
    expected = f"{what} beside or below the scenario's folder, as a relative path (./name)"
    path = _beside(ref, file=file, key=key, expected=expected)
    if path == _scenario_folder(file):
        raise ScenarioError(f"'{ref}' is not allowed (the scenario's own folder)", file=file, key=key,
                            expected=expected)
    if not path.is_dir():
        raise ScenarioError(f"'{ref}' is not a folder beside the scenario", file=file, key=key, expected=expected)
    return path


def _scenario_folder(file: str | None) -> Path:
    """The folder paths in the scenario ``file`` are relative to (the working folder without one)."""
    return Path(file).resolve().parent if file else Path.cwd().resolve()


def _beside(ref: str, *, file: str | None, key: str, expected: str) -> Path:
    """``ref`` resolved (links followed) against the scenario ``file``'s folder; an absolute path
    or one leaving that folder refused (:class:`ScenarioError` naming ``file`` and ``key``)."""
    base = _scenario_folder(file)
    if Path(ref).is_absolute():
        raise ScenarioError(f"'{ref}' is not allowed", file=file, key=key, expected=expected)
    path = (base / ref).resolve()
    if not path.is_relative_to(base):
        raise ScenarioError(f"'{ref}' leaves the scenario's folder", file=file, key=key, expected=expected)
    return path


#: the environment variable naming navsim's cache folder (default ``~/.cache/navsim``)
CACHE_ENV = "NAVSIM_CACHE"
_warned_folders: set[str] = set()


def usable_folder(folder: Path, what: str) -> Path | None:
    """``folder``, created, where a file can be written in it; else ``None``, with a warning
    (logged once per folder) naming ``what`` and the system's reason."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as exc:
        if str(folder) not in _warned_folders:
            _warned_folders.add(str(folder))
            logging.getLogger(__name__).warning("%s: %s; working without the %s", folder,
                                                exc.strerror or exc, what)
        return None
    return folder


def cache_dir(sub: str = "") -> Path | None:
    """navsim's cache folder, ``$NAVSIM_CACHE/<sub>`` (default ``~/.cache/navsim``; ``flights``:
    flown flights, ``numba``: compiled kernels), created; ``None`` (and a warning, see
    :func:`usable_folder`) where it cannot be created or written (a read-only or missing home, a
    path through a file): the caller then works without that cache, never caching elsewhere.

    Raises
    ------
    UsageError
        Where ``NAVSIM_CACHE`` is set but empty (it would otherwise mean the current folder).
    """
    value = os.environ.get(CACHE_ENV)
    if value is not None and not value.strip():
        raise UsageError(f"{CACHE_ENV} is set but empty: unset it (the cache is then "
                         f"~/.cache/navsim) or name a folder")
    try:
        base = Path(value) if value is not None else Path.home() / ".cache" / "navsim"
    except RuntimeError as exc:                      # no home folder to be found
        logging.getLogger(__name__).warning("%s; working without navsim's cache (set %s)", exc, CACHE_ENV)
        return None
    return usable_folder(base / sub if sub else base, f"{sub} cache" if sub else "cache")


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
        """Read ``name`` as ``kind`` with range checks; missing and no default is an error.

        A number is also checked against the global bounds where no bound of its own is
        declared (:func:`check_number`: |x| <= :data:`MAX_FLOAT` or :data:`MAX_INT`, no non-zero
        |x| below :data:`MIN_FLOAT`, no NaN, infinity or boolean)."""
        self._seen.add(name)
        if name not in self.data or self.data[name] is None:
            if default is _MISSING:
                raise self.missing(name, _TYPE_NAMES.get(kind, str(kind)))
            return default
        value = self.data[name]
        if kind in (float, int):
            value = check_number(value, kind, minimum=minimum, maximum=maximum,
                                 exclusive_minimum=exclusive_minimum, error=lambda m, e: self.error(m, name, e))
        elif kind is bool:
            if not isinstance(value, bool):
                raise self.error(f"is {_describe(value)}", name, expected="true or false")
        elif not isinstance(value, kind):
            raise self.error(f"is {_describe(value)}", name, expected=_TYPE_NAMES.get(kind))
        if choices is not None and value not in choices:
            raise self.error(f"is '{value}'", name, expected="one of " + ", ".join(map(str, choices)),
                             hint=close_match(value, choices))
        return value

    def missing(self, name: str, expected: str | None = None) -> ScenarioError:
        """The error for the missing key ``name``: naming an unread key of the mapping close to
        it as its misspelling when there is one (``sigma_mp`` for ``sigma_mps``)."""
        unread = [str(k) for k in self.data if k not in self._seen and str(k) != name]
        typo = difflib.get_close_matches(name, unread, n=1, cutoff=TYPO_CUTOFF)
        if typo:
            return ScenarioError(f"'{typo[0]}' is not a known key; did you mean '{name}'?", file=self.file,
                                 key=self.key(typo[0]), expected=f"{name}: {expected}" if expected else None)
        return self.error("is missing", name, expected=expected)

    def vector(self, name: str, default: Any = _MISSING, minimum: float = 0.0,
               maximum: float = MAX_FLOAT) -> list[float]:
        """Read ``name`` as three numbers above ``minimum`` and at most ``maximum``: ``[x, y, z]``,
        or one number for all three (each within the global bounds of :func:`check_number`)."""
        self._seen.add(name)
        v = self.data.get(name)
        if v is None:
            if default is _MISSING:
                raise self.missing(name, "a number or [x, y, z]")
            v = default
        low = None if minimum == -math.inf else minimum
        items = v if isinstance(v, list) and len(v) == 3 else [v] if not isinstance(v, list) else None
        above = "a positive number" if minimum == 0 else f"a number above {minimum:g}"
        if items is None:
            raise self.error(f"is {_short(v)}", name, expected=f"{above} or a list of three")
        out = []
        for x in items:
            out.append(check_number(x, float, exclusive_minimum=low, maximum=maximum,
                                    error=lambda m, e: self.error(f"is {_short(v)}", name,
                                                                  f"{above} or a list of three ({e})")))
        return out * 3 if len(out) == 1 else out

    def items(self, name: str, minimum: int, expected: str, hint: str | None = None) -> list:
        """Read ``name`` as a list of at least ``minimum`` entries."""
        self._seen.add(name)
        raw = self.data.get(name)
        if raw is None and name not in self.data:
            err = self.missing(name, expected)
            if err.detail != "is missing":
                raise err
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
                raise self.missing(name, "a mapping")
            return default
        return Node(self.data[name], self.key(name), self.file)

    def done(self) -> None:
        """Raise on the first key that was never read."""
        for name in self.data:
            if name not in self._seen:
                raise self.error("is not a known key", str(name), hint=close_match(name, self._seen))


def check_number(value: Any, kind: type = float, *, minimum: float | None = None,
                 maximum: float | None = None, exclusive_minimum: float | None = None, error=None):
    """``value`` as a ``kind`` (float or int) within its bounds, else ``error(message,
    expected)`` raised (default: a :class:`ScenarioError` without a key).

    Where no bound is given, the global ones hold: ``|x| <= MAX_FLOAT`` (floats) or ``MAX_INT``
    (integers); a float's non-zero magnitude is at least :data:`MIN_FLOAT`. Booleans, NaN,
    infinities and integers too large for a float are refused; ``-0.0`` is read as ``0.0``."""
    error = error or (lambda m, e: ScenarioError(m, expected=e))
    what = "a number" if kind is float else "an integer"
    if isinstance(value, bool) or not isinstance(value, (int, float) if kind is float else int):
        raise error(f"is {_describe(value)}", what)
    limit = MAX_FLOAT if kind is float else MAX_INT
    if isinstance(value, float) and not math.isfinite(value):
        raise error(f"is {value}", "a finite number")
    low = -limit if minimum is None and exclusive_minimum is None else minimum
    high = limit if maximum is None else maximum
    largest = max(abs(high), abs(low if low is not None else 0.0), limit)
    if abs(value) > largest:              # before a float of it overflows; the bound it passes named
        expected = (f"a value <= {_bound(high)}" if value > 0 and maximum is not None else
                    f"a value >= {_bound(low)}" if value < 0 and minimum is not None else
                    f"a value of magnitude <= {_bound(largest)}")
        raise error(f"is {_short(value)}", expected)
    value = float(value) + 0.0 if kind is float else value
    if kind is float and value != 0.0 and abs(value) < MIN_FLOAT:
        raise error(f"is {value:g}", f"0 or a magnitude >= {MIN_FLOAT:g}")
    if low is not None and value < low:
        raise error(f"is {_short(value)}", f"a value >= {_bound(low)}")
    if exclusive_minimum is not None and value <= exclusive_minimum:
        raise error(f"is {_short(value)}", f"a value > {_bound(exclusive_minimum)}")
    if value > high:
        raise error(f"is {_short(value)}", f"a value <= {_bound(high)}")
    return value


def check_numbers(value: Any, n: int, *, error, **bounds) -> list[float]:
    """``value`` as a list of ``n`` numbers, each within ``bounds`` (as :func:`check_number`),
    else ``error(message, expected)`` raised."""
    if not (isinstance(value, list) and len(value) == n):
        raise error(f"is {_describe(value) if not isinstance(value, list) else _short(value)}",
                    f"a list of {n} numbers")
    return [check_number(x, float, error=lambda m, e: error(f"is {_short(value)}", f"{n} numbers, each {e}"),
                         **bounds) for x in value]


@dataclass(frozen=True)
class Argument:
    """A number that an API call and a command-line option both take, declared once: the API
    checks a value (:meth:`check`), the command line reads its option's text (:meth:`parse`,
    an argparse ``type``); both refuse with the same words, a :class:`UsageError` naming the
    argument, the value and what was expected (``seed: -1 is below 0 (expected an integer
    0-9223372036854775807)``)."""

    name: str                                   #: the API's keyword (``chunk_runs``)
    kind: type = int                            #: int or float
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: float | None = None

    @property
    def option(self) -> str:
        """The command line's option, ``--chunk-runs``."""
        return "--" + self.name.replace("_", "-")

    @property
    def expected(self) -> str:
        """What the argument takes: ``an integer 1-1000000``, ``a number > 0``."""
        what = "an integer" if self.kind is int else "a finite number"
        limit = lambda x: str(x) if isinstance(x, int) else f"{x:g}"
        if self.minimum is not None and self.maximum is not None:
            return f"{what} {limit(self.minimum)}-{limit(self.maximum)}"
        bounds = [f"{op} {limit(x)}" for op, x in ((">=", self.minimum), (">", self.exclusive_minimum),
                                                   ("<=", self.maximum)) if x is not None]
        return " ".join([what, *bounds])

    def problem(self, value: Any, shown: str) -> str | None:
        """Why ``value`` (written ``shown``) is refused; None: it is taken."""
        integer = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if self.kind is int and not integer:
            return f"{shown} is not an integer"
        if self.kind is float and not (integer or isinstance(value, numbers.Real) and not isinstance(value, bool)):
            return f"{shown} is not a number"
        if self.kind is float and not math.isfinite(value):
            return f"{shown} is not a finite number"
        if self.minimum is not None and value < self.minimum:
            return f"{shown} is below {self.minimum}"
        if self.exclusive_minimum is not None and value <= self.exclusive_minimum:
            return f"{shown} is not above {self.exclusive_minimum}"
        if self.maximum is not None and value > self.maximum:
            return f"{shown} is above {self.maximum}"
        return None

    def check(self, value: Any):
        """``value`` as the argument's kind (a numpy integer as an ``int``); :class:`UsageError`
        naming the argument where it is refused."""
        why = self.problem(value, _short(value))
        if why is not None:
            raise UsageError(f"{self.name}: {why} (expected {self.expected})")
        return int(value) if self.kind is int else float(value) + 0.0

    def parse(self, text: str):
        """The value of the option's ``text``; :class:`UsageError` saying why not (without the
        option's name: argparse prefixes it)."""
        try:
            value = self.kind(text)
        except (ValueError, OverflowError):
            value = text
        why = self.problem(value, text if isinstance(value, (int, float)) else repr(text))
        if why is not None:
            raise UsageError(f"{why} (expected {self.expected})")
        return value


def _bound(x: float) -> str:
    """A bound for a message: as written (``0.0``), a large one short (``1e+12``) where that
    is exact (an integer such as ``2**63 - 1`` in full)."""
    if abs(x) < 1e6:
        return f"{x}"
    short = f"{x:g}"
    return short if not isinstance(x, int) or int(float(short)) == x else str(x)


def _short(value: Any) -> str:
    """``value`` for a message: a long integer by its size, not its digits."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10**15:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    if isinstance(value, float):          # as written (-3.0), a very large or small one short
        return repr(value) if value == 0 or 1e-4 <= abs(value) < 1e15 else f"{value:g}"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _describe(value: Any) -> str:
    if value is None:
        return "empty"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {_short(value)}"
    if isinstance(value, str):
        return f"the string '{value}'"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return type(value).__name__
