"""``--set PATH=VALUE``: one change to a YAML mapping, given on the command line or to the API.

Grammar
-------
``PATH`` is keys joined by dots, ``sensors.gps.override.position_sigma``; a key holding a list is
followed by ``[i]`` (the i-th entry, from 0) or ``[label]`` (the entry whose ``label``, or else
``name``, is that text: ``estimators[ES-KF 16].period_s``); the brackets' text is taken as it
stands, dots and spaces included. ``VALUE`` is YAML (``3 m``, ``200``, ``[1, 2, 3]``,
``{model: neo_m8n}``; an empty value is null, which a scenario reads as "not given").

A key the mapping lacks is added (``override`` under a sensor that has none); a list entry that
is not there, a key under a value that is not a mapping, and a path or value that does not
parse are refused here. Whether the changed mapping is a valid scenario is for the same
validation as a file's (:func:`navsim.experiment.scenario.load_scenario`): an error it finds at
a path a ``--set`` wrote names that ``--set`` (:func:`blame`).
"""

from __future__ import annotations

import copy
import difflib
from dataclasses import dataclass
from pathlib import Path

import yaml

from navsim.foundations.config import parse_yaml, close_match
from navsim.foundations.errors import ScenarioError


@dataclass(frozen=True)
class Override:
    """One change: the path as given, its parts, the value, and how messages name it."""

    path: str          #: ``sensors.gps.override.position_sigma`` as given
    parts: tuple       #: keys (str) and list selectors (``[i]`` int, ``[label]`` str in a 1-tuple)
    value: object      #: the value (read as YAML from a ``--set``); copied where it is set
    origin: str        #: how an error names it: ``--set PATH=VALUE``
    text: str          #: ``PATH=VALUE`` as recorded (``run.json``): as given, or the value as YAML

    def as_text(self) -> str:
        """``PATH=VALUE`` as recorded in ``run.json`` and ``scenario.resolved.yaml``."""
        return self.text


def make_override(path: str, value, origin: str | None = None, text: str | None = None) -> Override:
    """An :class:`Override` of ``value`` at ``path`` (a malformed path or a value YAML cannot
    hold is a :class:`ScenarioError` naming ``origin``, default ``--set PATH=VALUE``)."""
    path = path.strip()
    try:
        shown = text or f"{path}={_yaml_line(value)}"
    except yaml.YAMLError:
        raise _error(origin or f"--set {path}", f"its value {value!r} is not a YAML value",
                     hint="plain numbers, strings, booleans, lists and mappings (not numpy's or a tuple)") from None
    origin = origin or f"--set {shown}"
    return Override(path=path, parts=tuple(_split(path, origin)), value=copy.deepcopy(value), origin=origin,
                    text=shown)


def parse_override(text: str) -> Override:
    """``PATH=VALUE`` (split at the first ``=`` outside brackets; the value YAML) to an
    :class:`Override`; a malformed one is a :class:`ScenarioError` naming it."""
    cut = _value_start(text)
    path, value = (text, None) if cut is None else (text[:cut], text[cut + 1:])
    origin = f"--set {text}"
    if value is None or not path.strip():
        raise _error(origin, "is not PATH=VALUE", hint="--set sensors.gps.override.position_sigma='3 m'")
    try:
        parsed = parse_yaml(value, Path("--set")) if value.strip() else None
    except ScenarioError as exc:
        raise _error(origin, f"its value is {exc.detail}",
                     hint="quote a value holding ': ' or '#': --set \"description='a: b'\"") from None
    return make_override(path, parsed, origin, text=text)


def _value_start(text: str) -> int | None:
    """The index of the first ``=`` outside brackets (None: none)."""
    depth = 0
    for i, c in enumerate(text):
        depth += (c == "[") - (c == "]")
        if c == "=" and depth <= 0:
            return i
    return None


def _yaml_line(value) -> str:
    return yaml.safe_dump(value, default_flow_style=True, width=1_000_000).strip().removesuffix("\n...").strip()


def _split(path: str, origin: str) -> list:
    """``a.b[2].c[ES-KF 16]`` -> ``['a', 'b', (2,), 'c', ('ES-KF 16',)]``: keys joined by dots,
    each followed by any number of ``[selector]``; a selector's text runs to its matching
    ``]`` (brackets inside it nest); digits alone are an index."""
    parts, i = [], 0
    while i < len(path):
        end = min([j for j in (path.find(".", i), path.find("[", i)) if j >= 0], default=len(path))
        key = path[i:end]
        if not key or "]" in key:
            raise _error(origin, f"has an empty or malformed key at '{path[i:] or path}' in '{path}'",
                         hint="keys joined by dots, a list entry as key[0] or key[label]")
        parts.append(key)
        i = end
        while i < len(path) and path[i] == "[":
            close = _closing(path, i)
            sel = path[i + 1:close].strip() if close is not None else ""
            if not sel:
                raise _error(origin, f"has an unclosed or empty [ ] in '{path}'")
            parts.append((int(sel),) if sel.isascii() and sel.isdigit() else (sel,))
            i = close + 1
        if i < len(path):
            if path[i] != "." or i == len(path) - 1:
                raise _error(origin, f"has '{path[i:]}' after a key or a [ ] in '{path}'",
                             hint="a '.' and a key, or '[' after a key or a [ ]")
            i += 1
    return parts


def _closing(path: str, i: int) -> int | None:
    """The index of the ``]`` matching the ``[`` at ``i`` (None: unclosed)."""
    depth = 0
    for j in range(i, len(path)):
        depth += (path[j] == "[") - (path[j] == "]")
        if depth == 0:
            return j
    return None


