"""The scenario as run: its mapping with the Monte Carlo settings the run used, as YAML a person
reads (multi-line text as literal blocks, no doubled quotes), typeset on text pages."""

from __future__ import annotations

import textwrap

import yaml

from navsim.report.figures import Page, ReportInput
from navsim.report.tables import layout, monospace_block

#: the lines of YAML shown (the rest is in ``scenario.resolved.yaml``)
MAX_LINES = 120
#: the widest line of the block, in characters (wider ones wrap under their indent)
WIDTH = 118


class _ReadableDumper(yaml.SafeDumper):
    """Multi-line strings as literal blocks (``|``); a string that must be quoted in double
    quotes (single quotes would double every apostrophe: ``P0''s``)."""


def _str(dumper: yaml.SafeDumper, value: str):
    if "\n" in value:
        return dumper.represent_scalar("tag:yaml.org,2002:str", value.strip("\n") + "\n", style="|")
    node = dumper.represent_scalar("tag:yaml.org,2002:str", value)
    if "'" in value:
        analysis = dumper.analyze_scalar(value)
        if not analysis.allow_flow_plain:
            node.style = '"'
    return node


_ReadableDumper.add_representer(str, _str)


def scenario_yaml(resolved: dict) -> str:
    """``resolved`` as the page shows it (also valid YAML that reads back to the same mapping)."""
    return yaml.dump(resolved, Dumper=_ReadableDumper, sort_keys=False, width=WIDTH, default_flow_style=None,
                     allow_unicode=True)


def _wrapped(text: str) -> list[str]:
    out = []
    for line in text.splitlines():
        indent = line[:len(line) - len(line.lstrip())]
        out += textwrap.wrap(line, WIDTH, subsequent_indent=indent + "    ", drop_whitespace=False) or [""]
    return out


def pages(inp: ReportInput) -> list[Page]:
    """The scenario's YAML with the ``montecarlo`` settings the run used (the first
    :data:`MAX_LINES` lines)."""
    record, resolved = inp.record, dict(inp.scenario.raw)
    resolved["montecarlo"] = {**(resolved.get("montecarlo") or {}), **record.montecarlo()}
    text = _wrapped(scenario_yaml(resolved))
    if len(text) > MAX_LINES:
        text = text[:MAX_LINES - 2] + ["...", "(the whole file: scenario.resolved.yaml)"]
    title = f"{inp.scenario.name}: the scenario as run"
    figs = layout(title, [monospace_block(text)])
    return [Page("scenario" if i == 0 else f"scenario_{i + 1}", "The scenario as run" + (" (continued)" if i else ""),
                 f) for i, f in enumerate(figs)]