def apply_overrides(data: dict | None, overrides) -> tuple[dict, dict]:
    """``data`` (not changed) with each override set, in order.

    Returns
    -------
    tuple
        ``(changed, written)``: the changed copy, and each override's path as validation names
        it (list entries by index: ``estimators[1].period_s``) -> ``(override, created)``, the
        keys it added that the mapping did not have (for :func:`blame`'s closest-path hint).
    """
    out = copy.deepcopy(data) if data is not None else {}
    written = {}
    for o in overrides:
        key_path, created = set_in(out, o)
        written[key_path] = (o, created)
    return out, written


def set_in(root: dict, o: Override) -> tuple[str, list]:
    """Set ``o`` in ``root`` in place; returns the path as validation names it and the first key
    it added, if any (``[(parent path, key, the parent's keys)]``)."""
    node, shown, created = root, "", []
    for n, part in enumerate(o.parts):
        last = n == len(o.parts) - 1
        if isinstance(part, tuple):
            index = _select(node, part[0], shown, o)
            if last:
                node[index] = copy.deepcopy(o.value)
            else:
                node = node[index]
            shown += f"[{index}]"
            continue
        if not isinstance(node, dict):
            raise _error(o.origin, f"{shown or 'the scenario'} is {_kind(node)}, not a mapping with '{part}'",
                         hint=f"set {shown} as a whole: --set '{shown}={{...}}'" if shown else None)
        if part not in node and not created:         # the first key added; those under it are new too
            created.append((shown, part, [str(k) for k in node]))
        shown = f"{shown}.{part}" if shown else part
        if last:
            node[part] = copy.deepcopy(o.value)
        else:
            if node.get(part) is None:
                node[part] = {} if not isinstance(o.parts[n + 1], tuple) else []
            node = node[part]
    return shown, created


def value_at(root: dict, path: str, origin: str):
    """The value at ``path`` (the grammar of ``--set``) in ``root``; a :class:`ScenarioError`
    naming ``origin`` and the closest existing key where the path leads nowhere."""
    o = make_override(path, None, origin)
    node, shown = root, ""
    for part in o.parts:
        if isinstance(part, tuple):
            node = node[_select(node, part[0], shown, o)]
            shown += f"[{part[0]}]"
            continue
        if not isinstance(node, dict) or part not in node:
            keys = [str(k) for k in node] if isinstance(node, dict) else []
            raise _error(origin, f"{shown or 'the scenario'} has no '{part}'",
                         hint=close_match(part, keys) or (f"its keys: {', '.join(keys)}" if keys else None))
        node = node[part]
        shown = f"{shown}.{part}" if shown else part
    return node


def _select(node, sel, shown: str, o: Override) -> int:
    """The index in the list ``node`` that ``[sel]`` names."""
    if not isinstance(node, list):
        raise _error(o.origin, f"{shown} is {_kind(node)}, not a list to index with [{sel}]")
    if isinstance(sel, int):
        if sel >= len(node):
            raise _error(o.origin, f"{shown} has {len(node)} entries, no [{sel}]",
                         hint=f"entries [0] to [{len(node) - 1}]" if node else None)
        return sel
    names = [_entry_name(x) for x in node]
    if sel in names:
        return names.index(sel)
    known = [x for x in names if x is not None]
    return _no_entry(o, shown, sel, known)


def _no_entry(o: Override, shown: str, sel: str, known: list) -> int:
    hint = close_match(sel, known)
    raise _error(o.origin, f"{shown} has no entry labelled '{sel}'",
                 hint=hint or ("the labels: " + ", ".join(known) if known else "index it by number: [0]"))


def _entry_name(x) -> str | None:
    if isinstance(x, dict):
        for key in ("label", "name"):
            if isinstance(x.get(key), str):
                return x[key]
    return None


def blame(error: ScenarioError, written: dict) -> ScenarioError:
    """``error`` (the validation of the changed mapping) naming the ``--set`` that wrote the path
    it is about, with the closest existing path where that ``--set`` added keys; ``error`` itself
    when no ``--set`` wrote there."""
    key = error.key or ""
    under = lambda k, p: k == p or k.startswith((p + ".", p + "["))
    # a --set at or above the error's key (the deepest one), else one it added a mapping for,
    # else one below it (the shallowest)
    above = [p for p in written if under(key, p)]
    added = [p for p, (_, created) in written.items() if any(under(key, _joined(a, b)) for a, b, _ in created)]
    below = [p for p in written if under(p, key)]
    hits = above or added or below
    if not hits:
        return error
    o, created = written[max(hits, key=len) if above or added else min(hits, key=len)]
    hint = error.hint or _closest(created)
    return ScenarioError(error.detail, file=error.file, key=error.key, expected=error.expected,
                         hint=hint, origin=o.origin)


def _joined(parent: str, key: str) -> str:
    return f"{parent}.{key}" if parent else key


def _closest(created: list) -> str | None:
    """'did you mean' for the first key a ``--set`` added beside existing ones."""
    for parent, key, siblings in created:
        match = difflib.get_close_matches(key, siblings, n=1, cutoff=0.6)
        if match:
            return f"the closest existing path: {_joined(parent, match[0])} (the --set added '{key}')"
    return None


def _kind(value) -> str:
    return "a list" if isinstance(value, list) else "null" if value is None else f"{type(value).__name__} {value!r}"


def _error(origin: str, message: str, hint: str | None = None) -> ScenarioError:
    return ScenarioError(message, hint=hint, origin=origin)


def set_comments(texts) -> str:
    """The ``--set`` changes as YAML comment lines (``# --set PATH=VALUE``; a value of several
    lines keeps each commented), the head of a written scenario."""
    return "".join("# --set " + "\n#   ".join(str(x).splitlines() or [""]) + "\n" for x in texts)
